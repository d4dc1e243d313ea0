"""Properties in the spec's own terms (roar/props.py): predicates, mission properties, temporal forms.

Every construct is checked against an independent evaluation: a plain breadth-first search over
the engine's enumerator (``Program.steps`` / ``Program.successor``), written here, that decodes
each state by printing its facts (``decode_state`` for variables and requests, the printed
``act``/``rstat`` facts for tasks) and evaluates the predicate with a Python function written
by hand. Safety verdicts are compared with the shallowest bad state of that search; the
temporal verdicts with a fair-cycle search written here over ``networkx`` (weak fairness per
agent: a cycle is fair when every agent enabled in all of its states moves on it; the cycle
through every edge of a strongly connected component is the fairest one it holds), and every
lasso counterexample is replayed on the search's graph: it closes, the goal never holds on it,
and it is fair.
"""

from __future__ import annotations

import re
from collections import deque
from pathlib import Path

import networkx as nx
import pytest

from roar_formal.clf.query import with_big_stack
from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job, load_properties
from roar_formal.roar.functional import functional_module, load_registry
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.explore import RoarSystem
from roar_formal.roar.spec import load_spec
from roar_formal.roar.props import parse_formula, view_of
from roar_formal.roar.report import decode_state

from repo import ROOT
FAULTY = ROOT / "models" / "faulty"
CAMERA_RETRY = (FAULTY / "camera_retry.roar", "camera::taken == true")
CAMERA_BOUNDED = (FAULTY / "camera_bounded.roar", "camera::taken == true")
RETRY_BOUNDED = (FAULTY / "retry_bounded.roar", "hand::holding == true")
RETRY_FOREVER = (FAULTY / "retry_forever.roar", "hand::holding == true")
MUTUAL = (FAULTY / "mutual_make.roar", "arm::started == true")
MUTUAL_FIXED = (FAULTY / "mutual_make_fixed.roar", "arm::started == true")


# ------------------------------------------------------------------ the independent search


class Oracle:
    """Every reachable state of a spec on a request, by a plain BFS over the engine, each decoded."""

    def __init__(self, spec: Path, request: str):
        reg = load_registry(functional_module(spec, None))
        self.model = compile_spec(load_spec(spec), request, registry=reg, functional="abstract")
        program = self.program = self.model.program()
        start = program.start_context(next(d for d in program.sig.directives
                                           if type(d).__name__ == "ExecDirective").start)
        system = RoarSystem(self.model, start)
        self.states, self.depth, self.edges = [start], [0], []   # edges: (src, dst, agent)
        self.events: list = []   # per edge: the events read from its printed facts
        ids = {canonical_key(start): 0}
        queue = deque([0])
        while queue:
            s = queue.popleft()
            for c in program.steps(self.states[s]):
                nxt, _ = program.successor(self.states[s], c)
                k = canonical_key(nxt)
                if k not in ids:
                    ids[k] = len(self.states)
                    self.states.append(nxt)
                    self.depth.append(self.depth[s] + 1)
                    queue.append(ids[k])
                self.edges.append((s, ids[k], system.agent_of(c, self.states[s])))
                self.events.append(self.printed_events(_))
        self.decoded = [self.decode(ctx) for ctx in self.states]

    def printed_events(self, step) -> set:
        """A step's events from its printed facts: ``pending F ...`` produced (a primitive starts) or
        consumed (it ends), ``rq R A ...`` produced with a new R (a constraint sent to A)."""
        show = self.program.show
        prod = [show(t).split() for _m, t in step.produced]
        cons = [show(t).split() for _m, t in step.consumed]
        out = set()
        for w in prod:
            if w[0] == "pending":
                out.add("starts " + "::".join(x for x in self.model.functions[w[1]] if x))
            if w[0] == "rq" and w[1] not in {c[1] for c in cons if c[0] == "rq"}:
                out.add("sent " + self.model.agents[w[2]])
        for w in cons:
            if w[0] == "pending":
                out.add("ends " + "::".join(x for x in self.model.functions[w[1]] if x))
        return out

    def decode(self, ctx) -> dict:
        show = self.program.show
        r0 = next(f.args[0] for _m, f, _n in ctx.facts() if show(f).startswith("rq ") and " itop " in show(f))
        d = decode_state(self.model, ctx, {r0: "R0"}, {})
        out = {"vars": {}, "R0": None, "agents": {}, "tasks": {}}
        for agent, row in d["agents"].items():
            for var, val in row["variables"].items():
                out["vars"][f"{agent}::{var}"] = val
            for r in row["requests"]:
                out["agents"].setdefault(agent, set()).add(r["state"])
                if r["request"] == "R0":
                    out["R0"] = r["state"]
        printed = [show(f).split() for _m, f, _n in ctx.facts()]
        paused = {w[1] for w in printed if w[0] == "rstat" and w[2] != "go"}
        for w in printed:
            if w[0] == "act":
                agent, task = self.model.tasks[w[3]]
                out["tasks"].setdefault(f"{agent}::{task}", []).append("paused" if w[1] in paused else "running")
        return out

    def holds(self, pred) -> list[bool]:
        return [bool(pred(d)) for d in self.decoded]

    def shallowest(self, bad: list[bool]):
        hits = [self.depth[s] for s, b in enumerate(bad) if b]
        return min(hits) if hits else None

    def fair_escape(self, seeds: list[bool], goal: list[bool]):
        """Is there a fair run from a seed state that never reaches a goal state? (an end state or a
        fair cycle among non-goal states reachable from a seed through non-goal states)"""
        g = nx.DiGraph()
        g.add_nodes_from(range(len(self.states)))
        enabled = {s: set() for s in range(len(self.states))}
        moves: dict = {}
        for a, b, agent in self.edges:
            enabled[a].add(agent)
            if not goal[a] and not goal[b]:
                g.add_edge(a, b)
                moves.setdefault((a, b), set()).add(agent)
        region = set()
        for s in range(len(self.states)):
            if seeds[s] and not goal[s]:
                region |= {s} | nx.descendants(g, s)
        if any(not enabled[s] for s in region):
            return "end"
        sub = g.subgraph(region)
        for comp in nx.strongly_connected_components(sub):
            inner = [(a, b) for a in comp for b in sub.successors(a) if b in comp]
            if not inner:
                continue
            always = set.intersection(*(enabled[s] for s in comp))
            moving = set().union(*(moves[e] for e in inner))
            if always <= moving:
                return "cycle"
        return None


