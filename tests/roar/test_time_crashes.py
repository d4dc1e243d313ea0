"""Crashes in the timed model (docs/semantics.md, "Crashes" and "Time").

What a crash stops or fails also gives up its deadline: a sleeping wait of a crashed agent stops at
once (``crash_stop_sleep``), and a held ensure waiting for its periodic re-check fails with the
availability entry (``unavailable_heldt``), its re-check cancelled. Without that, the dead
agent's deadline stays in the timer list: the clock waits for a step no rule takes, and the
network stops, or a dead ensure is re-armed for ever and its agent never comes back.

Checked against an independent oracle: a plain breadth-first search over the engine
(``Program.steps`` / ``Program.successor``) that asserts, in every state with no step, that no
timer is left (``tmrs vnil``) and no request handler is left over, and counts the states.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from roar_formal.clf.state import canonical_key
from roar_formal.clf.terms import Const
from roar_formal.roar.compile import Crashes, compile_spec
from roar_formal.roar.run import crash_setup, run_model
from roar_formal.roar.spec import load_spec
from roar_formal.errors import RoarError
from roar_formal.testing.api import load

from .seq_oracle import head_name

DATA = Path(__file__).parent / "data"
SPEC = DATA / "timed_same.roar"
REQUEST = "door::open == true"


def _facts(ctx, fam: str) -> list:
    bag = ctx.index.get(Const(fam))
    return list(bag.items) if bag else []


def _search(model) -> tuple[int, list, set]:
    """Breadth-first over the engine: the number of states, the states with no step, the rules taken."""
    program = model.program()
    start = program.start_context(next(d for d in program.sig.directives
                                       if type(d).__name__ == "ExecDirective").start)
    seen = {canonical_key(start)}
    level, ends, rules = [start], [], set()
    while level:
        nxt_level = []
        for ctx in level:
            steps = list(program.steps(ctx))
            if not steps:
                ends.append(ctx)
            for c in steps:
                nxt, step = program.successor(ctx, c)
                rules.add(step.rule)
                k = canonical_key(nxt)
                if k not in seen:
                    seen.add(k)
                    nxt_level.append(nxt)
        level = nxt_level
    return len(seen), ends, rules


def _oracle(crash: str):
    model = compile_spec(load_spec(SPEC), REQUEST, functional="abstract", crashes=Crashes((crash,), 1),
                         time="timed")
    n, ends, _rules = _search(model)
    return n, ends


@pytest.mark.parametrize("crash", ["lamp", "door"])
def test_a_crash_leaves_no_timer_and_no_request_behind(crash):
    n, ends = _oracle(crash)
    assert ends
    outcomes = set()
    for ctx in ends:
        assert [head_name(f.args[0]) for f in _facts(ctx, "tmrs")] == ["vnil"]   # no deadline left
        assert _facts(ctx, "hs") == []                                        # no handler left
        top = [f.args[0] for f in _facts(ctx, "rq") if head_name(f.args[3]) == "itop"]
        outcomes |= {head_name(f.args[1]) for f in _facts(ctx, "rs") if f.args[0] in top}
    assert outcomes == {"s_success", "s_failure"}   # the crash fails the mission on some runs only
    ex = load(SPEC).explore(REQUEST, properties=["deadlock", "mission-failure"], crash=[crash], time="timed")
    assert ex.states == n
    assert ex.verdicts["deadlock"].status == "holds"
    v = ex.verdicts["mission-failure"]
    assert v.status == "violated"
    assert f"{crash} unavailable" in str(ex) or "unavailable" in str(ex), str(ex)


def test_the_held_ensure_of_a_crashed_agent_fails_with_the_availability_entry():
    """The lamp crashes while the door's ensure on it is held: the ensure fails, with the lamp's
    unavailability, as it does untimed."""
    model = compile_spec(load_spec(SPEC), REQUEST, crashes=crash_setup(["lamp@1"]), time="timed")
    plain = run_model(model, seed=0, crashes=[])
    held = next(e.step for e in plain.events if e.kind == "state" and e.data["request"] == "R1"
                and e.data["to"] == "success")
    failed = []
    for step in range(held, len(plain.steps) + 1):
        try:
            r = run_model(model, seed=0, crashes=[f"lamp@{step}"])
        except RoarError:   # (the lamp handles no request any more from this step on)
            break
        if any(e.kind == "state" and e.data["request"] == "R1" and (e.data["from"], e.data["to"]) == ("success", "failure")
               for e in r.events):
            failed.append(step)   # the held ensure failed while held, with the lamp's unavailability
            assert any(e.kind == "state" and e.data["request"] == "R1" and "lamp is unavailable" in e.text
                       for e in r.events)
    assert failed, "no crash caught the ensure held"


def test_a_timed_crash_counterexample_replays(tmp_path, roar_cli):
    """A job with both: its counterexample records the crash and the time mode, and replays on the
    model it was found on."""
    import json

    from roar_formal.verify.check import run_job, save_counterexample
    from roar_formal.verify.jobs import load_job
    from roar_formal.verify.replay import replay_trace
    job = tmp_path / "job.toml"
    job.write_text(f'name = "lamp_down"\nspec = "{SPEC.as_posix()}"\nrequest = "{REQUEST}"\ntime = "timed"\n'
                   '[faults]\ncrash = ["lamp"]\n'
                   '[expect]\ndeadlock = "holds"\nmission-failure = "violated"\n', encoding="utf-8")
    code, out, err = roar_cli("check", job, "--no-traces")
    assert code == 0, (out, err)
    res = run_job(load_job(job))
    path = save_counterexample(res, "mission-failure", tmp_path)
    header = json.loads(path.read_text(encoding="utf-8").splitlines()[0])
    assert header["crash"] == ["lamp"] and header["time"] == "timed"
    back = replay_trace(path, SPEC)
    assert back.confirmed is True and back.compiled.crashes == Crashes(("lamp",), 1) and back.compiled.timing
    assert any(e["text"] == "lamp crashed" for s in back.steps for e in s["events"])


# ------------------------------------------------------------------ crashes and the logic activation


def test_a_crash_during_a_decision_through_the_functional_layer():
    """The mover's task pre-conditions call the functional layer: its decisions go through a logic
    activation (``h_lq``). A crash at any moment of it fails the dead request
    (``unavailable_lq``, ``unavailable_lq_call`` while a call is pending) and leaves nothing
    behind. Oracle: a plain breadth-first search over the engine; in every state with no step no
    handler, logic activation or pending call is left, the mover's mask is empty, and a failed
    boss request carries the unavailability."""
    spec = DATA / "crash_logic.roar"
    request = "boss::done == true"
    model = compile_spec(load_spec(spec), request, functional="abstract", crashes=Crashes(("mover",), 1))
    n, ends, rules = _search(model)
    assert {"unavailable_lq", "unavailable_lq_call"} <= rules   # a crash reached both phases
    outcomes = set()
    for ctx in ends:
        for fam in ("hs", "lsnap", "ctl", "pending"):
            assert _facts(ctx, fam) == [], fam
        assert [head_name(f.args[1]) for f in _facts(ctx, "mask")] == ["vnil", "vnil"]
        top = [f.args[0] for f in _facts(ctx, "rq") if head_name(f.args[3]) == "itop"]
        outcomes |= {head_name(f.args[1]) for f in _facts(ctx, "rs") if f.args[0] in top}
    assert outcomes == {"s_success", "s_failure"}
    ex = load(spec).explore(request, properties=["deadlock", "mission-failure"], crash=["mover"])
    assert ex.states == n
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "violated"
