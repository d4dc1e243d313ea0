"""``roar-verify simulate`` and ``roar-verify conform``: specs on the pymunk reference robot."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from ..errors import RoarError
from ..outputs import check_outputs

__all__ = ["register"]


def _console():
    from .console import make_console
    return make_console()


def register(app: typer.Typer) -> None:
    @app.command("simulate")
    def simulate_cmd(
        spec: Path = typer.Argument(..., help="A spec: a .roar file, a hyper .ability file, or a hyper folder."),
        scenario: Path = typer.Option(..., "--scenario", "-s", help="The robot's world (TOML, models/scenarios/)."),
        request: str = typer.Option(..., "--request", "-r", help="The constraint to enforce."),
        seed: Optional[int] = typer.Option(None, "--seed", help="Seed of the scheduler and of every noise term "
                                           "(default: the scenario's seed)."),
        fault: list[str] = typer.Option([], "--fault", help="Turn on a fault point of the scenario (door_closes), "
                                        "or make a primitive fail (NAME, NAME:K, NAME=OUTCOME). Repeatable."),
        functional: Optional[Path] = typer.Option(None, "--functional",
                                                  help="Functional-layer module (default: SPEC.py next to the spec)."),
        trace: Optional[Path] = typer.Option(None, "--trace", help="Write the robot trace (JSON Lines) here."),
        png: Optional[Path] = typer.Option(None, "--png", help="Draw the map, planned paths and trajectory here."),
        max_steps: int = typer.Option(200_000, "--max-steps", min=1, help="Stop after this many CLF steps."),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="Show the CLF rule of each event."),
        as_json: bool = typer.Option(False, "--json", help="Print the result as JSON."),
    ) -> None:
        """Run SPEC on a request with its primitives on the pymunk robot, in simulated time.

        Prints the ROAR-level trace with the simulated time and the robot's pose at each event.
        Exit status: 0 when the request succeeds, 1 when it fails or does not finish, 2 on bad input.
        """
        from ..testing.api import load_spec
        from .console import show

        spec_obj = load_spec(spec, functional=functional)
        check_outputs((("--trace", trace), ("--png", png)), spec_obj.input_files() + [scenario])
        report = spec_obj.run(request, scenario=scenario, seed=seed, faults=fault, max_steps=max_steps,
                              strict_faults=True)
        if trace is not None:
            _writing(trace, lambda: report.save_trace(trace))
        if png is not None:
            report.save_picture(png)
        if as_json:
            print(json.dumps(report.as_json(), indent=2))
        else:
            from rich.text import Text
            console = _console()
            show(console, report.lines(verbose))
            if trace is not None:
                console.print(Text(f"trace written to {trace}"))
            if png is not None:
                console.print(Text(f"picture written to {png}"))
        if not report.ok:
            raise typer.Exit(1)

    @app.command("conform")
    def conform_cmd(
        spec: Path = typer.Argument(..., help="A spec with a robot binding (robot_registry() in its module)."),
        scenario: Path = typer.Option(..., "--scenario", "-s", help="The robot's world (TOML)."),
        request: str = typer.Option(..., "--request", "-r", help="The constraint to enforce."),
        runs: int = typer.Option(10, "--runs", "-n", help="Number of seeded runs."),
        seed: Optional[int] = typer.Option(None, "--seed", help="Seed of the first run (run k uses seed + k; "
                                           "default: the scenario's seed)."),
        fault: list[str] = typer.Option([], "--fault", help="Fault points always on (others are drawn at random)."),
        no_random_faults: bool = typer.Option(False, "--no-random-faults",
                                              help="Do not draw fault points at random."),
        functional: Optional[Path] = typer.Option(None, "--functional", help="Functional-layer module."),
        max_steps: int = typer.Option(200_000, "--max-steps", min=1, help="CLF step bound of each run."),
        as_json: bool = typer.Option(False, "--json", help="Print the report as JSON."),
    ) -> None:
        """Check the spec's declared outcomes against the robot: N seeded runs with random faults.

        Every robot result must fall into a declared outcome, and every run must replay on the
        compiled (abstract) model; an outcome the robot never produced is a warning. Exit status:
        0 when the abstraction is sound for these runs, 1 when it is not, 2 on bad input.
        """
        from rich.text import Text
        from ..testing.api import load_spec

        if runs < 1 or runs > 10_000:
            raise RoarError(f"--runs {runs}: expected a number of runs from 1 to 10000")
        spec_obj = load_spec(spec, functional=functional)
        console = _console()
        rep = spec_obj.conform(request, scenario, runs=runs, seed=seed, faults=fault,
                               random_faults=not no_random_faults, max_steps=max_steps,
                               on_run=None if as_json else
                               (lambda k, r: console.print(Text(f"  run {k + 1}/{runs}: seed {r.seed}, faults "
                                                                f"{', '.join(r.faults) or 'none'}: request {r.outcome} at "
                                                                f"t = {r.time:.2f} s, {r.calls} calls"
                                                                + (f", DIVERGES at step {r.divergence.step} ({r.divergence.rule}: "
                                                                   f"{r.divergence.reason})" if r.divergence
                                                                   else "")), soft_wrap=True)))
        if as_json:
            print(json.dumps(rep.as_json(), indent=2))
        else:
            for line, style in rep.lines():
                console.print(Text(line, style=style), soft_wrap=True)
        if not rep.sound:
            raise typer.Exit(1)


def _modules(spec) -> list:
    """Where the spec's functional-layer module may be (an output never goes there)."""
    from ..roar.functional import module_candidates
    return module_candidates(spec) if spec is not None else []


