"""The one way the command line prints: rich consoles that never rewrite what they print.

rich replaces ``:name:`` emoji codes and interprets ``[style]`` markup by
default, so ``p.clf:100:5: ...`` would print as ``p.clf💯5: ...`` and a
message id such as ``[bold]`` would vanish or raise. Every console of the
command line comes from :func:`make_console`: emoji substitution, markup and
highlighting are off. A line of ours that wants style passes ``markup=True``
and escapes (:func:`rich.markup.escape`) every part that comes from input,
or builds a :class:`rich.text.Text` (see :func:`styled`). Control characters in
printed strings (an escape sequence hidden in a trace or a file name) are
shown as ``\\x1b``, never sent to the terminal.
"""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.text import Text

from ..lines import Lines, visible

class SafeConsole(Console):
    """A console whose strings never carry control characters to the terminal."""

    def render_str(self, text: str, **kwargs: Any) -> Text:  # every printed string passes here
        return super().render_str(visible(text), **kwargs)

    def on_broken_pipe(self) -> None:
        """The reader of the output went away (``check ... | head``): stop quietly with the status
        of a process killed by SIGPIPE (128 + 13) as a shell reports it, not rich's 1, which
        would read as "a verdict differs from its expectation". The SIGTERM path unwinds the
        same way, so files being written are removed."""
        import os
        import sys
        self.quiet = True
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # no real file behind sys.stdout (a test's capture)
            pass
        raise SystemExit(141)


def make_console(**kwargs: Any) -> Console:
    """A console with emoji substitution, markup and highlighting off (overridable per print).

    Off a terminal (a pipe, a CI log) with no COLUMNS set, lines may be 200 characters wide, so
    tables fit their content instead of being cut at rich's default of 80."""
    import os
    import sys
    stream = sys.stderr if kwargs.get("stderr") else sys.stdout
    if "width" not in kwargs and "COLUMNS" not in os.environ and not getattr(stream, "isatty", lambda: False)():
        kwargs["width"] = 200
    kwargs.setdefault("highlight", False)
    kwargs.setdefault("markup", False)
    kwargs["emoji"] = False
    return SafeConsole(**kwargs)


def styled(*parts: Any) -> Text:
    """Text from plain strings and ``(text, style)`` pairs; nothing in it is markup or emoji."""
    return Text.assemble(*parts)


def show(console: Console, lines: Lines) -> None:
    """Print a report of the library (:class:`~roar_formal.lines.Lines`) with its styles."""
    for line in lines:
        console.print(Text.assemble(*line.segments), soft_wrap=not line.wrap)
