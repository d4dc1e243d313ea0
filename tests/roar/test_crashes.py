"""Crashes (issue 14, faults the paper names): an agent goes down and comes back; the
constraints it handles fail with an availability entry in their error context, and their
emitters react as ROAR says (docs/semantics.md, "Crashes").

The explorer's verdicts are cross-checked against an independent search written here: a plain
breadth-first enumeration through the engine's ``Program.steps`` / ``Program.successor`` that
decodes every state from its printed facts and checks what a crash must mean: a down agent runs
nothing of its own (no statement, decision or check), and once nothing about it can move any
more, every request it handled is final, failed ones with the availability entry first in their
error context, no activation of it is left and its mask is empty; a crash and a comeback change
no variable. Runs with ``--crash`` are checked on their narrated events and replayed step by
step on the enumerator. Without faults, a spec compiles to the very same model.
"""

from __future__ import annotations

import re
from collections import deque
from pathlib import Path

import pytest

from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.roar.compile import Crashes, compile_spec
from roar_formal.roar.run import CrashAt, crash_setup, describe_ec, parse_crash, run_model
from roar_formal.roar.spec import load_spec
from roar_formal.testing.api import load_spec as api_load
from roar_formal.verify.check import roar_events, run_job
from roar_formal.verify.jobs import load_job

from repo import ROOT
from .test_run import replay_on_enumerator
from .printed import args_of

DATA = Path(__file__).resolve().parent / "data"
SPEC = DATA / "crash_callee.roar"
DONE = "tracker::done == true"       # tracker can do without cam (recipe wide)
LOCKED = "tracker::locked == true"   # it cannot (recipe hold only)


def write_job(tmp_path: Path, request: str, faults: str, name: str = "job") -> Path:
    job = tmp_path / f"{name}.toml"
    job.write_text(f'spec = "{SPEC}"\nrequest = "{request}"\n{faults}', encoding="utf-8")
    return job


# ------------------------------------------------------------------ opt-in: the same model without faults


@pytest.mark.parametrize("spec,req", [(SPEC, DONE), (ROOT / "models" / "conflict.roar", "mission::done == true"),
                                          (ROOT / "models" / "demo_loco",
                                           "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5")])
def test_without_crashes_the_model_is_the_same(spec, req):
    ast = load_spec(spec)
    plain = compile_spec(ast, req)
    assert compile_spec(ast, req, crashes=Crashes()).spec_text == plain.spec_text
    assert compile_spec(ast, req, crashes=None).spec_text == plain.spec_text
    assert not plain.fair_outcomes and plain.crashes is None
    agent = ast.agents[0].name
    crashing = compile_spec(ast, req, crashes=Crashes((agent,)))
    assert crashing.spec_text != plain.spec_text and crashing.crashes.agents == (agent,)


def test_a_job_without_faults_or_with_an_empty_crash_list_has_none(tmp_path):
    assert load_job(write_job(tmp_path, DONE, "", "plain")).crashes is None
    assert load_job(write_job(tmp_path, DONE, "[faults]\ncrash = []\n", "empty")).crashes is None
    job = load_job(write_job(tmp_path, DONE, '[faults]\ncrash = ["cam"]\nmax_crashes = 2\n', "two"))
    assert job.crashes.agents == ("cam",) and job.crashes.bound == 2 and not job.crashes.scheduled


# ------------------------------------------------------------------ the independent search


