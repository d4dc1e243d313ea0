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
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Optional, Union

from ..clf.backward import Backward
from ..clf.context import Context
from ..clf.parser import parse_expr
from ..clf.forward import enabled_steps
from ..clf.program import Program
from ..clf.query import with_big_stack
from ..clf.signature import Elaborator, ExecDirective, Signature, extend_signature
from ..errors import RoarError
from ..trace.format import write_trace
from ..explore.graph import StateGraph
from ..explore.ground import GroundExplorer, GroundModel, GroundingStopped, NotGround
from .claims import trace_claim
from .jobs import Job
from ..explore.properties import check_states, Verdict, check_deadlock, check_livelock
from ..explore.search import Budget, Explorer, rss_mb
from ..explore.symmetry import discover_clf
from ..explore.system import ClfSystem, Options

FIRST_ROUND = 20_000


@dataclass
class JobResult:
    job: Job
    verdicts: dict[str, Verdict]
    graph: StateGraph
    backend: str
    seconds: float
    memory_mb: float
    mismatches: list[str] = field(default_factory=list)
    program: Optional[Program] = None
    reduction: str = "off"  # 'on', 'off' or 'not used by the ground backend'
    fingerprint: Optional[dict] = None  # of the sources explored (trace/fingerprint.py)
    symmetry: str = ""  # symmetry reduction: what it found (the job turned it on), else ""

    @property
    def unexpected(self) -> list[str]:
        """What makes the job fail: verdicts other than the expected ones, and violations of
        properties the job expects nothing of (a violation is an error unless [expect] says so)."""
        out = list(self.mismatches)
        for p, v in self.verdicts.items():
            if p not in self.job.expect and v.status == "violated":
                out.append(f"{p}: violated, and the job expects nothing of it: a violation is an error "
                           f"(write [expect] {p} = \"violated\" if it is intended)")
        return out

    @property
    def ok(self) -> bool:
        return not self.unexpected

    @property
    def incomplete(self) -> list[str]:
        """Properties the job expects nothing of whose search ran out of budget: no verdict."""
        return [p for p, v in self.verdicts.items() if p not in self.job.expect and v.status == "incomplete"]


def load_model(job: Job) -> tuple[Program, Context]:
    program = Program.from_file(job.model)
    execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
    if not execs:
        raise RoarError(f"{job.model} has no #exec directive to start the search from", None)
    if job.start > len(execs):
        raise RoarError(f"{job.path}: 'start = {job.start}' but {job.model.name} has only {len(execs)} #exec "
                        "directive(s)")
    return program, program.start_context(execs[job.start - 1].start)


def make_accept(program: Program, text: str, where: str) -> Callable[[Context], bool]:
    """A final-state test from a positive CLF type: the context must match it exactly
    (every linear fact accounted for; affine ones may be left over)."""
    expr = parse_expr(text, file=where)
    el = Elaborator(program.sig)
    el._begin()
    s = el.pos(expr)
    el._solve_postponed(expr.pos)
    for x in el.evars:
        x.scope = 1 << 62  # pattern variables may stand for fresh names

    def accept(ctx: Context) -> bool:
        bw = Backward(program)
        return any(True for _ in bw._match_pos(s, ctx))

    return accept


