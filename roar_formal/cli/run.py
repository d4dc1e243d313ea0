"""``roar-verify run SPEC --request ...`` and ``roar-verify compile SPEC --request ...``."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import typer

from .console import make_console, show
from ..errors import Pos, RoarError
from ..outputs import check_outputs

#: where an error in the text of ``--request`` is reported (its column counted in the option's value)
COMMAND_LINE_REQUEST = Pos("--request", 1, 1)


def register(app: typer.Typer) -> None:
    @app.command("run")
    def run(
        spec: Path = typer.Argument(..., help="A spec: a .roar file, a hyper .ability file, or a hyper folder."),
        request: str = typer.Option(..., "--request", "-r",
                                    help="The constraint to enforce, e.g. 'loco::pos == loco::goal where loco::goal == 5'."),
        seed: int = typer.Option(0, "--seed", help="Seed of the committed-choice scheduler."),
        fault: list[str] = typer.Option([], "--fault",
                                        help="Make a primitive fail: NAME (every call), NAME:K (its K-th call) "
                                             "or NAME=OUTCOME (a declared outcome). Repeatable."),
        crash: list[str] = typer.Option([], "--crash",
                                        help="Make an agent crash: AGENT@STEP (at that step of the run, or the first "
                                             "one after it at which the agent handles a request; it comes back as "
                                             "soon as it can) or AGENT@STEP-BACK (it comes back at step BACK). "
                                             "Its pending constraints fail with an availability entry. Repeatable."),
        functional: Optional[Path] = typer.Option(None, "--functional",
                                                  help="Functional-layer module (default: SPEC.py next to the spec)."),
        time: str = typer.Option("untimed", "--time", help="'untimed' (default) or 'timed': model the periods of "
                                 "wait, assert and ensure with a discrete clock (docs/semantics.md, Time)."),
        wait_timeout: Optional[int] = typer.Option(None, "--wait-timeout", help="Timed only: a wait with a period "
                                                   "gives up after this many milliseconds (a local failure)."),
        max_steps: int = typer.Option(100_000, "--max-steps", min=1, help="Stop after this many CLF steps."),
        trace: Optional[Path] = typer.Option(None, "--trace", help="Write the JSON Lines trace here."),
        fair: bool = typer.Option(False, "--fair", help="Fair round-robin scheduling instead of seeded random."),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="Show the CLF rule of each event."),
        as_json: bool = typer.Option(False, "--json", help="Print the result as JSON."),
        png: Optional[Path] = typer.Option(None, "--png", help="Draw the run's message sequence chart here (PNG)."),
        svg: Optional[Path] = typer.Option(None, "--svg", help="Draw the run's message sequence chart here (SVG)."),
        dot: Optional[Path] = typer.Option(None, "--dot", help="Write the run's task tree here (DOT: goals, "
                                           "commands, sequential-achievement constraints; `dot -Tsvg` draws it)."),
    ) -> None:
        """Run SPEC on a request to quiescence and print the ROAR-level trace.

        Exit status: 0 when the request succeeds, 1 when it fails or does not finish, 2 on bad input.
        """
        from ..testing.api import load_spec, parse_faults
        from ..roar.run import parse_crash
        faults = parse_faults(fault)
        crashes = [parse_crash(c) for c in crash]
        spec_obj = load_spec(spec, functional=functional)
        check_outputs((("--trace", trace), ("--png", png), ("--svg", svg), ("--dot", dot)), spec_obj.input_files())
        # a bad request (or time) is reported before anything is printed
        spec_obj.compile(request, "python", crashes=crashes or None, time=time, wait_timeout=wait_timeout,
                         request_at=COMMAND_LINE_REQUEST)
        console = make_console()
        report = spec_obj.run(request, seed=seed, faults=faults, max_steps=max_steps, fair=fair, strict_faults=True,
                              crashes=crashes, time=time, wait_timeout=wait_timeout)
        if not as_json:
            show(console, report.header_lines())
            show(console, report.event_lines(verbose))   # the one step table of run, simulate and replay
        if trace is not None:
            _writing(trace, lambda: report.save_trace(trace))
        drawn = report.save_chart(png, svg) if png is not None or svg is not None else []
        if dot is not None:
            _writing(dot, lambda: report.save_task_tree(dot))
        if as_json:
            print(json.dumps(report.as_json(), indent=2))
        else:
            show(console, report.end_lines())
            if trace is not None:
                console.print(f"trace written to {trace}")
            for path in drawn:
                console.print(f"chart written to {path}")
            if dot is not None:
                console.print(f"task tree written to {dot}")
        if not report.ok:
            raise typer.Exit(1)

    @app.command("compile")
    def compile_cmd(
        spec: Path = typer.Argument(..., help="A spec: a .roar file, a hyper .ability file, or a hyper folder."),
        request: str = typer.Option(..., "--request", "-r", help="The constraint to enforce."),
        output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the CLF program here (default: stdout)."),
        functional: Optional[Path] = typer.Option(None, "--functional", help="Functional-layer module (for outcomes)."),
        time: str = typer.Option("untimed", "--time", help="'untimed' (default) or 'timed' (docs/semantics.md, Time)."),
        wait_timeout: Optional[int] = typer.Option(None, "--wait-timeout",
                                                   help="Timed only: a wait with a period gives up after this many ms."),
    ) -> None:
        """Print the CLF program a spec and a request compile to (framework included).

        Primitives become their declared outcome rules, so `roar-verify clf` runs the result.
        """
        from ..testing.api import load_spec
        from ..trace.format import write_atomic
        spec_obj = load_spec(spec, functional=functional)
        model = spec_obj.compile(request, "abstract", time=time, wait_timeout=wait_timeout,
                                 request_at=COMMAND_LINE_REQUEST)
        if output is None:
            sys.stdout.write(model.text)
        else:
            check_outputs([("--output", output)], spec_obj.input_files())
            _writing(output, lambda: write_atomic(output, model.text))


def _writing(path: Path, write) -> None:
    """Run ``write``; a file that cannot be written is the user's error (exit 2), not ours."""
    try:
        write()
    except OSError as exc:
        raise RoarError(f"{path}: cannot write: {exc.strerror or exc}") from None
