"""Interchangeable agents of a compiled ROAR model: the symmetries symmetry reduction may use.

Two agents are *candidates* when their specs are identical up to their names (the agent
printed with its name, and its own qualified name ``X::``, written as a placeholder). For each
set of k candidates, the permutation of two of them renames everything the compiler named
after them (``CompiledModel``'s tables): the agent constant ``a_X``, its cells ``v_X_var``,
tasks, recipes, functions, the constraint constants sent to it (``cN_X``, in order), and its
statement sites (``ppN_kind``, in order). The compiled rules named after those (``stN_...``,
``select_cN_X``, ...) follow from them: a rule's image is the declaration whose type is the
image of its type.

A candidate is never trusted by its names: it is used only when
:func:`roar_formal.explore.symmetry.verify` finds that it maps every declaration of the
compiled signature (framework included) onto a declaration, and the start state onto itself.
The labels the compiler numbers tasks and constraints with (``task_id t_X_work 2``,
``cst_id c1_X 1``) are compared without their numbers; the framework reads them only by
comparing two of them (``cst_eq_i``, ``ti_cons``, ``mh_hd``), which this module checks on the
signature it is given before it lets labels differ.

Why this rarely finds a symmetry among agents that act: a ROAR model starts from one request
to one agent, and an agent that sends requests to others names them in its recipes, in order
(``ensure(w1::done); ensure(w2::done)``): a permutation of w1 and w2 maps the first statement
onto a statement that sends to w2 first, which the model does not have. Verification says so
(the declaration it fails on), and the job reports no symmetry rather than a wrong count.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Optional

from ..clf.context import Context
from ..clf.terms import Const, Lam, Node, Root
from ..explore.symmetry import Check, ConstPerm, MAX_ORDER, close_group, factorial_order, verify
from .compile import CompiledModel

#: label families: the position of the label (a number) in ``task_id T N`` / ``cst_id C N``
LABELS = {"task_id": 1, "cst_id": 1}
#: the framework clauses that read labels, each comparing two labels for equality
LABEL_READERS = frozenset({"cst_eq_i", "ti_cons", "mh_hd"})


@dataclass
class Symmetry:
    """What symmetry discovery found on a compiled model."""

    blocks: list[list[str]] = field(default_factory=list)     # interchangeable agents, verified
    group: list[ConstPerm] = field(default_factory=list)      # every element, the identity first
    rejected: list[str] = field(default_factory=list)         # candidates refused, and why

    @property
    def order(self) -> int:
        return len(self.group)

    @property
    def agents(self) -> set[str]:
        return {a for b in self.blocks for a in b}

    def note(self) -> str:
        """The sentence a report prints."""
        if self.order > 1:
            k = sum(len(b) for b in self.blocks)
            sets = "; ".join(", ".join(b) for b in self.blocks)
            return f"symmetry: {k} agents interchangeable ({sets}), group of order {self.order:,}"
        why = "; ".join(self.rejected) if self.rejected else "no two agents have identical specs"
        return f"symmetry: none found ({why}); the search is the plain one"


def _norm(text: str, name: str) -> str:
    return re.sub(rf"\b{re.escape(name)}\b", "\0SELF\0", text)


def candidates(model: CompiledModel) -> list[list[str]]:
    """Sets (two or more) of agents whose specs are identical up to their names."""
    from .pretty import format_agent
    by_text: dict[str, list[str]] = {}
    for ag in model.spec.agents:
        by_text.setdefault(_norm(format_agent(ag), ag.name), []).append(ag.name)
    return [names for names in by_text.values() if len(names) > 1]


def _num(name: str) -> int:
    m = re.match(r"[a-z]+(\d+)_", name)
    return int(m.group(1)) if m else 0


def roles(model: CompiledModel, agent: str) -> dict:
    """Everything the compiler named after ``agent``: role -> constant name."""
    out: dict = {}
    for c, a in model.agents.items():
        if a == agent:
            out[("agent",)] = c
    for c, (a, var) in model.cells.items():
        if a == agent:
            out[("cell", var)] = c
    for c, (a, t) in model.tasks.items():
        if a == agent:
            out[("task", t)] = c
    for c, (a, t, r) in model.recipes.items():
        if a == agent:
            out[("recipe", t, r)] = c
    for c, (a, name) in model.functions.items():
        if a == agent:
            out[("fn", name)] = c
    csts = sorted((c for c, (a, _t) in model.csts.items() if a == agent), key=_num)
    for i, c in enumerate(csts):
        out[("cst", i)] = c
    sites = sorted((s.const for s in model.sites.values() if s.agent == agent), key=_num)
    for i, c in enumerate(sites):
        out[("site", i, model.sites[c].kind)] = c
    return out


def _labels_safe(sig) -> Optional[str]:
    """None when the signature reads the label families only where LABEL_READERS do, else why not."""
    fams = {Const(f) for f in LABELS}
    readers = set()
    for info in sig.consts.values():
        if info.is_family or getattr(info, "builtin", False):
            continue
        cl = info.classifier
        if type(cl) is Root and cl.head in fams:
            continue   # a label itself
        if _mentions(cl, fams):
            readers.add(info.name)
    extra = readers - LABEL_READERS
    if extra:
        return f"the model reads task or constraint labels in {', '.join(sorted(extra))}, not only by equality"
    return None


def _mentions(t, fams: set) -> bool:
    if not isinstance(t, Node):
        return False
    if type(t) is Root:
        return t.head in fams or any(_mentions(a, fams) for a in t.args)
    if type(t) is Lam:
        return _mentions(t.body, fams)
    return any(_mentions(getattr(t, f), fams) for f in type(t).fields)


def _tables_follow(model: CompiledModel, g: ConstPerm) -> Check:
    """What the explorer reads of the model besides its signature follows the permutation: the
    cells each constraint's where clause writes (exclusive-writes), the fairness groups of the
    fair outcome rules."""
    for c, cells in model.where_cells.items():
        if sorted(model.where_cells.get(g.name(c), [])) != sorted(g.name(x) for x in cells):
            return Check(False, f"the cells the where clause of {c} writes do not follow the permutation")
    agent_of = {c: a for c, a in model.agents.items()}
    rename = {agent_of[c]: agent_of[g.name(c)] for c in agent_of if g.name(c) in agent_of}
    for (ag, t), others in model.incompatible.items():
        if sorted(model.incompatible.get((rename.get(ag, ag), t), ())) != sorted(others):
            return Check(False, f"the tasks {ag}::{t} masks (incompatible tasks) do not follow the permutation")
    if model.fair_outcomes:
        return Check(False, "the model has fair outcome rules, whose fairness groups symmetry reduction does not "
                            "rename")
    return Check(True)


def discover(model: CompiledModel, start: Context, limit: int = MAX_ORDER) -> Symmetry:
    """The verified symmetries of a compiled model: for each set of candidates, the transpositions
    of consecutive members, each verified on the signature and the start state; a set whose
    transpositions all pass is a block (its k! permutations are symmetries: a group generated
    by automorphisms holds only automorphisms). Refused above ``limit`` elements."""
    sig = model.program().sig
    out = Symmetry()
    unsafe = _labels_safe(sig)
    labels = None if unsafe else LABELS
    gens: list[ConstPerm] = []
    sets = []
    for names in candidates(model):
        # agents identical in text may still be compiled differently (one receives the request,
        # or constraints the other does not): split them by what the compiler named after them
        by_roles: dict = {}
        for n in names:
            by_roles.setdefault(frozenset(roles(model, n)), []).append(n)
        parts = [p for p in by_roles.values() if len(p) > 1]
        if len(by_roles) > 1 and not parts:
            out.rejected.append(f"{', '.join(names)} have identical specs but are sent different constraints")
        sets.extend(parts)
    for names in sets:
        rs = [roles(model, n) for n in names]
        block_gens = []
        failed: Optional[Check] = None
        pair = None
        for a, b, ra, rb in zip(names, names[1:], rs, rs[1:]):
            m = {}
            for role, x in ra.items():
                y = rb[role]
                m[x], m[y] = y, x
            g = ConstPerm(m)
            chk = verify(sig, start, g, labels)
            rules = chk.rules
            if chk.ok:
                chk = _tables_follow(model, g)
            if not chk.ok:
                failed, pair = chk, (a, b)
                break
            block_gens.append(ConstPerm(m, rules))
        if failed is not None:
            reason = failed.reason + (f" ({unsafe})" if unsafe and "label" in failed.reason else "")
            if failed.decl:
                source = spec_source(model, failed.decl)
                if source:
                    reason += f"; in the spec: {source}"
            out.rejected.append(f"{pair[0]} and {pair[1]} have identical specs, but exchanging them does not map "
                                f"the model onto itself: {reason}")
            continue
        out.blocks.append(list(names))
        gens.extend(block_gens)
    if factorial_order(len(b) for b in out.blocks) > limit:
        close_group(gens, limit)   # raises, with the message
    out.group = close_group(gens, limit)
    return out


def spec_source(model: CompiledModel, decl: str) -> Optional[str]:
    """What a compiled declaration comes from, in the spec's terms (None when it is the framework's
    or the compiler's own): a statement's rule names its statement and position, a recipe's tables
    the recipe."""
    site = model.site_of_rule(decl)
    if site is not None:
        where = f" at {site.pos.line}:{site.pos.col}" if site.pos is not None else ""
        return f"{site.agent}.{site.task}.{site.recipe}: '{site.text}'{where}"
    for prefix, what in (("cdom_", "the constraints it sends, in the order it sends them"),
                         ("body_", "its body, in order"), ("end_", "its end block, in order"),
                         ("pre_", "its pre-conditions"), ("rinfo_", "its preference and counts")):
        if decl.startswith(prefix) and decl[len(prefix):] in model.recipes:
            agent, task, recipe = model.recipes[decl[len(prefix):]]
            return f"recipe {agent}.{task}.{recipe}: {what}"
    return None


def names_permuted(sym: Symmetry, text: str) -> Optional[tuple[str, int]]:
    """The first agent of a permuted set that ``text`` names, and its column (1-based), or None."""
    best = None
    for a in sym.agents:
        m = re.search(rf"(?<![\w:]){re.escape(a)}\b", text)
        if m and (best is None or m.start() < best[1] - 1):
            best = (a, m.start() + 1)
    return best
