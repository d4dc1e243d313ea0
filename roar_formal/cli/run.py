"""``roar-verify run SPEC --request ...`` and ``roar-verify compile SPEC --request ...``."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape

from .console import make_console, show
from ..errors import RoarError


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
        functional: Optional[Path] = typer.Option(None, "--functional",
                                                  help="Functional-layer module (default: SPEC.py next to the spec)."),
        max_steps: int = typer.Option(100_000, "--max-steps", help="Stop after this many CLF steps."),
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
        from ..roar.functional import functional_module, load_registry
        from ..roar.traces import jsonable, write_run_trace
        from ..roar.compile import compile_spec
        from ..roar.spec import load_spec
        from ..roar.run import parse_fault, run_model
        faults = [parse_fault(f) for f in fault]
        spec_ast = load_spec(spec)
        if png is not None or svg is not None or dot is not None:
            from ..roar.sources import spec_files
            from ..verify.pictures import check_output_file
            for path, option in ((png, "--png"), (svg, "--svg"), (dot, "--dot")):
                if path is not None:
                    check_output_file(path, option, [Path(f) for f in spec_files(spec_ast)] + [Path(spec)])
        reg = load_registry(functional_module(spec, functional))
        model = compile_spec(spec_ast, request, registry=reg, functional="python")
        console = make_console()
        if not as_json:
            console.print(f"[bold]{escape(str(spec))}[/]: request [cyan]{escape(request)}[/]"
                          + (f", faults {escape(', '.join(fault))}" if fault else "") + f", seed {seed}", markup=True)

        res = run_model(model, seed=seed, max_steps=max_steps, registry=reg, faults=faults, fair=fair)
        rules = [s[0] for s in res.steps]
        if not as_json:   # the one step table of run, simulate and replay (trace/render.py)
            from ..trace.render import event_lines, event_rows
            show(console, event_lines(event_rows(res.events, rules=rules), verbose=verbose))
        if trace is not None:
            _writing(trace, lambda: write_run_trace(trace, res, spec, request, seed, fault,
                                                   functional_module(spec, functional)))
        drawn = []
        if png is not None or svg is not None:
            from ..verify.pictures import write_chart
            from ..verify.report import run_report
            drawn = write_chart(run_report(res), f"{Path(spec).name}: request {request}: {res.outcome}",
                                f"the run of {request}", png, svg)
        if dot is not None:
            from ..roar.traces import run_records
            from ..tca.roar_runs import task_tree_events
            from ..tca.tree_dot import task_tree_dot
            from ..trace.format import write_atomic
            header, records = run_records(res, spec, request, seed, fault, functional_module(spec, functional))
            text = task_tree_dot(task_tree_events(header, records),
                                 f"{Path(spec).name}: request {request}: {res.outcome}")
            _writing(dot, lambda: write_atomic(dot, text))
        if as_json:
            print(json.dumps({"spec": str(spec), "request": request, "seed": seed, "faults": fault,
                              "outcome": res.outcome, "quiescent": res.quiescent, "clf_steps": len(res.steps),
                              "error_context": res.error_context, "final": {k: jsonable(v) for k, v in res.final.items()},
                              "events": [dict(step=e.step, **e.as_json()) for e in res.events]}, indent=2))
        else:
            style = "green" if res.ok else "red"
            end = "quiescent" if res.quiescent else f"stopped after {max_steps} steps"
            console.print(f"[{style}]request {escape(res.outcome)}[/] after {len(res.steps)} CLF steps ({end})",
                          markup=True)
            for line in res.error_context:
                console.print(f"  error context: {line}")
            if trace is not None:
                console.print(f"trace written to {trace}")
            for path in drawn:
                console.print(f"chart written to {path}")
            if dot is not None:
                console.print(f"task tree written to {dot}")
        if not res.ok:
            raise typer.Exit(1)

    @app.command("compile")
    def compile_cmd(
        spec: Path = typer.Argument(..., help="A spec: a .roar file, a hyper .ability file, or a hyper folder."),
        request: str = typer.Option(..., "--request", "-r", help="The constraint to enforce."),
        output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the CLF program here (default: stdout)."),
        functional: Optional[Path] = typer.Option(None, "--functional", help="Functional-layer module (for outcomes)."),
    ) -> None:
        """Print the CLF program a spec and a request compile to (framework included).

        Primitives become their declared outcome rules, so `roar-verify clf` runs the result.
        """
        from ..roar.functional import functional_module, load_registry
        from ..trace.format import write_atomic
        from ..roar.compile import compile_spec
        from ..roar.spec import load_spec
        from ..roar.ast import walk
        reg = load_registry(functional_module(spec, functional))
        spec_ast = load_spec(spec)
        model = compile_spec(spec_ast, request, registry=reg, functional="abstract")
        if output is None:
            sys.stdout.write(model.text)
        else:
            if output.exists() and output.resolve() == Path(spec).resolve():
                raise RoarError(f"{output}: refusing to overwrite the spec itself")
            sources = {Path(f).resolve() for f in {n.pos.file for n in walk(spec_ast)} if Path(f).is_file()}
            if output.resolve() in sources:
                raise RoarError(f"{output}: refusing to overwrite a file of the spec")
            _writing(output, lambda: write_atomic(output, model.text))


def _writing(path: Path, write) -> None:
    """Run ``write``; a file that cannot be written is the user's error (exit 2), not ours."""
    try:
        write()
    except OSError as exc:
        raise RoarError(f"{path}: cannot write: {exc.strerror or exc}") from None