_ORACLES: dict = {}


def oracle(which) -> Oracle:
    if which not in _ORACLES:
        _ORACLES[which] = with_big_stack(Oracle, *which)
    return _ORACLES[which]


def _job(tmp_path: Path, which, props: str, expect: dict | None = None, name: str = "j") -> Path:
    spec, request = which
    p = tmp_path / f"{name}.props.toml"
    p.write_text(props, encoding="utf-8")
    j = tmp_path / f"{name}.toml"
    exp = "".join(f'{k} = "{v}"\n' for k, v in (expect or {}).items())
    j.write_text(f'name = "{name}"\nspec = "{spec}"\nrequest = "{request}"\nproperties = ["{p}"]\n'
                 + (f"[expect]\n{exp}" if exp else ""), encoding="utf-8")
    return j


def _lasso_ok(res, verdict, goal_fn) -> None:
    """The lasso of a verdict, replayed on the engine's states: it closes, never meets the goal and
    is fair (weak fairness per agent, enabled agents computed by the engine)."""
    cx = verdict.counterexample
    assert cx.kind == "lasso" and cx.cycle
    model, start, explorer = res.roar
    g = res.graph
    states = [int(g.src[e]) for e in cx.cycle]
    assert int(g.dst[cx.cycle[-1]]) == states[0] == cx.final_state
    for a, b in zip(cx.cycle, cx.cycle[1:]):
        assert int(g.dst[a]) == int(g.src[b])
    for s in states:
        assert not goal_fn(view_of(model, explorer.states[s]))
    system = explorer.system
    program = model.program()
    moving = {g.groups.names[int(g.group[e])] for e in cx.cycle}
    enabled = [{system.agent_of(c, explorer.states[s]) for c in program.steps(explorer.states[s])} for s in states]
    starving = set.intersection(*enabled) - moving
    assert not starving, f"agents {starving} are enabled all along the cycle and never move"


# ------------------------------------------------------------------ 1. syntax and names


@pytest.mark.parametrize("text,form", [
    ("arm::holding == true && gripper::closed == false", "state"),
    ("ptu::heading != 0", "state"),
    ("!(a::x < 3 || a::y >= 2.5) && a::s == \"ok\"", "state"),
    ("a::p.x + 2 * -a::n / 4 > 1", "state"),
    ("request R0 finished", "state"),
    ("request R0 in temporary-failure", "state"),
    ("task arm::pick running", "state"),
    ("agent planner in temporary-failure", "state"),
    ("agent planner idle", "state"),
    ("always !request R0 failed", "always"),
    ("eventually request R0 succeeded", "eventually"),
    ("request R0 running leads-to request R0 finished", "leads-to"),
])
def test_every_construct_parses(text, form):
    assert parse_formula(text).form == form


@pytest.mark.parametrize("text,col,words", [
    ("arm::holding = true", 14, ["'='", "equality is '=='"]),
    ("arm::x == 1 and arm::y", 13, ["'and'", "write &&"]),
    ("arm::x ==", 10, ["end of the property", "expected a predicate"]),
    ("request R0 done", 12, ["unknown request status 'done'", "finished"]),
    ("agent p in tempfail", 12, ["did you mean 'temporary-failure'"]),
    ("task a::t sleeping", 11, ["unknown task status", "running, paused, active, idle"]),
    ("request R2 running", 9, ["only R0"]),
    ("a::x leads to a::y", 6, ["'leads-to'"]),
    ("always eventually a::x == 5", 19, ["'always' and 'eventually': temporal operators do not nest"]),
    ("eventualy a::x == true", 11, ["did you mean 'eventually'"]),
    ("a::read() == true", 8, ["unexpected '('", "cannot call a function", "primitive agent::f starts"]),
    ("a::x == 5 lead-to a::y", 11, ["did you mean 'leads-to'"]),
])
def test_syntax_errors_are_located_with_what_was_expected(text, col, words):
    from roar_formal.errors import Pos
    with pytest.raises(RoarError) as e:
        parse_formula(text, Pos("p.toml", 7, 12))
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == ("p.toml", 7, 12 + col - 1)
    for w in words:
        assert w in e.value.message, e.value.message