class Oracle:
    """Every reachable state of the spec with crashes, by a plain BFS over the engine, with the
    facts of each state printed and read back here."""

    def __init__(self, request: str, agents: tuple):
        self.model = compile_spec(load_spec(SPEC), request, crashes=Crashes(agents))
        p = self.program = self.model.program()
        start = p.start_context(next(d for d in p.sig.directives if type(d).__name__ == "ExecDirective").start)
        self.states, self.edges = [start], []   # edges: (src, dst, rule, consumed words, produced words)
        ids = {canonical_key(start): 0}
        self.enabled: list = []
        queue = deque([0])
        while queue:
            s = queue.popleft()
            here = []
            for c in p.steps(self.states[s]):
                nxt, step = p.successor(self.states[s], c)
                k = canonical_key(nxt)
                if k not in ids:
                    ids[k] = len(self.states)
                    self.states.append(nxt)
                    queue.append(ids[k])
                words = lambda fs: [p.show(f).split(" ", 1) for _m, f in fs]
                self.edges.append((s, ids[k], c.rule, words(step.consumed), words(step.produced)))
                here.append((c.rule, [p.show(f) for _m, f in c.consumed]))
            self.enabled.append(here)
        self.facts = [[p.show(f) for _m, f, _n in ctx.facts()] for ctx in self.states]

    # -- decoding: printed facts, split into family and arguments
    def family(self, s: int, fam: str) -> list[list[str]]:
        return [args_of(f) for f in self.facts[s] if f.split(" ", 1)[0] == fam]

    def epoch(self, s: int, agent: str) -> int:
        (e,) = [int(a[1][len("t_ep"):]) for a in self.family(s, "cep") if a[0] == f"a_{agent}"]
        return e

    def requests_of(self, s: int, agent: str) -> set:
        return {a[0] for a in self.family(s, "rq") if a[1] == f"a_{agent}"}

    def activations_of(self, s: int, agent: str) -> set:
        reqs = self.requests_of(s, agent)
        return {a[0] for fam in ("act", "chk") for a in self.family(s, fam) if a[1] in reqs}

    def involves(self, s: int, consumed: list, agent: str) -> bool:
        """Does a step consuming these printed facts touch the agent's requests or activations?"""
        reqs, insts = self.requests_of(s, agent), self.activations_of(s, agent)
        for f in consumed:
            a = args_of(f)
            if a and (a[0] in reqs or a[0] in insts or a[0] == f"a_{agent}"):
                return True
        return False

    def own_rule(self, rule: str, agent: str) -> bool:
        """A compiled rule of the agent: a statement or check of its recipes, or a decision on a
        constraint sent to it."""
        m = re.match(r"st(\d+)_", rule)
        if m:
            site = next(x for c, x in self.model.sites.items() if c.startswith(f"pp{m.group(1)}_"))
            return site.agent == agent
        m = re.match(r"(?:select|reselect|final|ensure_broken|ensure_broken_top)_(c\d+_\w+)$", rule)
        return bool(m) and self.model.csts[m.group(1)][0] == agent

    def quiescent(self, s: int) -> bool:
        return not self.enabled[s]

    def r0_state(self, s: int) -> str:
        r0 = next(a[0] for a in self.family(s, "rq") if a[3] == "itop")
        got = [a[1] for a in self.family(s, "rs") if a[0] == r0]
        return got[0] if got else "none"


def check_crash_semantics(o: Oracle, agent: str) -> dict:
    """What a crash of ``agent`` must mean, state by state and step by step; returns counts
    (so that a test can see the checks were not vacuous)."""
    seen = {"down": 0, "settled": 0, "failed_unavailable": 0, "crashes": 0, "backs": 0, "emitter_killed": 0}
    for s in range(len(o.states)):
        e = o.epoch(s, agent)
        if e % 2 == 0:
            continue
        seen["down"] += 1
        # a crashed agent runs nothing of its own: no statement, check or decision of it is enabled
        assert not [r for r, _c in o.enabled[s] if o.own_rule(r, agent)], o.facts[s]
        # once nothing about the agent can move (its comeback aside), its work is all undone
        if any(o.involves(s, c, agent) for r, c in o.enabled[s] if r not in ("back", "back_armed")):
            continue
        seen["settled"] += 1
        reqs = o.requests_of(s, agent)
        assert not [a for a in o.family(s, "hs") if a[0] in reqs], "a handler of the crashed agent is left"
        states = {a[0]: a[1] for a in o.family(s, "rs")}
        assert all(states.get(r) in ("s_success", "s_failure") for r in reqs), (states, reqs)
        assert not o.activations_of(s, agent) and not [a for a in o.family(s, "ctl")
                                                       if a[0] in o.activations_of(s, agent)]
        assert [a[1] for a in o.family(s, "mask") if a[0] == f"a_{agent}"] == ["vnil"]
        for a in o.family(s, "ecf"):
            if a[0] in reqs and states.get(a[0]) == "s_failure":
                assert a[1].startswith(f"(vcons (vunavail a_{agent}) "), a
    for src, dst, rule, consumed, produced in o.edges:
        reqs = o.requests_of(src, agent)
        failing = [x[1].split(" ", 1)[0] for x in produced if x[0] == "rs" and x[1].endswith(" s_failure")]
        for r in failing:
            if r in reqs:   # in this spec a request of the agent fails only by its crash, with the entry first
                (ec,) = [x[1].split(" ", 1)[1] for x in produced if x[0] == "ecf" and x[1].startswith(r + " ")]
                assert ec.startswith(f"(vcons (vunavail a_{agent}) "), (rule, ec)
                assert rule.startswith("unavailable")
                seen["failed_unavailable"] += 1
        if rule == "constraint_failed" and any(x[0] == "rq" and x[1].split(" ")[1] == f"a_{agent}" for x in consumed):
            # its emitter reacts as ROAR says: the recipe that sent it is killed with the constraint's
            # failure and its error context (5.2), which starts with the availability entry
            (kill,) = [x[1] for x in produced if x[0] == "kill"]
            assert re.search(rf"\(k_cst c\d+_\w+ \(vcons \(vunavail a_{agent}\) ", kill), kill
            seen["emitter_killed"] += 1
        if rule in ("crash", "back", "back_armed"):
            seen["crashes" if rule == "crash" else "backs"] += 1
            # variables persist: neither step changes a cell
            cells = lambda fs: sorted(" ".join(x) for x in fs if x[0] == "contains")
            assert cells(consumed) == cells(produced)
            assert (o.epoch(dst, agent) % 2 == 1) == (rule == "crash")
    return seen


