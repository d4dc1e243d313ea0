"""Metric claims: a property that must hold for every run whose durations lie
within the model's bounds, exactly when a stated bound on those bounds holds.

Both directions are decided by Z3 on the model's unrolled task tree, under
the eager execution semantics of ``schedule.py``, with every duration bound
``name.lo``/``name.hi`` a symbolic parameter:

* sufficient: no parameters meeting the bound admit durations that break the
  property, over the claim's generic window with its context (start, waits
  imposed from above) free, hence for every unrolling; and, as a cross-check,
  at every instance of the claim in the model's own unrolling (unsat answers);
* necessary: with the durations outside one instance's window fixed to their
  lower bounds, quantifier elimination over the window's durations gives the
  exact condition Q for that instance to hold in every run; Q implies the
  bound (an unsat answer for Q and not bound). If every run satisfies the
  property, in particular those runs do, so the bound holds.

The same query with the model's own bounds says whether the model, as
configured, has the property; a failure yields a run that breaks it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Optional

import z3

from ..errors import RoarError
from .claims import Ref, build, parse_claim, refs
from .countermodel import format_number
from .model import Claim, Model
from .prover import Outcome
from .schedule import Schedule, Timing, z3_max, z3_min
from .theorems import Obligation
from .unroll import Instance, Node, unroll
from .window import Window

QE_TIMEOUT_MS = 20000


OUTSIDE = "(outside)"


@dataclass
class MetricResult:
    """Each direction: True (proved), False (refuted, see ``witness``) or None (unknown)."""

    claim: Claim
    sufficient: Optional[bool] = None  # for every context of the window, so every unrolling
    sufficient_unrolled: Optional[bool] = None  # on the model's own unrolling (a cross-check)
    necessary: Optional[bool] = None
    holds_as_configured: Optional[bool] = None
    seconds: float = 0.0
    exact_condition: Optional[z3.BoolRef] = None
    witness: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def status(self) -> str:
        if self.sufficient and self.necessary and self.sufficient_unrolled:
            return "proved"
        if False in (self.sufficient, self.necessary, self.sufficient_unrolled):
            return "refuted"
        return "unknown"


class _Symbols:
    """Symbolic duration bounds and per-message durations for one instance."""

    def __init__(self, inst: Instance):
        self.inst = inst
        self.lo = {d: z3.Real(f"{d}.lo") for d in inst.model.durations}
        self.hi = {d: z3.Real(f"{d}.hi") for d in inst.model.durations}
        self.delay = {m: z3.Real(f"delay({m})") for m in inst.nodes}
        self.work = {m: z3.Real(f"work({m})") for m in inst.nodes}

    def param(self, name: str) -> str:
        return self.inst.model.classes[self.inst.nodes[name].cls].work

    def well_formed(self) -> z3.BoolRef:
        return z3.And([z3.And(0 < self.lo[d], self.lo[d] <= self.hi[d]) for d in self.lo])

    def within(self, messages) -> z3.BoolRef:
        out = []
        for m in messages:
            w = self.param(m)
            out += [self.lo["dispatch"] <= self.delay[m], self.delay[m] <= self.hi["dispatch"],
                    self.lo[w] <= self.work[m], self.work[m] <= self.hi[w]]
        return z3.And(out)

    def configured(self) -> z3.BoolRef:
        """The model's own numbers for the bounds."""
        out = []
        for d, (lo, hi) in self.inst.model.durations.items():
            out += [self.lo[d] == z3.RealVal(str(lo)), self.hi[d] == z3.RealVal(str(hi))]
        return z3.And(out)

    def schedule(self, lowest: frozenset = frozenset()) -> Schedule:
        """The symbolic schedule; messages in ``lowest`` take their lower bounds."""
        timing = {}
        for m in self.inst.nodes:
            if m in lowest:
                timing[m] = Timing(self.lo["dispatch"], self.lo[self.param(m)])
            else:
                timing[m] = Timing(self.delay[m], self.work[m])
        return Schedule(self.inst, timing, z3.RealVal(0), z3_max, z3_min)


def _resolve(inst: Instance, start: str, path, k: int) -> Optional[str]:
    here: Optional[str] = start
    for name, index in path:
        if here is None:
            return None
        key = name if index is None else f"{name}[{k + (1 if index == 'k+1' else 0)}]"
        here = inst.nodes[here].slots.get(key)
    return here