@pytest.mark.parametrize("text,words", [
    ("camra::taken == true", ["unknown agent 'camra'", "did you mean 'camera'"]),
    ("camera::taken == 1", ["bool", "int", "cannot be equal"]),
    ("camera::tacken == true", ["no variable 'tacken'", "did you mean 'taken'"]),
    ("taken == true", ["not qualified", "did you mean 'camera::taken'"]),
    ("task camera::shot running", ["no task 'shot'", "did you mean 'shoot'"]),
    ("agent ptuu idle", ["unknown agent 'ptuu'", "did you mean 'ptu'"]),
    ("ptu::heading", ["is int, not a condition"]),
    ("ptu::heading < true", ["compares numbers"]),
    ("primitive ptu starts", ["agent 'ptu' exports no function the spec calls", "never happens", "camera"]),
])
def test_names_and_types_are_resolved_against_the_spec_with_located_errors(tmp_path, text, words):
    job = _job(tmp_path, CAMERA_BOUNDED, f'[invariant]\nnever = ["{text}"]\n')
    with pytest.raises(RoarError) as e:
        run_job(load_job(job))
    assert e.value.pos is not None and e.value.pos.file.endswith("j.props.toml") and e.value.pos.line == 2
    for w in words:
        assert w in e.value.message, e.value.message


