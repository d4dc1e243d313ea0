"""Input files are data of bounded size that a reader can finish: refuse the others before opening.

A FIFO blocks ``open``; ``/dev/zero`` or ``/dev/urandom`` never ends; a multi-gigabyte file
exhausts memory. :func:`check_input_file` is called by every reader before it opens a file
the user named (directly or through a job file) and turns such inputs into a user error.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import Pos, RoarError

#: the largest input file a reader accepts (models, specs, jobs, traces, scenarios)
MAX_INPUT_BYTES = 64 << 20

_KINDS = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def check_input_file(path, pos: Pos | None = None) -> None:
    """Raise a :class:`RoarError` if ``path`` exists and is not a regular file of bounded size.

    A missing file or a folder is left to the reader (it says so in its own words)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return
    for test, what in _KINDS:
        if test(st.st_mode):
            raise RoarError(f"cannot read {Path(path)}: it is {what}, not a regular file", pos)
    if stat.S_ISREG(st.st_mode) and st.st_size > MAX_INPUT_BYTES:
        raise RoarError(f"cannot read {Path(path)}: {st.st_size:,} bytes, more than the {MAX_INPUT_BYTES >> 20} MiB "
                        "an input file may have", pos)


def toml_limit_error(exc: BaseException, text: str, file: str, lead: str = "invalid TOML") -> RoarError:
    """The located error for what ``tomllib.loads`` raises beyond :class:`tomllib.TOMLDecodeError`:
    a ``RecursionError`` (arrays or inline tables nested too deeply) or a ``ValueError`` (an
    integer past Python's int-string limit). The position is the first line that goes too deep
    or holds the long number."""
    import re
    lines = text.splitlines() or [""]
    if isinstance(exc, RecursionError):
        depth = 0
        for n, line in enumerate(lines, 1):
            for c, ch in enumerate(line, 1):
                depth += 1 if ch in "[{" else -1 if ch in "]}" else 0
                if depth > 100:
                    return RoarError(f"{lead}: arrays or tables nested too deeply (more than 100 levels)",
                                     Pos(file, n, c))
        return RoarError(f"{lead}: arrays or tables nested too deeply", Pos(file, 1, 1))
    for n, line in enumerate(lines, 1):
        m = re.search(r"\d[\d_]{4000,}", line)
        if m:
            return RoarError(f"{lead}: a number with more than 4000 digits", Pos(file, n, m.start() + 1))
    return RoarError(f"{lead}: {exc}", Pos(file, 1, 1))