def claim_instances(inst: Instance, claim: Claim, tree) -> list[tuple[str, int]]:
    """(message, k) for every message of the claim's class where all its refs exist."""
    paths = [r.path for r in refs(tree)]
    ks = range(1, max(inst.model.sizes.values(), default=1) + 1)
    out = []
    for node in inst.nodes.values():
        if node.cls != claim.about:
            continue
        for k in ks:
            if all(_resolve(inst, node.id, p, k) for p in paths):
                out.append((node.id, k))
                if not any(i for p in paths for _, i in p):
                    break
    return out


def _property(inst: Instance, sched: Schedule, tree, at: tuple[str, int]) -> z3.BoolRef:
    def resolve(ref: Ref) -> z3.ArithRef:
        return sched.value(ref.fn, _resolve(inst, at[0], ref.path, at[1]))

    return build(tree, resolve)


def _bound(sym: _Symbols, claim: Claim) -> z3.BoolRef:
    tree = parse_claim(claim.bound, claim.pos, "bound")

    def resolve(ref: Ref) -> z3.ArithRef:
        name = ref.path[0][0]
        if name not in sym.lo:
            raise RoarError(f"claim {claim.name}: bound names {name}, which is not in [durations]", claim.pos)
        return (sym.lo if ref.fn == "lo" else sym.hi)[name]

    return build(tree, resolve)


def _run_text(model: z3.ModelRef, sched: Schedule, messages: list[str]) -> list[str]:
    def num(e) -> str:
        v = model.eval(e, model_completion=True)
        return format_number(Fraction(v.numerator_as_long(), v.denominator_as_long()))

    return [f"  {m}: handled {num(sched.value('start', m))} .. {num(sched.value('end', m))}" for m in messages]


def _window_messages(inst: Instance, model: Model, claim: Claim, at: tuple[str, int]) -> list[str]:
    """The instance's messages standing for the claim's generic window."""
    members = Window(model, claim, full=True).members
    out = []
    for key in members:
        path = [] if key == "self" else [_split(step) for step in key.split(".")]
        m = _resolve(inst, at[0], path, at[1])
        if m:
            out.append(m)
    return out


def _split(step: str):
    if "[" in step:
        name, index = step[:-1].split("[")
        return name, index
    return step, None


def _window_instance(model: Model, claim: Claim) -> tuple[Instance, Optional[str]]:
    """The claim's generic window as a small instance, and why it cannot stand for
    every context (None when it can: every wait on a window message comes from it)."""
    window = Window(model, claim, full=True)
    parent = {c: p.key for p in window.members.values() for c in p.children.values()}
    nodes = {k: Node(k, m.cls, model.classes[m.cls].kind, parent.get(k), slots=dict(m.children))
             for k, m in window.members.items()}
    constraints, reason = [], None
    for m in window.members.values():
        for con in model.classes[m.cls].constraints:
            first, second = m.children.get(con.first), m.children.get(con.second)
            if first and second:
                constraints.append((con.relation, first, second))
            elif second and not first:
                reason = f"{second} waits on {con.first}, outside the window"
    return Instance(model, nodes, "self", constraints), reason


def _generic_sufficiency(model: Model, claim: Claim, tree, bound_of) -> tuple[Optional[bool], list[str]]:
    """The bound implies the claim whatever the window's context: the start of
    ``self`` and the waits its ancestors impose are free."""
    inst, reason = _window_instance(model, claim)
    if reason:
        return None, [f"no generic proof: {reason}"]
    sym = _Symbols(inst)
    sched = sym.schedule()
    sched.memo[("start", "self")] = z3.Real("start(self)")
    sched.memo[("ach_end", OUTSIDE)] = z3.Real("waits from outside")
    sched.seq_before["self"].append(OUTSIDE)
    prop = _property(inst, sched, tree, ("self", 1))
    achieved = [k[1] for k in sched.memo if k[0].startswith("ach") and k[1] in inst.nodes]
    partial = [g for g in achieved if inst.nodes[g].kind == "goal"
               and len(inst.nodes[g].slots) < len(model.classes[inst.nodes[g].cls].slots)]
    if partial:
        return None, [f"no generic proof: the achievement of {partial[0]} depends on messages outside the window"]
    s = z3.Solver()
    s.add(sym.well_formed(), sym.within(inst.nodes), bound_of(sym), z3.Not(prop))
    answer = s.check()
    if answer == z3.sat:
        return False, ["the bound holds but, in some context, the window breaks the claim:"] + _run_text(
            s.model(), sched, list(inst.nodes))
    return (True if answer == z3.unsat else None), []


