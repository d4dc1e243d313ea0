"""Compiling forward-chaining rules into matching templates.

A rule such as ``Pi X. Pi D. eval (num X) D -o {return X D}`` becomes a
:class:`Template`: numbered slots for its ``Pi`` (and head ``Exists``)
variables, premise patterns in which the bound variables are slots
(:class:`Meta`), and head actions (make a fresh name, add a fact, add a rule).
A rule nested in a head (a destination-passing continuation) is a template
whose slots continue its parent's, and a live rule in the context is a
template plus the parent's slot values (a closure): nothing is substituted
when it is created, only when it fires.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Optional

from ..errors import Pos, UnsupportedError
from .builtins import BUILTINS
from .printer import show
from .terms import (Aff, Bang, BVar, Const, Exists, Imp, Lam, Meta, Monad, Node, One, Pi, Root, Tensor, Top,
                    TypeNode, With, apply, bvar, map_bvars, subst)

LIN, PERS, AFF = "1", "!", "@"


def positive_parts(s: Node, fresh, mode: str = LIN, positions: Optional[list] = None) -> list[tuple[str, Node]]:
    """Split a positive type into (mode, part) leaves: atoms, ``T`` and negative types.

    ``Exists x:A. S`` calls ``fresh(hint, A)`` for the term that stands for x (a new
    name when the type is assumed, a logic variable when it is matched). Used by
    every place that assumes or matches a positive type, so they agree on modes. ``positions``
    receives, per Exists, the number of leaves before it (where a proof term puts its witness)."""
    out: list[tuple[str, Node]] = []
    stack = [(s, mode)]
    while stack:
        t, m = stack.pop()
        tt = type(t)
        if tt is Tensor:
            stack.append((t.right, m))
            stack.append((t.left, m))
        elif tt is One:
            continue
        elif tt is Exists:
            if positions is not None:
                positions.append(len(out))
            stack.append((subst(t.body, [fresh(t.hint, t.dom)]), m))
        elif tt is Bang:
            stack.append((t.body, PERS))
        elif tt is Aff:
            stack.append((t.body, AFF if m != PERS else PERS))
        else:
            out.append((m, t))
    return out


@dataclass(eq=False)
class Premise:
    mode: str  # LIN, PERS or AFF: how the fact is used
    pattern: Node  # an atom with slots, or a goal type when ``backward``
    family: Optional[Const]
    backward: bool = False  # solved by proof search rather than found in the context


@dataclass(eq=False)
class Template:
    """One alternative of a rule: premises and, if ``forward``, a monadic head."""

    name: str
    nslots: int
    nouter: int  # slots bound before this template fires (its closure's)
    premises: list[Premise]
    head: list = field(default_factory=list)  # actions, see ``_head``
    forward: bool = True
    slot_names: list[str] = field(default_factory=list)
    source: Optional[Node] = None  # the type it was compiled from (slots as Metas)
    match_plan: Optional[tuple] = field(default=None, repr=False)  # forward._plans, made on first use
    # slots of Pi variables that no premise determines: the head then puts logic variables in
    # the context (Celf's semantics), and the rules reading them take the general path
    open_slots: tuple = ()
    # (premises before it, its slot) of each Pi binder in order: where a proof term puts its argument
    pi_slots: tuple = ()

    @cached_property
    def backward_premises(self) -> bool:
        """Does some premise need proof search (not just a lookup in the context)?"""
        return any(p.backward for p in self.premises)


def _conv(t: Node, env: list[int], lam_depth: int = 0) -> Node:
    """Turn binder references of a type's term into slot references."""
    if t.maxb <= lam_depth:
        return t
    tt = type(t)
    if tt is Root:
        args = tuple(_conv(a, env, lam_depth) for a in t.args)
        h = t.head
        if type(h) is BVar and h.index >= lam_depth:
            j = h.index - lam_depth
            return apply(Root(Meta(env[len(env) - 1 - j]), ()), args) if args else Root(Meta(env[len(env) - 1 - j]), ())
        return Root(h, args)
    if tt is Lam:
        return Lam(_conv(t.body, env, lam_depth + 1))
    raise AssertionError("types are converted by _conv_type")