def _writing(path: Path, write) -> None:
    try:
        write()
    except OSError as exc:
        raise RoarError(f"{path}: cannot write: {exc.strerror or exc}") from None


def replay_robot(trace: Path, model: Optional[Path], on_robot: Optional[Path], seed: Optional[int], fault: list[str],
                 loops: int, png: Optional[Path], functional: Optional[Path], force: bool) -> int:
    """``roar-verify replay`` for robot traces (``--model SPEC``) and for counterexamples on the robot
    (``--on-robot SCENARIO``). Returns the exit status. Only the spec named on the command line is
    compiled and only its functional-layer module is imported: nothing the trace names is run."""
    from ..robot.setup import prepare, split_faults
    from rich.text import Text
    from ..trace.format import read_trace
    from ..robot.report import TRACE_KIND

    header, records = read_trace(trace)
    console = _console()
    if model is None:
        named = header.get("spec")
        raise RoarError(f"{trace}: pass the spec to replay it on: --model SPEC"
                        + (f" (the trace was made from {named}; it is not opened from the trace)" if named else ""))
    from ..robot.conform import check_records
    check_records(records, str(trace))
    request = header.get("request")
    if not isinstance(request, str) or not request:
        raise RoarError(f"{trace}: the trace header records no request: is it a trace of a ROAR spec?")
    if header.get("robot") is not None:   # a counterexample the robot-backed explorer found
        return _replay_robot_backed(trace, header, records, model, on_robot, loops, png, functional, force, console)
    if on_robot is not None:
        check_outputs([("--png", png)], [trace, model, on_robot, functional] + _modules(model))
        _same_spec(trace, header, model, force)
        from ..robot.onrobot import replay_on_robot
        spec_ast, compiled, binding, sc = prepare(model, request, on_robot, functional)
        world_faults, prims = split_faults(fault, sc, compiled)
        if prims:
            raise RoarError("replay --on-robot takes the scenario's fault points only; the counterexample "
                            "already says how each primitive call ends")
        if any(r.get("rule") == "functional_layer" for r in records) and header.get("kind") == TRACE_KIND:
            raise RoarError(f"{trace}: a robot trace, not a counterexample: replay it on the model with --model "
                            f"alone")
        console.print(Text(f"{trace}: {len(records)} steps of {header.get('kind', 'a trace')} for request "
                           f"{request}, on scenario {sc.name}" + (f" with {', '.join(world_faults)}" if world_faults
                                                                  else "")), soft_wrap=True)
        # a path that is not a deadlock's ends where a safety property is broken: it need not stay there
        stuck = header.get("property") in (None, "deadlock")
        res = replay_on_robot(compiled, binding.robot, sc, records, seed=seed, faults=world_faults, loops=loops,
                              stuck=stuck,
                              on_line=lambda line: console.print(Text(line), soft_wrap=True))
        console.print(Text(res.message, style="green" if res.realised else "red"), soft_wrap=True)
        x, y, th = res.pose
        console.print(Text(f"robot at ({x:.2f}, {y:.2f}), heading {th * 57.29577951308232:.0f}° at "
                           f"t = {res.time:.2f} s"))
        if png is not None:
            from ..robot.report import draw_robot
            draw_robot(png, res.robot, title=f"{sc.name}: counterexample "
                       f"{'realised' if res.realised else 'not realised'} (t = {res.time:.1f} s)",
                       marks=[] if res.realised else [(x, y, "diverges here")])
            console.print(Text(f"picture written to {png}"))
        return 0 if res.realised else 1
    if header.get("kind") != TRACE_KIND:
        raise RoarError(f"{trace}: not a robot trace (kind {header.get('kind')!r}); a counterexample replays on the "
                        f"engine with --model alone, or on the robot with --on-robot SCENARIO --model SPEC")
    from ..robot.conform import replay_robot_trace
    rp, confirmed, why = replay_robot_trace(trace, header, records, model, functional, force)
    if rp.ok:
        console.print(Text(f"replayed {rp.steps} robot steps on the model of {model}: every step is a step of the "
                           f"model, and each of the {len(rp.outcomes)} functional-layer answers falls into a "
                           f"declared outcome", style="green"), soft_wrap=True)
        if confirmed is False:
            console.print(Text(f"NOT CONFIRMED: {why}", style="bold red"), soft_wrap=True)
            return 1
        return 0
    for line in rp.divergence.lines():
        console.print(Text(line, style="red" if line.startswith("step") else ""), soft_wrap=True)
    return 1