@pytest.fixture(scope="module")
def oracles():
    return {}


def oracle(cache: dict, request: str, agents: tuple) -> Oracle:
    key = (request, agents)
    if key not in cache:
        cache[key] = Oracle(request, agents)
    return cache[key]


def explored(tmp_path: Path, request: str, agents: list, name: str):
    faults = "[faults]\ncrash = [" + ", ".join(f'"{a}"' for a in agents) + "]\n"
    return run_job(load_job(write_job(tmp_path, request, faults, name)))


def acyclic(o: Oracle) -> bool:
    succ: dict = {}
    indeg = [0] * len(o.states)
    for src, dst, *_ in o.edges:
        if dst != src:
            succ.setdefault(src, set()).add(dst)
    for src, ds in succ.items():
        for d in ds:
            indeg[d] += 1
    if any(src == dst for src, dst, *_ in o.edges):
        return False
    queue, n = deque(i for i, d in enumerate(indeg) if d == 0), 0
    while queue:
        s = queue.popleft()
        n += 1
        for d in succ.get(s, ()):
            indeg[d] -= 1
            if indeg[d] == 0:
                queue.append(d)
    return n == len(o.states)


# ------------------------------------------------------------------ exploration, checked against the oracle


def test_callee_crash_with_a_second_recipe_recovers(tmp_path, oracles):
    res = explored(tmp_path, DONE, ["cam"], "done_cam")
    o = oracle(oracles, DONE, ("cam",))
    assert res.graph.n_states == len(o.states) > 39   # 39 without the crash
    assert {p: v.status for p, v in res.verdicts.items()} == {
        "deadlock": "holds", "mission-completion": "holds", "mission-failure": "holds"}
    # the oracle's view: no cycle, and every end state has the mission done
    assert acyclic(o)
    ends = [s for s in range(len(o.states)) if o.quiescent(s)]
    assert ends and all(o.r0_state(s) == "s_success" for s in ends)
    seen = check_crash_semantics(o, "cam")
    assert seen["crashes"] and seen["backs"] and seen["settled"] and seen["failed_unavailable"] \
        and seen["emitter_killed"]
    # the recovery is real: in some end state cam crashed before it moved, and wide did the job
    cells = lambda s: {a[0]: a[1] for a in o.family(s, "contains")}
    assert any(o.epoch(s, "cam") > 0 and cells(s)["v_cam_heading"] == "(vnum 0)" and
               cells(s)["v_tracker_done"] == "(vbool tt)" for s in ends)


def test_callee_crash_without_an_alternative_fails_the_mission(tmp_path, oracles):
    res = explored(tmp_path, LOCKED, ["cam"], "locked_cam")
    o = oracle(oracles, LOCKED, ("cam",))
    v = res.verdicts
    assert res.graph.n_states == len(o.states)
    assert (v["deadlock"].status, v["mission-completion"].status, v["mission-failure"].status) == \
        ("holds", "violated", "violated")
    # the oracle: R0 fails in some end state, always with the chain task -> constraint -> unavailable
    ends = [s for s in range(len(o.states)) if o.quiescent(s)]
    failed = [s for s in ends if o.r0_state(s) == "s_failure"]
    assert failed and all(o.r0_state(s) in ("s_success", "s_failure") for s in ends)
    r0 = lambda s: next(a[0] for a in o.family(s, "rq") if a[3] == "itop")
    for s in failed:
        (ec,) = [a[1] for a in o.family(s, "ecf") if a[0] == r0(s)]
        assert ec.startswith("(vcons (vtsk t_tracker_lock) (vcons (vcst c") and "(vunavail a_cam)" in ec
    check_crash_semantics(o, "cam")
    # the counterexample narrates the crash and the failure with its reason
    assert "unavailable: agent cam crashed" in v["mission-failure"].message
    texts = [e.text for step in roar_events(res, v["mission-failure"]) for e in step]
    assert "cam may crash in this run" in texts and "cam crashed" in texts
    assert any(t.startswith("R1 ") and t.endswith("cam is unavailable (it crashed)") for t in texts)
    assert any("R0 temporary failure -> failure" in t for t in texts)


