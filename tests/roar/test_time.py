"""Time (issue 14; the paper's 4.4, 5.2 and 8.3): the periods of ``wait``, ``assert`` and
``ensure`` in a discrete clock, switchable per job (docs/semantics.md, "Time").

Untimed (the default), a spec compiles to the very model it compiled to before time existed.
Timed, a clock counts ticks (the gcd of the spec's periods); a wait polls at its period and,
with a job's ``wait_timeout``, fails with a timeout entry in its error context; an assert with a
period is checked at its period; a held ensure is re-checked at its period, not at any moment.

Every verdict of the explorer is cross-checked against an independent search written here: a
plain breadth-first enumeration through the engine's ``Program.steps`` / ``Program.successor``
that decodes every state from its printed facts and checks, in Python, what the clock must
mean (the clock advances only when nothing is due; a sleeper wakes exactly at its deadline, one
period after it went to sleep; a held ensure is looked at only at its deadline; a timeout comes
after at least the timeout's time of polling) and the verdicts themselves (deadlock, failure).
"""

from __future__ import annotations

import json
import re
from collections import deque
from pathlib import Path

import pytest

from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.roar.compile import Crashes, TIME_GROUP, Timing, compile_spec
from roar_formal.roar.run import describe_ec
from roar_formal.roar.spec import load_spec
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.verify.replay import replay_trace

from .printed import args_of

from repo import ROOT

DATA = Path(__file__).resolve().parent / "data"
TIMEOUT_SPEC = DATA / "wait_timeout.roar"    # a wait nothing ever satisfies
SAME_SPEC = DATA / "timed_same.roar"         # a wait that is satisfied, a held ensure
SLAMMED = ROOT / "models" / "faulty" / "ensure_slammed.roar"
OPEN, DONE = "door::open == true", "user::done == true"


def write_job(tmp_path: Path, spec: Path, request: str, extra: str = "", name: str = "job") -> Path:
    job = tmp_path / f"{name}.toml"
    job.write_text(f'spec = "{spec}"\nrequest = "{request}"\n{extra}', encoding="utf-8")
    return job


# ------------------------------------------------------------------ untimed: the same model, to the byte


@pytest.mark.parametrize("spec,req", [
    (ROOT / "models" / "conflict.roar", "mission::done == true"),
    (ROOT / "models" / "spa_loop.roar", "exec::arrived == true"),
    (ROOT / "models" / "demo_loco", "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5"),
    (SLAMMED, DONE),
    (TIMEOUT_SPEC, OPEN),
])
def test_untimed_compiles_to_the_model_without_time(spec, req):
    ast = load_spec(spec)
    plain = compile_spec(ast, req)
    for off in (None, "untimed", Timing(), Timing("untimed")):
        other = compile_spec(ast, req, time=off)
        assert other.text == plain.text and other.timing is None
    for word in ("tmrs", "clock", "m_sleep", "spoll", "h_heldt", "held_arm"):
        assert not re.search(rf"\b{word}\b", plain.spec_text), word
    assert "tick" not in plain.fair_outcomes and plain.tick_ms is None
    timed = compile_spec(ast, req, time="timed")
    if timed.tick_ms is None:   # no period in the spec: no clock, the same model
        assert timed.spec_text == plain.spec_text
    else:
        assert timed.spec_text != plain.spec_text and timed.fair_outcomes["tick"] == TIME_GROUP


def test_the_clock_of_a_spec():
    m = compile_spec(load_spec(SAME_SPEC), OPEN, time="timed")
    assert (m.tick_ms, m.cycle) == (50, 3)   # periods 50 and 100 ms: a tick of 50, two at most
    assert "eperiod_c1_lamp : eperiod c1_lamp 2." in m.spec_text
    m = compile_spec(load_spec(ROOT / "models" / "conflict.roar"), "mission::done == true", time="timed")
    assert (m.tick_ms, m.cycle) == (100, 2)
    m = compile_spec(load_spec(ROOT / "models" / "demo_loco"),
                     "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5", time="timed")
    assert (m.tick_ms, m.cycle) == (10, 2)
    m = compile_spec(load_spec(ROOT / "models" / "faulty" / "retry_forever.roar"), "hand::holding == true",
                     time="timed")   # no period written: no clock
    assert m.tick_ms is None and m.timing.mode == "timed"
    assert m.spec_text == compile_spec(load_spec(ROOT / "models" / "faulty" / "retry_forever.roar"),
                                       "hand::holding == true").spec_text