def test_a_syntax_error_in_a_property_file_points_inside_the_string(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[invariant]\nalways = ["ptu::heading != 0",\n          "ptu::heading => 1"]\n', encoding="utf-8")
    with pytest.raises(RoarError) as e:
        load_properties(p)
    assert (e.value.pos.line, e.value.pos.col) == (3, 25) and "'='" in e.value.message


def test_spec_predicates_need_a_job_on_a_spec(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[invariant]\nnever = ["arm::x == 1"]\n', encoding="utf-8")
    j = tmp_path / "j.toml"
    j.write_text(f'model = "{ROOT / "models/philosophers/ok.clf"}"\nproperties = ["{p}"]\n', encoding="utf-8")
    with pytest.raises(RoarError, match="needs a job on a spec") as e:
        load_job(j)
    assert e.value.pos.line == 2


def test_temporal_names_are_checked(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[temporal]\ndeadlock = "always request R0 live"\n', encoding="utf-8")
    with pytest.raises(RoarError, match="built-in property"):
        load_properties(p)


# ------------------------------------------------------------------ 2. predicates against the oracle


PREDICATES = [
    # (text, the same predicate on a decoded state of the oracle)
    ("camera::taken == true", lambda d: d["vars"]["camera::taken"] == "true"),
    ("camera::taken == false && ptu::heading != 0",
     lambda d: d["vars"]["camera::taken"] == "false" and d["vars"]["ptu::heading"] != "0"),
    ("camera::attempts >= 1 || ptu::target == 90",
     lambda d: int(d["vars"]["camera::attempts"]) >= 1 or d["vars"]["ptu::target"] == "90"),
    ("!(ptu::heading == ptu::target)", lambda d: d["vars"]["ptu::heading"] != d["vars"]["ptu::target"]),
    ("ptu::heading + 2 * camera::attempts - 1 > 90",
     lambda d: int(d["vars"]["ptu::heading"]) + 2 * int(d["vars"]["camera::attempts"]) - 1 > 90),
    ("ptu::heading / 4 == 22", lambda d: int(d["vars"]["ptu::heading"]) // 4 == 22),
    ("-ptu::heading < -45", lambda d: -int(d["vars"]["ptu::heading"]) < -45),
    ("request R0 running", lambda d: d["R0"] == "running"),
    ("request R0 pending", lambda d: d["R0"] == "pending"),
    ("request R0 sent", lambda d: d["R0"] == "sent"),
    ("request R0 temporary-failure", lambda d: d["R0"] == "temporary failure"),
    ("request R0 paused", lambda d: d["R0"] == "paused"),
    ("request R0 succeeded", lambda d: d["R0"] == "success"),
    ("request R0 failed", lambda d: d["R0"] == "failure"),
    ("request R0 finished", lambda d: d["R0"] in ("success", "failure")),
    ("request R0 live", lambda d: d["R0"] in ("sent", "pending", "running", "paused", "temporary failure")),
    ("agent ptu in running", lambda d: "running" in d["agents"].get("ptu", ())),
    ("agent ptu in succeeded", lambda d: "success" in d["agents"].get("ptu", ())),
    ("agent ptu in pending", lambda d: "pending" in d["agents"].get("ptu", ())),
    ("agent camera in temporary-failure", lambda d: "temporary failure" in d["agents"].get("camera", ())),
    ("agent ptu idle", lambda d: not set(d["agents"].get("ptu", ())) & {"sent", "pending", "running", "paused",
                                                                         "temporary failure"}),
    ("task camera::shoot running", lambda d: "running" in d["tasks"].get("camera::shoot", [])),
    ("task camera::shoot paused", lambda d: "paused" in d["tasks"].get("camera::shoot", [])),
    ("task ptu::point active", lambda d: bool(d["tasks"].get("ptu::point"))),
    ("task ptu::point idle", lambda d: not d["tasks"].get("ptu::point")),
    ("task camera::shoot running && agent ptu in running && camera::attempts == 2",
     lambda d: "running" in d["tasks"].get("camera::shoot", []) and "running" in d["agents"].get("ptu", ())
     and d["vars"]["camera::attempts"] == "2"),
]


@pytest.mark.parametrize("which", [CAMERA_BOUNDED, CAMERA_RETRY], ids=["bounded", "retry"])
def test_predicates_agree_with_the_oracle_on_every_reachable_state(which):
    o = oracle(which)
    for text, fn in PREDICATES:
        if "attempts" in text and which is CAMERA_RETRY:
            continue
        f = parse_formula(text).bind(o.model)
        mine = [bool(f.pf(view_of(o.model, ctx))) for ctx in o.states]
        assert mine == o.holds(fn), text
    # the predicates are not vacuous on these states: most of them are true somewhere and false somewhere
    if which is CAMERA_BOUNDED:
        mixed = [text for text, fn in PREDICATES if len(set(o.holds(fn))) == 2]
        # (R0 is never paused nor failed here, and the camera's task never paused)
        assert len(mixed) >= len(PREDICATES) - 4, [t for t, _ in PREDICATES if t not in mixed]


@pytest.mark.parametrize("text,fn", [
    ("ptu::heading != 0 && request R0 live", lambda d: d["vars"]["ptu::heading"] != "0" and d["R0"] != "success"),
    ("camera::attempts == 2 && task camera::shoot running",
     lambda d: d["vars"]["camera::attempts"] == "2" and "running" in d["tasks"].get("camera::shoot", [])),
    ("agent camera in temporary-failure", lambda d: "temporary failure" in d["agents"].get("camera", ())),
    ("camera::attempts > 2", lambda d: int(d["vars"]["camera::attempts"]) > 2),
])
def test_never_and_always_verdicts_agree_with_the_oracle(tmp_path, text, fn):
    o = oracle(CAMERA_BOUNDED)
    bad = o.holds(fn)
    want = o.shallowest(bad)
    for key, negate in (("never", False), ("always", True)):
        shown = f"!({text})" if negate else text
        res = run_job(load_job(_job(tmp_path, CAMERA_BOUNDED, f'[invariant]\n{key} = ["{shown}"]\n', name=key)))
        v = res.verdicts["invariant"]
        assert v.status == ("holds" if want is None else "violated"), (key, v.message)
        assert res.graph.n_states == len(o.states)
        if want is not None:
            assert len(v.counterexample.prefix) == want
            final = res.roar[2].states[v.counterexample.final_state]
            assert fn(o.decode(final))
            assert f"{key} {shown!r}" in v.message
            for var in ("camera::attempts", "ptu::heading"):
                if var in text:
                    assert f"{var} = " in v.message   # violations print the variables' values


def test_a_violated_invariant_prints_the_values_it_read(tmp_path):
    res = run_job(load_job(_job(tmp_path, CAMERA_BOUNDED,
                                '[invariant]\nnever = ["camera::taken == false && ptu::heading == 90"]\n')))
    v = res.verdicts["invariant"]
    assert v.status == "violated"
    assert "camera::taken = false; ptu::heading = 90" in v.message


def test_clf_patterns_still_work_on_a_spec_next_to_predicates(tmp_path):
    props = '[invariant]\nnever = ["rs R s_running", "camera::attempts > 2"]\n'
    res = run_job(load_job(_job(tmp_path, CAMERA_BOUNDED, props)))
    v = res.verdicts["invariant"]
    o = oracle(CAMERA_BOUNDED)
    assert v.status == "violated"
    running = o.shallowest(o.holds(lambda d: any("running" in s for s in d["agents"].values())))
    assert len(v.counterexample.prefix) == running and "rs R s_running" in v.message


# ------------------------------------------------------------------ 3. mission properties


def test_mission_failure_is_reported_with_its_error_context(tmp_path):
    res = run_job(load_job(_job(tmp_path, RETRY_BOUNDED, 'check = ["mission-failure"]\n')))
    v = res.verdicts["mission-failure"]
    o = oracle(RETRY_BOUNDED)
    assert v.status == "violated"
    assert len(v.counterexample.prefix) == o.shallowest(o.holds(lambda d: d["R0"] == "failure"))
    assert "error context" in v.message and "task failed: hand::take" in v.message
    assert "local failure: hand.take.close" in v.message and "assert(grip())" in v.message


@pytest.mark.parametrize("which,status,shape", [
    (CAMERA_RETRY, "violated", "lasso"),
    (CAMERA_BOUNDED, "holds", None),
    (RETRY_FOREVER, "violated", "lasso"),
    (RETRY_BOUNDED, "violated", "path"),   # three failed grips: the run ends with R0 failed
    (MUTUAL, "violated", "path"),          # the deadlock: the run ends with R0 running
    (MUTUAL_FIXED, "holds", None),
], ids=["camera_retry", "camera_bounded", "retry_forever", "retry_bounded", "mutual_make", "mutual_make_fixed"])
def test_mission_completion_agrees_with_the_oracle(tmp_path, which, status, shape):
    res = run_job(load_job(_job(tmp_path, which, 'check = ["mission-completion"]\n')))
    v = res.verdicts["mission-completion"]
    o = oracle(which)
    goal = o.holds(lambda d: d["R0"] == "success")
    seeds = [s == 0 for s in range(len(o.states))]
    escape = o.fair_escape(seeds, goal)
    assert v.status == status == ("holds" if escape is None else "violated"), v.message
    if shape is None:
        return
    assert v.counterexample.kind == shape and {"path": "end", "lasso": "cycle"}[shape] == escape
    if shape == "lasso":
        _lasso_ok(res, v, lambda view: view.r0 == "success")
        assert "never succeeds" in v.message
    else:
        final = res.roar[2].states[v.counterexample.final_state]
        assert res.program.steps(final) == [] and o.decode(final)["R0"] != "success"
        assert "a run ends with request R0" in v.message


def test_the_camera_retry_job_reports_a_lasso_in_spec_terms():
    from roar_formal.verify.report import counterexample_report
    res = run_job(load_job(ROOT / "checker" / "camera_retry.toml"))
    assert res.ok
    v = res.verdicts["mission-completion"]
    rep = counterexample_report(res, "mission-completion")
    loop = [ev["text"] for s in rep["steps"] if s["loop"] for ev in s["events"]]
    assert any("make" in t and "ptu::heading == ptu::target" in t for t in loop)    # the sub-request is sent ...
    assert any("pending -> success" in t for t in loop)                             # ... and succeeds every time
    assert any("snap() = false" in t for t in loop)
    assert "stays temporary failure" in v.message or "stays running" in v.message


def test_camera_retry_livelock_old_and_new_progress(tmp_path):
    """The issue's complaint: with the old progress (any request reaching a final state) the endless
    retry is no livelock; with progress in the spec's terms (the job's request finishes) it is."""
    old = run_job(load_job(_job(tmp_path, CAMERA_RETRY, 'check = ["livelock"]\n', name="old")))
    new = run_job(load_job(_job(tmp_path, CAMERA_RETRY,
                                'check = ["livelock"]\n[livelock]\nprogress = ["request R0 finished"]\n', name="new")))
    assert old.verdicts["livelock"].status == "holds"
    # a holds by the default progress says what it counted as progress, and how to name the request's
    assert "progress: any request of any agent finishing" in old.verdicts["livelock"].message
    assert "request R0 finished" in old.verdicts["livelock"].message
    assert new.verdicts["livelock"].status == "violated"
    assert "progress: any request" not in new.verdicts["livelock"].message
    _lasso_ok(new, new.verdicts["livelock"], lambda view: view.r0 in ("success", "failure"))


@pytest.mark.parametrize("which", [CAMERA_RETRY, CAMERA_BOUNDED, RETRY_FOREVER, RETRY_BOUNDED, MUTUAL_FIXED],
                         ids=["camera_retry", "camera_bounded", "retry_forever", "retry_bounded",
                              "mutual_make_fixed"])
@pytest.mark.parametrize("progress,fn", [
    ("request R0 finished", lambda d: d["R0"] in ("success", "failure")),
    ("agent ptu in succeeded", lambda d: "success" in d["agents"].get("ptu", ())),
], ids=["r0-finished", "ptu-succeeded"])
def test_livelock_progress_in_spec_terms_agrees_with_the_oracle(tmp_path, which, progress, fn):
    """Livelock with progress predicate P: a fair cycle among states where P never holds (a step
    into a P state is progress), i.e. a fair run escaping P from some reachable state."""
    if "ptu" in progress and "camera" not in str(which[0]):
        progress, fn = "request R0 finished", (lambda d: d["R0"] in ("success", "failure"))
    res = run_job(load_job(_job(tmp_path, which, f'check = ["livelock"]\n[livelock]\nprogress = ["{progress}"]\n')))
    v = res.verdicts["livelock"]
    o = oracle(which)
    goal = o.holds(fn)
    # only cycles count for livelock (a run that ends is deadlock's business): a fair cycle escaping P
    escape = o.fair_escape([True] * len(o.states), goal)
    has_cycle = escape == "cycle" or (escape == "end" and _has_fair_cycle(o, goal))
    assert v.status == ("violated" if has_cycle else "holds"), v.message
    if v.status == "violated":
        _lasso_ok(res, v, lambda view: bool(parse_formula(progress).bind(o.model).pf(view)))


def _has_fair_cycle(o: Oracle, goal: list) -> bool:
    """A fair cycle among non-goal states (anywhere reachable), the oracle's way."""
    g = nx.DiGraph()
    enabled = {s: set() for s in range(len(o.states))}
    moves: dict = {}
    for a, b, agent in o.edges:
        enabled[a].add(agent)
        if not goal[a] and not goal[b]:
            g.add_edge(a, b)
            moves.setdefault((a, b), set()).add(agent)
    for comp in nx.strongly_connected_components(g):
        inner = [(a, b) for a in comp for b in g.successors(a) if b in comp]
        if inner and set.intersection(*(enabled[s] for s in comp)) <= set().union(*(moves[e] for e in inner)):
            return True
    return False


# ------------------------------------------------------------------ 4. temporal forms


TEMPORAL = [
    # (which, formula, seeds, goal) on the oracle's decoded states
    (CAMERA_BOUNDED, "eventually camera::attempts == 2",
     lambda d: False, lambda d: d["vars"]["camera::attempts"] == "2"),
    (CAMERA_BOUNDED, "eventually camera::taken == true",
     lambda d: False, lambda d: d["vars"]["camera::taken"] == "true"),
    (CAMERA_BOUNDED, "agent ptu in running leads-to agent ptu in succeeded",
     lambda d: "running" in d["agents"].get("ptu", ()), lambda d: "success" in d["agents"].get("ptu", ())),
    (CAMERA_RETRY, "request R0 running leads-to request R0 finished",
     lambda d: d["R0"] == "running", lambda d: d["R0"] in ("success", "failure")),
    (CAMERA_RETRY, "request R0 running leads-to camera::taken == true || request R0 temporary-failure",
     lambda d: d["R0"] == "running",
     lambda d: d["vars"]["camera::taken"] == "true" or d["R0"] == "temporary failure"),
    (RETRY_BOUNDED, "request R0 running leads-to request R0 finished",
     lambda d: d["R0"] == "running", lambda d: d["R0"] in ("success", "failure")),
    (RETRY_BOUNDED, "task hand::take running leads-to hand::holding == true",
     lambda d: "running" in d["tasks"].get("hand::take", []), lambda d: d["vars"]["hand::holding"] == "true"),
    (MUTUAL, "eventually arm::parked == true",
     lambda d: False, lambda d: d["vars"]["arm::parked"] == "true"),
    (MUTUAL_FIXED, "request R0 pending leads-to arm::started == true",
     lambda d: d["R0"] == "pending", lambda d: d["vars"]["arm::started"] == "true"),
]


@pytest.mark.parametrize("which,text,seed_fn,goal_fn", TEMPORAL, ids=[t[1] for t in TEMPORAL])
def test_eventually_and_leads_to_agree_with_the_oracle(tmp_path, which, text, seed_fn, goal_fn):
    res = run_job(load_job(_job(tmp_path, which, f'[temporal]\nprop = "{text}"\n')))
    v = res.verdicts["prop"]
    o = oracle(which)
    goal = o.holds(goal_fn)
    seeds = [s == 0 for s in range(len(o.states))] if text.startswith("eventually") else o.holds(seed_fn)
    escape = o.fair_escape(seeds, goal)
    assert v.status == ("holds" if escape is None else "violated"), (escape, v.message)
    if v.status == "violated":
        f = parse_formula(text).bind(o.model)
        goal_of = f.qf if f.q is not None else f.pf
        if v.counterexample.kind == "lasso":
            _lasso_ok(res, v, lambda view: bool(goal_of(view)))
        else:
            final = res.roar[2].states[v.counterexample.final_state]
            assert res.program.steps(final) == [] and not goal_fn(o.decode(final))
        # from the seed on, the goal never holds along the counterexample
        model, _start, explorer = res.roar
        g = res.graph
        path = list(v.counterexample.prefix) + list(v.counterexample.cycle)
        visited = [0] + [int(g.dst[e]) for e in path]
        seed_at = max(i for i, s in enumerate(visited[:len(v.counterexample.prefix) + 1])
                      if (f.q is None and i == 0) or (f.q is not None and f.pf(view_of(model, explorer.states[s]))))
        assert not any(goal_of(view_of(model, explorer.states[s])) for s in visited[seed_at:])
        # the saved trace carries the claim, and replay re-decides it on the model (verify/claims.py)
        from roar_formal.verify.check import save_counterexample
        from roar_formal.verify.replay import replay_trace
        trace = save_counterexample(res, "prop", tmp_path)
        rep = replay_trace(trace, which[0])
        assert rep.confirmed is True, rep.confirmation


@pytest.mark.parametrize("which,text,fn", [
    (CAMERA_BOUNDED, "always camera::attempts <= 2", lambda d: int(d["vars"]["camera::attempts"]) <= 2),
    (CAMERA_BOUNDED, "always camera::attempts <= 1", lambda d: int(d["vars"]["camera::attempts"]) <= 1),
    (RETRY_BOUNDED, "always !request R0 failed", lambda d: d["R0"] != "failure"),
])
def test_always_agrees_with_the_oracle(tmp_path, which, text, fn):
    res = run_job(load_job(_job(tmp_path, which, f'[temporal]\nprop = "{text}"\n')))
    v = res.verdicts["prop"]
    o = oracle(which)
    want = o.shallowest([not x for x in o.holds(fn)])
    assert v.status == ("holds" if want is None else "violated")
    if want is not None:
        assert len(v.counterexample.prefix) == want


def test_a_temporal_property_is_expected_by_its_name(tmp_path):
    j = _job(tmp_path, CAMERA_RETRY, '[temporal]\nsnap-ends = "request R0 running leads-to request R0 finished"\n',
             {"snap-ends": "violated"})
    res = run_job(load_job(j))
    assert res.ok and res.verdicts["snap-ends"].counterexample.kind == "lasso"


# ------------------------------------------------------------------ 5. defaults


def test_a_spec_job_without_properties_checks_the_defaults_and_says_so(tmp_path):
    spec, request = CAMERA_RETRY
    j = tmp_path / "bare.toml"
    j.write_text(f'spec = "{spec}"\nrequest = "{request}"\n', encoding="utf-8")
    job = load_job(j)
    assert job.props.check == ["deadlock", "mission-completion", "mission-failure"] and job.props.defaulted
    res = run_job(job)
    assert [(p, v.status) for p, v in res.verdicts.items()] == [
        ("deadlock", "holds"), ("mission-completion", "violated"), ("mission-failure", "holds")]
    assert all("(a default property)" in v.message for v in res.verdicts.values())
    assert not res.ok   # nothing expected: the violation is an error


# ------------------------------------------------------------------ 6. events


STEP_NEVER = [
    ("primitive camera::snap starts && camera::attempts == 2",
     lambda ev, d: "starts camera::snap" in ev and d["vars"]["camera::attempts"] == "2"),
    ("constraint sent to ptu && ptu::heading == 90", lambda ev, d: "sent ptu" in ev and d["vars"]["ptu::heading"] == "90"),
    ("primitive camera::grab_frame ends", lambda ev, d: "ends camera::grab_frame" in ev),
    ("primitive camera starts && request R0 paused", lambda ev, d: any(e.startswith("starts camera::") for e in ev)
     and d["R0"] == "paused"),
]


@pytest.mark.parametrize("text,fn", STEP_NEVER, ids=[t for t, _ in STEP_NEVER])
def test_event_invariants_agree_with_the_oracle(tmp_path, text, fn):
    o = oracle(CAMERA_BOUNDED)
    hits = [o.depth[a] + 1 for (a, _b, _g), ev in zip(o.edges, o.events) if fn(ev, o.decoded[a])]
    res = run_job(load_job(_job(tmp_path, CAMERA_BOUNDED, f'[invariant]\nnever = ["{text}"]\n')))
    v = res.verdicts["invariant"]
    assert v.status == ("violated" if hits else "holds"), v.message
    if hits:
        assert len(v.counterexample.prefix) == min(hits) and "its events:" in v.message


@pytest.mark.parametrize("which,event,fn", [
    (CAMERA_BOUNDED, "primitive camera::snap starts", lambda ev: "starts camera::snap" in ev),
    (CAMERA_BOUNDED, "primitive camera::grab_frame starts", lambda ev: "starts camera::grab_frame" in ev),
    (CAMERA_RETRY, "primitive camera::snap ends", lambda ev: "ends camera::snap" in ev),
    (CAMERA_RETRY, "constraint sent to ptu", lambda ev: "sent ptu" in ev),
], ids=["bounded-snap", "bounded-frame", "retry-snap-ends", "retry-sent-ptu"])
def test_eventually_an_event_agrees_with_the_oracle(tmp_path, which, event, fn):
    """`eventually EVENT` is violated when a run from the start never takes a step with the event
    and ends, or closes a weakly fair cycle: checked on the plain enumerator's graph."""
    o = oracle(which)
    n = len(o.states)
    out = {s: [] for s in range(n)}
    for (a, b, agent), ev in zip(o.edges, o.events):
        out[a].append((b, agent, fn(ev)))
    region, todo = {0}, [0]
    while todo:
        u = todo.pop()
        for b, _agent, hit in out[u]:
            if not hit and b not in region:
                region.add(b)
                todo.append(b)
    violated = any(not out[u] for u in region)
    g = nx.DiGraph()
    moves: dict = {}
    for a in region:
        for b, agent, hit in out[a]:
            if not hit and b in region:
                g.add_edge(a, b)
                moves.setdefault((a, b), set()).add(agent)
    for comp in nx.strongly_connected_components(g):
        inner = [(a, b) for a in comp for b in g.successors(a) if b in comp]
        if inner and set.intersection(*({x[1] for x in out[s]} for s in comp)) <= set().union(*(moves[e] for e in inner)):
            violated = True
    res = run_job(load_job(_job(tmp_path, which, f'[temporal]\nev = "eventually {event}"\n')))
    assert res.verdicts["ev"].status == ("violated" if violated else "holds"), res.verdicts["ev"].message


@pytest.mark.parametrize("which,progress,fn", [
    (CAMERA_RETRY, "primitive camera::snap ends", lambda ev: "ends camera::snap" in ev),
    (CAMERA_RETRY, "constraint sent to ptu", lambda ev: "sent ptu" in ev),
    (RETRY_FOREVER, "primitive hand starts", lambda ev: any(e.startswith("starts hand::") for e in ev)),
    (CAMERA_RETRY, "constraint sent to camera", lambda ev: "sent camera" in ev),   # R0 is sent by no step
], ids=["snap-ends", "sent-to-ptu", "hand-starts", "sent-to-camera"])
def test_event_progress_agrees_with_the_oracle(tmp_path, which, progress, fn):
    """Livelock with event progress: a fair cycle none of whose steps has the event."""
    o = oracle(which)
    g = nx.DiGraph()
    enabled = {s: set() for s in range(len(o.states))}
    moves: dict = {}
    for (a, b, agent), ev in zip(o.edges, o.events):
        enabled[a].add(agent)
        if not fn(ev):
            g.add_edge(a, b)
            moves.setdefault((a, b), set()).add(agent)
    fair = False
    for comp in nx.strongly_connected_components(g):
        inner = [(a, b) for a in comp for b in g.successors(a) if b in comp]
        if inner and set.intersection(*(enabled[s] for s in comp)) <= set().union(*(moves[e] for e in inner)):
            fair = True
    res = run_job(load_job(_job(tmp_path, which, f'check = ["livelock"]\n[livelock]\nprogress = ["{progress}"]\n')))
    v = res.verdicts["livelock"]
    assert v.status == ("violated" if fair else "holds"), v.message
    assert fair == (progress == "constraint sent to camera")   # both verdicts are exercised


# ------------------------------------------------------------------ 7. robot-backed jobs


def test_robot_backed_jobs_decide_the_spec_properties_and_a_horizon_is_no_end(tmp_path):
    """verify/robot.py's decide: the same properties on (CLF state, robot state) pairs; a state cut at
    the scenario's horizon has no successor but is not the end of a run."""
    data = ROOT / "tests" / "robot" / "data" / "explore"
    props = tmp_path / "p.toml"
    props.write_text('check = ["mission-completion", "mission-failure"]\n[temporal]\n'
                     'ends = "request R0 running leads-to request R0 finished"\n'
                     '[invariant]\nnever = ["primitive left starts && request R0 failed"]\n', encoding="utf-8")
    job = tmp_path / "pair.toml"
    job.write_text(f'spec = "{data / "pair.roar"}"\nrequest = "mission::done == true"\nproperties = ["{props}"]\n'
                   f'[robot]\nscenario = "{data / "pair.toml"}"\nfaults = ["blind", "spill"]\nquantise = "exact"\n'
                   'compare = false\n', encoding="utf-8")
    res = run_job(load_job(job))
    assert res.backend == "robot" and res.robot.horizon_states > 0
    assert {p: v.status for p, v in res.verdicts.items()} == {
        "mission-completion": "holds", "mission-failure": "holds", "ends": "holds", "invariant": "holds"}


# ------------------------------------------------------------------ events in temporal forms


def test_eventually_and_leads_to_read_events(tmp_path):
    """`eventually EVENT` is decided on steps: a run reaches it by taking a step on which the event
    happens; `EVENT leads-to P` starts from the states such steps reach."""
    (tmp_path / "p.toml").write_text(
        "[temporal]\n"
        "snap-happens = \"eventually primitive camera::snap starts\"\n"
        "frame-happens = \"eventually primitive camera::grab_frame starts\"\n"
        "snap-then-done = \"primitive camera::snap ends leads-to request R0 finished\"\n")
    (tmp_path / "job.toml").write_text(
        f"name = \"camera_events\"\nspec = \"{CAMERA_BOUNDED[0]}\"\nrequest = \"{CAMERA_BOUNDED[1]}\"\n"
        "properties = [\"p.toml\"]\n[expect]\nframe-happens = \"violated\"\n")
    res = with_big_stack(lambda: run_job(load_job(tmp_path / "job.toml")))
    assert res.ok, res.mismatches
    v = res.verdicts
    assert v["snap-happens"].status == "holds" and v["snap-then-done"].status == "holds"
    frame = v["frame-happens"]
    assert frame.status == "violated" and frame.message.startswith(
        "a run ends without 'primitive camera::grab_frame starts'")
    # its run is a complete run (it ends) on which no step starts grab_frame
    from roar_formal.roar.props import step_events
    model, _start, explorer = res.roar
    cx = frame.counterexample
    assert cx.kind == "path" and not cx.cycle
    assert not explorer.system.successors(explorer.states[cx.final_state])
    events = [step_events(model, explorer.steps[e]) for e in cx.prefix]
    assert any(("starts", "camera", "snap") in ev for ev in events)
    assert not any(("starts", "camera", "grab_frame") in ev for ev in events)


@pytest.mark.parametrize("prop,message", [
    ("always primitive camera::snap starts", "events (primitive ... starts, constraint sent to ...) are steps, not states"),
    ("primitive camera::snap starts", "an event alone is not a temporal property"),
])
def test_events_where_a_state_is_needed_are_refused(tmp_path, prop, message):
    (tmp_path / "p.toml").write_text(f"[temporal]\nx = \"{prop}\"\n")
    (tmp_path / "job.toml").write_text(
        f"name = \"j\"\nspec = \"{CAMERA_BOUNDED[0]}\"\nrequest = \"{CAMERA_BOUNDED[1]}\"\nproperties = [\"p.toml\"]\n")
    with pytest.raises(RoarError, match=re.escape(message)):
        run_job(load_job(tmp_path / "job.toml"))


def test_fairness_on_always_and_an_unchecked_livelock_table_are_not_silent(tmp_path):
    (tmp_path / "p.toml").write_text('[temporal]\nx = { formula = "always ptu::heading >= 0", fairness = "strong" }\n')
    (tmp_path / "job.toml").write_text(
        f"name = \"j\"\nspec = \"{CAMERA_BOUNDED[0]}\"\nrequest = \"{CAMERA_BOUNDED[1]}\"\nproperties = [\"p.toml\"]\n")
    with pytest.raises(RoarError, match="fairness applies to 'eventually' and 'leads-to'") as e:
        load_job(tmp_path / "job.toml")
    assert e.value.pos.file.endswith("p.toml") and e.value.pos.line == 2
    # a [livelock] table without livelock in check: the table says how to check it, so it is checked
    (tmp_path / "p.toml").write_text('check = ["deadlock"]\n[livelock]\nprogress = ["request R0 finished"]\n')
    job = load_job(tmp_path / "job.toml")
    assert job.props.check == ["deadlock", "livelock"]
    res = run_job(job)
    assert res.verdicts["livelock"].status == "holds" and res.verdicts["deadlock"].status == "holds"


def test_a_strongly_fair_counterexample_says_so(tmp_path):
    j = _job(tmp_path, CAMERA_RETRY, '[temporal]\nends = { formula = "request R0 running leads-to request R0 finished", '
                                     'fairness = "strong" }\n')
    v = run_job(load_job(j)).verdicts["ends"]
    assert v.status == "violated" and "a strongly fair cycle of" in v.message


def test_states_that_read_alike_share_one_view_and_others_do_not():
    """The decoded states are kept once per distinct reading (roar/props.py ``views``): the key
    tells apart what a predicate could tell apart, values by type (True is not 1, a list is not
    a tuple), and is the same for Views built apart from equal parts."""
    from roar_formal.roar.props import View, _view_key

    def view(values, tasks=None):
        return View(dict(values), "running", None, {"arm": {"running"}}, dict(tasks or {}))

    assert _view_key(view({("a", "x"): 1})) == _view_key(view({("a", "x"): 1}))
    assert _view_key(view({("a", "x"): 1})) != _view_key(view({("a", "x"): True}))
    assert _view_key(view({("a", "x"): [1, 2]})) != _view_key(view({("a", "x"): (1, 2)}))
    assert _view_key(view({}, {("arm", "t"): {"go"}})) != _view_key(view({}, {("arm", "t"): {"paused"}}))
    assert _view_key(view({("a", "x"): 1, ("a", "y"): 2})) == _view_key(view({("a", "y"): 2, ("a", "x"): 1}))


def test_leads_to_whose_trigger_is_never_reached_holds_only_vacuously_and_fails_the_job(tmp_path):
    """``P leads-to Q`` with no reachable P state checked nothing: the verdict says so and the job
    fails (the oracle agrees P is unreachable); a reachable trigger is an ordinary holds."""
    o = oracle(CAMERA_BOUNDED)
    assert not any(o.holds(lambda d: d["vars"]["camera::attempts"] == "9"))
    res = run_job(load_job(_job(tmp_path, CAMERA_BOUNDED,
                                '[temporal]\nprop = "camera::attempts == 9 leads-to camera::taken == true"\n')))
    v = res.verdicts["prop"]
    assert v.status == "holds" and "vacuously" in v.message and not res.ok
    assert any("holds only vacuously" in u for u in res.unexpected)
    res = run_job(load_job(_job(tmp_path, CAMERA_BOUNDED, '[temporal]\nprop = "agent ptu in running leads-to '
                                                          'agent ptu in succeeded"\n', name="live")))
    assert not res.verdicts["prop"].details.get("vacuous")