def test_caller_crash_fails_its_request_and_aborts_what_it_holds(tmp_path, oracles):
    res = explored(tmp_path, LOCKED, ["tracker"], "locked_tracker")
    o = oracle(oracles, LOCKED, ("tracker",))
    assert res.graph.n_states == len(o.states)
    assert res.verdicts["deadlock"].status == "holds" and res.verdicts["mission-failure"].status == "violated"
    seen = check_crash_semantics(o, "tracker")
    assert seen["failed_unavailable"]
    # tracker crashed while its recipe held the make on cam: that make was aborted (cam is
    # never left handling it), and cam's recipe was stopped by the abort, running its end
    crashed_holding = [src for src, _d, rule, _c, _p in o.edges
                       if rule == "crash" and [a for a in o.family(src, "hs") if a[0] in o.requests_of(src, "cam")]]
    assert crashed_holding, "no crash of tracker while cam handled its make: the case is not explored"
    for s in range(len(o.states)):
        if o.quiescent(s) and o.epoch(s, "tracker") > 0 and o.r0_state(s) == "s_failure":
            assert not o.requests_of(s, "cam") and not o.activations_of(s, "cam")
    assert any(r == "cleanup_abort" and o.epoch(src, "tracker") % 2 == 1 for src, _d, r, _c, _p in o.edges)


def test_two_crashes_bound_and_both_agents(tmp_path):
    one = explored(tmp_path, DONE, ["cam", "tracker"], "both")
    assert one.verdicts["deadlock"].status == "holds"
    job = load_job(write_job(tmp_path, DONE, '[faults]\ncrash = ["cam"]\nmax_crashes = 2\n', "twice"))
    twice = run_job(job)
    assert twice.verdicts["deadlock"].status == "holds"
    assert twice.verdicts["mission-completion"].status == "holds"
    m = twice.roar[0]
    assert "epn_3 : ep_next t_ep3 t_ep4." in m.spec_text   # two crashes: epochs 0 to 4


# ------------------------------------------------------------------ runs with --crash


def events(res) -> list[tuple[int, str, str]]:
    return [(e.step, e.agent, e.text) for e in res.events]


def test_run_with_a_crash_narrates_it_and_recovers():
    spec = api_load(SPEC)
    rep = spec.run(DONE, crashes=["cam@21"])
    ev = events(rep.result)
    texts = [t for _i, _a, t in ev]
    i = texts.index("cam crashed")
    assert ev[i][0] == 21 and ev[i][1] == "cam"
    assert texts[i + 1] == "R1: recipe motors stopped: cam crashed (no end block; the requests it holds are aborted)"
    assert texts[i + 2] == "R1: recipe motors ended: stopped: its agent crashed"
    assert texts[i + 3] == "R1 running -> failure  (cam::heading == cam::target): cam is unavailable (it crashed)"
    assert texts[i + 4] == "cam back"
    assert "R0: recipe with_cam ended: constraint failed: cam::heading == cam::target" in texts[i:]
    assert "R0: task track, recipe wide" in texts[i:]
    assert rep.ok and rep.result.final["cam::heading"] == 0   # the stopped recipe never moved it
    assert replay_on_enumerator(rep.result) == len(rep.result.steps)


