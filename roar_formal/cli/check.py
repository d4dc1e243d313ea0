"""``roar-verify check PATH...`` and ``roar-verify replay TRACE``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer
from rich.console import Console
from rich.live import Live
from rich.table import Table
from rich.text import Text

from ..errors import RoarError
from .console import make_console, show, styled


def register(app: typer.Typer) -> None:
    @app.command("check")
    def check(
        paths: List[Path] = typer.Argument(..., help="Job files (*.toml) or folders of them; or a .clf program "
                                           "or a ROAR spec to check with the default properties."),
        request: Optional[str] = typer.Option(None, "--request", "-r",
                                              help="With a spec: the request to enforce."),
        prop: List[str] = typer.Option([], "--property", "-p", help="With a model or spec: a property to check "
                                       "(deadlock, livelock, sequential-achievement, exclusive-writes, "
                                       "incompatible-tasks, mission-completion, mission-failure); "
                                       "repeatable or comma-separated. Default: deadlock on a .clf program; "
                                       "deadlock, mission-completion and mission-failure on a spec."),
        prop_files: List[Path] = typer.Option([], "--properties", help="With a model or spec: a property file "
                                              "(TOML, as a job names) saying what to check and how: livelock "
                                              "progress, invariants, temporal formulas. Repeatable."),
        time: Optional[str] = typer.Option(None, "--time", help="With a spec: 'untimed' (default) or 'timed' "
                                           "(the periods of wait, assert and ensure on a discrete clock; "
                                           "docs/semantics.md, Time)."),
        wait_timeout: Optional[int] = typer.Option(None, "--wait-timeout", help="With a spec, timed: a wait with "
                                                   "a period gives up after this many milliseconds."),
        functional: Optional[Path] = typer.Option(None, "--functional", help="With a spec: this functional-layer "
                                                  "module instead of the one next to it (SPEC.py)."),
        max_states: Optional[int] = typer.Option(None, "--max-states", help="Overrides every job's state bound."),
        max_seconds: Optional[float] = typer.Option(
            None, "--max-seconds",
            help="Overrides every job's time bound (a spec or model named directly, with no job file: 600 s by default)."),
        max_memory: Optional[int] = typer.Option(
            None, "--max-memory", help="Overrides every job's memory bound, in MiB of resident memory."),
        symmetry: bool = typer.Option(False, "--symmetry", help="Symmetry reduction: one state per set of states "
                                      "that differ only by exchanging interchangeable agents (or constants), when "
                                      "the model has verified symmetries (docs/checking.md, Symmetry reduction)."),
        search: Optional[str] = typer.Option(
            None, "--search", help="Overrides every job's search: bfs (default), dfs, or swarm (randomized "
            "depth-first searches for bugs, never a proof; docs/checking.md, Choosing a search mode)."),
        visited: Optional[str] = typer.Option(
            None, "--visited", help="Overrides every job's visited set: exact (default), hash or bitstate (less "
            "memory a state, a 'holds' not verified)."),
        as_json: bool = typer.Option(False, "--json", help="Print one JSON document for machines."),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="Counterexamples in more detail: on a .clf model the facts each step "
                                     "consumed and produced; on a spec the CLF rule of each event."),
        traces: Path = typer.Option(Path("roar-traces"), "--traces",
                                    help="Folder where counterexample traces are written."),
        no_traces: bool = typer.Option(False, "--no-traces", help="Do not write counterexample traces."),
        png: Optional[Path] = typer.Option(None, "--png", help="Folder for a message sequence chart (PNG) of "
                                           "each counterexample."),
        svg: Optional[Path] = typer.Option(None, "--svg", help="Folder for a message sequence chart (SVG) of "
                                           "each counterexample."),
        dot: Optional[Path] = typer.Option(None, "--dot", help="Folder for the explored state graph (DOT) of each "
                                           "counterexample's job, its path highlighted (small models only)."),
        html: Optional[Path] = typer.Option(None, "--html", help="Folder for an HTML report (index.html): the "
                                            "summary, each verdict and counterexample, its chart and its trace."),
    ) -> None:
        """Run verification jobs; exit 0 only when every verdict is the expected one.

        Exit status: 0 every verdict as expected; 1 a verdict differs from its expectation, or a
        property the job expects nothing of is violated; 2 bad input; 4 no violation, but a search
        ran out of budget on a property the job expects nothing of (no verdict).
        """
        import math
        from ..testing.api import is_model_path, load_jobs, write_html_report

        console = make_console(stderr=as_json)
        props = [x.strip() for p in prop for x in p.split(",") if x.strip()]
        models = [p for p in paths if is_model_path(p)]
        if (request or props or prop_files) and not models:
            given = ", ".join(o for o, v in (("--request", request), ("--property", props),
                                             ("--properties", prop_files)) if v)
            if not any(p.is_file() or (p.is_dir() and any(p.glob("*.toml"))) for p in paths):
                raise RoarError(f"no model, spec or job file among {', '.join(map(str, paths))}: {given} "
                                f"{'needs' if ', ' not in given else 'need'} a .clf program or a ROAR spec named "
                                f"on the command line")
            raise RoarError(f"{given}: for a model or spec named on the command line; a job file says its own")
        if max_states is not None and max_states < 1:
            raise RoarError(f"--max-states {max_states}: expected a positive number of states")
        if max_seconds is not None and not (math.isfinite(max_seconds) and max_seconds > 0):
            raise RoarError(f"--max-seconds {max_seconds}: expected a positive, finite number of seconds")
        from ..verify.jobs import MIN_MEMORY_MB
        if max_memory is not None and max_memory < MIN_MEMORY_MB:
            raise RoarError(f"--max-memory {max_memory}: expected a whole number of MiB, at least {MIN_MEMORY_MB}")
        from ..verify.pictures import check_output_folder
        outputs = [(png, "--png"), (svg, "--svg"), (dot, "--dot"), (html, "--html")]
        if not no_traces and traces != Path("roar-traces"):   # the default is checked when written
            outputs.append((traces, "--traces"))
        for folder, opt in outputs:
            if folder is not None:   # checked before any work starts
                check_output_folder(folder, opt, list(paths))
        if html is not None:   # (a folder of the user's own files is refused before the search, too)
            from ..verify.html import check_report_folder
            check_report_folder(html)
        # every job file is checked before anything runs
        jobs = load_jobs(paths, request=request, properties=props, time=time, wait_timeout=wait_timeout,
                         functional=functional, property_files=prop_files)
        files = [j.path for j in jobs if not is_model_path(j.path)]
        if search is not None or visited is not None:   # every job named, refused before anything runs
            from ..verify.jobs import apply_search_options
            for job in jobs:
                apply_search_options(job.job, search, visited)
        if symmetry:   # every job named, as the bounds below (refused before anything runs)
            from ..verify.jobs import symmetry_refusals
            for job in jobs:
                inner = job.job   # the verify.jobs.Job the API's job wraps
                inner.symmetry = True
                symmetry_refusals(inner)
        for job in jobs:   # command-line bounds override the jobs'
            if max_states is not None:
                job.budget.max_states = max_states
            if max_seconds is not None:
                job.budget.max_seconds = max_seconds
            if max_memory is not None:
                job.budget.max_memory_mb = max_memory
        results = []
        stems: set = set()   # the file stems of the jobs checked so far (traces, pictures)
        import time as _time
        for job in jobs:
            status = {"text": f"{job.name}: loading", "round": 1, "last": 0, "plain_at": _time.monotonic(),
                      "began": _time.monotonic()}

            def progress(st: dict, job=job) -> None:
                phase = st.get("phase")   # (a robot job's comparison: the abstract model's search)
                if phase != status.get("phase"):
                    status.update(phase=phase, round=1, last=0)
                if st["states"] < status["last"]:   # a search started again with a larger budget
                    status["round"] += 1
                status["last"] = st["states"]
                if getattr(job, "search", None) == "swarm" and not phase:   # (a swarm's searches, not budget rounds)
                    rnd = f" (search {status['round']} of {job.swarm_runs})"
                else:
                    rnd = f" (round {status['round']})" if status["round"] > 1 else ""
                rnd = f" ({phase}){rnd}" if phase else rnd
                status["text"] = (f"{job.name}{rnd}: {st['states']:,} states, {st['transitions']:,} transitions, "
                                  f"{st['states_per_s']:,.0f} states/s, frontier {st['frontier']:,}, "
                                  f"{st['memory_mb']:,.0f} MiB, {_time.monotonic() - status['began']:,.0f} s")
                if console.is_terminal:
                    live.update(status["text"])
                elif _time.monotonic() - status["plain_at"] >= max(5.0, 0.2 * (_time.monotonic() - status["began"])):
                    # a log (not a terminal): a plain line every 5 s, then further apart as the search
                    # goes on (a fifth of the time so far), so a long search writes tens of lines
                    status["plain_at"] = _time.monotonic()
                    console.print(status["text"], soft_wrap=True)

            try:
                with Live(status["text"], console=console, transient=True,
                          refresh_per_second=4, redirect_stdout=False) as live:
                    res = job.run(progress)
            except KeyboardInterrupt:
                console.print(styled(("interrupted: ", "yellow"), f"{status['text']}; no verdict"), soft_wrap=True)
                raise typer.Exit(130)
            results.append(res)
            # two jobs of one name (files in different folders) write their traces and pictures
            # side by side, not one over the other: the later one's files are <name>-2, -3, ...
            stem, n = res.result.job.name, 1
            while stem in stems:
                n += 1
                stem = f"{res.result.job.name}-{n}"
            stems.add(stem)
            if n > 1:
                res.result.file_stem = stem
            if no_traces:
                res.result.saved = {}
            else:
                try:
                    res.save_counterexamples(traces)
                except OSError as exc:
                    raise RoarError(f"--traces {traces}: cannot write: {exc.strerror or exc}") from None
            res.save_pictures(png, svg, dot, tuple(paths) + tuple(files))
            if not as_json:
                show(console, res.lines(verbose))
        if html is not None:
            page = write_html_report(html, results, tuple(paths) + tuple(files))
            if not as_json:
                console.print(f"HTML report: {page}", soft_wrap=True)
        if as_json:
            print(json.dumps([r.as_json() for r in results], indent=2))
        else:
            _summary(console, results)
        ok = all(r.ok for r in results)
        short = [(r, [p for p, v in r.result.verdicts.items() if v.status == "incomplete"]) for r in results]
        short = [(r, ps) for r, ps in short if ps]   # every verdict a budget left open, expected or not
        if short and not as_json:
            names = ", ".join(f"{r.name} ({', '.join(ps)})" for r, ps in short)
            console.print(styled(("incomplete: ", "yellow"), f"{names}: {_budget_hint([r.result for r, _ps in short])}"
                                 + ("" if not ok else " (exit status 4)")), soft_wrap=True)
        if not ok:
            raise typer.Exit(1)
        if any(r.incomplete for r in results):   # no violation, but no verdict either: its own exit code
            raise typer.Exit(4)

    @app.command("replay")
    def replay_cmd(
        trace: Path = typer.Argument(..., help="A trace (JSON Lines) written by 'roar-verify check' (a "
                                               "counterexample), 'run --trace' or 'simulate --trace'."),
        model: Optional[Path] = typer.Option(
            None, "--model",
            help="The model to replay on: the ROAR spec of a job on a spec or of a robot trace (its "
                 "functional-layer module is found next to it), or the .clf program. Required: a trace's own "
                 "paths are never opened (docs/trust.md)."),
        states: bool = typer.Option(False, "--states", help="Print the whole state after every step."),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="Show each step's CLF rule and facts too."),
        interactive: bool = typer.Option(False, "--interactive", "-i",
                                         help="Step through the trace: next, back, jump, state, agent, end, quit."),
        on_robot: Optional[Path] = typer.Option(None, "--on-robot", help="Drive the reference robot of this "
                                                "scenario through the counterexample (needs --model SPEC)."),
        seed: Optional[int] = typer.Option(None, "--seed", help="With --on-robot: the robot's seed (default: the "
                                           "scenario's)."),
        fault: List[str] = typer.Option([], "--fault", help="With --on-robot: a fault point of the scenario."),
        loops: int = typer.Option(3, "--loops", help="With --on-robot: how many times to drive a lasso's cycle."),
        png: Optional[Path] = typer.Option(None, "--png", help="Draw the trace's message sequence chart here (PNG); "
                                           "with --on-robot, the robot's run."),
        svg: Optional[Path] = typer.Option(None, "--svg", help="Draw the trace's message sequence chart here (SVG)."),
        dot: Optional[Path] = typer.Option(None, "--dot", help="Write the trace's task tree here (DOT), as "
                                           "tca-check reads it."),
        functional: Optional[Path] = typer.Option(
            None, "--functional", help="With a spec: this functional-layer module instead of the one next to it."),
        force: bool = typer.Option(False, "--force",
                                   help="Replay even if the model's sources differ from those the trace records."),
    ) -> None:
        """Step through a trace on the engine, checking that every step is enabled.

        On a spec the steps print as ROAR events and variable changes (CLF with -v), then the
        final per-agent state; the trace's claim is confirmed on the model (a deadlock is still a
        deadlock, a cycle closes, the sequential-achievement pair is still broken): exit 1 if not.
        The model comes from --model, never from the trace: a trace is data (docs/trust.md).
        A robot trace (from `simulate --trace`) replays on the compiled model of the spec given with
        --model; a counterexample replays on the robot with --on-robot SCENARIO --model SPEC.
        """
        from ..trace.format import read_trace
        head = read_trace(trace)[0]
        if on_robot is not None or head.get("kind") == "roar-robot-run" or head.get("robot") is not None:
            from .robot import replay_robot
            if loops < 1 or loops > 1000:
                raise RoarError(f"--loops {loops}: expected 1 to 1000")
            code = replay_robot(trace, model, on_robot, seed, fault, loops, png, functional, force)
            if code:
                raise typer.Exit(code)
            return
        from ..testing.api import replay
        from ..outputs import check_outputs

        from ..roar.functional import module_candidates
        check_outputs((("--png", png), ("--svg", svg), ("--dot", dot)),
                      [trace, model, functional] + (module_candidates(model) if model is not None else []))
        if dot is not None:   # a trace with nothing to draw is refused before the work
            from ..tca.roar_runs import task_tree_events
            from ..tca.tree_dot import task_tree_dot
            tree_events = task_tree_events(head, read_trace(trace)[1], str(trace))
            if not tree_events:
                raise RoarError(f"--dot {dot}: the trace holds no task-tree message (no request, no primitive "
                                "call): a task tree is drawn from a trace of a ROAR spec")
        console = make_console()
        rep = replay(trace, model, functional=functional, force=force, _from_cli=True)
        if interactive:
            for note in rep.notes:
                console.print(f"note: {note}", style="yellow")
            _interactive_replay(console, rep, verbose)
            show(console, rep.replayed_lines())
        else:
            show(console, rep.body_lines(verbose, states))
        for path in rep.save_chart(png, svg):
            console.print(f"chart written to {path}")
        if dot is not None:
            from ..trace.format import write_atomic
            write_atomic(dot, task_tree_dot(tree_events, f"{Path(trace).name}: {rep.claim}"))
            console.print(f"task tree written to {dot}")
        show(console, rep.confirmation_lines())
        if rep.confirmed is False:
            raise typer.Exit(1)


_REPLAY_HELP = ("commands: Enter or n (next step), b (back), j N (jump to step N), s (state), "
                "a AGENT (one agent's row), e (the end), q (quit), h (this help)")


def _interactive_replay(console: Console, rep, verbose: bool) -> None:
    """Step through a replayed trace: the state is always the one after the shown step."""
    import sys

    n = rep.steps
    i = 0
    console.print(f"{n} steps; {_REPLAY_HELP}", style="dim")
    while True:
        try:
            console.print(f"[{i}/{n}]> ", end="")
            line = sys.stdin.readline()
        except KeyboardInterrupt:
            console.print()
            return
        if not line:   # end of input
            console.print()
            return
        cmd, _, arg = line.strip().partition(" ")
        if cmd in ("", "n"):
            if i >= n:
                console.print("at the end of the trace", style="yellow")
                continue
            i += 1
            show(console, rep.step_lines(i, verbose, always=True))
        elif cmd == "b":
            if i == 0:
                console.print("at the start of the trace", style="yellow")
                continue
            i -= 1
            console.print(f"back to the state after step {i}" if i else "back to the start")
        elif cmd == "j":
            if not arg.strip().isdigit() or not 0 <= int(arg) <= n:
                console.print(f"j N: N from 0 to {n}", style="yellow")
                continue
            i = int(arg)
            if i:
                show(console, rep.step_lines(i, verbose, always=True))
        elif cmd == "e":
            i = n
            show(console, rep.step_lines(i, verbose, always=True))
        elif cmd == "s":
            show(console, rep.state_lines(i))
        elif cmd == "a":
            if not arg.strip():
                console.print("a AGENT: name an agent", style="yellow")
                continue
            show(console, rep.state_lines(i, arg.strip()))
        elif cmd == "q":
            return
        elif cmd in ("h", "?", "help"):
            console.print(_REPLAY_HELP)
        else:
            console.print(f"unknown command {cmd!r}; {_REPLAY_HELP}", style="yellow")


def _budget_hint(short: list) -> str:
    """What to do about the searches of ``short`` (job results with a verdict left open) that ran
    out of budget: the bounds that ran out, by their options, and the modes for a model too large
    to exhaust."""
    from ..verify.jobs import cycle_properties
    reasons = {x.graph.stop_reason for x in short}
    if all(x.job.search == "swarm" and x.graph.stop_reason.startswith("swarm:") for x in short):
        # its members stopped at their own bound
        return ("no randomized search found a violation of these, nor covered the state space; more or longer ones may "
                "([swarm] runs and max_states in the job file)")
    opts = [opt for word, opt in (("state budget", "--max-states"), ("time budget", "--max-seconds"),
                                  ("memory budget", "--max-memory")) if any(word in x for x in reasons)]
    if all(x.job.search == "swarm" for x in short):   # a bound of the job ended the swarm early
        return (f"the job's budget ended the randomized searches early; raise it ({', '.join(opts) or '--max-seconds'}, "
                "or a job's [bounds]) to let every search of [swarm] run")
    opts = opts or ["--max-states", "--max-seconds", "--max-memory"]
    out = f"a budget ran out before a verdict; raise it ({', '.join(opts)}, or a job's [bounds]); "
    if any("memory budget" in x for x in reasons):
        # hash compaction and bitstate save memory, not time; bitstate decides no property read on cycles
        modes = ("--visited hash" if any(cycle_properties(x.job) for x in short) else
                 "--visited hash or bitstate")
        return (out + f"for a model too large to exhaust, {modes} (less memory a state, not verified), or "
                "--search swarm (bug hunting); a job file's visited and search keys say the same (docs/checking.md, "
                "Choosing a search mode)")
    return (out + "for a model too large to exhaust in time, --search swarm (or a job file's search = \"swarm\"; "
            "bug hunting: it finds violations sooner, it never verifies) (docs/checking.md, Choosing a search mode)")


def _summary(console: Console, results) -> None:
    from ..testing.api import STATUS_STYLE
    from ..verify.searching import TOO_SMALL
    t = Table(title="verification summary")
    t.add_column("job")
    props = sorted({p for r in results for p in r.verdicts})
    for p in props:
        t.add_column(p)
    t.add_column("states", justify="right")
    t.add_column("time", justify="right")
    t.add_column("result")
    for r in results:
        cells = []
        for p in props:
            v = r.verdicts.get(p)
            if v is None:
                cells.append("-")
            else:
                want = r.expected(p)
                mark = "" if want is None or want == v.status else f" (want {want})"
                # a "holds" of hash compaction or bitstate is a bug-hunting result, not a proof
                mode = v.details.get("visited") if v.status == "holds" else None
                small = mode == "bitstate" and v.details.get("omission_probability", 0) > TOO_SMALL
                cells.append(Text.assemble((v.status, STATUS_STYLE[v.status]),
                                           (f" ({mode}, {'bit array too small' if small else 'not verified'})",
                                            "yellow") if mode else "", mark))
        unproved = any(v.status == "holds" and v.details.get("visited") for v in r.verdicts.values())
        # a swarm that found nothing: its statistics are its last search's; the verdicts say the total
        swarm = max((v.details.get("swarm_states", 0) for v in r.verdicts.values()), default=0)
        states = f"{swarm:,} (swarm)" if swarm > r.states else f"{r.states:,}"
        t.add_row(r.name, *cells, states, f"{r.seconds:.2f} s",
                  Text("as expected" + (", not verified" if unproved else ""),
                       style="yellow" if unproved else "green") if r.ok and not r.incomplete else
                  Text("incomplete", style="yellow") if r.ok else Text("unexpected", style="red"))
    console.print(t)
