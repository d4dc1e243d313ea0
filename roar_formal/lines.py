"""Styled lines: what the library's reports produce, and what the command line prints.

Reports (counterexamples, step tables, robot replays) are written once, as a
:class:`Lines` document: plain text in segments, each with an optional style
name (``"dim"``, ``"red"``, ...). The command line (``roar_formal.cli``) shows
a document on a terminal with colours; the library (``roar_formal.testing``,
failure messages) joins it into plain text. Text is never read as markup, so
names and strings from a user's spec print as written.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Iterator, Union

Segment = tuple[str, str]          # (text, style name or "")
Part = Union[str, Segment]

__all__ = ["Line", "Lines", "Part", "Segment", "visible"]

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def visible(text: str) -> str:
    """``text`` with control characters (other than newline and tab) written as ``\\xNN``:
    an escape sequence hidden in a trace or a file name is shown, never sent to a terminal."""
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


@dataclass
class Line:
    segments: list[Segment]
    wrap: bool = False   # True: a terminal may fold it at its width; False: printed as one line

    @property
    def text(self) -> str:
        return "".join(t for t, _s in self.segments)

    def __str__(self) -> str:
        return self.text


@dataclass
class Lines:
    """A document of styled lines, appended to in order."""

    items: list[Line] = field(default_factory=list)

    def add(self, *parts: Part, style: str = "", wrap: bool = False) -> "Lines":
        """Append one line made of ``parts``: strings (in ``style``) or ``(text, style)`` pairs."""
        segs = [(p, style) if isinstance(p, str) else (str(p[0]), p[1] or "") for p in parts]
        self.items.append(Line(segs, wrap))
        return self

    def extend(self, other: "Lines") -> "Lines":
        self.items.extend(other.items)
        return self

    def __iter__(self) -> Iterator[Line]:
        return iter(self.items)

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i):
        """Line ``i`` (a :class:`Line`; ``.text`` is its plain text), or a slice of them."""
        return self.items[i]

    def text(self) -> str:
        """The document as plain text, one line per line (control characters made visible)."""
        return "\n".join(visible(line.text) for line in self.items)
