"""The axiom set's obligations: each comes out as expected, none holds vacuously."""

from __future__ import annotations

import pytest
import z3

from roar_formal.tca.axioms import BY_NAME as AXIOMS, THEORY, Axiom
from roar_formal.tca.prover import dependencies, find_model, prove
from roar_formal.tca.theorems import BY_NAME, OBLIGATIONS, WITH_LEMMA

PROVED = [o.name for o in OBLIGATIONS if o.expect == "proved"]


@pytest.fixture(scope="module")
def outcomes():
    return {o.name: prove(o) for o in OBLIGATIONS}


@pytest.mark.parametrize("name", [o.name for o in OBLIGATIONS])
def test_obligation_comes_out_as_expected(outcomes, name):
    outcome = outcomes[name]
    assert outcome.status == BY_NAME[name].expect, outcome.reason


def _row(cm, name):
    return next(r for r in cm.rows if name in r.names)


def test_goal_countermodel_really_breaks_precedes(outcomes):
    """Read the printed countermodel back: m3 and m4 are goals under m1 and m2,
    SeqAch(m1, m2) holds, and m3's handling ends after m4's starts."""
    cm = outcomes["seq_ach_goals"].countermodel
    m1, m2, m3, m4 = (_row(cm, n) for n in ("m1", "m2", "m3", "m4"))
    assert {r.kind for r in (m1, m2, m3, m4)} == {"goal"}
    assert (m1.element, m2.element) in cm.relations["seq_ach"]
    assert (m1.element, m3.element) in cm.relations["desc"]
    assert (m2.element, m4.element) in cm.relations["desc"]
    assert m3.times["end"] > m4.times["start"]
    assert m1.times["ach_end"] < m2.times["ach_start"]


def test_second_goal_countermodel_plans_ahead(outcomes):
    cm = outcomes["seq_ach_goal_second"].countermodel
    m3, m4 = _row(cm, "m3"), _row(cm, "m4")
    assert m3.kind in ("command", "monitor") and m4.kind == "goal"
    assert m3.times["end"] > m4.times["start"]


def test_countermodel_prints_every_witness(outcomes):
    text = str(outcomes["seq_ach_goals"].countermodel)
    for name in ("m1", "m2", "m3", "m4", "SeqAch", "desc"):
        assert name in text


@pytest.fixture(scope="module")
def needed():
    return {name: dependencies(BY_NAME[name]) for name in PROVED}


@pytest.mark.parametrize("name", PROVED)
def test_dependency_set_alone_proves_it(needed, name):
    deps = needed[name]
    assert deps, f"{name} needs no axiom: it is a tautology"
    assert prove(BY_NAME[name].with_assumptions(tuple(deps))).status == "proved"


@pytest.mark.parametrize("name", PROVED)
def test_every_needed_axiom_is_really_needed(needed, name):
    """Removing any one member of the computed dependency set leaves a countermodel."""
    for axiom in needed[name]:
        assert find_model(BY_NAME[name].without(axiom)) is not None, f"{name} still holds without {axiom}"


def test_dependency_sets_are_what_the_paper_proof_uses(needed):
    assert set(needed["seq_ach"]) == {"l_desc_nesting", "a7_command", "d_seq_ach", "a5_precedes"}
    assert set(needed["desc_nesting_base"]) == {"a8_nesting", "q_leaf"}
    assert set(needed["desc_nesting_step"]) == {"a8_nesting", "q_leaf"}


def test_theorem_needs_the_induction_lemma():
    assert find_model(BY_NAME["seq_ach"].without("l_desc_nesting")) is not None


def _axiom(name, formula) -> Axiom:
    return Axiom(name, "test", name, formula)


def _reversed_achievement(v):
    m = v.msg_const("m")
    return z3.ForAll([m], v.ach_end(m) < v.ach_start(m))


def _goals_seq_ach_themselves(v):
    m, t = v.msg_const("m"), z3.Real("t")
    return z3.ForAll([m, t], z3.Implies(v.kind(m) == v.kinds["goal"], v.seq_ach(m, m, t)))


def test_consistency_check_catches_a_contradictory_axiom():
    outcome = prove(BY_NAME["consistency"].adding(_axiom("reversed", _reversed_achievement)))
    assert outcome.status == "inconsistent"


def test_nonvacuity_check_catches_an_axiom_that_only_rules_out_goals():
    """'Every goal is SeqAch-before itself' leaves models (without goals), so
    plain consistency passes, but the theorem's hypothesis becomes unsatisfiable."""
    bad = _axiom("goals_before_themselves", _goals_seq_ach_themselves)
    assert prove(BY_NAME["consistency"].adding(bad)).status == "consistent"
    assert prove(BY_NAME["seq_ach_nonvacuous"].adding(bad)).status == "inconsistent"


def test_theory_lists_axioms_one_to_eight():
    sources = {a.source.split(" (")[0] for a in THEORY}
    assert {f"Axiom {i}" for i in range(1, 9)} <= sources
    assert set(WITH_LEMMA) == {a.name for a in THEORY} | {"l_desc_nesting"}
    assert AXIOMS["a8_nesting"].summary


def test_unsat_core_of_a_refuted_claim_is_none():
    assert dependencies(BY_NAME["seq_ach_goals"]) is None
