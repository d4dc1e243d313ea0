"""Simmons' task-tree axioms 1 to 8, their definitions, and the desc lemma, in Z3.

Each formula is universally closed and carries quantifier patterns (the terms
whose appearance triggers an instance), so proofs take milliseconds. The
reconstruction of each garbled axiom is argued in ``docs/tca.md``.
Time-dependent definitions are stated as equivalences, which Z3's macro finder
turns into substitutions; that keeps countermodel search cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import z3

from .vocabulary import Vocabulary, vocabulary


@dataclass(frozen=True)
class Axiom:
    """One named formula of the theory."""

    name: str
    source: str  # "Axiom 4", "Axiom 4 (reading)", "added", "definition", "lemma"
    summary: str
    build: Callable[[Vocabulary], z3.BoolRef]


def _msgs(v: Vocabulary, *names: str) -> list[z3.ExprRef]:
    return [v.msg_const(n) for n in names]


def _a1_child(v: Vocabulary) -> z3.BoolRef:
    p, c = _msgs(v, "p", "c")
    t, t1 = z3.Reals("t t1")
    return z3.ForAll(
        [p, c, t1, t],
        z3.Implies(z3.And(v.send(p, c, t1), t1 < t), v.child_of(p, c, t)),
        patterns=[z3.MultiPattern(v.send(p, c, t1), v.child_of(p, c, t))],
    )


def _a1_sent_by_parent(v: Vocabulary) -> z3.BoolRef:
    p, c = _msgs(v, "p", "c")
    t = z3.Real("t")
    return z3.ForAll(
        [p, c, t],
        z3.Implies(v.child_of(p, c, t), z3.And(v.start(p) <= v.sent(c), v.sent(c) <= v.end(p), v.sent(c) < t)),
        patterns=[v.child_of(p, c, t)],
    )


def _a1_one_parent(v: Vocabulary) -> z3.BoolRef:
    p, q, c = _msgs(v, "p", "q", "c")
    t = z3.Real("t")
    return z3.ForAll(
        [p, q, c, t],
        z3.Implies(z3.And(v.child_of(p, c, t), v.child_of(q, c, t)), p == q),
        patterns=[z3.MultiPattern(v.child_of(p, c, t), v.child_of(q, c, t))],
    )


def _a1_sender(v: Vocabulary) -> z3.BoolRef:
    p, c = _msgs(v, "p", "c")
    t1 = z3.Real("t1")
    return z3.ForAll(
        [p, c, t1],
        z3.Implies(v.send(p, c, t1), t1 == v.sent(c)),
        patterns=[v.send(p, c, t1)],
    )


def _interval(lo, hi) -> Callable[[Vocabulary], z3.BoolRef]:
    def build(v: Vocabulary) -> z3.BoolRef:
        (m,) = _msgs(v, "m")
        return z3.ForAll([m], getattr(v, lo)(m) < getattr(v, hi)(m), patterns=[getattr(v, lo)(m), getattr(v, hi)(m)])

    return build


def _holds_inside(pred, lo, hi) -> Callable[[Vocabulary], z3.BoolRef]:
    def build(v: Vocabulary) -> z3.BoolRef:
        (m,) = _msgs(v, "m")
        t = z3.Real("t")
        inside = z3.And(getattr(v, lo)(m) < t, t < getattr(v, hi)(m))
        return z3.ForAll([m, t], getattr(v, pred)(m, t) == inside, patterns=[getattr(v, pred)(m, t)])

    return build


def _a3_completed(v: Vocabulary) -> z3.BoolRef:
    (m,) = _msgs(v, "m")
    t = z3.Real("t")
    return z3.ForAll([m, t], v.completed(m, t) == (t > v.end(m)), patterns=[v.completed(m, t)])


def _a4_scheduable(v: Vocabulary) -> z3.BoolRef:
    m, m1 = _msgs(v, "m", "m1")
    t = z3.Real("t")
    predecessors_done = z3.ForAll(
        [m1],
        z3.Implies(v.precedes(m1, m, t), v.completed(m1, t)),
        patterns=[v.precedes(m1, m, t)],
    )
    ready = z3.And(t > v.sent(m), z3.Or(v.kind(m) == v.kinds["query"], predecessors_done))
    return z3.ForAll([m, t], v.scheduable(m, t) == ready, patterns=[v.scheduable(m, t)])


def _a4_dispatch(v: Vocabulary) -> z3.BoolRef:
    (m,) = _msgs(v, "m")
    return z3.ForAll([m], v.sent(m) <= v.start(m), patterns=[v.sent(m), v.start(m)])


def _a5_precedes(v: Vocabulary) -> z3.BoolRef:
    m1, m2 = _msgs(v, "m1", "m2")
    t = z3.Real("t")
    return z3.ForAll([m1, m2, t], v.precedes(m1, m2, t) == (v.end(m1) <= v.start(m2)), patterns=[v.precedes(m1, m2, t)])


def _a7_command(v: Vocabulary) -> z3.BoolRef:
    (m,) = _msgs(v, "m")
    same = z3.And(v.start(m) == v.ach_start(m), v.end(m) == v.ach_end(m))
    return z3.ForAll(
        [m],
        z3.Implies(v.is_kind(m, "command", "monitor"), same),
        patterns=[v.ach_start(m), v.ach_end(m), v.start(m), v.end(m)],
    )


def _a7_goal(v: Vocabulary) -> z3.BoolRef:
    (m,) = _msgs(v, "m")
    later = z3.And(v.start(m) <= v.ach_start(m), v.end(m) <= v.ach_end(m))
    return z3.ForAll(
        [m],
        z3.Implies(v.is_kind(m, "goal"), later),
        patterns=[v.ach_start(m), v.ach_end(m), v.start(m), v.end(m)],
    )


def _a8_nesting(v: Vocabulary) -> z3.BoolRef:
    p, c = _msgs(v, "p", "c")
    t = z3.Real("t")
    return z3.ForAll(
        [p, c, t],
        z3.Implies(z3.And(v.child_of(p, c, t), v.not_query(p), v.not_query(c)), v.nested(p, c)),
        patterns=[v.child_of(p, c, t)],
    )


def _q_leaf(v: Vocabulary) -> z3.BoolRef:
    p, c = _msgs(v, "p", "c")
    t = z3.Real("t")
    return z3.ForAll([p, c, t], z3.Implies(v.child_of(p, c, t), v.not_query(p)), patterns=[v.child_of(p, c, t)])


def _desc_child(v: Vocabulary) -> z3.BoolRef:
    a, m = _msgs(v, "a", "m")
    t = z3.Real("t")
    return z3.ForAll([a, m, t], z3.Implies(v.child_of(a, m, t), v.desc(a, m, t)), patterns=[v.child_of(a, m, t)])


def _desc_step(v: Vocabulary) -> z3.BoolRef:
    a, x, m = _msgs(v, "a", "x", "m")
    t = z3.Real("t")
    return z3.ForAll(
        [a, x, m, t],
        z3.Implies(z3.And(v.child_of(a, x, t), v.desc(x, m, t)), v.desc(a, m, t)),
        patterns=[z3.MultiPattern(v.child_of(a, x, t), v.desc(x, m, t))],
    )


def _desc_unfold(v: Vocabulary) -> z3.BoolRef:
    a, m = _msgs(v, "a", "m")
    t = z3.Real("t")
    w = v.via(a, m, t)  # the child of a through which m descends (a Skolem function)
    return z3.ForAll(
        [a, m, t],
        z3.Implies(v.desc(a, m, t), z3.Or(v.child_of(a, m, t), z3.And(v.child_of(a, w, t), v.desc(w, m, t)))),
        patterns=[v.desc(a, m, t)],
    )


def _ordered(rel, lo, hi, strict=True) -> Callable[[Vocabulary], z3.BoolRef]:
    def build(v: Vocabulary) -> z3.BoolRef:
        m1, m2 = _msgs(v, "m1", "m2")
        t = z3.Real("t")
        first, second = getattr(v, lo)(m1), getattr(v, hi)(m2)
        order = first < second if strict else first <= second
        return z3.ForAll([m1, m2, t], z3.Implies(getattr(v, rel)(m1, m2, t), order), patterns=[getattr(v, rel)(m1, m2, t)])

    return build


def _lemma_desc_nesting(v: Vocabulary) -> z3.BoolRef:
    a, m = _msgs(v, "a", "m")
    t = z3.Real("t")
    return z3.ForAll(
        [a, m, t],
        z3.Implies(z3.And(v.desc(a, m, t), v.not_query(m)), z3.And(v.not_query(a), v.nested(a, m))),
        patterns=[v.desc(a, m, t)],
    )


AXIOMS: tuple[Axiom, ...] = (
    Axiom("a1_child", "Axiom 1", "once p's handler sends c, c is a child of p", _a1_child),
    Axiom("a1_sent_by_parent", "Axiom 1 (reading)", "a child was sent while its parent was being handled", _a1_sent_by_parent),
    Axiom("a1_one_parent", "Axiom 1 (reading)", "a message is the child of one node only", _a1_one_parent),
    Axiom("a1_sender", "Axiom 1 (reading)", "sending c on behalf of p issues c", _a1_sender),
    Axiom("a2_interval", "Axiom 2", "start(m) < end(m)", _interval("start", "end")),
    Axiom("a2_active", "Axiom 2", "active exactly between start and end", _holds_inside("active", "start", "end")),
    Axiom("a3_completed", "Axiom 3", "completed exactly after end", _a3_completed),
    Axiom("a4_scheduable", "Axiom 4", "scheduable once issued and its predecessors completed", _a4_scheduable),
    Axiom("a4_dispatch", "Axiom 4 (reading)", "a message is handled only after it is issued", _a4_dispatch),
    Axiom("a5_precedes", "Axiom 5", "precedes(m1, m2) iff end(m1) <= start(m2)", _a5_precedes),
    Axiom("a6_interval", "Axiom 6", "ach.start(m) < ach.end(m)", _interval("ach_start", "ach_end")),
    Axiom("a6_achieving", "Axiom 6", "achieving exactly inside the achievement interval",
          _holds_inside("achieving", "ach_start", "ach_end")),
    Axiom("a7_command", "Axiom 7", "a command or monitor is achieved exactly while active", _a7_command),
    Axiom("a7_goal", "Axiom 7", "a goal is achieved from after its start until after its end", _a7_goal),
    Axiom("a8_nesting", "Axiom 8", "a parent is achieved at least while its children are", _a8_nesting),
    Axiom("q_leaf", "added", "a query message has no children", _q_leaf),
)

DEFINITIONS: tuple[Axiom, ...] = (
    Axiom("d_desc_child", "definition", "a child is a descendant", _desc_child),
    Axiom("d_desc_step", "definition", "a descendant of a child is a descendant", _desc_step),
    Axiom("d_desc_unfold", "definition", "a descendant is a child or descends from one", _desc_unfold),
    Axiom("d_seq_ach", "definition", "SeqAch(m1, m2) implies ach.end(m1) < ach.start(m2)",
          _ordered("seq_ach", "ach_end", "ach_start")),
    Axiom("d_delay_planning", "definition", "DelayPlanning(m1, m2) implies ach.end(m1) < start(m2)",
          _ordered("delay_planning", "ach_end", "start")),
)

LEMMAS: tuple[Axiom, ...] = (
    Axiom("l_desc_nesting", "lemma", "a non-query descendant is achieved within its ancestor", _lemma_desc_nesting),
)

THEORY: tuple[Axiom, ...] = AXIOMS + DEFINITIONS
BY_NAME: dict[str, Axiom] = {a.name: a for a in AXIOMS + DEFINITIONS + LEMMAS}


def formulas(names: tuple[str, ...] | list[str], v: Vocabulary | None = None) -> dict[str, z3.BoolRef]:
    """The formulas of the named axioms, definitions or lemmas over ``v``."""
    v = v or vocabulary()
    return {n: BY_NAME[n].build(v) for n in names}
