"""Ordering claims of a model as proof obligations over a generic window.

A claim about class C speaks of one arbitrary C message ``self`` and some
messages below it. The window holds ``self``, the messages the claim names,
and, as long as some appear, the non-repeated, non-chained children that a
constraint ties to a child already there, as fresh constants; the facts are what the model's handlers guarantee about them
(kinds, who sent whom, the declared constraints among them), nothing about
``self``'s context. Since a proof from these facts uses no property of the
particular message, it proves the claim for every C message of every
unrolling, however long the chains (first-order generalisation; no induction
over the chain is needed because the facts are the same at every link).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import z3

from ..errors import RoarError
from .claims import Ref, build, parse_claim, refs
from .model import Claim, Model
from .theorems import WITH_LEMMA, Obligation
from .vocabulary import Vocabulary


@dataclass
class Member:
    """A window message: its class, and its materialised children by child reference."""

    key: str
    cls: str
    children: dict[str, str] = field(default_factory=dict)  # "leg" or "arc[k+1]" -> key


def _key(parent: str, name: str, index: Optional[str]) -> str:
    step = f"{name}[{index}]" if index else name
    return step if parent == "self" else f"{parent}.{step}"


class Window:
    """The messages a claim needs around a generic ``self``: those it names, and
    the fixed children a constraint ties to a member's child (``full``: every
    fixed child, as timing needs, since a handler waits for its queries)."""

    def __init__(self, model: Model, claim: Claim, full: bool = False):
        self.model, self.claim, self.full = model, claim, full
        self.tree = parse_claim(claim.holds, claim.pos)
        self.members: dict[str, Member] = {"self": Member("self", claim.about)}
        for ref in refs(self.tree):
            self.resolve_path(ref.path)
        grown = True
        while grown:
            size = len(self.members)
            for key in list(self.members):
                self._add_fixed_children(key)
            grown = len(self.members) > size

    def resolve_path(self, path) -> str:
        here = "self"
        for name, index in path:
            cls = self.model.classes[self.members[here].cls]
            slot = cls.slot(name)
            if slot is None:
                raise self._fail(f"{cls.name} issues no {name}")
            if bool(slot.repeat) != bool(index):
                raise self._fail(f"index {name} exactly when it repeats, as {name}[k] or {name}[k+1]")
            here = self._member(here, name, index, slot.cls)
        return here

    def _fail(self, message: str) -> RoarError:
        return RoarError(f"claim {self.claim.name}: {message}", self.claim.pos)

    def _member(self, parent: str, name: str, index: Optional[str], cls: str) -> str:
        key = _key(parent, name, index)
        if key not in self.members:
            self.members[key] = Member(key, cls)
            self.members[parent].children[f"{name}[{index}]" if index else name] = key
            if self.full:
                self._add_fixed_children(key)
        return key

    def _add_fixed_children(self, key: str) -> None:
        """Fixed children constrained together with a child already present (all of them if ``full``)."""
        member = self.members[key]
        cls = self.model.classes[member.cls]
        partners = {c.first if c.second in member.children else c.second for c in cls.constraints
                    if c.first in member.children or c.second in member.children}
        for slot in cls.slots:
            if not slot.repeat and not slot.chain and (self.full or slot.name in partners):
                self._member(key, slot.name, None, slot.cls)

    def facts(self, v: Vocabulary, w: dict[str, z3.ExprRef]) -> z3.BoolRef:
        """What the handlers guarantee about the window, at the time witness ``t``."""
        t = w["t"]
        out = [z3.Distinct(*[w[k] for k in self.members])] if len(self.members) > 1 else []
        for m in self.members.values():
            cls = self.model.classes[m.cls]
            out.append(v.kind(w[m.key]) == v.kinds[cls.kind])
            for child in m.children.values():
                p, c = w[m.key], w[child]
                out += [v.sent(c) < t, v.child_of(p, c, t)]
            relation = {"seq_ach": v.seq_ach, "delay_planning": v.delay_planning, "precedes": v.precedes}
            for con in cls.constraints:
                first, second = m.children.get(con.first), m.children.get(con.second)
                if first and second:
                    out.append(relation[con.relation](w[first], w[second], t))
        return z3.And(out)

    def conclusion(self, v: Vocabulary, w: dict[str, z3.ExprRef]) -> z3.BoolRef:
        def resolve(ref: Ref) -> z3.ArithRef:
            return getattr(v, ref.fn)(w[self.resolve_path(ref.path)])

        return build(self.tree, resolve)


def _order_only(tree) -> bool:
    """True when the claim only compares times (countermodels may then show ranks)."""
    if isinstance(tree, tuple):
        if tree[0] in ("+", "-", "*", "neg"):
            return False
        parts = tree[1] if tree[0] == "and" else tree[1:]
        return all(_order_only(p) for p in parts)
    return not hasattr(tree, "numerator")


def claim_obligation(model: Model, claim: Claim) -> Obligation:
    """The ordering claim as an obligation: window facts imply the claim."""
    window = Window(model, claim)

    def statement(v: Vocabulary, w: dict[str, z3.ExprRef]):
        return window.facts(v, w), window.conclusion(v, w)

    return Obligation(
        f"{model.name}:{claim.name}",
        claim.says or claim.holds,
        claim.expect,
        WITH_LEMMA,
        statement,
        tuple(window.members) + ("t",),
        group=model.name,
        order_only=_order_only(window.tree),
        check_vacuity=True,
    )


def model_obligations(model: Model) -> list[Obligation]:
    return [claim_obligation(model, c) for c in model.claims if not c.metric]