def _split_tensor(text: str) -> list[str]:
    """``A * B * C`` at parenthesis depth 0 -> [A, B, C]."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "*" and depth == 0:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    parts.append(cur.strip())
    return [p for p in parts if p]


def make_never(program: Union[str, Signature], file: str, patterns: list) -> Callable[[Context], Optional[str]]:
    """Invariant patterns as rules that must never be enabled: pattern ``A * B`` is violated by
    a state exactly when ``A -o B -o {1}`` could fire there (a sub-multiset match, with
    upper-case names as pattern variables and ``!A`` for persistent facts). ``program`` is the
    program's text, or its elaborated signature (a compiled model's: extended, not re-read)."""
    rules = []
    for k, (pat, pos) in enumerate(patterns):
        parts = _split_tensor(pat)
        rules.append(f"never_{k} : " + " -o ".join(parts) + " -o {1}.")
    extra = "\n".join(rules) + "\n"
    try:
        prog = Program.from_text(program + "\n" + extra, file) if isinstance(program, str) else \
            Program(extend_signature(program, extra, file))
    except RoarError as exc:
        # the error is in a pattern: point at the property file
        k = next((i for i, r in enumerate(rules) if r.split(" :")[0] in exc.message), None)
        pat, pos = patterns[k] if k is not None else patterns[0]
        raise RoarError(f"invariant pattern {pat!r}: {exc.message}", pos) from None
    tpls = [t for t in prog.templates if t.name.startswith("never_")]
    prover = prog.prover()

    def bad(ctx: Context) -> Optional[str]:
        for t in tpls:
            if any(True for _ in enabled_steps([t], ctx, prover, first_only=True)):
                return f"a reachable state matches the forbidden pattern {patterns[int(t.name[6:])][0]!r}"
        return None

    bad.templates = tuple(tpls)  # the reduction keeps these rules in every stubborn set
    return bad


def run_job(job: Job, on_progress: Optional[Callable[[dict], None]] = None) -> JobResult:
    if getattr(job, "robot", None) is not None:
        from .robot import run_robot_job   # the robot is the functional layer (verify/robot.py)
        return with_big_stack(run_robot_job, job, on_progress)
    if job.is_roar:
        return with_big_stack(run_roar_job, job, on_progress)
    return with_big_stack(_run_job, job, on_progress)


def run_roar_job(job: Job, on_progress) -> JobResult:
    """A job on a ROAR spec: the compiled model explored with primitives as their outcomes,
    weak fairness per agent, requests reaching a final state as progress (by default)."""
    from ..roar.functional import functional_module, load_registry
    from ..roar.compile import compile_spec
    from ..roar.explore import RoarSystem, roar_final
    from ..roar.spec import load_spec
    from ..roar.sources import spec_fingerprint
    t0 = time.perf_counter()
    fn_path = functional_module(job.spec, job.functional)
    reg = load_registry(fn_path)
    spec_ast = load_spec(job.spec)
    fingerprint = spec_fingerprint(job.spec, spec_ast, fn_path)
    model = compile_spec(spec_ast, job.request, registry=reg, functional="abstract",
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
            _reduction_options(options, props, never)
    accept_ctx = make_accept(program, props.accept, f"{props.sources[0] if props.sources else job.path} "
                             "[deadlock] accept") if props.accept else roar_final

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
        return verdicts

    def explore(opts: Options):
        ex = make_explorer(job, symmetric(RoarSystem(model, start, opts, pairs), sym), on_progress)
        ctx_of = ex.states.__getitem__   # one per explorer: the decoded states are cached on it
        return ex, lambda g: decide(g, ex.states, ex.system, ctx_of, ex.steps.__getitem__)

    explorer, graph, verdicts = _search(job, t0, explore, options)
    _mark_reduction(job, verdicts, reduction)
    _mark_symmetry(sym, verdicts, graph)
    mismatches = [f"{p}: expected {want}, got {verdicts[p].status}" for p, want in job.expect.items()
                  if verdicts[p].status != want]
    backend = "general" + VISITED_NOTE[job.visited]
    if getattr(job, "cluster", None) is not None:
        from .cluster import cluster_note
        backend += cluster_note(explorer)
    res = JobResult(job, verdicts, graph, backend, time.perf_counter() - t0, rss_mb(), mismatches, program,
                    reduction, fingerprint, sym.note if sym is not None else "")
    res.roar = (model, start, explorer)
    return res


@dataclass
class SymmetryUse:
    """The symmetries a job's search uses: the group (identity first) and the report's sentence."""

    group: list
    note: str


def symmetric(system, sym: Optional[SymmetryUse]):
    """``system``, its states keyed up to the symmetries when the job found some."""
    if sym is None or len(sym.group) < 2:
        return system
    from ..explore.symmetry import SymmetricSystem
    return SymmetricSystem(system, sym.group, sym.note)


def _mark_symmetry(sym: Optional[SymmetryUse], verdicts: dict, graph: StateGraph) -> None:
    if sym is None:
        return
    quotient = len(sym.group) > 1
    for v in verdicts.values():
        v.message += (f" ({sym.note}; {graph.n_states:,} states of the quotient)" if quotient else f" ({sym.note})")
        v.details["symmetry"] = sym.note
        v.details["symmetry_order"] = len(sym.group)


def _symmetry_where(job: Job):
    return job.symmetry_at, ("symmetry = true" if job.symmetry_at is not None else "--symmetry")


def _refuse_named(job: Job, named, permuted: str) -> None:
    """Refuse the job's patterns and spec predicates that name a constant or agent the group moves:
    a property that tells the images of a state apart is not decided by the quotient."""
    where, opt = _symmetry_where(job)
    props = job.props
    for text, pos in props.never if "invariant" in props.check else ():
        hit = named(text)
        if hit:
            raise RoarError(f"{opt}: the invariant pattern {text!r} names {hit[0]}, one of the {permuted} symmetry "
                            f"reduction interchanges: the quotient cannot tell its states apart; check it without "
                            f"symmetry", pos)
    if props.accept and named(props.accept):
        raise RoarError(f"{opt}: the [deadlock] accept pattern names {named(props.accept)[0]}, one of the {permuted} "
                        f"symmetry reduction interchanges; check it without symmetry", where)
    formulas = (props.spec_never + props.spec_always) if "invariant" in props.check else []
    formulas += [f for n, f in props.temporal.items() if n in props.check]
    for f in formulas:
        hit = named(f.text)
        if hit:
            raise RoarError(f"{opt}: property {f.text!r} names agent {hit[0]}, one of the {permuted} symmetry "
                            f"reduction interchanges: the quotient keeps one state of each set of states that differ "
                            f"only by exchanging them, so it cannot decide a property that tells them apart; check it "
                            f"without symmetry", f.at(hit[1]) or where)
    if "incompatible-tasks" in props.check and props.incompatible_pairs:
        for pair in props.incompatible_pairs:
            for text, pos in pair:
                hit = named(text)
                if hit:
                    raise RoarError(f"{opt}: incompatible-tasks names {text!r}, of agent {hit[0]}, one of the "
                                    f"{permuted} symmetry reduction interchanges; check it without symmetry", pos)


def clf_symmetry(job: Job, program: Program, start: Context) -> SymmetryUse:
    """The interchangeable constants of a .clf model (explore/symmetry.py, discover_clf), verified."""
    import re
    from ..explore.symmetry import close_group, factorial_order, MAX_ORDER, transpositions, verify
    blocks, notes = discover_clf(program, start)
    gens = transpositions(blocks)
    for g in gens:   # (discover_clf verified them; a group is used only once each generator passes)
        chk = verify(program.sig, start, g)
        if not chk.ok:
            raise RoarError(f"symmetry reduction: a candidate symmetry failed verification: {chk.reason}")
        g.rules = chk.rules
    if factorial_order(len(b) for b in blocks) > MAX_ORDER:
        close_group(gens)   # refuses, with the message
    group = close_group(gens)
    if len(group) > 1:
        names = [[m[""] for m in b] for b in blocks]
        k = sum(len(b) for b in names)
        note = (f"symmetry: {k} constants interchangeable ({'; '.join(', '.join(b) for b in names)}), "
                f"group of order {len(group):,}")
        moved = {m for b in names for m in b}

        def named(text: str):
            for w in re.finditer(r"[A-Za-z_][A-Za-z0-9_']*", text):
                if w.group(0) in moved:
                    return w.group(0), w.start() + 1
            return None
        _refuse_named(job, named, "constants")
    else:
        why = "; ".join(notes) if notes else "no two constants of one type are mentioned by no rule"
        note = f"symmetry: none found ({why}); the search is the plain one"
    return SymmetryUse(group, note)


def roar_symmetry(job: Job, model, start: Context) -> SymmetryUse:
    """The interchangeable agents of a compiled spec (roar/symmetry.py), verified on the model."""
    from ..roar.symmetry import discover, names_permuted
    sym = discover(model, start)
    if sym.order > 1:
        _refuse_named(job, lambda text: names_permuted(sym, text), "agents")
    return SymmetryUse(sym.group, sym.note())


def spec_properties(job: Job, model):
    """The job's properties in the spec's terms, bound to its compiled model (roar/props.py)."""
    from ..roar.props import SpecChecks
    return SpecChecks(job.props, model)


def mark_defaults(props, verdicts: dict) -> None:
    """Say which properties a job checked by default (a job on a spec that names none)."""
    if getattr(props, "defaulted", False):
        for v in verdicts.values():
            if "(a default property)" not in v.message:
                v.message += " (a default property)"


def roar_setup(job: Job, model) -> tuple:
    """(program, start context, options, sequential pairs) of a job on a compiled spec: weak
    fairness per agent, the property files' progress rules (or requests reaching a final state)."""
    from ..roar.explore import PROGRESS_RULES, job_sequence_pairs
    program = model.program()
    start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
    start = program.start_context(start_d.start)
    props = job.props
    options = Options(progress_rules=tuple(props.progress) or PROGRESS_RULES, fairness="agent",
                      canonical=job.canonical)
    pairs = []
    if "sequential-achievement" in props.check:
        pairs = job_sequence_pairs(model, props.sequence_recipes, props.sequence_kept, str(job.path))
    return program, start, options, pairs