# ------------------------------------------------------------------ the independent search


def _nums(lst: str) -> list[int]:
    return [int(x) for x in re.findall(r"\(vnum (\d+)\)", lst)]


class Oracle:
    """Every reachable state of a compiled spec, by a plain BFS over the engine, with the facts
    of each state printed and read back here."""

    def __init__(self, spec: Path, request: str, time=None):
        self.model = compile_spec(load_spec(spec), request, time=time)
        p = self.program = self.model.program()
        start = p.start_context(next(d for d in p.sig.directives if type(d).__name__ == "ExecDirective").start)
        self.states, self.edges = [start], []   # edges: (src, dst, rule, consumed, produced) printed
        ids = {canonical_key(start): 0}
        queue = deque([0])
        self.succ: list[list[int]] = []
        while queue:
            s = queue.popleft()
            while len(self.succ) <= s:
                self.succ.append([])
            for c in p.steps(self.states[s]):
                nxt, step = p.successor(self.states[s], c)
                k = canonical_key(nxt)
                if k not in ids:
                    ids[k] = len(self.states)
                    self.states.append(nxt)
                    queue.append(ids[k])
                self.succ[s].append(ids[k])
                self.edges.append((s, ids[k], c.rule, [p.show(f) for _m, f in step.consumed],
                                   [p.show(f) for _m, f in step.produced]))
        while len(self.succ) < len(self.states):
            self.succ.append([])
        self.facts = [[p.show(f) for _m, f, _n in ctx.facts()] for ctx in self.states]

    def family(self, s: int, fam: str) -> list[list[str]]:
        return [args_of(f) for f in self.facts[s] if f.split(" ", 1)[0] == fam]

    def clock(self, s: int) -> tuple[int, list[int]]:
        (c,), (t,) = self.family(s, "clock"), self.family(s, "tmrs")
        return int(c[0]), _nums(t[0])

    def r0(self, s: int) -> str:
        r0 = next(a[0] for a in self.family(s, "rq") if a[3] == "itop")
        return next(a[1] for a in self.family(s, "rs") if a[0] == r0)

    def final(self, s: int) -> bool:
        """Every request final, no activation left (the explorer's accepted end)."""
        return not self.family(s, "ctl") and all(a[1] in ("s_success", "s_failure") for a in self.family(s, "rs"))

    def deadlocks(self) -> list[int]:
        return [s for s in range(len(self.states)) if not self.succ[s] and not self.final(s)]

    def failure_contexts(self) -> list[list[str]]:
        """The error contexts of R0 in the states where it failed, described."""
        out = []
        for s in range(len(self.states)):
            if self.r0(s) == "s_failure":
                r0 = next(a[0] for a in self.family(s, "rq") if a[3] == "itop")
                (ec,) = [ctx for ctx in self.states[s].facts() if self.program.show(ctx[1]).startswith(f"ecf {r0}")]
                out.append(describe_ec(ec[1].args[1], self.model))
        return out

    def reaches(self, good) -> list[bool]:
        """For each state: can it reach a state where ``good`` holds?"""
        ok = [good(s) for s in range(len(self.states))]
        pred: list[list[int]] = [[] for _ in self.states]
        for s, d, *_ in self.edges:
            pred[d].append(s)
        queue = deque(s for s in range(len(self.states)) if ok[s])
        while queue:
            d = queue.popleft()
            for s in pred[d]:
                if not ok[s]:
                    ok[s] = True
                    queue.append(s)
        return ok


