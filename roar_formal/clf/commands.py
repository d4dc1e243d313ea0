"""``roar-verify clf FILE``: run a Celf program's directives."""

from __future__ import annotations

from pathlib import Path

import typer

from ..console import make_console
from ..errors import QueryError, RoarError


def celf_category(exc: Exception) -> str:
    """The kind of failure Celf would report: parse error, type error, mode error or query failed."""
    from ..errors import SyntaxError_, TypeError_, UnsupportedError
    from .signature import ModeError

    if isinstance(exc, SyntaxError_):
        return "parse error"
    if isinstance(exc, ModeError):
        return "mode error"
    if isinstance(exc, (TypeError_, UnsupportedError)):
        return "type error"
    if isinstance(exc, QueryError):
        return "query failed"
    return ""


def register(app: typer.Typer) -> None:
    @app.command("clf")
    def clf(
        file: Path = typer.Argument(..., help="A Celf program (.clf)."),
        seed: int = typer.Option(0, "--seed", help="Seed of the committed-choice scheduler."),
        trace: bool = typer.Option(False, "--trace", help="Print the context after every forward step."),
        fair: bool = typer.Option(False, "--fair", help="Fair round-robin scheduling instead of random."),
        proof: bool = typer.Option(False, "--proof", help="Print the proof term of each #query solution."),
    ) -> None:
        """Type-check FILE and run its #query, #exec and #trace directives."""
        from .query import run_file, with_big_stack

        console = make_console()

        def emit(line: str) -> None:
            style = None
            if line.endswith(" ok."):
                style = "green"
            elif line.endswith(" error.") or line == "No solution.":
                style = "red"
            elif line.startswith((" #", "Solution")):
                style = "cyan"
            console.print(line, style=style, markup=False, soft_wrap=True)

        def job():
            return run_file(file, seed=seed, emit=emit, trace=trace, fair=fair, proofs=proof)

        try:
            with_big_stack(job)
        except RecursionError:
            raise RoarError(f"{file}: the program recursed too deeply for this engine") from None
        except RoarError as exc:
            category = celf_category(exc)
            if category and not exc.message.startswith(category):
                exc.notes.append(f"({category}, in Celf's terms)")
            raise
