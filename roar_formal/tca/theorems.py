"""Proof obligations about the axiom set: the paper's theorem, its remark, the
induction lemma for desc, and consistency.

An obligation names its assumptions (axioms, definitions, lemmas), a few
witness constants, and a claim ``hypothesis => conclusion`` over them; the
prover negates the claim on the witnesses. A consistency obligation has no
conclusion: the hypothesis together with the assumptions must have a model.

The chain for the paper's theorem is fully machine-checked except the one
rule Z3 cannot state, induction over the least fixpoint ``desc``:
``desc_nesting_base`` and ``desc_nesting_step`` are its two premises, which
give lemma ``l_desc_nesting`` (``desc_nesting_needs_induction`` shows the
first-order unfolding alone does not); ``seq_ach`` then uses the lemma.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Optional

import z3

from .axioms import LEMMAS, THEORY, Axiom
from .vocabulary import Vocabulary

Witness = dict[str, z3.ExprRef]
Claim = Callable[[Vocabulary, Witness], tuple[z3.BoolRef, Optional[z3.BoolRef]]]

THEORY_NAMES: tuple[str, ...] = tuple(a.name for a in THEORY)
WITH_LEMMA: tuple[str, ...] = THEORY_NAMES + tuple(a.name for a in LEMMAS)


@dataclass(frozen=True)
class Obligation:
    """A claim to prove or refute, or a set of formulas to show consistent."""

    name: str
    statement: str
    expect: str  # proved | refuted | consistent | inconsistent
    assumptions: tuple[str, ...]
    claim: Claim
    witnesses: tuple[str, ...] = ()
    group: str = "axioms"
    order_only: bool = True  # the claim only compares times (countermodels may show ranks)
    added: tuple[Axiom, ...] = ()  # axioms outside the theory, e.g. a candidate to test for consistency
    # a proof must also show its hypotheses satisfiable (a model's facts that contradict the
    # axioms prove every claim): the built-in theorems have their own non-vacuity obligations
    check_vacuity: bool = False

    @property
    def is_consistency(self) -> bool:
        return self.expect in ("consistent", "inconsistent")

    def with_assumptions(self, assumptions: tuple[str, ...]) -> "Obligation":
        """The same claim under other assumptions (dependency and vacuity checks)."""
        return replace(self, assumptions=tuple(assumptions))

    def without(self, *names: str) -> "Obligation":
        return self.with_assumptions(tuple(a for a in self.assumptions if a not in names))

    def adding(self, *axioms: Axiom) -> "Obligation":
        """The same claim with further axioms assumed."""
        return replace(self, added=self.added + tuple(axioms))


FOUR = ("m1", "m2", "m3", "m4", "t")
CM = ("command", "monitor")


def _seq_ach_claim(first_kinds: tuple[str, ...], second_kinds: tuple[str, ...]) -> Claim:
    def claim(v: Vocabulary, w: Witness):
        m1, m2, m3, m4, t = w["m1"], w["m2"], w["m3"], w["m4"], w["t"]
        hyp = z3.And(
            v.is_kind(m1, "goal"), v.is_kind(m2, "goal"),
            v.is_kind(m3, *first_kinds), v.is_kind(m4, *second_kinds),
            v.seq_ach(m1, m2, t), v.desc(m1, m3, t), v.desc(m2, m4, t),
        )
        return hyp, v.precedes(m3, m4, t)

    return claim


def _nesting(v: Vocabulary, a, m) -> z3.BoolRef:
    return z3.And(v.not_query(a), v.nested(a, m))


def _lemma_claim(v: Vocabulary, w: Witness):
    a, m, t = w["a"], w["m"], w["t"]
    return z3.And(v.desc(a, m, t), v.not_query(m)), _nesting(v, a, m)


def _base_claim(v: Vocabulary, w: Witness):
    a, m, t = w["a"], w["m"], w["t"]
    return z3.And(v.child_of(a, m, t), v.not_query(m)), _nesting(v, a, m)


def _step_claim(v: Vocabulary, w: Witness):
    a, x, m, t = w["a"], w["x"], w["m"], w["t"]
    induction_hypothesis = z3.Implies(v.not_query(m), _nesting(v, x, m))
    hyp = z3.And(v.child_of(a, x, t), v.desc(x, m, t), induction_hypothesis, v.not_query(m))
    return hyp, _nesting(v, a, m)


def _scheduable_claim(v: Vocabulary, w: Witness):
    m, t = w["m"], w["t"]
    return v.active(m, t), v.scheduable(m, t)


def _waits_claim(v: Vocabulary, w: Witness):
    m, m1, t = w["m"], w["m1"], w["t"]
    hyp = z3.And(v.not_query(m), v.precedes(m1, m, t), v.scheduable(m, t))
    return hyp, v.completed(m1, t)


def _delay_claim(v: Vocabulary, w: Witness):
    m1, m2, m3, t = w["m1"], w["m2"], w["m3"], w["t"]
    hyp = z3.And(v.delay_planning(m1, m2, t), v.desc(m1, m3, t), v.not_query(m3))
    return hyp, v.precedes(m3, m2, t)


def _subtrees_claim(v: Vocabulary, w: Witness):
    m1, m2, m3, m4, t = w["m1"], w["m2"], w["m3"], w["m4"], w["t"]
    hyp = z3.And(
        v.seq_ach(m1, m2, t),
        z3.Or(m3 == m1, v.desc(m1, m3, t)), z3.Or(m4 == m2, v.desc(m2, m4, t)),
        v.is_kind(m3, *CM), v.is_kind(m4, *CM),
    )
    return hyp, v.precedes(m3, m4, t)


def _satisfiable(v: Vocabulary, w: Witness):
    return z3.BoolVal(True), None


def _theorem_hypothesis(v: Vocabulary, w: Witness):
    hyp, _ = _seq_ach_claim(("command", "monitor"), ("command", "monitor"))(v, w)
    return hyp, None



OBLIGATIONS: tuple[Obligation, ...] = (
    Obligation("consistency", "the axioms, definitions and lemma have a model", "consistent",
               WITH_LEMMA, _satisfiable),
    Obligation("seq_ach_nonvacuous",
               "the theorem's hypothesis is satisfiable: SeqAch(m1, m2) with command descendants m3, m4",
               "consistent", WITH_LEMMA, _theorem_hypothesis, FOUR),
    Obligation("desc_nesting_base",
               "induction base: childOf(a, m) and m not a query imply a not a query and ach(m) within ach(a)",
               "proved", THEORY_NAMES, _base_claim, ("a", "m", "t")),
    Obligation("desc_nesting_step",
               "induction step: childOf(a, x), desc(x, m) and the lemma for (x, m) give the lemma for (a, m)",
               "proved", THEORY_NAMES, _step_claim, ("a", "x", "m", "t")),
    Obligation("desc_nesting_needs_induction",
               "the lemma does not follow from the fixpoint equation of desc alone (e.g. a childOf cycle)",
               "refuted", THEORY_NAMES, _lemma_claim, ("a", "m", "t")),
    Obligation("seq_ach",
               "paper's theorem: SeqAch(m1, m2), m3 a command/monitor descendant of m1, m4 one of m2 "
               "imply precedes(m3, m4)",
               "proved", WITH_LEMMA, _seq_ach_claim(CM, CM), FOUR),
    Obligation("seq_ach_goals",
               "paper's remark: the theorem fails when m3 and m4 are goals (planning in advance)",
               "refuted", WITH_LEMMA, _seq_ach_claim(("goal",), ("goal",)), FOUR),
    Obligation("seq_ach_goal_first",
               "the theorem still holds when m3 is a goal (its planning ends within its achievement)",
               "proved", WITH_LEMMA, _seq_ach_claim(("goal", "command", "monitor"), CM), FOUR),
    Obligation("seq_ach_goal_second",
               "the theorem fails as soon as m4 is a goal: m2's subtree may plan before m1's is achieved",
               "refuted", WITH_LEMMA, _seq_ach_claim(CM, ("goal",)), FOUR),
    Obligation("seq_ach_subtrees",
               "the trace checker's rule: SeqAch(m1, m2) orders every command/monitor of m1's subtree "
               "before every one of m2's, roots included, whatever the kinds of m1 and m2",
               "proved", WITH_LEMMA, _subtrees_claim, FOUR),
    Obligation("delay_planning_subtree",
               "DelayPlanning(m1, m2): every non-query descendant of m1 precedes m2",
               "proved", WITH_LEMMA, _delay_claim, ("m1", "m2", "m3", "t")),
    Obligation("handled_when_scheduable",
               "a message is handled only while it is scheduable: active(m) implies scheduable(m)",
               "proved", THEORY_NAMES, _scheduable_claim, ("m", "t")),
    Obligation("scheduable_waits",
               "a goal, command or monitor is scheduable only once every message preceding it is completed",
               "proved", THEORY_NAMES, _waits_claim, ("m", "m1", "t")),
)

BY_NAME: dict[str, Obligation] = {o.name: o for o in OBLIGATIONS}