def _same_spec(trace: Path, header: dict, model: Path, force: bool) -> None:
    """Refuse (unless ``force``) to drive the robot with a counterexample recorded on another spec
    than ``model``: its spec files' digests, as the trace's fingerprint records them, must be
    ``model``'s (the functional-layer module may differ: on the robot it is the robot's binding).
    Checked before the trace's request is compiled on the spec, which would otherwise fail on a
    name the other spec has."""
    from ..roar.sources import spec_fingerprint
    from ..roar.spec import load_spec
    recorded = header.get("fingerprint")
    files = recorded.get("files") if isinstance(recorded, dict) else None
    if not isinstance(files, dict) or force:
        return
    theirs = {k: v for k, v in files.items() if str(k).startswith("spec:")}
    mine = {k: v for k, v in spec_fingerprint(model, load_spec(model), None)["files"].items() if k.startswith("spec:")}
    if theirs and sorted(theirs.values()) != sorted(mine.values()):
        named = ", ".join(k.split(":", 1)[1] for k in theirs)
        raise RoarError(f"{trace}: the counterexample was recorded on another spec than {model} (recorded: "
                        f"{named}; the files differ): replay it with --model naming that spec, or pass --force")


def _replay_robot_backed(trace: Path, header: dict, records: list, model: Path, on_robot: Optional[Path], loops: int,
                         png: Optional[Path], functional: Optional[Path], force: bool, console) -> int:
    """``replay TRACE --on-robot SCENARIO --model SPEC`` on a robot-backed counterexample: one robot,
    driven straight through the counterexample's launches, fault choices and advances."""
    from ..robot.setup import prepare
    from rich.text import Text
    from ..trace.fingerprint import fingerprint
    from ..robot.onrobot import check_robot_records, replay_robot_path
    info = header["robot"]
    if not isinstance(info, dict):
        raise RoarError(f"{trace}: the header's 'robot' must be an object")
    if on_robot is None:
        raise RoarError(f"{trace}: a counterexample found on the robot; replay it with --on-robot SCENARIO "
                        f"(it was found on {info.get('scenario_name', 'a scenario')}; the trace's paths are never "
                        f"opened) and --model SPEC")
    check_outputs([("--png", png)], [trace, model, on_robot, functional] + _modules(model))
    check_robot_records(records, str(trace))
    mine = fingerprint([("scenario", "scenario.toml", on_robot)])
    theirs = info.get("scenario_fingerprint")
    if isinstance(theirs, dict) and theirs != mine and not force:
        raise RoarError(f"{trace}: the counterexample was found on another scenario than {on_robot} (its "
                        f"fingerprint differs); pass the scenario it was found on, or --force")
    spec_ast, compiled, binding, sc = prepare(model, header["request"], on_robot, functional)
    console.print(Text(f"{trace}: {len(records)} steps of a robot-backed counterexample ({header.get('property')}) "
                       f"for request {header['request']}, on scenario {sc.name}"), soft_wrap=True)
    res = replay_robot_path(compiled, binding.robot, sc, header, records, loops,
                            on_line=lambda line: console.print(Text(line), soft_wrap=True))
    console.print(Text(res.message, style="green" if res.realised else "red"), soft_wrap=True)
    if png is not None:
        from ..robot.report import draw_robot
        x, y, _th = res.pose
        marks = []
        bad = info.get("violation")
        if res.realised and isinstance(bad, dict) and isinstance(bad.get("pose"), list) and len(bad["pose"]) == 3:
            marks.append((float(bad["pose"][0]), float(bad["pose"][1]), f"violated at t = {float(bad['t']):.2f} s"))
        draw_robot(png, res.robot, title=f"{sc.name}: {header.get('property')} counterexample "
                   f"{'realised' if res.realised else 'not realised'} (t = {res.time:.1f} s)",
                   marks=marks or [(x, y, ("the cycle repeats here" if any(r.get("loop") for r in records) else
                                           "the path ends here") if res.realised else "diverges here")])
        console.print(Text(f"picture written to {png}"))
    return 0 if res.realised else 1