def _conv_type(t: Node, env: list[int], alloc) -> Node:
    """Convert a whole type (binders inside stay binders, but outer ones become slots)."""
    # Types inside heads keep their own binders; we convert those via fresh slots too.
    tt = type(t)
    if tt is Root:
        return _conv(t, env)
    if isinstance(t, TypeNode):
        if tt in (Pi, Exists):
            dom = _conv_type(t.dom, env, alloc)
            s = alloc(t.hint)
            body = _conv_type(t.body, env + [s], alloc)
            return tt(t.hint, dom, body)
        vals = [(_conv_type(getattr(t, f), env, alloc) if isinstance(getattr(t, f), Node) else getattr(t, f))
                for f in tt.fields]
        return tt(*vals)
    return _conv(t, env)


class Compiler:
    """Compiles types into templates; one instance per rule source."""

    def __init__(self, name: str, pos: Optional[Pos] = None, backward_families: frozenset = frozenset()):
        self.name = name
        self.pos = pos
        self.backward_families = backward_families
        self.names: list[str] = []

    def alloc(self, hint: str) -> int:
        self.names.append(hint)
        return len(self.names) - 1

    def compile(self, ty: Node) -> list[Template]:
        """All alternatives of a closed negative type (``&`` distributes over premises)."""
        out: list[Template] = []
        self._walk(ty, [], [], out, 0)
        return out

    def _walk(self, ty: Node, env: list[int], prem: list[Premise], out: list, nouter: int,
              pis: tuple = ()) -> None:
        tt = type(ty)
        if tt is Pi:
            s = self.alloc(ty.hint)
            self._walk(ty.body, env + [s], prem, out, nouter, pis + ((len(prem), s),))
        elif tt is Imp:
            dom = ty.dom
            # A built-in premise is always decided by the engine (it consumes nothing, so
            # its mode does not matter); another atom is proved backwards when its family
            # has clauses (as Celf does: the context's facts first, then the clauses; a
            # linear or affine premise may consume facts of the context doing so), and
            # found in the context otherwise.
            if type(dom) is Root and dom.head not in BUILTINS and dom.head not in self.backward_families:
                p = Premise(ty.mode, _conv(dom, env), dom.head)
            else:
                p = Premise(ty.mode, _conv_type(dom, env, self.alloc), dom.head if type(dom) is Root else None,
                            backward=True)
            self._walk(ty.body, env, prem + [p], out, nouter, pis)
        elif tt is With:
            self._walk(ty.left, env, prem, out, nouter, pis)
            self._walk(ty.right, env, prem, out, nouter, pis)
        elif tt is Monad:
            actions: list = []
            self._head(ty.body, env, actions)
            out.append(self._finish(prem, actions, True, nouter, pis))
        else:  # an atom or T: usable by backward chaining only
            out.append(self._finish(prem, [], False, nouter, pis))

    def _finish(self, prem, actions, forward, nouter, pis: tuple = ()) -> Template:
        return Template(self.name, 0, nouter, prem, actions, forward, self.names, pi_slots=pis)

    def _head(self, s: Node, env: list[int], actions: list) -> None:
        ts = type(s)
        if ts is Tensor:
            self._head(s.left, env, actions)
            self._head(s.right, env, actions)
        elif ts is One:
            return
        elif ts is Exists:
            slot = self.alloc(s.hint)
            actions.append(("fresh", slot, s.hint))
            self._head(s.body, env + [slot], actions)
        elif ts is Bang:
            self._produce(s.body, env, PERS, actions)
        elif ts is Aff:
            self._produce(s.body, env, AFF, actions)
        else:
            self._produce(s, env, LIN, actions)

    def _produce(self, a: Node, env: list[int], mode: str, actions: list) -> None:
        if type(a) is Root:
            actions.append(("fact", mode, _conv(a, env)))
        elif type(a) is Top:
            actions.append(("inert", mode, a))
        else:
            # a rule in the context: compile now with this environment
            subs = self.compile_nested(a, env)
            actions.append(("rule", mode, subs, a, tuple(env)))

    def compile_nested(self, a: Node, env: list[int]) -> list[Template]:
        out: list[Template] = []
        nouter_mark = len(self.names)
        self._walk(a, env, [], out, nouter_mark)
        return out


