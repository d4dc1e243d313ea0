"""The signature of the TCA task-tree logic, as Z3 declarations.

Simmons writes ``Holds(p(x), t)`` for "p(x) holds at time t"; here every
time-dependent predicate takes its time point as a last argument, so
``Holds(childOf(p, c), t)`` is ``childOf(p, c, t)``. Time is the reals.

The message sort is either uninterpreted (proofs: valid in every structure)
or a finite enumeration (model search: Z3 finds countermodels reliably when
it can enumerate the messages; a finite model is a genuine countermodel).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import z3

KINDS = ("query", "goal", "command", "monitor")


@lru_cache(maxsize=None)
def kind_sort() -> tuple[z3.DatatypeSortRef, tuple[z3.ExprRef, ...]]:
    """The message kinds (one enumeration shared by every vocabulary)."""
    sort, values = z3.EnumSort("Kind", list(KINDS))
    return sort, tuple(values)


@lru_cache(maxsize=None)
def message_sort(domain_size: int | None) -> z3.SortRef:
    """``Msg`` uninterpreted, or ``MsgN`` with exactly N elements ``e0..e(N-1)``."""
    if domain_size is None:
        return z3.DeclareSort("Msg")
    sort, _ = z3.EnumSort(f"Msg{domain_size}", [f"e{i}" for i in range(domain_size)])
    return sort


@dataclass(frozen=True)
class Vocabulary:
    """Sorts, kinds, interval functions and time-indexed relations of the logic."""

    msg: z3.SortRef
    kind_sort: z3.SortRef
    kinds: dict[str, z3.ExprRef]
    kind: z3.FuncDeclRef
    sent: z3.FuncDeclRef
    start: z3.FuncDeclRef
    end: z3.FuncDeclRef
    ach_start: z3.FuncDeclRef
    ach_end: z3.FuncDeclRef
    send: z3.FuncDeclRef
    child_of: z3.FuncDeclRef
    active: z3.FuncDeclRef
    completed: z3.FuncDeclRef
    scheduable: z3.FuncDeclRef
    precedes: z3.FuncDeclRef
    achieving: z3.FuncDeclRef
    desc: z3.FuncDeclRef
    via: z3.FuncDeclRef
    seq_ach: z3.FuncDeclRef
    delay_planning: z3.FuncDeclRef

    @property
    def finite(self) -> bool:
        return isinstance(self.msg, z3.DatatypeSortRef)

    def msg_const(self, name: str) -> z3.ExprRef:
        return z3.Const(name, self.msg)

    def is_kind(self, m: z3.ExprRef, *names: str) -> z3.BoolRef:
        return z3.Or([self.kind(m) == self.kinds[n] for n in names])

    def not_query(self, m: z3.ExprRef) -> z3.BoolRef:
        return self.kind(m) != self.kinds["query"]

    def nested(self, outer: z3.ExprRef, inner: z3.ExprRef) -> z3.BoolRef:
        """The achievement interval of ``inner`` lies within that of ``outer``."""
        return z3.And(self.ach_start(outer) <= self.ach_start(inner), self.ach_end(inner) <= self.ach_end(outer))


@lru_cache(maxsize=None)
def vocabulary(domain_size: int | None = None) -> Vocabulary:
    """The vocabulary over an uninterpreted message sort, or a finite one of ``domain_size``."""
    msg = message_sort(domain_size)
    ksort, kvalues = kind_sort()
    real, boolean = z3.RealSort(), z3.BoolSort()

    def fn(name: str, *sig: z3.SortRef) -> z3.FuncDeclRef:
        return z3.Function(name, *sig)

    return Vocabulary(
        msg=msg,
        kind_sort=ksort,
        kinds=dict(zip(KINDS, kvalues)),
        kind=fn("kind", msg, ksort),
        sent=fn("sent", msg, real),
        start=fn("start", msg, real),
        end=fn("end", msg, real),
        ach_start=fn("ach.start", msg, real),
        ach_end=fn("ach.end", msg, real),
        send=fn("send", msg, msg, real, boolean),
        child_of=fn("childOf", msg, msg, real, boolean),
        active=fn("active", msg, real, boolean),
        completed=fn("completed", msg, real, boolean),
        scheduable=fn("scheduable", msg, real, boolean),
        precedes=fn("precedes", msg, msg, real, boolean),
        achieving=fn("achieving", msg, real, boolean),
        desc=fn("desc", msg, msg, real, boolean),
        via=fn("desc.via", msg, msg, real, msg),
        seq_ach=fn("SeqAch", msg, msg, real, boolean),
        delay_planning=fn("DelayPlanning", msg, msg, real, boolean),
    )
