"""``roar-verify simulate`` and ``roar-verify conform``: specs on the pymunk reference robot."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from ..errors import RoarError

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
        seed: int = typer.Option(0, "--seed", help="Seed of the scheduler and of every noise term."),
        fault: list[str] = typer.Option([], "--fault", help="Turn on a fault point of the scenario (door_closes), "
                                        "or make a primitive fail (NAME, NAME:K, NAME=OUTCOME). Repeatable."),
        functional: Optional[Path] = typer.Option(None, "--functional",
                                                  help="Functional-layer module (default: SPEC.py next to the spec)."),
        trace: Optional[Path] = typer.Option(None, "--trace", help="Write the robot trace (JSON Lines) here."),
        png: Optional[Path] = typer.Option(None, "--png", help="Draw the map, planned paths and trajectory here."),
        max_steps: int = typer.Option(200_000, "--max-steps", help="Stop after this many CLF steps."),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="Show the CLF rule of each event."),
        as_json: bool = typer.Option(False, "--json", help="Print the result as JSON."),
    ) -> None:
        """Run SPEC on a request with its primitives on the pymunk robot, in simulated time.

        Prints the ROAR-level trace with the simulated time and the robot's pose at each event.
        Exit status: 0 when the request succeeds, 1 when it fails or does not finish, 2 on bad input.
        """
        from ..roar.sources import spec_files
        from ..robot.setup import prepare, split_faults
        from ..trace.render import event_lines, event_rows
        from .console import show
        from ..robot.report import draw_sim, write_robot_trace
        from ..robot.sim import simulate

        spec_ast, model, binding, sc = prepare(spec, request, scenario, functional)
        world_faults, prim_faults = split_faults(fault, sc, model)
        for p in (trace, png):
            _check_output(p, spec_ast, spec, scenario)
        console = _console()
        if not as_json:
            from rich.text import Text
            console.print(Text(f"{spec}: request {request} on scenario {sc.name}, seed {seed}"
                               + (f", faults {', '.join(fault)}" if fault else "")), soft_wrap=True)
        res = simulate(model, binding.robot, sc, seed=seed, faults=world_faults, prim_faults=prim_faults,
                       max_steps=max_steps)
        rules = [st.rule for st in res.run.steps.raw]
        if trace is not None:
            _writing(trace, lambda: write_robot_trace(trace, res, str(spec), request, str(scenario),
                                                      spec_files(spec_ast)))
        if png is not None:
            draw_sim(png, res)
        x, y, th = res.robot.world.base.pose
        if as_json:
            print(json.dumps({"spec": str(spec), "scenario": str(scenario), "request": request, "seed": seed,
                              "faults": fault, "outcome": res.outcome, "end": res.end,
                              "time": round(res.robot.time, 4), "pose": [x, y, th],
                              "clf_steps": len(res.run.steps), "error_context": res.run.error_context,
                              "calls": [c.as_json() for c in res.calls],
                              "uncovered": [c.n for c in res.uncovered()],
                              "events": [dict(step=e.step, time=round(res.times[e.step - 1], 4), **e.as_json())
                                         for e in res.events]}, indent=2))
        else:
            show(console, event_lines(event_rows(res.events, res.times, res.poses, rules), verbose=verbose))
            from rich.text import Text
            end = {"quiescent": "quiescent", "horizon": f"horizon of {sc.horizon:g} s reached",
                   "max-steps": f"stopped after {max_steps} CLF steps",
                   "zero-time loop": "stopped: the agents kept stepping without the robot's time advancing, "
                                     "a loop that calls no primitive taking time"}[res.end]
            line = Text(f"request {res.outcome}", style="green" if res.ok else "red")
            line.append(f" at t = {res.robot.time:.2f} s after {len(res.run.steps)} CLF steps ({end}); "
                        f"robot at ({x:.2f}, {y:.2f}), heading {th * 57.29577951308232:.0f}°")
            console.print(line, soft_wrap=True)
            for e in res.run.error_context:
                console.print(Text(f"  error context: {e}"), soft_wrap=True)
            for c in res.uncovered():
                console.print(Text(f"  warning: call {c.n} {c.function}({', '.join(map(str, c.args))}) at "
                                   f"t = {c.t_end:.2f} s returned {c.result.as_json()}, which no declared outcome "
                                   f"covers", style="yellow"), soft_wrap=True)
            if trace is not None:
                console.print(Text(f"trace written to {trace}"))
            if png is not None:
                console.print(Text(f"picture written to {png}"))
        if not res.ok:
            raise typer.Exit(1)

    @app.command("conform")
    def conform_cmd(
        spec: Path = typer.Argument(..., help="A spec with a robot binding (robot_registry() in its module)."),
        scenario: Path = typer.Option(..., "--scenario", "-s", help="The robot's world (TOML)."),
        request: str = typer.Option(..., "--request", "-r", help="The constraint to enforce."),
        runs: int = typer.Option(10, "--runs", "-n", help="Number of seeded runs."),
        seed: int = typer.Option(0, "--seed", help="Seed of the first run (run k uses seed + k)."),
        fault: list[str] = typer.Option([], "--fault", help="Fault points always on (others are drawn at random)."),
        no_random_faults: bool = typer.Option(False, "--no-random-faults",
                                              help="Do not draw fault points at random."),
        functional: Optional[Path] = typer.Option(None, "--functional", help="Functional-layer module."),
        max_steps: int = typer.Option(200_000, "--max-steps", help="CLF step bound of each run."),
        as_json: bool = typer.Option(False, "--json", help="Print the report as JSON."),
    ) -> None:
        """Check the spec's declared outcomes against the robot: N seeded runs with random faults.

        Every robot result must fall into a declared outcome, and every run must replay on the
        compiled (abstract) model; an outcome the robot never produced is a warning. Exit status:
        0 when the abstraction is sound for these runs, 1 when it is not, 2 on bad input.
        """
        from ..robot.setup import prepare, split_faults
        from rich.text import Text
        from ..robot.conform import conform

        if runs < 1 or runs > 10_000:
            raise RoarError(f"--runs {runs}: expected a number of runs from 1 to 10000")
        spec_ast, model, binding, sc = prepare(spec, request, scenario, functional)
        world_faults, prim_faults = split_faults(fault, sc, model)
        if prim_faults:
            raise RoarError("conform draws the scenario's fault points; primitive faults "
                            f"({', '.join(map(str, prim_faults))}) are not allowed here")
        console = _console()
        rep = conform(spec_ast, request, model, binding, sc, runs=runs, seed=seed, always=world_faults,
                      random_faults=not no_random_faults, max_steps=max_steps, spec_name=str(spec),
                      on_run=None if as_json else
                      (lambda k, r: console.print(Text(f"  run {k + 1}/{runs}: seed {r.seed}, faults "
                                                       f"{', '.join(r.faults) or 'none'}: request {r.outcome} at "
                                                       f"t = {r.time:.2f} s, {r.calls} calls"
                                                       + (f", DIVERGES at step {r.divergence}" if r.divergence
                                                          else "")), soft_wrap=True)))
        if as_json:
            print(json.dumps(rep.as_json(), indent=2))
        else:
            for line, style in rep.lines():
                console.print(Text(line, style=style), soft_wrap=True)
        if not rep.sound:
            raise typer.Exit(1)


def _check_output(path: Optional[Path], spec_ast, spec: Path, scenario: Path) -> None:
    """Refuse, before the work starts, an output path that would overwrite an input or cannot be written."""
    from ..roar.sources import spec_files
    if path is None:
        return
    p = Path(path)
    inputs = ({Path(f).resolve() for f in spec_files(spec_ast)} if spec_ast is not None else set()) \
        | {Path(scenario).resolve(), Path(spec).resolve()}
    if p.exists() and p.resolve() in inputs:
        raise RoarError(f"{p}: refusing to overwrite an input file")
    if p.exists() and p.is_dir():
        raise RoarError(f"{p}: is a folder, expected a file path")
    parent = p.parent if str(p.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise RoarError(f"{p}: cannot write: {parent} is not a folder")


def _writing(path: Path, write) -> None:
    try:
        write()
    except OSError as exc:
        raise RoarError(f"{path}: cannot write: {exc.strerror or exc}") from None


def replay_robot(trace: Path, model: Optional[Path], on_robot: Optional[Path], seed: int, fault: list[str],
                 loops: int, png: Optional[Path], functional: Optional[Path], force: bool) -> int:
    """``roar-verify replay`` for robot traces (``--model SPEC``) and for counterexamples on the robot
    (``--on-robot SCENARIO``). Returns the exit status. Only the spec named on the command line is
    compiled and only its functional-layer module is imported: nothing the trace names is run."""
    from ..roar.sources import spec_files
    from ..robot.setup import prepare, split_faults
    from rich.text import Text
    from ..roar.compile import compile_spec
    from ..trace.format import read_trace
    from ..robot.report import TRACE_KIND, sources_fingerprint

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
        _check_output(png, None, model, on_robot)
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
        res = replay_on_robot(compiled, binding.robot, sc, records, seed=seed, faults=world_faults, loops=loops,
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
    from ..roar.spec import load_spec
    from ..robot.binding import load_robot_binding
    from ..robot.conform import replay_on_model
    spec_ast = load_spec(model)
    mine = sources_fingerprint(spec_files(spec_ast))
    theirs = header.get("spec_fingerprint")
    if theirs and theirs != mine and not force:
        raise RoarError(f"{trace}: the trace was made from other sources than {model} (its fingerprint differs): "
                        f"it is stale; simulate again, or pass --force to replay it anyway")
    binding = load_robot_binding(model, functional)
    abstract = compile_spec(spec_ast, request, registry=binding.abstract or binding.robot, functional="abstract")
    rp = replay_on_model(abstract, binding.robot, records)
    if rp.ok:
        console.print(Text(f"replayed {rp.steps} robot steps on the model of {model}: every step is a step of the "
                           f"model, and each of the {len(rp.outcomes)} functional-layer answers falls into a "
                           f"declared outcome", style="green"), soft_wrap=True)
        return 0
    for line in rp.divergence.lines():
        console.print(Text(line, style="red" if line.startswith("step") else ""), soft_wrap=True)
    return 1


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
    _check_output(png, None, model, on_robot)
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