def _necessity(inst: Instance, sym: _Symbols, claim: Claim, tree, at: tuple[str, int],
               bound: z3.BoolRef) -> tuple[Optional[bool], z3.BoolRef, list[str]]:
    """The exact condition for the claim at ``at`` in every run (durations outside
    its window at their lower bounds), and whether it implies the bound."""
    window = _window_messages(inst, inst.model, claim, at)
    low = sym.schedule(frozenset(m for m in inst.nodes if m not in window))
    every_run = z3.ForAll([sym.delay[m] for m in window] + [sym.work[m] for m in window],
                          z3.Implies(sym.within(window), _property(inst, low, tree, at)))
    goal = z3.Goal()
    goal.add(sym.well_formed(), every_run)
    exact = z3.Then("qe", "ctx-solver-simplify")(goal).as_expr()
    s = z3.Solver()
    s.set("timeout", QE_TIMEOUT_MS)
    s.add(sym.well_formed(), exact, z3.Not(bound))
    answer = s.check()
    if answer == z3.sat:
        m = s.model()
        values = ", ".join(f"{p} = {m.eval(p, model_completion=True)}"
                           for p in list(sym.lo.values()) + list(sym.hi.values()))
        return False, exact, [f"every run keeps the claim at {at[0]}, yet the bound fails, for {values}"]
    return (True if answer == z3.unsat else None), exact, []


def check_metric(model: Model, claim: Claim, sizes: Optional[dict[str, int]] = None) -> MetricResult:
    """Decide both directions of a metric claim, and the model's own configuration."""
    began = time.perf_counter()
    inst = unroll(model, sizes)
    tree = parse_claim(claim.holds, claim.pos)
    at_all = claim_instances(inst, claim, tree)
    if not at_all:
        raise RoarError(f"claim {claim.name}: no {claim.about} in the unrolled model has all it names", claim.pos)
    result = MetricResult(claim)
    result.sufficient, notes = _generic_sufficiency(model, claim, tree, lambda sym: _bound(sym, claim))
    (result.witness if result.sufficient is False else result.notes).extend(notes)

    sym = _Symbols(inst)
    sched = sym.schedule()
    broken = z3.Or([z3.Not(_property(inst, sched, tree, at)) for at in at_all])
    base = z3.And(sym.well_formed(), sym.within(inst.nodes))
    bound = _bound(sym, claim)
    result.sufficient_unrolled, run = _decide(z3.And(base, bound, broken), sched, inst, claim, tree, at_all)
    result.witness += (["the bound holds but this run breaks the claim:"] + run) if run else []
    result.necessary, result.exact_condition, why = _necessity(inst, sym, claim, tree, at_all[0], bound)
    result.witness += why
    result.holds_as_configured, run = _decide(z3.And(base, sym.configured(), broken), sched, inst, claim, tree,
                                             at_all)
    result.witness += (["with the model's own bounds, this run breaks the claim:"] + run) if run else []
    result.seconds = time.perf_counter() - began
    return result


def _decide(formula: z3.BoolRef, sched: Schedule, inst: Instance, claim: Claim, tree,
            at_all: list[tuple[str, int]]) -> tuple[Optional[bool], list[str]]:
    """True when ``formula`` (a broken claim) is unsatisfiable; else the run, around the first break."""
    s = z3.Solver()
    s.add(formula)
    answer = s.check()
    if answer != z3.sat:
        return (True if answer == z3.unsat else None), []
    model = s.model()
    at = next(a for a in at_all if z3.is_false(model.eval(_property(inst, sched, tree, a), model_completion=True)))
    shown = _window_messages(inst, inst.model, claim, at)
    return False, [f"at {at[0]}:"] + _run_text(model, sched, shown)


def metric_outcome(model: Model, claim: Claim, sizes: Optional[dict[str, int]] = None) -> Outcome:
    """The metric claim as a row of the ``prove`` report."""
    r = check_metric(model, claim, sizes)
    ob = Obligation(f"{model.name}:{claim.name}", f"{claim.says or claim.holds} iff {claim.bound}",
                    claim.expect, (), _not_a_formula, group=model.name)
    directions = [f"sufficient for every context: {_word(r.sufficient)}",
                  f"sufficient on the unrolled model: {_word(r.sufficient_unrolled)}",
                  f"necessary: {_word(r.necessary)}",
                  f"the model's own bounds meet it: {_word(r.holds_as_configured)}"]
    return Outcome(ob, r.status, r.seconds, reason="; ".join(directions + r.notes), details=r.witness)


def _word(value: Optional[bool]) -> str:
    return {True: "yes", False: "no", None: "unknown"}[value]


def _not_a_formula(v, w):
    raise TypeError("a metric claim is decided by check_metric, not as a formula")
