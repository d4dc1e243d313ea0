"""The running test's settings, as the pytest plugin sets them: kept in a module that imports
nothing, so that the plugin costs other projects' test suites nothing."""

from __future__ import annotations

import contextvars
from pathlib import Path
from typing import Callable, Optional

#: (budget keywords, the traces folder when first asked for) of the running test, set by the
#: plugin around each test; the folder is a function so that no test pays for making it
PLUGIN: contextvars.ContextVar[Optional[tuple[dict, Callable[[], Path]]]] = contextvars.ContextVar(
    "roar_formal_pytest", default=None)