def _reduction_options(options: Options, props, never) -> None:
    """Partial-order reduction for every property the job checks (see reduction.py): an
    invariant's forbidden patterns stay in every stubborn set, the families a monitor or a
    Python-computed invariant reads make their rules visible, progress steps are visible."""
    from ..clf.terms import Const
    from ..roar.explore import EXCLUSIVE_WRITES_FAMILIES, MONITOR_FAMILIES
    options.reduction = True
    options.observers = tuple(never.templates) if never is not None else ()
    visible: set = set()
    if "sequential-achievement" in props.check:
        visible |= MONITOR_FAMILIES
    if "exclusive-writes" in props.check:
        visible |= EXCLUSIVE_WRITES_FAMILIES
    options.visible_families = frozenset(Const(f) for f in visible)


def _search(job: Job, t0: float, explore, options: Options):
    """Explore in growing rounds until the graph is complete, every property is violated, or
    a budget runs out; returns (explorer, graph, verdicts).

    ``explore(options)`` makes an explorer and the function deciding the verdicts on its
    graph. Under reduction with weak fairness, a livelock verdict of "holds" is confirmed on
    the unreduced graph: a reduced graph keeps every fair cycle it shows (fairness is judged
    with every enabled group, expanded or not) but may miss one (docs/checking.md)."""
    if getattr(job, "cluster", None) is not None:   # search = "distributed", or a swarm on a cluster
        from .cluster import on_cluster
        return on_cluster(job, t0, explore, options)
    if job.search == "swarm":
        return swarm(job, t0, explore, options)
    explorer, decide = explore(options)
    graph, verdicts = search_rounds(job, t0, explorer, decide)
    hashed_note(explorer, verdicts)
    lv = verdicts.get("livelock")
    if options.reduction and lv is not None and lv.status == "holds" and options.fairness != "none":
        full_options = replace(options, reduction=False)
        ex2, decide2 = explore(full_options)
        graph2, verdicts2 = search_rounds(job, t0, ex2, decide2)
        lv2 = verdicts2["livelock"]
        if lv2.status == "holds":
            lv.message += f"; confirmed without reduction ({graph2.n_states:,} states)"
            lv.details["confirmed_states"] = graph2.n_states
        else:
            # keep one graph for every counterexample: the unreduced one
            for v in verdicts2.values():
                v.details["reduction"] = "missed a fair livelock; verdicts from the unreduced graph"
            return ex2, graph2, verdicts2
    return explorer, graph, verdicts


