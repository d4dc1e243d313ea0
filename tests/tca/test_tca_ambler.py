"""The Ambler walking model: loading, unrolling, its claims, simulated runs."""

from __future__ import annotations

import dataclasses
import random
from fractions import Fraction

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roar_formal.errors import RoarError
from roar_formal.tca.check import check_events, check_trace
from roar_formal.tca.claims import parse_claim
from roar_formal.tca.metric import check_metric
from roar_formal.tca.model import load_model, parse_model
from roar_formal.tca.prover import prove
from roar_formal.tca.schedule import Schedule, Timing, sample_timing, simulate
from roar_formal.tca.unroll import unroll
from roar_formal.tca.window import claim_obligation, model_obligations

from repo import ROOT
AMBLER = ROOT / "models" / "ambler" / "ambler.toml"


@pytest.fixture(scope="module")
def ambler():
    return load_model(AMBLER)


def claim(model, name):
    return next(c for c in model.claims if c.name == name)


def test_unrolls_arcs_and_step_chains(ambler):
    inst = unroll(ambler, {"arcs": 3, "steps": 5})
    steps = [n for n in inst.nodes.values() if n.cls == "TakeStep"]
    assert len(steps) == 15 and len(inst.nodes) == 1 + 3 + 15 * 4
    assert inst.nodes["arc2.step3"].parent == "arc2.step2"
    assert inst.nodes["arc2.step5"].slots.keys() == {"sense", "leg", "body"}  # the chain ends
    assert ("seq_ach", "arc1", "arc2") in inst.constraints
    assert ("delay_planning", "arc2.step3.leg", "arc2.step4") in inst.constraints
    assert ("seq_ach", "arc3.step1.body", "arc3.step2") in inst.constraints


@pytest.mark.parametrize("ob", model_obligations(load_model(AMBLER)), ids=lambda o: o.name)
def test_ordering_claims(ob):
    assert prove(ob).status == ob.expect


def test_at_most_one_step_needs_the_delay_planning_constraint(ambler):
    """Without delay_planning(leg, next) the step planner could run two steps ahead."""
    step = ambler.classes["TakeStep"]
    kept = tuple(c for c in step.constraints if c.relation != "delay_planning")
    looser = dataclasses.replace(ambler, classes={**ambler.classes, "TakeStep": dataclasses.replace(
        step, constraints=kept)})
    outcome = prove(claim_obligation(looser, claim(looser, "at_most_one_step_ahead")))
    assert outcome.status == "refuted"
    cm = outcome.countermodel
    row = {n: r for r in cm.rows for n in r.names}
    assert row["body"].times["ach_end"] >= row["next.next"].times["start"]


def test_at_least_one_step_ahead_holds_exactly_under_the_bound(ambler):
    result = check_metric(ambler, claim(ambler, "at_least_one_step_ahead"))
    assert (result.sufficient, result.sufficient_unrolled, result.necessary, result.holds_as_configured) == \
           (True, True, True, True)
    assert result.status == "proved"


@pytest.mark.parametrize("bound,fails", [
    ("sense.hi + plan.hi <= body.lo", "sufficient"),  # forgets the dispatch delays
    ("sense.hi + plan.hi + 3 * dispatch.hi <= body.lo", "necessary"),  # asks for more than needed
    ("sense.hi + plan.hi + 2 * dispatch.hi - dispatch.lo <= body.lo + leg.lo", "sufficient"),  # leg does not help
])
def test_wrong_bounds_are_refuted_in_the_right_direction(ambler, bound, fails):
    result = check_metric(ambler, dataclasses.replace(claim(ambler, "at_least_one_step_ahead"), bound=bound))
    assert result.status == "refuted"
    assert getattr(result, fails) is False
    assert result.witness


def test_a_slow_planner_breaks_the_claim_as_configured(ambler):
    slow = dataclasses.replace(ambler, durations={**ambler.durations, "plan": (Fraction(4), Fraction(7))})
    result = check_metric(slow, claim(slow, "at_least_one_step_ahead"))
    assert result.status == "proved" and result.holds_as_configured is False
    assert any("handled" in line for line in result.witness)


def _plans_ahead(inst, timing) -> bool:
    """Plain Python: each non-first step's plan is done when the previous body move ends."""
    sched = Schedule(inst, timing)
    for node in inst.nodes.values():
        nxt = node.slots.get("next")
        if node.cls == "TakeStep" and nxt:
            if sched.value("end", nxt) > sched.value("end", node.slots["body"]):
                return False
    return True


def _bound_holds(model) -> bool:
    d = model.durations
    return d["sense"][1] + d["plan"][1] + 2 * d["dispatch"][1] - d["dispatch"][0] <= d["body"][0]


