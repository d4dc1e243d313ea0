"""User-facing errors: every error a user can cause carries a location.

The CLI catches :class:`RoarError` and prints ``file:line:col: message``
without a Python traceback; anything else reaching the CLI is a bug.
"""

from __future__ import annotations

from dataclasses import dataclass


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


class SyntaxError_(RoarError):
    """Malformed input text (named with a trailing underscore to avoid the builtin)."""


class TypeError_(RoarError):
    """An ill-typed or ill-formed declaration."""


class UnsupportedError(RoarError):
    """A construct the engine refuses rather than misreads."""


class QueryError(RoarError):
    """A directive whose outcome differs from what it declared (e.g. solution count)."""