def make_explorer(job: Job, system, on_progress):
    """The explorer of a job's search: ``search.Explorer``, or on a cluster (a job with a [cluster]
    table, inside ``cluster.on_cluster``) the distributed one or a swarm member run as a task."""
    if getattr(job, "cluster", None) is not None:
        from .cluster import make_explorer as on_the_cluster
        return on_the_cluster(job, system, on_progress, explorer_order(job))
    return Explorer(system, explorer_order(job), on_progress, job.visited, job.bits)


def explorer_order(job: Job) -> str:
    """The explorer's order for the job's search (a swarm's members search depth first)."""
    return "dfs" if job.search == "swarm" else "bfs" if job.search == "distributed" else job.search


def swarm(job: Job, t0: float, explore, options: Options):
    """Search = "swarm": up to ``job.swarm_runs`` depth-first searches, each taking successors in
    its own random order and visiting at most ``job.swarm_states`` states, until one finds a
    violation (its counterexample is real but not the shortest) or covers the whole state space
    (then the verdicts are those of a complete search). Otherwise no verdict is "holds": the
    properties not found violated are "incomplete", with what the swarm covered."""
    total = 0
    last = None
    for i in range(job.swarm_runs):
        remaining = None
        if job.budget.max_seconds is not None:
            remaining = job.budget.max_seconds - (time.perf_counter() - t0)
            if remaining <= 0 and last is not None:
                break
        explorer, decide = explore(options)
        explorer.shuffle(i)
        graph = explorer.run(Budget(max_states=job.swarm_states, max_seconds=remaining,
                                    max_memory_mb=job.budget.max_memory_mb))
        stated_time(job, graph)
        verdicts = decide(graph)
        total += graph.n_states
        hashed_note(explorer, verdicts)
        last = (explorer, graph, verdicts, i + 1)
        if graph.complete:
            for v in verdicts.values():
                v.message += f" [swarm: search {i + 1} covered the whole state space]"
            return explorer, graph, verdicts
        if any(v.violated for v in verdicts.values()):
            for v in verdicts.values():
                if v.violated:
                    v.message += (f" [swarm: found by randomized depth-first search {i + 1} of {job.swarm_runs}; "
                                  f"a real counterexample, not the shortest]")
            break
    explorer, graph, verdicts, done = last
    for p, v in verdicts.items():
        if not v.violated:
            verdicts[p] = Verdict(p, "incomplete",
                                  f"no violation found by {done} randomized depth-first search"
                                  f"{'es' if done != 1 else ''} ({total:,} states visited in all, at most "
                                  f"{job.swarm_states:,} each): a bug-hunting result, not verified",
                                  v.counterexample, {**v.details, "swarm_runs": done, "swarm_states": total})
    return explorer, graph, verdicts


