"""``roar-verify clf FILE``: run a Celf program's directives.

Start-up matters here (a small Celf program runs in a few milliseconds): the command reads its
plain options itself (:func:`fast_args`) and prints its lines without rich (:func:`line_printer`),
so neither typer nor rich is imported on that path; ``register`` (the Typer command, for
``--help`` and unusual arguments) imports typer only when it is called.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path
from typing import Callable, Optional

from ..errors import QueryError, RoarError
from ..lines import visible


def celf_category(exc: Exception) -> str:
    """The kind of failure Celf would report: parse error, type error, mode error, general error
    (Celf's "Error in query": malformed bounds) or query failed."""
    from ..errors import SyntaxError_, TypeError_, UnsupportedError
    from ..clf.query import MalformedQueryError
    from ..clf.signature import ModeError

    if isinstance(exc, SyntaxError_):
        return "parse error"
    if isinstance(exc, ModeError):
        return "mode error"
    if isinstance(exc, UnsupportedError):
        return "not supported by this engine"
    if isinstance(exc, TypeError_):
        return "type error"
    if isinstance(exc, MalformedQueryError):
        return "general error"
    if isinstance(exc, QueryError):
        return "query failed"
    from ..clf.builtins import BuiltinError
    if isinstance(exc, BuiltinError):   # numbers and strings are an extension: Celf has no such error
        return "built-in error, an extension"
    return ""


_COLOURS = {"green": "32", "red": "31", "cyan": "36"}


def line_style(line: str) -> Optional[str]:
    """The colour of an output line on a terminal: verdicts green or red, solutions cyan."""
    if line.endswith(" ok.") or line.startswith("Success: "):
        return "green"
    if line == "Query failed" or line.startswith(("Exec failed", "Trace failed")):
        return "red"
    if line.startswith((" #", "Solution")):
        return "cyan"
    return None


def line_printer(stream=None) -> Callable[[str], None]:
    """Print one output line: as written (control characters shown as ``\\xNN``), coloured only
    on a terminal (not with ``NO_COLOR`` set or ``TERM=dumb``)."""
    out = stream if stream is not None else sys.stdout
    colour = (getattr(out, "isatty", lambda: False)() and "NO_COLOR" not in os.environ
              and os.environ.get("TERM") != "dumb")

    def emit(line: str) -> None:
        text = visible(line)
        style = line_style(line) if colour else None
        if style:
            text = f"\x1b[{_COLOURS[style]}m{text}\x1b[0m"
        out.write(text + "\n")

    return emit


def run_clf(file: Path, seed: int = 0, trace: bool = False, fair: bool = False, proof: bool = True,
            max_steps: Optional[int] = None) -> None:
    """The ``roar-verify clf`` command: check and run FILE as Celf does (see docs/clf.md)."""
    from ..clf.query import run_file, with_big_stack

    if max_steps is not None and max_steps < 1:
        raise RoarError(f"--max-steps is a number of steps above 0, not {max_steps}")
    emit = line_printer()

    def job():
        return run_file(file, seed=seed, emit=emit, trace=trace, fair=fair, proofs=proof, max_steps=max_steps)

    try:
        with_big_stack(job)
    except BrokenPipeError:  # `roar-verify clf f.clf | head`: the reader left; stop quietly
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):  # no real file behind sys.stdout (a test's capture)
            pass
        sys.exit(141)  # 128 + SIGPIPE, as a shell reports a pipeline cut short
    except RecursionError:
        raise RoarError(f"{file}: the program recursed too deeply for this engine") from None
    except RoarError as exc:
        category = celf_category(exc)
        if category.startswith("built-in"):
            exc.notes.append("(an error of the built-in numbers and strings, an extension Celf does not have)")
        elif category.startswith("not supported"):
            exc.notes.append("(a construct Celf reads that this engine does not support)")
        elif category and not exc.message.startswith(category):
            exc.notes.append(f"({category}, in Celf's terms)")
        raise
    finally:
        sys.stdout.flush()


#: the options fast_args reads that take a number: option -> the numbers it takes
_NUMBER_OPTIONS = {"--seed": r"-?[0-9]+", "--max-steps": r"[0-9]+"}


def fast_args(args: list[str]) -> Optional[dict]:
    """The options of ``roar-verify clf ARGS`` read without Typer (whose start-up costs more
    than a small Celf program takes to run), or None when they need Typer (help, errors)."""
    out: dict = {"seed": 0, "trace": False, "fair": False, "proof": True, "max_steps": None}
    files = []
    i = 0
    while i < len(args):
        a = args[i]
        if a in ("--trace", "--fair", "--proof"):
            out[a[2:]] = True
        elif a == "--no-proof":
            out["proof"] = False
        elif a.split("=", 1)[0] in _NUMBER_OPTIONS:
            name, pattern = a.split("=", 1)[0], _NUMBER_OPTIONS[a.split("=", 1)[0]]
            if a == name:   # the value in the next argument, or after '='
                i += 1
                v = args[i] if i < len(args) else ""
            else:
                v = a[len(name) + 1:]
            if not re.fullmatch(pattern, v):
                return None
            out[name[2:].replace("-", "_")] = int(v)
        elif a.startswith("-") and a != "-":
            return None
        else:
            files.append(a)
        i += 1
    if len(files) != 1:
        return None
    out["file"] = Path(files[0])
    return out


def register(app) -> None:
    import typer

    @app.command("clf")
    def clf(
        file: Path = typer.Argument(..., help="A Celf program (.clf)."),
        seed: int = typer.Option(0, "--seed", help="Seed of the committed-choice scheduler."),
        trace: bool = typer.Option(False, "--trace", help="Print the context before and after every forward "
                                                          "step of #exec too (as #trace does)."),
        fair: bool = typer.Option(False, "--fair", help="Fair round-robin scheduling instead of random."),
        proof: bool = typer.Option(True, "--proof/--no-proof",
                                   help="Print each #query solution's proof term, as Celf does (the default); "
                                        "--no-proof prints 'Solution: _' and skips building the terms."),
        max_steps: Optional[int] = typer.Option(None, "--max-steps", help="Stop '#exec *' and '#trace *' "
                                                "after this many steps, failing, if the program has not quiesced "
                                                "(Celf runs them on, for ever if nothing ends them)."),
    ) -> None:
        """Type-check FILE and run its #query, #exec and #trace directives, as Celf does."""
        run_clf(file, seed=seed, trace=trace, fair=fair, proof=proof, max_steps=max_steps)
