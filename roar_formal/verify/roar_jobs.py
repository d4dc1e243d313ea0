"""Running a job on a spec: compile, explore with the ROAR system, decide the properties in
the CLF and the spec's terms (the abstract model; verify/robot.py runs the robot-backed ones)."""

from __future__ import annotations

import time

from ..errors import RoarError
from ..explore.graph import StateGraph
from .jobs import Job
from ..explore.properties import check_states, Verdict, check_deadlock, check_livelock
from ..explore.search import rss_mb
from ..explore.system import Options
from .cluster import cluster_note
from .explorers import make_explorer, run_search
from .models import (make_accept, make_never, mark_defaults, note_default_progress, reduction_options, roar_setup,
                     spec_properties)
from .results import JobResult
from .searching import VISITED_NOTE, mark_reduction
from .symmetries import mark_symmetry, roar_symmetry, symmetric


def run_roar_job(job: Job, on_progress) -> JobResult:
    """A job on a ROAR spec: the compiled model explored with primitives as their outcomes,
    weak fairness per agent, requests reaching a final state as progress (by default)."""
    from ..roar.functional import functional_module, load_registry
    from ..roar.compile import compile_spec
    from ..roar.explore import RoarSystem, roar_final
    from ..roar.report import growing_variables
    from ..roar.spec import load_spec
    from ..roar.sources import spec_fingerprint
    t0 = time.perf_counter()
    fn_path = functional_module(job.spec, job.functional)
    reg = load_registry(fn_path)
    spec_ast = load_spec(job.spec)
    fingerprint = spec_fingerprint(job.spec, spec_ast, fn_path)
    model = compile_spec(spec_ast, job.request, registry=reg, functional="abstract", request_at=job.request_at,
                         crashes=getattr(job, "crashes", None),   # [faults] crash (docs/semantics.md, Crashes)
                         time=getattr(job, "time", None))         # time / [time] (docs/semantics.md, Time)
    from ..roar.compile import nothing_timed, timeout_unused
    why = nothing_timed(model)
    if why:
        if job.time.where:   # a job file's time / [time]
            raise RoarError(why, job.time.where[0])
        raise RoarError(f"{job.spec}: --time timed: {why}")
    why = timeout_unused(model)
    if why:
        if len(job.time.where) > 1 and job.time.where[1] is not None:   # a job file's [time] wait_timeout
            raise RoarError(why, job.time.where[1])
        raise RoarError(f"{job.spec}: {why}")   # --wait-timeout of `check SPEC`, the API's explore
    program, start, options, pairs = roar_setup(job, model)
    sym = roar_symmetry(job, model, start) if job.symmetry else None
    props = job.props
    never = make_never(model.program().sig, str(job.spec), props.never) if "invariant" in props.check and props.never \
        else None
    spec_checks = spec_properties(job, model)
    reduction = "off"
    if job.reduction:
        if spec_checks.in_use:
            reduction = "not used with properties in the spec's terms"
        else:
            reduction = "on"
            reduction_options(options, props, never)
    accept_ctx = make_accept(program, props.accept, f"{props.sources[0] if props.sources else job.path} "
                             "[deadlock] accept", props.accept_at) if props.accept else roar_final

    def decide(graph: StateGraph, states: list, system: RoarSystem, ctx_of, step_of) -> dict[str, Verdict]:
        verdicts: dict[str, Verdict] = {}
        for p in props.check:
            if p == "deadlock":
                verdicts[p] = check_deadlock(graph, lambda sid: accept_ctx(states[sid]))
            elif p == "livelock":
                verdicts[p] = check_livelock(spec_checks.progress_graph(graph, ctx_of, step_of)
                                             if spec_checks.progress else graph, strong=props.strong)
            elif p == "invariant" or p in spec_checks.handles:
                verdicts[p] = spec_checks.decide(p, graph, ctx_of,
                                                 (lambda sid: never(states[sid])) if never is not None else None,
                                                 step_of)
            elif p == "sequential-achievement":
                verdicts[p] = check_states(graph, p, lambda sid: system.sequence_reason(states[sid]))
            elif p == "exclusive-writes":
                def bad(sid):
                    w = system.shared_write(states[sid])
                    return (f"{w[0]} is written by the where clauses of two live constraints: "
                            f"{' and '.join(w[1])}") if w else None
                verdicts[p] = check_states(graph, p, bad)
        mark_defaults(props, verdicts)
        note_default_progress(props, verdicts)
        return verdicts

    def explore(opts: Options):
        ex = make_explorer(job, symmetric(RoarSystem(model, start, opts, pairs), sym), on_progress)
        ctx_of = ex.states.__getitem__   # one per explorer: the decoded states are cached on it
        return ex, lambda g: decide(g, ex.states, ex.system, ctx_of, ex.steps.__getitem__)

    explorer, graph, verdicts = run_search(job, t0, explore, options)
    mark_reduction(job, verdicts, reduction, explorer)
    mark_symmetry(sym, verdicts, graph)
    open_ = [v for v in verdicts.values() if v.status == "incomplete"]
    if open_ and not graph.complete:
        store = explorer.steps
        grown = growing_variables(model, graph, store.items if getattr(store, "pack", None) else store)
        if grown:
            why = (f"; {'; '.join(grown)}: if nothing bounds it, the state space is infinite and no budget "
                   "is enough (a recipe's pre-condition such as 'tries < 3' bounds a counter)")
            open_[0].message += why   # (said once; every open verdict carries it in its details)
            for v in open_:
                v.details["growing"] = grown
    mismatches = [f"{p}: expected {want}, got {verdicts[p].status}" for p, want in job.expect.items()
                  if verdicts[p].status != want]
    backend = "general" + VISITED_NOTE[job.visited]
    if getattr(job, "cluster", None) is not None:
        backend += cluster_note(explorer)
    res = JobResult(job, verdicts, graph, backend, time.perf_counter() - t0, rss_mb(), mismatches, program,
                    reduction, fingerprint, sym.note if sym is not None else "")
    res.roar = (model, start, explorer)
    return res