#: what a job's visited-set mode adds to its backend's name
VISITED_NOTE = {"exact": "", "hash": ", hash compaction", "bitstate": ", bitstate"}


def hashed_note(explorer, verdicts: dict) -> None:
    """Under hash compaction, say what each verdict is worth: a "holds" is a bug-hunting result
    with a bound on the probability that a state was missed, never a proof; a counterexample is
    real once replay confirms it (a collision could join two paths that are not one). Under
    bitstate hashing the same, with the probability that a new state was taken for a visited one."""
    if getattr(explorer, "bitstate", None) is not None:
        bitstate_note(explorer, verdicts)
        return
    if not getattr(explorer, "hashed", False):
        return
    p = explorer.omission_probability()
    for v in verdicts.values():
        v.details["visited"] = "hash"
        v.details["omission_probability"] = p
        if v.status == "holds":
            v.message += (f" [hash compaction: not verified; the probability that a state was missed is at "
                          f"most {p:.1e}]")
        elif v.status == "violated":
            v.message += " [hash compaction: replay the trace to confirm it]"


def bitstate_note(explorer, verdicts: dict) -> None:
    g = explorer.graph
    p, lost = explorer.omission_probability(), explorer.expected_omissions()
    what = (f"{g.n_states:,} states in {explorer.bits:,} bits, 3 bits each: at the end a new state was taken "
            f"for a visited one with probability {p:.1e}; about {lost:,.1f} states were so taken, and their "
            f"successors may be missed too")
    for v in verdicts.values():
        v.details.update(visited="bitstate", omission_probability=p, expected_omissions=lost, bits=explorer.bits,
                         unrecorded_transitions=g.n_unrecorded)
        if v.status == "holds":
            v.message += f" [bitstate: not verified; {what}]"
        elif v.status == "violated":
            v.message += " [bitstate: a real path; replay the trace to confirm it]"