def check_clock(o: Oracle) -> dict:
    """What the clock must mean, edge by edge; returns counts (so a test sees it was not vacuous)."""
    m = o.model
    n = {"tick": 0, "wake": 0, "sleep": 0, "recheck": 0, "arm": 0}
    for src, dst, rule, consumed, produced in o.edges:
        t, due = o.clock(src)
        t2, due2 = o.clock(dst)
        assert due == sorted(due) and due2 == sorted(due2)
        assert all(0 <= x < m.cycle for x in due + due2) and 0 <= t < m.cycle
        if not due2:
            assert t2 == 0, "nothing waits on time: the clock is back to 0"
        if rule == "tick":   # time passes only while something waits on it, and nothing is due now
            n["tick"] += 1
            assert due and t not in due and t2 == (t + 1) % m.cycle and due2 == due
            continue
        assert t not in due or rule != "tick"
        sleeping = [f for f in consumed if f.startswith("ctl ") and " (m_sleep " in f]
        if rule == "wake":   # a sleeper wakes at its deadline, exactly
            n["wake"] += 1
            (f,) = sleeping
            assert int(re.search(r"\(m_sleep (\d+)\)", f).group(1)) == t
        else:
            assert not sleeping or rule in ("kill_sleep",), rule
        slept = [f for f in produced if f.startswith("ctl ") and " (m_sleep " in f]
        for f in slept:   # ... one period after it went to sleep
            n["sleep"] += 1
            site = re.search(r"\(spoll (pp\d+_\w+) \d+\)", f).group(1)
            period = m.sites[site].period_ms
            assert int(re.search(r"\(m_sleep (\d+)\)", f).group(1)) == (t + int(period) // m.tick_ms) % m.cycle
        held = [f for f in consumed if f.startswith("hs ") and "(h_heldt " in f]
        if rule.startswith(("ensure_check_", "ensure_broken_")):   # a held ensure is looked at its deadline
            n["recheck"] += 1
            (f,) = held
            assert int(re.search(r"\(h_heldt (\d+)\)", f).group(1)) == t
        if rule == "held_arm":
            n["arm"] += 1
            (f,) = [f for f in produced if f.startswith("hs ")]
            cst = next(x for x in m.csts if f" {x} " in " ".join(produced))
            period = int(re.search(rf"eperiod_{cst} : eperiod {cst} (\d+)\.", m.spec_text).group(1))
            assert int(re.search(r"\(h_heldt (\d+)\)", f).group(1)) == (t + period) % m.cycle
    return n


def ticks_before(o: Oracle, start_rule: str, end_rule: str) -> set[int]:
    """The numbers of ticks, on every path, between a step ``start_rule`` and a step ``end_rule``
    (the state graph must have no cycle)."""
    order, seen = [], set()

    def visit(s):   # topological order (iterative DFS)
        stack = [(s, iter(o.succ[s]))]
        seen.add(s)
        while stack:
            v, it = stack[-1]
            for w in it:
                assert w not in {x for x, _ in stack}, "the graph has a cycle"
                if w not in seen:
                    seen.add(w)
                    stack.append((w, iter(o.succ[w])))
                    break
            else:
                order.append(v)
                stack.pop()
    visit(0)
    counts: dict[int, set] = {s: set() for s in range(len(o.states))}
    got: set[int] = set()
    out_edges: dict[int, list] = {}
    for e in o.edges:
        out_edges.setdefault(e[0], []).append(e)
    for s in reversed(order):
        for src, dst, rule, *_ in out_edges.get(s, ()):
            here = {k + (rule == "tick") for k in counts[s]}
            if rule == end_rule:
                got |= counts[s]
            if rule == start_rule:
                here |= {0}
            counts[dst] |= here
    return got


@pytest.fixture(scope="module")
def oracles():
    return {}


def oracle(cache: dict, spec: Path, request: str, time=None) -> Oracle:
    key = (spec, request, repr(time))
    if key not in cache:
        cache[key] = Oracle(spec, request, time)
    return cache[key]


def explored(tmp_path: Path, spec: Path, request: str, extra: str, name: str):
    return run_job(load_job(write_job(tmp_path, spec, request, extra, name)))


def test_a_wait_that_never_holds_deadlocks_untimed(tmp_path, oracles):
    o = oracle(oracles, TIMEOUT_SPEC, OPEN)
    res = explored(tmp_path, TIMEOUT_SPEC, OPEN, "", "untimed")
    assert res.graph.n_states == len(o.states)
    (dead,) = o.deadlocks()   # blocked in the wait for ever
    assert any(a[1].startswith("(m_block") for a in o.family(dead, "ctl"))
    assert res.verdicts["deadlock"].status == "violated" and res.verdicts["mission-failure"].status == "holds"
    assert not o.failure_contexts()


def test_a_wait_times_out_timed(tmp_path, oracles):
    timing = Timing("timed", 250)
    o = oracle(oracles, TIMEOUT_SPEC, OPEN, timing)
    res = explored(tmp_path, TIMEOUT_SPEC, OPEN, '[time]\nmode = "timed"\nwait_timeout = 250\n', "timeout")
    assert res.graph.n_states == len(o.states)
    counts = check_clock(o)
    assert counts["tick"] >= 3 and counts["wake"] >= 3 and counts["sleep"] >= 3
    # no deadlock: the request fails, with the timeout in its error context, located at the wait
    assert not o.deadlocks() and res.verdicts["deadlock"].status == "holds"
    contexts = o.failure_contexts()
    assert contexts and all(ec[0] == "task failed: door::open_door" for ec in contexts)
    timeout = "local failure: door.open_door.on_sensor at 21:13: timeout: wait(sensor == true, 100) did not " \
              "hold within 250 ms (3 polls every 100 ms)"
    assert all(timeout in ec for ec in contexts), contexts
    assert res.verdicts["mission-failure"].status == "violated"
    assert "timeout: wait(sensor == true, 100)" in res.verdicts["mission-failure"].message
    # the timeout comes after at least 250 ms of polling: 3 ticks of 100 ms on every path
    wait = next(c for c, s in o.model.sites.items() if s.kind == "wait")
    assert ticks_before(o, f"st{wait[2:]}_false", f"st{wait[2:]}_timeout") == {3}


def test_a_wait_without_timeout_polls_for_ever_timed(tmp_path, oracles):
    o = oracle(oracles, TIMEOUT_SPEC, OPEN, "timed")
    res = explored(tmp_path, TIMEOUT_SPEC, OPEN, 'time = "timed"\n', "polls")
    assert res.graph.n_states == len(o.states)
    check_clock(o)
    # no deadlock, no failure, and no end: the wait polls for ever (a cycle, under fairness)
    assert not o.deadlocks() and not any(o.final(s) for s in range(len(o.states)))
    assert not o.failure_contexts()
    assert res.verdicts["deadlock"].status == "holds" and res.verdicts["mission-failure"].status == "holds"
    v = res.verdicts["mission-completion"]
    assert v.status == "violated" and v.counterexample.kind == "lasso"
    assert TIME_GROUP in v.message   # the agents moving on the cycle: the clock (and the door's poll)


@pytest.mark.parametrize("time", [None, "timed"])
def test_the_same_verdict_timed_and_untimed(tmp_path, oracles, time):
    o = oracle(oracles, SAME_SPEC, OPEN, time)
    res = explored(tmp_path, SAME_SPEC, OPEN, 'time = "timed"\n' if time else "", f"same_{time}")
    assert res.graph.n_states == len(o.states)
    if time:
        counts = check_clock(o)
        assert counts["arm"] and counts["recheck"] and counts["wake"] and counts["tick"]
    assert not o.deadlocks() and res.verdicts["deadlock"].status == "holds"
    assert not o.failure_contexts() and res.verdicts["mission-failure"].status == "holds"
    # every state can still reach the request's success, and every end is that success
    assert all(o.reaches(lambda s: o.r0(s) == "s_success"))
    assert all(o.r0(s) == "s_success" for s in range(len(o.states)) if not o.succ[s])
    assert res.verdicts["mission-completion"].status == "holds"


def test_state_counts_timed_and_untimed(tmp_path):
    """The clock multiplies the states (docs/semantics.md, Time, where these figures are quoted)."""
    counts = {}
    for spec, req, name in ((SAME_SPEC, OPEN, "same"), (TIMEOUT_SPEC, OPEN, "timeout"), (SLAMMED, DONE, "slammed")):
        for time in ("untimed", "timed"):
            counts[(name, time)] = explored(tmp_path, spec, req, f'time = "{time}"\n', f"{name}_{time}").graph.n_states
    assert counts == {("same", "untimed"): 189, ("same", "timed"): 336,
                      ("timeout", "untimed"): 12, ("timeout", "timed"): 14,
                      ("slammed", "untimed"): 2341, ("slammed", "timed"): 2854}


def test_a_held_ensure_is_re_checked_at_its_period(tmp_path, oracles):
    """The seeded fault of ensure_slammed.roar is found timed too: the held ensure, looked at only
    at its period, still finds the door shut, and the mission fails with the breach."""
    o = oracle(oracles, SLAMMED, DONE, "timed")
    res = explored(tmp_path, SLAMMED, DONE, 'time = "timed"\n', "slammed")
    assert res.graph.n_states == len(o.states)
    counts = check_clock(o)
    assert counts["recheck"] and counts["arm"]
    broke = [e for e in o.edges if e[2].startswith("ensure_broken_")]
    assert broke
    contexts = o.failure_contexts()
    assert any("ensured constraint stopped holding: door::open == true" in ec for ec in contexts)
    assert res.verdicts["mission-failure"].status == "violated"
    assert "ensured constraint stopped holding" in res.verdicts["mission-failure"].message
    assert not o.deadlocks() and res.verdicts["deadlock"].status == "holds"


def test_an_assert_with_a_period_is_checked_at_its_period(tmp_path):
    spec = tmp_path / "lamp.roar"
    spec.write_text("""
lamp = ability {
  context = { { } { bool on = false; bool hot = false; } { } }
  tasks = {
    light = task {
      post = { {on == true} }
      recipes = {
        careful = recipe {
          body = { set hot true; assert(hot == false, 30); set on true; }
        }
      }
    }
    cool = task {
      post = { {hot == false} }
      recipes = { fan = recipe { body = { set hot false; } } }
    }
  }
}
""", encoding="utf-8")
    o = Oracle(spec, "lamp::on == true", "timed")
    counts = check_clock(o)
    assert counts["sleep"] and counts["wake"] and o.model.tick_ms == 30
    # the assert sleeps when reached, and is evaluated at the wake: false (nothing cools the lamp),
    # a local failure, and the recipe is tried again (the same sleep, then the same failure)
    rules = {e[2] for e in o.edges}
    assert {r for r in rules if "_assert" in r} == {"st2_assert_sleep", "st2_assert_false"}
    for src, _dst, rule, consumed, _produced in o.edges:
        if rule == "st2_assert_false":   # evaluated only from the polled form, after a wake
            assert any("(spoll pp2_assert 0)" in f for f in consumed)
    assert not o.deadlocks()


def test_a_timed_assert_makes_its_calls_once_after_its_sleep(tmp_path):
    """An assert with a period that calls the functional layer sleeps first, then makes its call
    and is evaluated at the wake, once: the call is not made before the sleep as well (its answer
    was thrown away, and a fault on it had no effect)."""
    spec = tmp_path / "cam.roar"
    spec.write_text("""
cam = ability {
  context = { { } { bool seen = false; } { } }
  export = { { } { bool detect(); } { } }
  tasks = {
    look = task {
      post = { {seen == true} }
      recipes = { r = recipe { body = { assert(detect(), 50); set seen true; } } }
    }
  }
}
""", encoding="utf-8")
    o = Oracle(spec, "cam::seen == true", "timed")
    # in every explored state where the call is made, the activation has slept already: the code
    # it runs is the call, then the polled assert (never the sleep still to come)
    for _src, _dst, rule, consumed, _produced in o.edges:
        if rule.endswith("_call"):
            code = next(f for f in consumed if f.startswith("ctl "))
            assert "(spoll pp" in code and "_assert_sleep" not in code, code
    from roar_formal.testing.api import load
    r = load(spec).run("cam::seen == true", time="timed", faults=["detect:1"])
    texts = [e.text for e in r.events]
    calls = [t for t in texts if t.startswith("detect()")]
    assert calls[:2] == ["detect()", "detect() = false"]          # the first call is the one evaluated
    assert any("local failure" in t and "assert(detect(), 50)" in t for t in texts)
    assert r.outcome == "success" and len([t for t in calls if t == "detect()"]) == 2   # one per try


# ------------------------------------------------------------------ replay: the header records the options


def test_a_timed_counterexample_replays(tmp_path):
    res = explored(tmp_path, TIMEOUT_SPEC, OPEN, '[time]\nmode = "timed"\nwait_timeout = 250\n', "timeout")
    path = save_counterexample(res, "mission-failure", tmp_path)
    header = json.loads(path.read_text(encoding="utf-8").splitlines()[0])
    assert header["time"] == "timed" and header["wait_timeout"] == 250
    back = replay_trace(path, TIMEOUT_SPEC)
    assert back.confirmed is True and back.compiled.timing == Timing("timed", 250)
    assert any("timeout" in e["text"] for s in back.steps for e in s["events"])
    # a lasso of the timed model (the wait polling for ever) replays, its cycle closing
    res = explored(tmp_path, TIMEOUT_SPEC, OPEN, 'time = "timed"\n', "polls")
    back = replay_trace(save_counterexample(res, "mission-completion", tmp_path), TIMEOUT_SPEC)
    assert back.confirmed is True and back.result.cycle_closes


def test_a_crash_counterexample_replays(tmp_path):
    spec = DATA / "crash_callee.roar"
    res = explored(tmp_path, spec, "tracker::locked == true", '[faults]\ncrash = ["cam"]\n', "crash")
    path = save_counterexample(res, "mission-failure", tmp_path)
    header = json.loads(path.read_text(encoding="utf-8").splitlines()[0])
    assert header["crash"] == ["cam"] and header["max_crashes"] == 1 and "time" not in header
    back = replay_trace(path, spec)
    assert back.confirmed is True and back.compiled.crashes == Crashes(("cam",), 1)
    assert any(e["text"] == "cam crashed" for s in back.steps for e in s["events"])


def test_a_bad_header_is_refused(tmp_path):
    res = explored(tmp_path, TIMEOUT_SPEC, OPEN, '[time]\nmode = "timed"\nwait_timeout = 250\n', "timeout")
    path = save_counterexample(res, "mission-failure", tmp_path)
    lines = path.read_text(encoding="utf-8").splitlines()
    header = json.loads(lines[0])
    header["time"] = "sometimes"
    path.write_text("\n".join([json.dumps(header)] + lines[1:]) + "\n", encoding="utf-8")
    with pytest.raises(RoarError, match="time mode it cannot mean"):
        replay_trace(path, TIMEOUT_SPEC, force=True)


# ------------------------------------------------------------------ the job key: located errors


@pytest.mark.parametrize("extra,fragment,line,col", [
    ('time = "sometimes"\n', 'time is "untimed" or "timed" (or a [time] table), not "sometimes"', 3, 8),
    ("time = 5\n", "time is \"untimed\" or \"timed\" (or a [time] table), not 5", 3, 8),
    ('[time]\nmode = "fast"\n', '[time] mode is "untimed" or "timed"', 4, 8),
    ('[time]\nwait_timeout = 0\n', "wait_timeout is a whole number of milliseconds, at least 1", 4, 16),
    ('[time]\nwait_timeout = "1s"\n', 'not "1s"', 4, 16),
    ('[time]\nwait_timeout = 2.5\n', "not 2.5", 4, 16),
    ('[time]\nmode = "untimed"\nwait_timeout = 100\n', "wait_timeout needs mode = \"timed\"", 5, 16),
    ('[time]\nperiod = 100\n', "unknown key 'period' in [time]", 4, 1),
])
def test_bad_time_values_are_located(tmp_path, roar_cli, extra, fragment, line, col):
    job = write_job(tmp_path, TIMEOUT_SPEC, OPEN, extra)
    code, out, err = roar_cli("check", job)
    assert code == 2, (out, err)
    assert err.startswith("error: ") and "Traceback" not in err, err
    assert f"{job}:{line}:{col}:" in err and fragment in err, err


def test_time_on_a_clf_model_job_is_refused(tmp_path, roar_cli):
    job = tmp_path / "clf.toml"
    job.write_text(f'model = "{ROOT / "models" / "philosophers" / "dl.clf"}"\ntime = "timed"\n')
    code, out, err = roar_cli("check", job)
    assert code == 2 and f"{job}:2:1:" in err and "'time' belongs to a job on a spec" in err, err


def test_a_period_that_is_not_a_literal_is_located_timed(tmp_path, roar_cli):
    spec = tmp_path / "var.roar"
    spec.write_text("""
door = ability {
  context = { { } { bool open = false; int every = 100; } { } }
  tasks = {
    open_it = task {
      post = { {open == true} }
      recipes = { r = recipe { body = { wait(open == true, every); } } }
    }
  }
}
""", encoding="utf-8")
    assert compile_spec(load_spec(spec), OPEN).timing is None   # untimed: the period is not read
    job = write_job(tmp_path, spec, OPEN, 'time = "timed"\n')
    code, out, err = roar_cli("check", job)
    assert code == 2 and "Traceback" not in err, (out, err)
    assert f"{spec}:7:60:" in err and "a period must be a literal number of milliseconds, not 'every'" in err, err


def test_a_job_without_time_is_untimed(tmp_path):
    assert load_job(write_job(tmp_path, TIMEOUT_SPEC, OPEN)).time is None
    assert load_job(write_job(tmp_path, TIMEOUT_SPEC, OPEN, 'time = "untimed"\n', "off")).time is None
    job = load_job(write_job(tmp_path, TIMEOUT_SPEC, OPEN, '[time]\nwait_timeout = 40\n', "on"))
    assert (job.time.mode, job.time.wait_timeout) == ("timed", 40)


# ------------------------------------------------------------------ runs: time is slow


def test_a_timed_run_ticks_only_when_nothing_else_can_happen():
    from roar_formal.roar.run import run_model
    from .test_run import replay_on_enumerator
    m = compile_spec(load_spec(TIMEOUT_SPEC), OPEN, time=Timing("timed", 250))
    prog = m.program()
    for seed in (0, 3):
        res = run_model(m, seed=seed)
        assert res.outcome == "failure" and res.quiescent
        assert any("timeout: wait(sensor == true, 100)" in x for x in res.error_context), res.error_context
        ticks = [i for i, (rule, _c, _p) in enumerate(res.steps, 1) if rule == "tick"]
        assert len(ticks) == 3   # 300 ms of polling: the poll at or after 250 ms times out
        assert replay_on_enumerator(res) == len(res.steps)   # every step, ticks included, is the model's
    # a tick is taken only in a state where nothing but the clock could move
    res = run_model(m, seed=1)
    start = next(d for d in prog.sig.directives if hasattr(d, "start"))
    ctx = prog.start_context(start.start)
    for rule, _c, _p in res.steps:
        enabled = {c.rule for c in prog.steps(ctx)}
        if rule == "tick":
            assert enabled == {"tick"}, enabled
        choice = next(c for c in prog.steps(ctx) if c.rule == rule)
        ctx, _st = prog.successor(ctx, choice)
    # untimed, the same spec blocks in its wait (no clock, no timeout)
    res = run_model(compile_spec(load_spec(TIMEOUT_SPEC), OPEN), seed=0)
    assert res.outcome != "failure" and not any(rule == "tick" for rule, _c, _p in res.steps)


def test_a_clock_too_fine_is_refused_at_the_period(tmp_path):
    spec = tmp_path / "fine.roar"
    spec.write_text("""
door = ability {
  context = { { } { bool open = false; } { } }
  tasks = {
    open_it = task {
      post = { {open == true} }
      recipes = { r = recipe { body = { wait(open == true, 7); wait(open == true, 10000); } } }
    }
  }
}
""", encoding="utf-8")
    with pytest.raises(RoarError, match="would count 10,000 ticks of 1 ms") as e:
        compile_spec(load_spec(spec), OPEN, time="timed")
    assert (e.value.pos.line, e.value.pos.col) == (7, 83)
    assert compile_spec(load_spec(spec), OPEN).timing is None   # untimed, the periods are not read


# ------------------------------------------------------------------ the command line and the API


def test_a_timed_run_on_the_command_line_fails_with_its_timeout_and_replays(tmp_path, roar_cli):
    trace = tmp_path / "run.jsonl"
    code, out, _ = roar_cli("run", TIMEOUT_SPEC, "-r", OPEN, "--time", "timed", "--wait-timeout", "250",
                            "--trace", trace)
    assert code == 1 and "request failure" in out
    assert "timeout: wait(sensor == true, 100) did not hold within 250 ms (3 polls every 100 ms)" in out
    header = json.loads(trace.read_text().splitlines()[0])
    assert header["time"] == "timed" and header["wait_timeout"] == 250
    code, out, _ = roar_cli("replay", trace, "--model", TIMEOUT_SPEC)
    assert code == 0 and out.count("every step is a step of the model") == 1
    # untimed, the same run blocks in its wait: the trace's header is what makes replay timed
    code, out, _ = roar_cli("run", TIMEOUT_SPEC, "-r", OPEN)
    assert code == 1 and "timeout:" not in out and "request running after 11 CLF steps (quiescent)" in out


def test_check_a_spec_timed_on_the_command_line(tmp_path, roar_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, _ = roar_cli("check", TIMEOUT_SPEC, "-r", OPEN, "--time", "timed", "--wait-timeout", "250",
                            "--no-traces")
    assert code == 1
    assert "deadlock: holds" in out and "mission-failure: violated" in out and "timeout: wait(" in out
    code, out, _ = roar_cli("check", TIMEOUT_SPEC, "-r", OPEN, "--no-traces")
    assert code == 1 and "deadlock: violated" in out


@pytest.mark.parametrize("argv, message", [
    (["check", ROOT / "models" / "philosophers" / "dl.clf", "--time", "timed"],
     "--time is for a ROAR spec; a .clf program has no periods"),
    (["check", ROOT / "checker" / "aim.toml", "--time", "timed"],
     "--time is for a spec named on the command line; a job file says its own"),
    (["run", TIMEOUT_SPEC, "-r", OPEN, "--time", "tmed"], "time must be one of untimed, timed, not 'tmed'"),
    (["run", TIMEOUT_SPEC, "-r", OPEN, "--wait-timeout", "100", "--time", "untimed"],
     "wait_timeout needs the timed mode"),
    (["run", TIMEOUT_SPEC, "-r", OPEN, "--time", "timed", "--wait-timeout", "0"],
     "wait_timeout is a whole number of milliseconds, at least 1, not 0"),
])
def test_bad_time_options_are_refused(roar_cli, argv, message):
    code, out, err = roar_cli(*argv)
    assert code == 2 and message in out + err and "Traceback" not in out + err


def test_the_api_runs_and_explores_timed():
    from roar_formal.testing.api import load
    spec = load(TIMEOUT_SPEC)
    report = spec.run(OPEN, time="timed", wait_timeout=250)
    assert not report.ok and "timeout: wait(" in str(report)
    assert "timeout: wait(" not in str(spec.run(OPEN))
    e = spec.explore(OPEN, properties=["deadlock", "mission-failure"], time="timed", wait_timeout=250)
    assert e.verdicts["deadlock"].status == "holds" and e.verdicts["mission-failure"].status == "violated"
    assert spec.explore(OPEN, properties=["deadlock"]).verdicts["deadlock"].status == "violated"
    e = spec.explore(OPEN, properties=["deadlock", "mission-failure"], crash=["door"], time="timed",
                     wait_timeout=250)   # (timed and crashes together: tests/roar/test_time_crashes.py)
    assert e.verdicts["deadlock"].status == "holds" and e.verdicts["mission-failure"].status == "violated"


def test_the_timed_mode_on_a_spec_without_periods_is_refused(tmp_path, roar_cli):
    """Nothing would be timed: the model would be the untimed one, and a 'timed' check would be
    one in name only. The library compiles it (above); the job, the command line and the API refuse."""
    spec = ROOT / "models" / "faulty" / "retry_forever.roar"
    job = write_job(tmp_path, spec, "hand::holding == true", 'time = "timed"\n')
    code, out, err = roar_cli("check", job)
    assert code == 2 and "job.toml:3:8: the timed mode models the periods" in out + err
    code, out, err = roar_cli("check", spec, "-r", "hand::holding == true", "--time", "timed")
    assert code == 2 and "--time timed: the timed mode models the periods" in out + err
    code, out, err = roar_cli("run", spec, "-r", "hand::holding == true", "--time", "timed")
    assert code == 2 and "this spec writes none" in out + err and "Traceback" not in out + err
