"""Robot-backed verification jobs: a job with ``robot = ...`` explored with the robot as functional layer.

Loads the spec, its robot binding and the scenario; explores (CLF state,
robot state) pairs (robot/explore.py) with the same rounds and budgets as
abstract jobs; decides deadlock, fair livelock, sequential achievement,
CLF invariants, exclusive writes and the robot invariants of the property
files; then, unless the job says ``compare = false``, checks the abstract
model of the same spec (the primitives as their declared outcomes) and sets
the two verdicts side by side. A robot verdict that is worse than the
abstract one, or a robot result no declared outcome covers, means the
abstract model misses a behaviour of this robot: an error, whatever the job
expects.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Callable, Optional

from ..errors import Pos, RoarError
from .models import make_never, mark_defaults, note_default_progress, roar_setup, spec_properties
from .results import JobResult, counterexample_steps
from .roar_jobs import run_roar_job
from .searching import search_rounds
from .jobs import Job
from ..explore.properties import Verdict, check_deadlock, check_livelock, check_states
from ..explore.search import Explorer, rss_mb
from ..robot.explore import Abstraction, FaultChoices, RobotSystem, RobotTree

__all__ = ["run_robot_job", "RobotInvariant", "RobotRun"]


class RobotInvariant:
    """One condition of [robot-invariant]: ``never`` true or ``always`` true on every robot state."""

    def __init__(self, cond, kind: str):
        self.cond = cond
        self.kind = kind
        self.text = cond.text

    def violated(self, robot) -> Optional[str]:
        bad = self.cond.holds(robot) if self.kind == "never" else not self.cond.holds(robot)
        if not bad:
            return None
        return f"the robot state breaks [robot-invariant] {self.kind} {self.text!r} at t = {robot.time:.2f} s " \
               f"({self.cond.explain(robot)})"


@dataclass
class RobotRun:
    """What a robot-backed job explored, beyond the graph: for reports, traces and pictures."""

    tree: RobotTree
    system: RobotSystem
    explorer: Explorer
    scenario: object
    abstraction: Abstraction
    faults: dict
    on: tuple
    seed: int
    horizon_states: int = 0
    comparison: list = field(default_factory=list)   # (property, abstract status, robot status, why)
    abstract: Optional[JobResult] = None

    def header(self, scenario_path) -> dict:
        """What a counterexample trace records about the robot (replay --on-robot checks it)."""
        from ..trace.fingerprint import fingerprint
        return {"scenario": str(scenario_path), "scenario_name": self.scenario.name,
                "scenario_fingerprint": fingerprint([("scenario", "scenario.toml", scenario_path)]),
                "seed": self.seed, "on": list(self.on),
                "faults": {n: None if at is None else sorted(at) for n, at in self.faults.items()},
                "abstraction": self.abstraction.as_json(), "dt": self.scenario.dt,
                "horizon": float(self.scenario.horizon)}

    def draw_counterexample(self, res, prop: str, path) -> None:
        """The counterexample of ``prop`` driven on a straight robot, drawn as its trajectory
        (the pan angle for a pan unit) with the failing point marked: where a robot invariant
        broke, else where the path ends or the cycle repeats."""
        from ..robot.onrobot import replay_robot_path
        from ..robot.report import draw_robot
        v = res.verdicts[prop]
        records = counterexample_steps(res.graph, v, res)
        header = {"robot": {"seed": self.seed, "on": list(self.on)}}
        rp = replay_robot_path(res.roar[0], self.tree.registry, self.scenario, header, records)
        node = self.explorer.states[v.counterexample.final_state].node
        x, y, _th = rp.pose
        if prop == "robot-invariant" and node.bad:
            _i, _why, t, pose = node.bad[0]
            marks = [(pose[0], pose[1], f"violated at t = {t:.2f} s")]
        else:
            marks = [(x, y, "the cycle repeats here" if v.counterexample.cycle else "the path ends here")]
        draw_robot(path, rp.robot, title=f"{self.scenario.name}: {prop} counterexample on the robot "
                   f"(t = {rp.time:.1f} s)", marks=marks)

    def describe(self) -> str:
        faults = ", ".join(f"{n} at {'any call' if at is None else ' or '.join(sorted(at))}"
                           for n, at in self.faults.items()) or "none"
        on = f"; on from the start: {', '.join(self.on)}" if self.on else ""
        return (f"scenario '{self.scenario.name}' (seed {self.seed}, horizon {float(self.scenario.horizon):g} s); "
                f"faults armable: {faults}{on}; abstraction: {self.abstraction.describe()}")


class _CtxStates:
    """The explorer's states seen as CLF contexts (the ROAR reports read contexts)."""

    def __init__(self, explorer: Explorer):
        self.explorer = explorer
        self.steps = explorer.steps
        self.system = explorer.system

    @property
    def states(self):
        return _CtxList(self.explorer.states)