def stated_time(job: Job, graph) -> None:
    """A search stopped by the time bound is given what the job's bound left after loading and
    compiling; its reason names the job's bound, the number the user wrote."""
    if job.budget.max_seconds is not None and graph.stop_reason.startswith("time budget of "):
        graph.stop_reason = f"time budget of {job.budget.max_seconds:g} s reached, loading and compiling included"


def search_rounds(job: Job, t0: float, explorer, decide):
    limit = job.budget.max_states
    k = FIRST_ROUND if limit is None else min(FIRST_ROUND, limit)
    graph = verdicts = None
    while True:
        remaining = None
        if job.budget.max_seconds is not None:
            remaining = max(0.0, job.budget.max_seconds - (time.perf_counter() - t0))
        graph = verdicts = None  # a restarting backend (ground) gives the last round's memory back first
        graph = explorer.run(Budget(max_states=k, max_seconds=remaining, max_memory_mb=job.budget.max_memory_mb))
        stated_time(job, graph)
        verdicts = decide(graph)
        if graph.complete or all(v.violated for v in verdicts.values()):
            return graph, verdicts
        if "state budget" not in graph.stop_reason or (limit is not None and k >= limit):
            return graph, verdicts
        grow = getattr(explorer, "GROWTH", 4)
        k = k * grow if limit is None else min(k * grow, limit)


def _mark_reduction(job: Job, verdicts: dict, reduction: str) -> None:
    if job.reduction:
        for v in verdicts.values():
            v.message += " (partial-order reduction)" if reduction == "on" else f" (reduction {reduction})"
            v.details.setdefault("reduction", reduction)


def _run_job(job: Job, on_progress) -> JobResult:
    from ..trace.fingerprint import clf_fingerprint
    t0 = time.perf_counter()
    program, start = load_model(job)
    fingerprint = clf_fingerprint(job.model)
    props = job.props
    options = Options(progress_rules=tuple(props.progress), fairness=props.fairness, canonical=job.canonical)
    accept_ctx = make_accept(program, props.accept, f"{props.sources[0] if props.sources else job.path} "
                             "[deadlock] accept") if props.accept else None
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
                raise RoarError(f"{job.path}: backend 'ground' cannot run this model: {exc}") from None
        except GroundingStopped as exc:
            grounding_stopped = str(exc)
    backend = "ground" if ground_model is not None or grounding_stopped else "general"
    reduction = "off"
    if job.reduction:
        if backend == "ground":
            reduction = "not used by the ground backend"
        else:
            reduction = "on"
            _reduction_options(options, props, never)

    def decide(graph: StateGraph, state_of) -> dict[str, Verdict]:
        accept = (lambda sid: accept_ctx(state_of(sid))) if accept_ctx else None
        verdicts = {}
        for p in props.check:
            if p == "invariant":
                verdicts[p] = check_states(graph, p, lambda sid: never(state_of(sid)))
            else:
                verdicts[p] = check_deadlock(graph, accept) if p == "deadlock" else \
                    check_livelock(graph, strong=job.props.strong)
        return verdicts

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

        _explorer, graph, verdicts = _search(job, t0, explore, options)
        backend += VISITED_NOTE[job.visited]
        if getattr(job, "cluster", None) is not None:
            from .cluster import cluster_note
            backend += cluster_note(_explorer)
    _mark_reduction(job, verdicts, reduction)
    _mark_symmetry(sym, verdicts, graph)
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


