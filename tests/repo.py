"""Where the project's own files are, for tests that read the bundled specs, jobs and docs.

Importable from every test folder (``tests/`` is on ``sys.path`` because of its ``conftest.py``).
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
"""The repository's top folder (``checker/``, ``models/``, ``docs/`` ... are under it)."""
