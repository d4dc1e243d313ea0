"""Incompatible tasks (4.3): two tasks of an agent whose post-conditions cannot hold together.

The logic layer masks, with every task it commits, the tasks incompatible with it, so that no
other constraint can start a task that would undo the committed one's result (a gripper's
``open`` while ``close`` holds a grasp). The paper defines incompatibility by the
post-conditions alone ("their post-conditions lead to inconsistency"), so it is decided once per
spec, here, with Z3 over the agent's variables.

The translation is conservative: what it cannot express (a ``last_error?``, an integer
division, a value of a type only the functional layer knows the inside of is kept only for
``==``) is dropped from the conjunction, which can only make fewer pairs incompatible. The
same function call or field read in two post-conditions is the same value, since both
post-conditions are claimed at the same instant. Each check has a fixed resource limit, so
the answer does not depend on the machine; a check that runs out counts as compatible.
"""

from __future__ import annotations

from typing import Optional

from . import ast as a
from .checks import CheckedSpec
from .pretty import format_expr

__all__ = ["incompatible_tasks"]

#: Z3's deterministic resource limit per satisfiability check
RLIMIT = 2_000_000


class _Untranslatable(Exception):
    """Raised inside the translation: this conjunct is dropped."""


def incompatible_tasks(checked: CheckedSpec) -> dict[tuple[str, str], list[str]]:
    """``(agent, task) -> [task, ...]``: the tasks of the same agent whose post-conditions are
    inconsistent with this one's, in declaration order (a symmetric relation; tasks without one
    are absent)."""
    cached = getattr(checked, "_incompatible", None)
    if cached is not None:
        return cached
    out: dict[tuple[str, str], list[str]] = {}
    for ag in checked.spec.agents:
        posted = [t for t in ag.tasks if t.post]
        if len(posted) < 2:
            continue
        import z3   # only specs with two tasks that have post-conditions pay for it
        tr = _Translator(checked, ag, z3)
        forms = {t.name: tr.conjunction(t.post) for t in posted}
        consistent = {name: _sat(z3, [f]) for name, f in forms.items()}
        for i, t in enumerate(posted):
            for u in posted[i + 1:]:
                if not (consistent[t.name] and consistent[u.name]):
                    continue  # a task whose own post-condition is unsatisfiable is left alone
                if not _sat(z3, [forms[t.name], forms[u.name]]):
                    out.setdefault((ag.name, t.name), []).append(u.name)
                    out.setdefault((ag.name, u.name), []).append(t.name)
    order = {(ag.name, t.name): i for ag in checked.spec.agents for i, t in enumerate(ag.tasks)}
    for (agent, _), names in out.items():
        names.sort(key=lambda n: order[(agent, n)])
    object.__setattr__(checked, "_incompatible", out)
    return out


def _sat(z3, forms) -> bool:
    """False only when Z3 proves the conjunction unsatisfiable within the resource limit."""
    s = z3.Solver()
    s.set("rlimit", RLIMIT)
    s.add(*forms)
    return s.check() != z3.unsat


class _Translator:
    def __init__(self, checked: CheckedSpec, agent: a.Agent, z3):
        self.checked, self.agent, self.z3 = checked, agent, z3
        self.consts: dict[str, object] = {}
        self.sorts: dict[str, object] = {}

    def conjunction(self, exprs) -> object:
        kept = []
        for e in exprs:
            for conj in a.conjuncts(e):
                try:
                    kept.append(self.expr(conj))
                except _Untranslatable:
                    pass
        return self.z3.And(*kept) if kept else self.z3.BoolVal(True)

    # ------------------------------------------------------------ types
    def sort(self, ty: Optional[str]):
        z3 = self.z3
        if ty == "bool":
            return z3.BoolSort()
        if ty == "int":
            return z3.IntSort()
        if ty == "double":
            return z3.RealSort()
        if ty in ("string", "identifier"):
            return z3.StringSort()
        if ty and "::" in ty:
            owner, name = ty.split("::", 1)
            decl = self._type_decl(owner, name)
            if isinstance(decl, a.NewType):
                base = decl.base
                return self.sort(f"{base.agent}::{base.name}" if base.agent else
                                 (base.name if base.name in ("bool", "int", "double", "string", "identifier")
                                  else f"{owner}::{base.name}"))
            if isinstance(decl, a.OpaqueType):
                if ty not in self.sorts:
                    self.sorts[ty] = z3.DeclareSort(ty.replace("::", "__"))
                return self.sorts[ty]
        raise _Untranslatable(ty)

    def _type_decl(self, owner: str, name: str):
        for ag in self.checked.spec.agents:
            if ag.name == owner:
                for td in ag.types:
                    if td.name == name:
                        return td
        return None

    def type_of(self, e: a.Expr) -> Optional[str]:
        try:
            return self.checked.type_of(e)
        except KeyError:
            return None

    # ------------------------------------------------------------ expressions
    def const(self, key: str, ty: Optional[str]):
        if key not in self.consts:
            self.consts[key] = self.z3.Const(key, self.sort(ty))
        return self.consts[key]

    def expr(self, e: a.Expr):
        z3 = self.z3
        if isinstance(e, a.BoolLit):
            return z3.BoolVal(e.value)
        if isinstance(e, a.IntLit):
            return z3.IntVal(e.value)
        if isinstance(e, a.DoubleLit):
            return z3.RealVal(repr(e.value))
        if isinstance(e, a.StringLit):
            return z3.StringVal(e.value)
        if isinstance(e, (a.Name, a.Remote)):
            owner = e.agent if isinstance(e, a.Remote) else self.agent.name
            ty = self.checked.var_types.get((owner, e.name)) or self.type_of(e)
            return self.const(f"{owner}::{e.name}", ty)
        if isinstance(e, (a.Field, a.Call)):
            return self.const(format_expr(e), self.type_of(e))
        if isinstance(e, a.Unary):
            x = self.expr(e.operand)
            return z3.Not(x) if e.op == "!" else -x
        if isinstance(e, a.Binary):
            x, y = self.expr(e.left), self.expr(e.right)
            op = e.op
            if op == "&&":
                return z3.And(x, y)
            if op == "||":
                return z3.Or(x, y)
            if x.sort() != y.sort():
                raise _Untranslatable(op)
            if op == "==":
                return x == y
            if op == "!=":
                return x != y
            if isinstance(x.sort(), z3.DatatypeSortRef) or x.sort().kind() == z3.Z3_UNINTERPRETED_SORT:
                raise _Untranslatable(op)
            if x.sort() == z3.StringSort():
                if op == "+":
                    return z3.Concat(x, y)
                raise _Untranslatable(op)
            if op in ("<", "<=", ">", ">="):
                return {"<": x < y, "<=": x <= y, ">": x > y, ">=": x >= y}[op]
            if op == "+":
                return x + y
            if op == "-":
                return x - y
            if op == "*":
                return x * y
            if op == "/" and x.sort() == z3.RealSort():
                return x / y
            raise _Untranslatable(op)   # integer division truncates toward zero: not modelled
        raise _Untranslatable(type(e).__name__)
