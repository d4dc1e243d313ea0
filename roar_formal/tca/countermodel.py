"""Read a finite Z3 model of the task-tree logic into something a person can check:
each message with its kind and intervals, and the relations at the witness time."""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Optional

import z3

from .vocabulary import Vocabulary

RELATIONS = ("child_of", "desc", "seq_ach", "delay_planning", "precedes")
RELATION_LABEL = {"child_of": "childOf", "desc": "desc", "seq_ach": "SeqAch",
                  "delay_planning": "DelayPlanning", "precedes": "precedes"}
INTERVALS = ("sent", "start", "end", "ach_start", "ach_end")


def format_number(value: Fraction) -> str:
    """Exact, short: ``3``, ``2.5``, ``1/3``."""
    if value.denominator == 1:
        return str(value.numerator)
    den = value.denominator
    for p in (2, 5):
        while den % p == 0:
            den //= p
    if den == 1:
        return f"{float(value):g}" if len(f"{float(value):g}") < 12 else str(value)
    return str(value)


def _number(model: z3.ModelRef, term: z3.ExprRef) -> Optional[Fraction]:
    value = model.eval(term, model_completion=True)
    if z3.is_rational_value(value):
        return Fraction(value.numerator_as_long(), value.denominator_as_long())
    if z3.is_algebraic_value(value):
        return Fraction(value.approx(6).as_fraction())
    return None


@dataclass
class Row:
    element: str
    names: list[str]
    kind: str
    times: dict[str, Optional[Fraction]]

    @property
    def label(self) -> str:
        return f"{self.element} ({', '.join(self.names)})" if self.names else self.element


@dataclass
class Countermodel:
    """A finite model: rows per message, true relation pairs at time ``time``."""

    rows: list[Row]
    time: Optional[Fraction] = None
    relations: dict[str, list[tuple[str, str]]] = field(default_factory=dict)

    def lines(self) -> list[str]:
        """A plain-text rendering (the CLI draws the same data as a table)."""
        out = [f"at time t = {format_number(self.time)}" if self.time is not None else "model:"]
        for r in self.rows:
            ts = ", ".join(f"{k.replace('_', '.')}={format_number(v)}" for k, v in r.times.items() if v is not None)
            out.append(f"  {r.label}: {r.kind}; {ts}")
        for rel, pairs in self.relations.items():
            if pairs:
                out.append(f"  {RELATION_LABEL[rel]}: " + ", ".join(f"({a}, {b})" for a, b in pairs))
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())


def _elements(v: Vocabulary) -> list[z3.ExprRef]:
    sort = v.msg
    return [sort.constructor(i)() for i in range(sort.num_constructors())]


def rank_times(cm: Countermodel) -> Countermodel:
    """Rename every time value by its rank (0, 1, 2, ...).

    The logic compares time points and never adds them, so an order-preserving
    renaming of the time line maps a model to a model; ranks read far better
    than the dyadic fractions Z3 picks.
    """
    values = sorted({x for r in cm.rows for x in r.times.values() if x is not None} | (
        {cm.time} if cm.time is not None else set()))
    rank = {x: Fraction(i) for i, x in enumerate(values)}
    for r in cm.rows:
        r.times = {k: (rank[x] if x is not None else None) for k, x in r.times.items()}
    if cm.time is not None:
        cm.time = rank[cm.time]
    return cm


def read_countermodel(model: z3.ModelRef, v: Vocabulary, witnesses: dict[str, z3.ExprRef],
                      order_only: bool = True) -> Countermodel:
    """Tabulate ``model`` over the finite message sort of ``v``; with
    ``order_only`` (formulas that only compare times) times are shown as ranks."""
    elements = _elements(v)
    names: dict[str, list[str]] = {str(e): [] for e in elements}
    for name, const in witnesses.items():
        if name != "t":
            names[str(model.eval(const, model_completion=True))].append(name)
    rows = [
        Row(str(e), names[str(e)], str(model.eval(v.kind(e), model_completion=True)),
            {k: _number(model, getattr(v, k)(e)) for k in INTERVALS})
        for e in elements
    ]
    cm = Countermodel(rows)
    if "t" in witnesses:
        t = witnesses["t"]
        cm.time = _number(model, t)
        for rel in RELATIONS:
            if rel == "precedes" and len(elements) > 5:
                continue  # derivable from the intervals; too many pairs to read
            cm.relations[rel] = [
                (str(a), str(b)) for a in elements for b in elements
                if z3.is_true(model.eval(getattr(v, rel)(a, b, t), model_completion=True))
            ]
    return rank_times(cm) if order_only else cm