def finalize(templates: list[Template], nslots: int) -> None:
    """Every template of one rule source shares the slot layout (size ``nslots``)."""
    for t in templates:
        t.nslots = nslots
        for act in t.head:
            if act[0] == "rule":
                finalize(act[2], nslots)


def compile_rule(name: str, ty: Node, pos: Optional[Pos] = None,
                 backward_families: frozenset = frozenset()) -> list[Template]:
    """Compile a closed rule type from the signature or a start context."""
    c = Compiler(name, pos, backward_families)
    temps = c.compile(ty)
    finalize(temps, len(c.names))
    for t in temps:
        if t.forward:
            _check_determined(t, c.names, pos)
            _mark_nested(t, c.names)
    return temps


def _mark_nested(t: Template, names: list[str]) -> None:
    """The undetermined slots of the rules a head puts in the context (their logic variables)."""
    for act in t.head:
        if act[0] == "rule":
            for sub in act[2]:
                if sub.forward:
                    _check_determined(sub, names, None, builtins=False)
                    _mark_nested(sub, names)


def _metas_bound_by(p: Node, acc: set) -> None:
    """Slots that matching ``p`` binds (rigid occurrences, or heads of pattern spines)."""
    stack = [p]
    while stack:
        x = stack.pop()
        if not x.metas:
            continue
        if type(x) is Root:
            if type(x.head) is Meta:
                acc.add(x.head.index)
            stack.extend(x.args)
        elif type(x) is Lam:
            stack.append(x.body)
        elif isinstance(x, TypeNode):
            stack.extend(v for v in (getattr(x, f) for f in type(x).fields) if isinstance(v, Node))


def _check_determined(t: Template, names: list[str], pos: Optional[Pos], builtins: bool = True) -> None:
    bound: set = set(range(t.nouter))
    for p in t.premises:  # premises found in the context bind by matching (all are matched first)
        if not p.backward:
            _metas_bound_by(p.pattern, bound)
    for p in t.premises:  # then proved ones, in order: by unification, or a built-in's output
        if not p.backward:
            continue
        bi = BUILTINS.get(p.family)
        if bi is None or not builtins:
            _metas_bound_by(p.pattern, bound)
            continue
        args = p.pattern.args
        for i in range(bi.n_inputs):
            need: set = set()
            _metas_bound_by(args[i], need)
            free = sorted(s for s in need - bound if s < len(names))
            if free:
                nm = ", ".join(names[s] for s in free)
                raise UnsupportedError(
                    f"in rule '{t.name}': argument {i + 1} of the built-in '{bi.name}' ({nm}) is not "
                    f"determined by the premises before it; a built-in's inputs must be ground when it "
                    f"is evaluated (mode {bi.name} {bi.mode})", pos)
        if bi.output:
            _metas_bound_by(args[-1], bound)
    used: set = set()
    fresh = {a[1] for a in t.head if a[0] == "fresh"}
    _collect_head(t.head, used)
    missing = sorted(s for s in used - bound - fresh if s >= 0 and s < len(names)
                     and not _is_fresh_anywhere(t.head, s))
    # A Pi variable no premise determines is a logic variable when the rule fires (as in
    # Celf): the facts it reaches hold it until a later match instantiates it.
    t.open_slots = tuple(missing)


def _is_fresh_anywhere(actions: list, slot: int) -> bool:
    for a in actions:
        if a[0] == "fresh" and a[1] == slot:
            return True
        if a[0] == "rule":
            for t in a[2]:
                if _is_fresh_anywhere(t.head, slot):
                    return True
    return False


def _collect_head(actions: list, acc: set) -> None:
    """The slots the head reads: its facts' variables, and the outer variables a rule it puts in
    the context refers to (a variable only such a rule uses is as open as one only a fact uses)."""
    for a in actions:
        if a[0] == "fact":
            _metas_bound_by(a[2], acc)
        elif a[0] == "rule":
            outer = list(reversed(a[4]))   # de Bruijn index k (outside the rule) -> slot
            seen: set = set()

            def note(i: int, d: int) -> Node:
                seen.add(i - d)
                return bvar(i)

            map_bvars(a[3], 0, note)
            acc.update(outer[k] for k in seen if k < len(outer))


def describe(t: Template) -> str:
    return f"{t.name}: " + ", ".join(show(p.pattern) for p in t.premises)