class _CtxList:
    def __init__(self, states):
        self._s = states

    def __getitem__(self, i):
        return self._s[i].ctx

    def __len__(self) -> int:
        return len(self._s)


def _conditions(job: Job, scenario) -> list[RobotInvariant]:
    from ..robot.observe import check_condition, parse_condition
    out = []
    for kind, items in (("never", job.props.robot_never), ("always", job.props.robot_always)):
        for text, pos in items:
            file, line, col = (pos.file, pos.line, pos.col) if isinstance(pos, Pos) else (str(job.path), 1, 1)
            cond = parse_condition(text, file, line, col)
            check_condition(cond, scenario, file, line, col)
            out.append(RobotInvariant(cond, kind))
    return out


def _check_faults(job: Job, scenario, model) -> None:
    setup = job.robot
    names = list(setup.faults) + list(setup.on)
    for n in names:
        if n not in scenario.faults:
            from ..robot.scenario import did_you_mean
            known = ", ".join(scenario.faults) or "none"
            raise RoarError(f"[robot] fault point '{n}' is not in scenario '{scenario.name}'"
                            f"{did_you_mean(n, scenario.faults)}; its fault points: {known}", setup.pos)
    both = set(setup.faults) & set(setup.on)
    if both:
        raise RoarError(f"[robot] {', '.join(sorted(both))}: a fault point is either on from the start or armed "
                        "at a call, not both", setup.pos)
    fnames = {name for _owner, name in model.functions.values()} | \
             {f"{owner}::{name}" for owner, name in model.functions.values() if owner}
    for n, prims in setup.faults.items():
        for p in sorted(prims or ()):
            if p not in fnames:
                from ..robot.scenario import did_you_mean
                raise RoarError(f"[robot.faults] {n}: '{p}' is not a function the spec calls"
                                f"{did_you_mean(p, sorted(fnames))}", setup.pos)