def test_run_crash_waits_for_a_request_and_comes_back_when_told():
    model = compile_spec(load_spec(SPEC), LOCKED, functional="python", crashes=crash_setup(["cam@2-40"]))
    res = run_model(model, crashes=[parse_crash("cam@2-40")])
    ev = events(res)
    texts = [t for _i, _a, t in ev]
    # cam handles nothing before tracker's make: it crashes as the make reaches it
    sent = next(i for i, a, t in ev if t.startswith("make R1 to cam"))
    crashed = next(i for i, a, t in ev if t == "cam crashed")
    back = next(i for i, a, t in ev if t == "cam back")
    assert crashed == sent + 1 and back == len(res.steps) < 40   # (the run is over before step 40: back at its end)
    assert res.outcome == "failure"
    assert res.error_context == ["task failed: tracker::lock", "constraint failed: cam::heading == cam::target",
                                 "unavailable: agent cam crashed"]
    assert replay_on_enumerator(res) == len(res.steps)
    assert any(re.fullmatch(r"R1 (sent|pending) -> failure  \(cam::heading == cam::target\): cam is unavailable "
                            r"\(it crashed\)", t) for t in texts)


def test_run_crash_of_the_caller_aborts_its_make():
    rep = api_load(SPEC).run(LOCKED, crashes=["tracker@21"])
    texts = [t for _i, _a, t in events(rep.result)]
    i = texts.index("tracker crashed")
    assert "abort R1 (cam: cam::heading == cam::target)" in texts[i:]
    assert rep.result.outcome == "failure" and rep.result.error_context == ["unavailable: agent tracker crashed"]
    assert replay_on_enumerator(rep.result) == len(rep.result.steps)


def test_cli_run_crash(roar_cli):
    code, out, err = roar_cli("run", SPEC, "-r", DONE, "--crash", "cam@21")
    assert code == 0, err
    assert re.search(r"^ +21 cam +cam crashed$", out, re.M) and re.search(r"^ +\d+ cam +cam back$", out, re.M)
    code, out, err = roar_cli("run", SPEC, "-r", LOCKED, "--crash", "cam@21")
    assert code == 1 and "unavailable: agent cam crashed" in out
    for bad, fragment in (("cam", "expected AGENT@STEP"), ("cam@0", "expected AGENT@STEP"),
                          ("cam@5-3", "expected AGENT@STEP"), ("foo@3", "unknown agent 'foo'"), ("cma@3", "did you mean 'cam'?"),
                          ("cam@500", "never crashed")):
        code, out, err = roar_cli("run", SPEC, "-r", DONE, "--crash", bad)
        assert code == 2 and err.startswith("error: ") and fragment in err and "Traceback" not in err, (bad, err)


def test_crash_at_parses():
    assert parse_crash("ptu@4") == CrashAt("ptu", 4) and str(parse_crash(" ptu@4-9 ")) == "ptu@4-9"
    assert crash_setup(["a@1", "b@2", "a@5"]) == Crashes(("a", "b"), 3, True)
    with pytest.raises(RoarError, match="still down"):
        run_model(compile_spec(load_spec(SPEC), DONE, functional="python",
                               crashes=crash_setup(["cam@3-9", "cam@5"])), crashes=["cam@3-9", "cam@5"])


# ------------------------------------------------------------------ bad input: located, never a traceback


@pytest.mark.parametrize("faults,fragment,line,col", [
    ('[faults]\ncrash = ["cam", "nobody"]\n', "unknown agent 'nobody'", 4, 18),
    ('[faults]\ncrash = ["cma"]\n', "unknown agent 'cma' (did you mean 'cam'?)", 4, 11),
    ('[faults]\ncrash = ["cam"]\nmax_crashes = 0\n', "max_crashes is the number of crashes", 5, 15),
    ('[faults]\ncrash = ["cam"]\nmax_crashes = "two"\n', 'not "two"', 5, 15),
    ('[faults]\ncrash = ["cam"]\nmax_crashes = true\n', "not true", 5, 15),
    ('[faults]\ncrash = ["cam"]\nmax_crashes = 1.5\n', "not 1.5", 5, 15),
    ('[faults]\ncrash = "cam"\n', "crash is a list of agent names", 4, 9),
    ('[faults]\ncrash = ["cam", "cam"]\n', "names agent 'cam' twice", 4, 18),
    ('[faults]\ncrashes = ["cam"]\n', "unknown key 'crashes' in [faults]", 4, 1),
    ('[faults]\nmax_crashes = 2\n', "max_crashes without crash", 4, 15),
])
def test_bad_faults_are_located(tmp_path, roar_cli, faults, fragment, line, col):
    job = write_job(tmp_path, DONE, faults)
    code, out, err = roar_cli("check", job)
    assert code == 2, (out, err)
    assert err.startswith("error: ") and "Traceback" not in err, err
    assert f"{job}:{line}:{col}:" in err and fragment in err, err


