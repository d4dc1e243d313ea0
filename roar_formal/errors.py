"""User-facing errors: every error a user can cause carries a location.

The CLI catches :class:`RoarError` and prints ``file:line:col: message``
without a Python traceback; anything else reaching the CLI is a bug.
"""

from __future__ import annotations

import re
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterator, Optional


@dataclass(frozen=True)
class Pos:
    """A source location (1-based line and column)."""

    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class RoarError(Exception):
    """An error in user input (or a failed check) with an optional location."""

    def __init__(self, message: str, pos: Pos | None = None, notes: list[str] | None = None):
        super().__init__(message)
        self.message = message
        self.pos = pos
        self.notes = list(notes or [])

    def format(self) -> str:
        head = f"{self.pos}: {self.message}" if self.pos else self.message
        return "\n".join([head] + [f"  {n}" for n in self.notes])

    def __str__(self) -> str:  # pragma: no cover - convenience
        return self.format()


class ErrorList(RoarError):
    """Several problems found in one pass: the first as the message, the others as notes, all
    in ``errors`` (a user fixes them in one edit rather than one run per error)."""

    def __init__(self, errors: list[RoarError]):
        self.errors = []
        for e in errors:   # (a list inside a list: its own errors, in order)
            self.errors += e.errors if isinstance(e, ErrorList) else [e]
        first = self.errors[0]
        more = len(self.errors) - 1
        msg = first.message + (f" (and {more} more error{'s' if more > 1 else ''})" if more else "")
        super().__init__(msg, first.pos, notes=first.notes + [e.format() for e in self.errors[1:]])


@contextmanager
def collecting(errors: list) -> Iterator[None]:
    """Run a block, appending the :class:`RoarError` it raises to ``errors`` instead of
    stopping (the checks after it that do not depend on it still run)."""
    try:
        yield
    except RoarError as exc:
        errors.append(exc)


class SyntaxError_(RoarError):
    """Malformed input text (named with a trailing underscore to avoid the builtin)."""


class TypeError_(RoarError):
    """An ill-typed or ill-formed declaration."""


class UnsupportedError(RoarError):
    """A construct the engine refuses rather than misreads."""


class QueryError(RoarError):
    """A directive whose outcome differs from what it declared (e.g. solution count)."""


def did_you_mean(word: str, choices) -> str:
    """A hint naming the choice closest to a misspelt word, " (did you mean 'x'?)"; empty when
    none is close. Here, below every reader of user input, so that any of them can use it."""
    import difflib
    m = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean '{m[0]}'?)" if m else ""


def json_message(exc) -> str:
    """A ``json.JSONDecodeError``'s message for a located error: Python's ends some with "at"
    (its own text gives the position next), so that word becomes "here"."""
    return exc.msg[:-3] + " here" if exc.msg.endswith(" at") else exc.msg


def _moved(pos: Optional[Pos], tag: str, origin: Pos) -> Optional[Pos]:
    if pos is None or pos.file != tag:
        return pos
    if pos.line == 1:
        return Pos(origin.file, origin.line, origin.col + pos.col - 1)
    return Pos(origin.file, origin.line + pos.line - 1, pos.col)


def relocate(exc: RoarError, tag: str, origin: Pos) -> RoarError:
    """``exc`` with the positions inside a text parsed under the name ``tag`` (a request given as
    a string, say) moved to where that text is written: ``origin`` is where its first character
    is (a job file's line and column inside the quotes, a test's line). Changed in place."""
    exc.pos = _moved(exc.pos, tag, origin)
    for e in getattr(exc, "errors", ()) or ():
        if isinstance(e, RoarError):
            e.pos = _moved(e.pos, tag, origin)
    pattern = re.compile(re.escape(tag) + r":(\d+):(\d+)")

    def sub(m: re.Match) -> str:
        return str(_moved(Pos(tag, int(m.group(1)), int(m.group(2))), tag, origin))

    exc.notes = [pattern.sub(sub, n) for n in exc.notes]
    return exc


@contextmanager
def written_at(tag: str, origin: Optional[Pos]) -> Iterator[None]:
    """Errors raised inside, at positions of the text named ``tag``, are moved to ``origin``
    (see :func:`relocate`); with no origin, nothing changes."""
    try:
        yield
    except RoarError as exc:
        if origin is not None:
            relocate(exc, tag, origin)
        raise