def roar_events(result: JobResult, verdict: Verdict) -> Optional[list]:
    """The ROAR-level events of a counterexample (jobs on a spec), per step: a list of event lists."""
    roar = getattr(result, "roar", None)
    if roar is None or verdict.counterexample is None:
        return None
    from ..roar.explore import path_events
    model, start, explorer = roar
    cx = verdict.counterexample
    edges = list(cx.prefix) + list(cx.cycle)
    events = path_events(model, start, [explorer.steps[e] for e in edges])
    per_step: list = [[] for _ in edges]
    for ev in events:
        per_step[ev.step - 1].append(ev)
    return per_step


def counterexample_steps(graph: StateGraph, verdict: Verdict, result: Optional[JobResult] = None) -> list[dict]:
    """The counterexample as trace records, with the ROAR-level events of jobs on a spec."""
    cx = verdict.counterexample
    events = roar_events(result, verdict) if result is not None else None
    out = []
    for loop, edges in ((False, cx.prefix), (True, cx.cycle)):
        for e in edges:
            rec = graph.describe_edge(e) if graph.describe_edge else {"rule": graph.labels.names[graph.label[e]]}
            rec = dict(rec)
            rec["group"] = graph.groups.names[int(graph.group[e])]
            evs = events[len(out)] if events is not None else []
            rec["event"] = (evs[0].as_json() if len(evs) == 1 else
                            {"kind": "several", "events": [x.as_json() for x in evs]}) if evs else None
            rec["loop"] = loop
            out.append(rec)
    return out


def save_counterexample(result: JobResult, prop: str, folder: Path) -> Path:
    v = result.verdicts[prop]
    steps = counterexample_steps(result.graph, v, result)
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in result.job.name)
    path = folder / f"{safe}.{prop}.jsonl"
    job = result.job
    # paths are recorded for people to read; replay never opens them (docs/trust.md): it takes
    # the model from its command line and compares the fingerprint of its sources
    where = ({"spec": str(job.spec), "request": job.request,
              "functional": str(job.functional) if job.functional else None} if job.is_roar
             else {"model": str(job.model), "start": job.start})
    if getattr(job, "crashes", None):   # the model was compiled with these crashes ([faults])
        where["crash"], where["max_crashes"] = list(job.crashes.agents), job.crashes.bound
    if getattr(job, "time", None):      # ... and in the timed mode (replay recompiles the same model)
        where.update(job.time.header())
    if job.is_roar and getattr(result, "roar", None) is not None:   # the pairs of make; make the job checked (TCA reads them)
        header_pairs = {"seq_pairs": [[p.a, p.b, p.where, p.a_text, p.b_text, p.kept]
                                      for p in result.roar[2].system.pairs]}
    else:
        header_pairs = {}
    robot = getattr(result, "robot", None)
    if robot is not None:   # robot-backed: what replay --on-robot needs to drive the same robot
        header_pairs["robot"] = robot.header(job.robot.scenario)
        node = robot.explorer.states[v.counterexample.final_state].node
        if prop == "robot-invariant" and node.bad:   # where the robot broke it (mid-advance, maybe)
            _i, why, t, pose = node.bad[0]
            header_pairs["robot"]["violation"] = {"t": round(t, 4), "pose": [round(x, 6) for x in pose],
                                                  "why": why}
    if robot is None:   # what replay re-decides on the model (verify/claims.py)
        claim = trace_claim(job, prop)
        if claim:
            header_pairs["claim"] = claim
    header = {"kind": "counterexample", "property": prop, **where, **header_pairs, "fingerprint": result.fingerprint,
              "job": str(result.job.path), "shape": v.counterexample.kind,
              "final_state": result.graph.describe_state(v.counterexample.final_state)
              if result.graph.describe_state else []}
    write_trace(path, header, steps)
    return path