def _worst(inst):
    """Durations that stress planning ahead: slow planning, fast bodies, unlucky dispatching."""
    def pick_for(node):
        cls = inst.model.classes[node.cls]
        bounds = inst.model.durations
        fast_body = node.cls == "MoveBody"
        delay = bounds["dispatch"][0] if fast_body else bounds["dispatch"][1]
        work = bounds[cls.work][0] if fast_body else bounds[cls.work][1]
        return Timing(delay, work)

    return {n.id: pick_for(n) for n in inst.nodes.values()}


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.fractions(Fraction(5), Fraction(9)))
def test_concrete_runs_agree_with_the_bound(seed, body_lo):
    """No Z3: simulate runs and compare with the bound the metric analysis found."""
    model = load_model(AMBLER)
    model = dataclasses.replace(model, durations={**model.durations, "body": (body_lo, body_lo + 2)})
    inst = unroll(model, {"arcs": 2, "steps": 3})
    assert _plans_ahead(inst, sample_timing(inst, random.Random(seed))) or not _bound_holds(model)
    assert _plans_ahead(inst, _worst(inst)) == _bound_holds(model)


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 3), st.integers(1, 4), st.booleans())
def test_simulated_runs_conform_to_the_axioms(seed, arcs, steps, achievement):
    model = load_model(AMBLER)
    inst = unroll(model, {"arcs": arcs, "steps": steps})
    report = check_events(simulate(inst, sample_timing(inst, random.Random(seed)), achievement))
    assert report.ok, [v.explanation for v in report.violations]


def test_shipped_traces():
    traces = AMBLER.parent / "traces"
    assert check_trace(traces / "walk.jsonl").ok
    (v,) = check_trace(traces / "walk_leg_too_early.jsonl").violations
    assert v.rule == "seq_ach" and v.messages[1:] == ("arc1.step2", "arc1.step1.body", "arc1.step2.leg")


MINIMAL = """
[model]
name = "m"
root = "A"
[durations]
dispatch = [0.1, 0.2]
w = [1, 2]
[classes.A]
kind = "goal"
work = "w"
children = [{ name = "b", class = "B" }]
[classes.B]
kind = "command"
work = "w"
"""


@pytest.mark.parametrize("change,words,line", [
    (("[classes.B]", "[classes.B"), "malformed TOML", 12),
    (('kind = "command"', 'kind = "task"'), "kind must be one of", 12),
    (('class = "B"', 'class = "C"'), "unknown class 'C'", 11),
    (('kind = "command"', 'kind = "command"\nchildren = [{ name = "a", class = "A" }]'), "may not issue", 12),
    (("w = [1, 2]", "w = [2, 1]"), "0 < lo <= hi", 7),
    (('work = "w"\nchildren', 'work = "z"\nchildren'), "not in [durations]", 10),
    (("dispatch = [0.1, 0.2]\n", ""), "durations.dispatch", 5),
])
def test_model_errors_are_located(change, words, line):
    text = MINIMAL.replace(*change)
    with pytest.raises(RoarError) as info:
        parse_model(text, "m.toml")
    assert words in info.value.message
    assert info.value.pos.line == line


def test_recursion_must_use_a_chain():
    text = MINIMAL.replace('kind = "command"', 'kind = "goal"\nchildren = [{ name = "a", class = "A" }]')
    with pytest.raises(RoarError, match="without end"):
        parse_model(text, "m.toml")


@pytest.mark.parametrize("text,words", [
    ("ach_end(body) <", "expected more"),
    ("ach_end(body) < start(next", "expected )"),
    ("finish(body) < start(next)", "not one of"),
    ("ach_end(body) start(next)", "comparison"),
    ("start(arc[j]) < end(self)", "expected k"),
])
def test_claim_syntax_errors(text, words):
    with pytest.raises(RoarError, match="claim") as info:
        parse_claim(text)
    assert words in info.value.message


def test_claim_naming_a_missing_child(ambler):
    bad = dataclasses.replace(claim(ambler, "at_most_one_step_ahead"), holds="end(wing) < start(next)")
    with pytest.raises(RoarError, match="issues no wing"):
        claim_obligation(ambler, bad)


def test_a_claim_from_contradictory_constraints_is_vacuous_not_proved(ambler):
    """SeqAch both ways between two children: no task tree meets the model's facts, so every
    claim follows; prove must say vacuous (it said proved, even of start(a) < start(a))."""
    step = ambler.classes["TakeStep"]
    both = dataclasses.replace(step, constraints=step.constraints + tuple(
        dataclasses.replace(c, first=c.second, second=c.first) for c in step.constraints if c.relation == "seq_ach"))
    contra = dataclasses.replace(ambler, classes={**ambler.classes, "TakeStep": both})
    for name in ("steps_in_order", "next_plan_waits_for_leg"):
        outcome = prove(claim_obligation(contra, claim(contra, name)))
        assert outcome.status == "vacuous" and not outcome.ok and "contradict" in outcome.reason
    # the untouched model's claims are proved, their hypotheses having a model
    assert prove(claim_obligation(ambler, claim(ambler, "steps_in_order"))).status == "proved"