def run_robot_job(job: Job, on_progress: Optional[Callable[[dict], None]] = None) -> JobResult:
    from ..roar.compile import compile_spec
    from ..roar.spec import load_spec
    from ..roar.sources import spec_fingerprint
    from ..robot.binding import load_robot_binding
    from ..robot.scenario import load_scenario
    t0 = time.perf_counter()
    setup = job.robot
    scenario = load_scenario(setup.scenario)
    binding = load_robot_binding(job.spec, job.functional)
    spec_ast = load_spec(job.spec)
    fingerprint = spec_fingerprint(job.spec, spec_ast, binding.path)
    model = compile_spec(spec_ast, job.request, registry=binding.robot, functional="python",
                         request_at=job.request_at)
    _check_faults(job, scenario, model)
    conditions = _conditions(job, scenario) if "robot-invariant" in job.props.check else []
    program, start, options, pairs = roar_setup(job, model)
    props = job.props
    never = make_never(model.program().sig, str(job.spec), props.never) if "invariant" in props.check and props.never \
        else None
    abstraction = setup.quantise or Abstraction()
    choices = FaultChoices(dict(setup.faults))
    tree = RobotTree(model, binding.robot, scenario, setup.seed, setup.on, abstraction, conditions)
    system = RobotSystem(model, start, tree, choices, options, pairs)
    explorer = Explorer(system, job.search, on_progress)
    states = explorer.states
    spec_checks = spec_properties(job, model)   # properties in the spec's terms (roar/props.py)
    spec_checks.cut = lambda sid: states[sid].node.at_horizon   # a run cut at the horizon has not ended

    def ctx_of(sid: int):
        return states[sid].ctx

    def decide(graph) -> dict[str, Verdict]:
        verdicts: dict[str, Verdict] = {}
        for p in props.check:
            if p == "deadlock":
                verdicts[p] = check_deadlock(graph, lambda sid: system.final(states[sid]))
            elif p == "livelock":
                verdicts[p] = check_livelock(spec_checks.progress_graph(graph, ctx_of, explorer.steps.__getitem__)
                                             if spec_checks.progress else graph, strong=props.strong)
            elif p == "invariant" or p in spec_checks.handles:
                verdicts[p] = spec_checks.decide(p, graph, ctx_of, (lambda sid: never(states[sid].ctx))
                                                 if never is not None else None, explorer.steps.__getitem__)
            elif p == "sequential-achievement":
                verdicts[p] = check_states(graph, p, lambda sid: system.sequence_reason(states[sid].ctx))
            elif p == "exclusive-writes":
                def bad(sid):
                    w = system.shared_write(states[sid].ctx)
                    return (f"{w[0]} is written by the where clauses of two live constraints: "
                            f"{' and '.join(w[1])}") if w else None
                verdicts[p] = check_states(graph, p, bad)
            elif p == "robot-invariant":
                verdicts[p] = check_states(graph, p, lambda sid: _robot_bad(states[sid].node))
        mark_defaults(props, verdicts)
        note_default_progress(props, verdicts)
        return verdicts

    graph, verdicts = search_rounds(job, t0, explorer, decide)

    def describe_edge(e: int) -> dict:
        d = system.describe_step(explorer.steps[e])
        node = states[int(graph.dst[e])].node
        d["t"] = round(node.time, 4)
        d["pose"] = [round(v, 6) for v in node.pose]
        return d
    graph.describe_edge = describe_edge
    graph.describe_steps = None   # (each step with the robot's time and pose where it ended)
    run = RobotRun(tree, system, explorer, scenario, abstraction, dict(setup.faults), tuple(setup.on), tree.seed)
    run.horizon_states = sum(1 for s in states if s.node.at_horizon)
    tag = "robot-backed, " + ("exact" if abstraction.exact else
                              f"quantised to {abstraction.position:g} m / {abstraction.heading:g} deg")
    for v in verdicts.values():
        v.message += f" ({tag})"
        v.details["robot"] = run.describe()
        if v.status == "holds" and run.horizon_states:
            n = run.horizon_states
            v.message += f"; {n:,} state{'s' if n != 1 else ''} reached the {float(scenario.horizon):g} s horizon"
    if job.reduction:
        for v in verdicts.values():
            v.details["reduction"] = "not used with the robot"
    mismatches = [f"{p}: expected {want}, got {verdicts[p].status}" for p, want in job.expect.items()
                  if verdicts[p].status != want]
    res = JobResult(job, verdicts, graph, "robot", time.perf_counter() - t0, rss_mb(), mismatches, program,
                    "not used with the robot" if job.reduction else "off", fingerprint)
    res.roar = (model, start, _CtxStates(explorer))
    res.robot = run
    if tree.uncovered:
        shown = "; ".join(f"{fn}: {r.status} (value {r.value!r}{', failed' if r.failed else ''})"
                          for (fn, _s, _v), r in list(tree.uncovered.items())[:5])
        res.mismatches.append(f"the robot produced results no declared outcome covers: {shown} — the abstract "
                              "model misses them (an unsound abstraction; see roar-verify conform)")
    if setup.compare and binding.abstract is not None:
        _compare(job, res, run, t0, on_progress)
    res.seconds = time.perf_counter() - t0
    return res