def test_faults_on_a_clf_model_job_are_refused(tmp_path, roar_cli):
    job = tmp_path / "clf.toml"
    job.write_text(f'model = "{ROOT / "models" / "philosophers" / "dl.clf"}"\n[faults]\ncrash = ["p1"]\n')
    code, out, err = roar_cli("check", job)
    assert code == 2 and f"{job}:2:1:" in err and "'faults' belongs to a job on a spec" in err, err


def test_the_availability_entry_prints():
    from roar_formal.clf.terms import const
    m = compile_spec(load_spec(SPEC), DONE, crashes=Crashes(("cam",)))
    ec = const("vcons", const("vunavail", const("a_cam")), const("vnil"))
    assert describe_ec(ec, m) == ["unavailable: agent cam crashed"]


# ------------------------------------------------------------------ a paused end block whose request is released


def _from_state(model, facts: str):
    """The compiled model started from a state written by hand instead of its own start."""
    from roar_formal.roar.framework import with_framework
    text = "\n".join(line for line in model.spec_text.splitlines() if not line.startswith("#exec"))
    return with_framework(text + f"\n#exec * {facts}.\n", "<hand-made state>")


def test_a_released_request_lifts_the_pause_of_its_ending_activation():
    """An activation killed (its constraint failed: the crash) runs its end block; its emitter
    pauses it, then aborts its request (the emitter's own recipe failed): the abort's kill is a
    repeat (kill_again), and no continue can come any more: the abort's kill lifts the emitter's
    pause, with crashes (tests found the race on models/conflict.roar, ptu crashing) and without
    (a trial's spec reached it with a local failure alone: a false deadlock before)."""
    for crashes in (Crashes(("cam",)), None):
        m = compile_spec(load_spec(SPEC), DONE, crashes=crashes)
        end = next(s.const for s in m.sites.values() if s.recipe == "with_cam" and s.text == "set looked true")
        c_track = next(c for c, (a, t) in m.csts.items() if a == "tracker" and t == "tracker::done == true")
        c_cam = next(c for c, (a, _t) in m.csts.items() if a == "cam")
        epochs = "cep a_cam t_ep2 * cleft z * " if crashes else ""
        facts = (f"Exists r1. Exists i. {epochs}mask a_cam vnil * contains v_cam_target (vnum 30) * "
                 f"contains v_cam_heading (vnum 0) * contains v_tracker_done (vbool ff) * "
                 f"contains v_tracker_locked (vbool ff) * contains v_tracker_looked (vbool ff) * "
                 f"mask a_tracker (vcons (vpair (vtsk t_tracker_track) (vreq r1)) vnil) * "
                 f"rq r1 a_tracker {c_track} irel k_make * rs r1 s_paused * ppz r1 tt * "
                 f"hs r1 (h_abort i) vnil vnil (vcons (vtsk t_tracker_track) vnil) vnone * "
                 f"act i r1 t_tracker_track r_tracker_track_with_cam z * "
                 f"ending i (k_cst {c_cam} (vcons (vunavail a_cam) vnil)) * "
                 f"ctl i m_run (ccons {end} (ccons s_done cnil)) vnil * rstat i (pz z tt) * kill i k_abort")
        prog = _from_state(m, facts)
        ctx = prog.start_context(next(d for d in prog.sig.directives if hasattr(d, "start")).start)
        rules: list = []
        prog.run(ctx, on_step=lambda step, _c: rules.append(step.rule))
        left = sorted(prog.show(f) for _m, f, _n in ctx.facts())
        assert rules[0] == "kill_again" and "aborted" in rules, rules
        # the end block ran (it sets looked), the tasks are released, nothing of the request is left
        assert "contains v_tracker_looked (vbool tt)" in left and "mask a_tracker vnil" in left, left
        assert not [f for f in left if f.startswith(("ctl ", "rq ", "hs "))], left


def test_the_api_explores_with_crashes():
    spec = api_load(SPEC)
    ex = spec.explore(LOCKED, ["deadlock", "mission-failure"], crash=["cam"])
    assert ex.status("deadlock") == "holds" and ex.status("mission-failure") == "violated"
    assert spec.explore(LOCKED, ["mission-failure"]).status("mission-failure") == "holds"
    with pytest.raises(RoarError, match="unknown agent 'nobody'"):
        spec.explore(LOCKED, ["deadlock"], crash=["nobody"])
