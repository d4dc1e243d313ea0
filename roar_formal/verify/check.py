"""Running a verification job: load, choose a backend, search, decide, explain.

The search grows its state budget geometrically and re-decides after each
round: a violation found in a partial graph is real (a deadlock is an
expanded quiescent state; a livelock is a fair cycle among expanded states)
and, in breadth-first order, shortest; "holds" needs the complete graph. So
a livelock near the start of a huge graph is reported at once, and a budget
that runs out gives an honest "incomplete" verdict, never "verified".
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.query import with_big_stack
from ..errors import Pos, RoarError
from ..explore.graph import StateGraph
from ..explore.ground import GroundExplorer, GroundModel, GroundingStopped, NotGround
from ..explore.properties import check_states, Verdict, check_deadlock, check_livelock
from ..explore.search import Budget, Explorer, rss_mb
from ..explore.system import ClfSystem, Options
from .cluster import cluster_note
from .explorers import make_explorer, run_search
from .jobs import Job
from .models import check_progress_rules, load_model, make_accept, make_never, mark_defaults, reduction_options
from .results import JobResult, counterexample_steps, roar_events, save_counterexample
from .roar_jobs import run_roar_job
from .robot import run_robot_job   # the robot is the functional layer
from .searching import VISITED_NOTE, explorer_order, mark_reduction, search_rounds
from .symmetries import clf_symmetry, mark_symmetry, symmetric

#: what the package's users import from here (the modules below hold them)
__all__ = ["run_job", "run_roar_job", "JobResult", "counterexample_steps", "roar_events", "save_counterexample",
           "load_model", "make_never"]


def compiled_spec(program) -> bool:
    """Is this program a compiled ROAR spec (the framework's request states are declared)?"""
    return {"s_success", "s_failure", "rs", "rq"} <= set(program.sig.consts)


def run_job(job: Job, on_progress: Optional[Callable[[dict], None]] = None) -> JobResult:
    if getattr(job, "robot", None) is not None:
        return with_big_stack(run_robot_job, job, on_progress)
    if job.is_roar:
        return with_big_stack(run_roar_job, job, on_progress)
    return with_big_stack(_run_job, job, on_progress)


def _run_job(job: Job, on_progress) -> JobResult:
    from ..trace.fingerprint import clf_fingerprint
    t0 = time.perf_counter()
    program, start = load_model(job)
    fingerprint = clf_fingerprint(job.model)
    props = job.props
    check_progress_rules(props, program, spec=False)
    options = Options(progress_rules=tuple(props.progress), fairness=props.fairness, canonical=job.canonical)
    accept_ctx = make_accept(program, props.accept, f"{props.sources[0] if props.sources else job.path} "
                             "[deadlock] accept", props.accept_at) if props.accept else None
    never = make_never(Path(job.model).read_text(encoding="utf-8"), str(job.model), props.never) \
        if "invariant" in props.check else None
    ground_model = None
    grounding_stopped = None
    sym = clf_symmetry(job, program, start) if job.symmetry else None
    if job.backend in ("auto", "ground") and job.search == "bfs" and job.visited == "exact" and sym is None:
        deadline = t0 + job.budget.max_seconds if job.budget.max_seconds is not None else None
        try:
            ground_model = GroundModel(program, start, options, budget=job.budget, deadline=deadline)
        except NotGround as exc:
            if job.backend == "ground":
                raise RoarError(f"backend 'ground' cannot run this model: {exc}; drop the line (or write \"auto\") "
                                "to run it on the general backend",
                                job.backend_at or Pos(str(job.path), 1, 1)) from None
        except GroundingStopped as exc:
            grounding_stopped = str(exc)
    backend = "ground" if ground_model is not None or grounding_stopped else "general"
    reduction = "off"
    if job.reduction:
        if backend == "ground":
            reduction = "not used by the ground backend"
        else:
            reduction = "on"
            reduction_options(options, props, never)

    def decide(graph: StateGraph, state_of) -> dict[str, Verdict]:
        accept = (lambda sid: accept_ctx(state_of(sid))) if accept_ctx else None
        verdicts = {}
        for p in props.check:
            if p == "invariant":
                verdicts[p] = check_states(graph, p, lambda sid: never(state_of(sid)))
            else:
                verdicts[p] = check_deadlock(graph, accept) if p == "deadlock" else \
                    check_livelock(graph, strong=job.props.strong)
        dl = verdicts.get("deadlock")
        if dl is not None and dl.violated and accept is None and compiled_spec(program):
            # a compiled spec checked as a plain program: its runs end quiescent, successful or not
            dl.message += ("; this program is a compiled ROAR spec, whose every run ends in a quiescent "
                           "state (success included): check the spec itself with its request, which accepts "
                           "the states where every request is final, or give [deadlock] accept")
        return verdicts

    _explorer = None   # (the general backend's, for what its reduction left out)
    if grounding_stopped is not None:
        # the budget ran out before the search could start: the start state, unexpanded
        ex = Explorer(ClfSystem(program, start, options), explorer_order(job), on_progress, job.visited)
        graph = ex.run(Budget(max_states=1))
        graph.stop_reason = grounding_stopped
        verdicts = decide(graph, lambda sid: ex.states[sid])
    elif ground_model is not None:
        rounds = _GroundRounds(ground_model, on_progress)
        graph, verdicts = search_rounds(job, t0, rounds, lambda g: decide(g, rounds.state_of))
    else:
        def explore(opts: Options):
            ex = make_explorer(job, symmetric(ClfSystem(program, start, opts), sym), on_progress)
            return ex, lambda g: decide(g, lambda sid: ex.states[sid])

        _explorer, graph, verdicts = run_search(job, t0, explore, options)
        backend += VISITED_NOTE[job.visited]
        if getattr(job, "cluster", None) is not None:
            backend += cluster_note(_explorer)
    mark_reduction(job, verdicts, reduction, _explorer)
    mark_symmetry(sym, verdicts, graph)
    mark_defaults(props, verdicts)
    mismatches = []
    for p, want in job.expect.items():
        got = verdicts[p].status
        if got != want:
            mismatches.append(f"{p}: expected {want}, got {got}")
    return JobResult(job, verdicts, graph, backend, time.perf_counter() - t0, rss_mb(), mismatches, program,
                     reduction, fingerprint, sym.note if sym is not None else "")


class _GroundRounds:
    """The ground backend in rounds: each round searches afresh with the larger budget, so its
    budgets grow 16-fold rather than 4-fold (the rounds before the last cost at most a fifteenth
    of it, not a third; philosophers ok N = 12 through `check`: 20,000, 320,000, then the rest)."""

    GROWTH = 16

    def __init__(self, model: GroundModel, on_progress) -> None:
        self.model = model
        self.on_progress = on_progress
        self.gx: Optional[GroundExplorer] = None

    def run(self, budget: Budget) -> StateGraph:
        self.gx = None  # each round searches afresh: free the last one before the next takes memory
        self.gx = GroundExplorer(self.model, self.on_progress)
        return self.gx.run(budget)

    def state_of(self, sid: int) -> Context:
        return _row_context(self.model, self.gx.row_of(sid))


def _row_context(model: GroundModel, row) -> Context:
    ctx = Context()
    ctx.implicit = model.program.implicit
    for c, n in enumerate(row):
        mode, t = model.facts[c]
        for _ in range(int(n)):
            ctx.add_fact(t, mode)
    return ctx


# ---------------------------------------------------------------- counterexamples