def _robot_bad(node) -> Optional[str]:
    return node.bad[0][1] if node.bad else None


def _compare(job: Job, res: JobResult, run: RobotRun, t0: float,
             on_progress: Optional[Callable[[dict], None]] = None) -> None:
    """The abstract model's verdicts next to the robot's, and why they differ. Its search reports
    its progress as the robot's did, marked as the abstract model's (it can be the longer one)."""
    from ..clf.query import with_big_stack
    ajob = copy.copy(job)
    ajob.robot = None
    ajob.expect = {}
    ajob.props = copy.copy(job.props)
    ajob.props.check = [p for p in job.props.check if p != "robot-invariant"]   # all but the robot's own
    if not ajob.props.check:
        return
    budget = copy.copy(job.budget)
    if budget.max_seconds is not None:
        budget.max_seconds = max(1.0, budget.max_seconds - (time.perf_counter() - t0))
    ajob.budget = budget
    progress = None if on_progress is None else (lambda st: on_progress({**st, "phase": "abstract model"}))
    ares = with_big_stack(run_roar_job, ajob, progress)
    g = ares.graph
    if job.budget.max_seconds is not None and g is not None and (g.stop_reason or "").startswith("time budget of "):
        # (its bound was what the robot's search left of the job's: say the job's, and what was left)
        g.stop_reason = (f"time budget of {job.budget.max_seconds:g} s reached (the job's; {budget.max_seconds:.1f} s "
                         f"of it was left after the robot's search)")
    run.abstract = ares
    seen = run.tree.outcomes_seen
    model = res.roar[0]
    for p in ajob.props.check:
        a, r = ares.verdicts[p], res.verdicts[p]
        if "incomplete" in (a.status, r.status):   # (both incomplete is no agreement either)
            why = "no comparison: " + _out_of_budget(a.status == "incomplete" and ares.graph,
                                                     r.status == "incomplete" and res.graph)
        elif a.status == r.status:
            why = "agree"
        elif a.status == "violated":
            unseen = _unseen_outcomes(ares, a, model, seen)
            why = ("the abstract counterexample is not realised by this robot: "
                   + (f"it needs {', '.join(unseen)}, which the robot never produced" if unseen else
                      "every declared outcome it takes occurs on the robot, but the robot's timing and "
                      "physics never put them in this order"))
        else:
            why = ("the robot violates what the abstract model satisfies: the abstraction misses a robot behaviour "
                   "(an unsound model)")
            res.mismatches.append(f"{p}: abstract model {a.status}, robot {r.status}: {why}")
        run.comparison.append((p, a.status, r.status, why))


def _out_of_budget(abstract, robot) -> str:
    """Which of the two searches (their graphs, False if complete) ran out of budget, and where."""
    def where(g) -> str:
        why = g.stop_reason
        return f"{g.n_states:,} states" + (f", the {why}" if why and not why.startswith("state budget") else "")
    if abstract and robot:
        return (f"both searches ran out of budget (the abstract model's after {where(abstract)}, "
                f"the robot's after {where(robot)})")
    if abstract:
        return (f"the abstract model's search ran out of budget after {where(abstract)}; the robot's is complete "
                "(compare = false in [robot] skips the abstract search)")
    return f"the robot's search ran out of budget after {where(robot)}"


def _unseen_outcomes(ares: JobResult, v: Verdict, model, seen: dict) -> list[str]:
    """The declared outcomes an abstract counterexample takes that the robot search never produced."""
    g = ares.graph
    cx = v.counterexample
    out = []
    for e in list(cx.prefix) + list(cx.cycle):
        rule = g.labels.names[g.label[e]]
        if not rule.startswith("outcome_"):
            continue
        for fc, (owner, name) in model.functions.items():
            prefix = f"outcome_{fc}_"
            if rule.startswith(prefix):
                oname = rule[len(prefix):]
                shown = f"{owner + '::' if owner else ''}{name} = {oname}"
                if oname not in seen.get(fc, set()) and shown not in out:
                    out.append(shown)
    return out
