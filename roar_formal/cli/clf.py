"""``roar-verify clf FILE``: run a Celf program's directives."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Optional

import typer

from .console import make_console
from ..errors import QueryError, RoarError


def celf_category(exc: Exception) -> str:
    """The kind of failure Celf would report: parse error, type error, mode error or query failed."""
    from ..errors import SyntaxError_, TypeError_, UnsupportedError
    from ..clf.signature import ModeError

    if isinstance(exc, SyntaxError_):
        return "parse error"
    if isinstance(exc, ModeError):
        return "mode error"
    if isinstance(exc, UnsupportedError):
        return "not supported by this engine"
    if isinstance(exc, TypeError_):
        return "type error"
    if isinstance(exc, QueryError):
        return "query failed"
    return ""


def run_clf(file: Path, seed: int = 0, trace: bool = False, fair: bool = False, proof: bool = False) -> None:
    """The ``roar-verify clf`` command: check and run FILE as Celf does (see docs/clf.md)."""
    from ..clf.query import run_file, with_big_stack

    console = make_console()

    def emit(line: str) -> None:
        style = None
        if line.endswith(" ok."):
            style = "green"
        elif line.endswith(" error.") or line == "Query failed":
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
        if category.startswith("not supported"):
            exc.notes.append("(a construct Celf reads that this engine does not support)")
        elif category and not exc.message.startswith(category):
            exc.notes.append(f"({category}, in Celf's terms)")
        raise


def fast_args(args: list[str]) -> Optional[dict]:
    """The options of ``roar-verify clf ARGS`` read without Typer (whose start-up costs more
    than a small Celf program takes to run), or None when they need Typer (help, errors)."""
    out: dict = {"seed": 0, "trace": False, "fair": False, "proof": False}
    files = []
    i = 0
    while i < len(args):
        a = args[i]
        if a in ("--trace", "--fair", "--proof"):
            out[a[2:]] = True
        elif a == "--seed" or a.startswith("--seed="):
            if a == "--seed":
                i += 1
                v = args[i] if i < len(args) else ""
            else:
                v = a[len("--seed="):]
            if not re.fullmatch(r"-?[0-9]+", v):
                return None
            out["seed"] = int(v)
        elif a.startswith("-") and a != "-":
            return None
        else:
            files.append(a)
        i += 1
    if len(files) != 1:
        return None
    out["file"] = Path(files[0])
    return out


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
        run_clf(file, seed=seed, trace=trace, fair=fair, proof=proof)
