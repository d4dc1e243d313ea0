"""Static checks of a ROAR spec: names, visibility, where clauses, types.

:func:`check_spec` examines the whole spec, collects every problem as a
:class:`CheckError` (with a position and a short ``code``), and raises one
:class:`SpecCheckError` listing them all, the first (by position) as its
message and the others as notes; a spec without problems comes back as a
:class:`CheckedSpec`, the types the compiler needs included. :func:`spec_errors` returns the list
instead. :func:`check_request` does the same for a request (a constraint sent
from outside, e.g. ``demo_loco::pos == demo_loco::goal where demo_loco::goal == 5``).

Types are strings: the base types (``bool``, ``int``, ``double``, ``string``,
``identifier``) and ``agent::T`` for a type declared by an agent; ``newtype``
types are distinct from their base. There is no implicit conversion; in
particular ``int`` and ``double`` never mix (a double literal is ``1.0``). A
string literal fits both ``string`` and ``identifier``.

Error codes (``CheckError.code``): ``unknown-agent``, ``not-imported``,
``private``, ``unknown-variable``, ``unknown-type``, ``unknown-function``,
``ambiguous``, ``task-call``, ``duplicate``, ``shadow``, ``where``,
``constraint-agents``, ``set-remote``, ``set-handle``, ``abort``,
``handle-value``, ``type``, ``int-double``, ``not-bool``, ``arity``,
``field``, ``last-error``, ``no-recipe``, ``prefer``.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Optional, Union

from ..errors import ErrorList, Pos, TypeError_
from . import ast as a
from .parser import parse_constraint
from .pretty import format_expr

__all__ = ["CheckError", "SpecCheckError", "CheckedSpec", "check_spec", "spec_errors", "check_request",
           "request_errors", "typed_request"]

Ty = Optional[str]  # None: unknown (an error was reported already, or a logic variable)
STRLIT = "<string literal>"
HANDLE = "<ensure handle>"
_NUMERIC = ("int", "double")


class CheckError(TypeError_):
    """One problem found by the static checks."""

    def __init__(self, message: str, pos: Optional[Pos], code: str):
        super().__init__(message, pos)
        self.code = code


class SpecCheckError(ErrorList, TypeError_):
    """Every problem of a spec: the first as the message, the others as notes; all in ``errors``."""


def _key(e: CheckError):
    p = e.pos or Pos("", 0, 0)
    return (p.file, p.line, p.col, e.message)


def _show(t: Ty) -> str:
    if t == STRLIT:
        return "string"
    if t == HANDLE:
        return "an ensure handle"
    return str(t)


def _compat(x: Ty, y: Ty) -> bool:
    if x is None or y is None or x == y:
        return True
    return {x, y} <= {STRLIT, "string", "identifier"} and STRLIT in (x, y)


def _fmt(e: a.Expr) -> str:
    text = format_expr(e)
    return text if len(text) <= 60 else text[:57] + "..."


#: statements written like a call (`ensrue(x == 1)` is a call of an unknown function)
_CALL_KEYWORDS = ("make", "ensure", "wait", "assert", "abort")


def _did_you_mean(name: str, candidates) -> str:
    close = difflib.get_close_matches(name, sorted(set(candidates)), n=1, cutoff=0.75)
    return f"; did you mean '{close[0]}'?" if close else ""


def _at(p: Pos, here: Optional[Pos]) -> str:
    """A position relative to ``here``: 'line:col' in the same file, else the full position."""
    return f"{p.line}:{p.col}" if here is not None and p.file == here.file else str(p)


@dataclass
class _Scope:
    agent: Optional[a.Agent]  # None for a request
    visible: frozenset
    locals: dict = field(default_factory=dict)  # name -> (type, kind 'let'|'handle', pos)
    logic: bool = False  # capitalised unknown names are logic variables (rules)
    last_error: bool = False  # last_error?(...) allowed (recipe pre-conditions)
    aborted: dict = field(default_factory=dict)  # handle -> where this block aborts it

    @property
    def name(self) -> Optional[str]:
        return self.agent.name if self.agent else None

    def fresh(self, **kw) -> "_Scope":
        s = _Scope(self.agent, self.visible, {}, self.logic, self.last_error)
        for k, v in kw.items():
            setattr(s, k, v)
        return s


class _Checker:
    def __init__(self, spec: a.Spec):
        self.spec = spec
        self.errors: list[CheckError] = []
        self.agents: dict[str, a.Agent] = {}
        self.var_types: dict[tuple[str, str], Ty] = {}
        self.fn_sigs: dict[tuple[str, str], tuple[Ty, list[Ty]]] = {}
        self.structs: dict[str, dict[str, Ty]] = {}
        self.typed: dict[int, tuple[a.Expr, Ty]] = {}   # id(expr) -> (expr, its type)
        for ag in spec.agents:
            self.agents.setdefault(ag.name, ag)

    # -- reporting -----------------------------------------------------------
    def err(self, code: str, pos: Optional[Pos], msg: str) -> None:
        self.errors.append(CheckError(msg, pos, code))

    def result(self) -> list[CheckError]:
        seen, out = set(), []
        for e in sorted(self.errors, key=_key):
            k = (e.pos, e.message)
            if k not in seen:
                seen.add(k)
                out.append(e)
        return out

    def _dups(self, items, what: str, owner: str) -> None:
        first: dict[str, a.Node] = {}
        for it in items:
            if it.name in first:
                p = first[it.name].pos
                self.err("duplicate", it.pos, f"duplicate {what} '{it.name}' in {owner} "
                                              f"(first declared at {_at(p, it.pos)})")
            else:
                first[it.name] = it

    # -- agents --------------------------------------------------------------
    def agent_ref(self, name: str, pos: Pos, sc: _Scope, what: str = "") -> Optional[a.Agent]:
        """Look an agent up from scope ``sc``, reporting unknown or not imported agents."""
        target = self.agents.get(name)
        if target is None:
            known = ", ".join(sorted(self.agents)) or "none"
            self.err("unknown-agent", pos, f"unknown agent '{name}'{what} (the agents are: {known})"
                     + _did_you_mean(name, self.agents))
            return None
        if name not in sc.visible:
            me = sc.agent
            if me is not None and me.layout == "hyper":
                hint = f"add 'import \"{name}.ability\"' at the top of {me.name}.ability"
            else:
                hint = "import the file that declares it"
            self.err("not-imported", pos, f"agent '{name}' is not imported by agent '{sc.name}'; {hint}")
        return target

    def run(self) -> list[CheckError]:
        if not self.spec.agents:
            # (an empty file, or one of comments only: every request would name an unknown agent)
            self.err("no-agent", self.spec.pos, "the spec declares no agent: write 'NAME = ability { ... }'")
        first: dict[str, a.Agent] = {}
        for ag in self.spec.agents:
            if ag.name in first:
                p = first[ag.name].pos
                self.err("duplicate", ag.pos, f"duplicate agent '{ag.name}' (first declared at {_at(p, ag.pos)})")
            else:
                first[ag.name] = ag
        for ag in first.values():
            self.declarations(ag)
        for ag in first.values():
            self.bodies(ag)
        return self.result()

    def scope(self, ag: a.Agent) -> _Scope:
        return _Scope(ag, self.spec.visible(ag))

    def resolve_type(self, t: a.TypeRef, sc: _Scope) -> Ty:
        ag = sc.agent
        if t.agent is not None:
            owner = self.agent_ref(t.agent, t.pos, sc, f" in type '{t}'")
            if owner is None:
                return None
            if owner.type_decl(t.name) is None:
                self.err("unknown-type", t.pos, f"agent '{owner.name}' declares no type '{t.name}'")
                return None
            return f"{owner.name}::{t.name}"
        if t.name in a.BASE_TYPES:
            return t.name
        if ag is not None and ag.type_decl(t.name) is not None:
            return f"{ag.name}::{t.name}"
        owners = [b.name for b in self.spec.agents
                  if b.name in sc.visible and b is not ag and b.type_decl(t.name) is not None]
        if len(owners) == 1:
            return f"{owners[0]}::{t.name}"
        if len(owners) > 1:
            self.err("ambiguous", t.pos, f"type '{t.name}' is declared by agents {', '.join(owners)}; "
                                         f"write {owners[0]}::{t.name}")
            return None
        self.err("unknown-type", t.pos, f"unknown type '{t.name}' (the base types are "
                                        f"{', '.join(a.BASE_TYPES)}; others are declared in an export)")
        return None

    def declarations(self, ag: a.Agent) -> None:
        """Names and types of the agent's declarations (before any body refers to them)."""
        sc = self.scope(ag)
        owner = f"agent '{ag.name}'"
        self._dups(ag.vars, "variable", owner)
        self._dups(ag.types, "type", owner)
        self._dups(ag.functions, "function", owner)
        self._dups(ag.rules, "rule", owner)
        self._dups(ag.tasks, "task", owner)
        for f in ag.functions:
            if ag.task(f.name) is not None:
                self.err("duplicate", f.pos, f"'{f.name}' is both a function and a task of {owner}")
        for t in ag.types:
            q = f"{ag.name}::{t.name}"
            if isinstance(t, a.StructType):
                self._dups(t.fields, "field", f"struct '{t.name}'")
                self.structs[q] = {fd.name: self.resolve_type(fd.type, sc) for fd in reversed(t.fields)}
            elif isinstance(t, a.NewType):
                self.resolve_type(t.base, sc)
        for v in ag.vars:
            self.var_types.setdefault((ag.name, v.name), self.resolve_type(v.type, sc))
        for f in ag.functions:
            sig = (self.resolve_type(f.result, sc), [self.resolve_type(p.type, sc) for p in f.params])
            self.fn_sigs.setdefault((ag.name, f.name), sig)

    def bodies(self, ag: a.Agent) -> None:
        sc = self.scope(ag)
        for v in ag.vars:
            self.var_init(ag, v, sc)
        for r in ag.rules:
            rs = sc.fresh(logic=True)
            for e in r.premises + r.conclusions:
                self.cond(e, rs, f"rule '{r.name}'")
            self.rule_variables(ag, r)
        for t in ag.tasks:
            self.task(ag, t, sc)

    def rule_variables(self, ag: a.Agent, r: a.Rule) -> None:
        """A rule's logic variables stand for expressions: each conclusion variable must be bound
        by a premise (else the rule would conclude anything), a conjunct may not be a bare
        variable, and each variable has one type across the rule."""
        def logic(n: a.Node) -> bool:
            return isinstance(n, a.Name) and n.name[:1].isupper() and ag.var(n.name) is None
        what = f"rule '{r.name}'"
        bound = {n.name for e in r.premises for n in a.walk(e) if logic(n)}
        told: set[str] = set()
        for e in r.conclusions:   # (inside a call, `|- distance(A, A) == 0.0`, a variable is fine)
            for n in a.walk(e):
                if not isinstance(n, a.Binary) or n.op not in a.COMPARISONS:
                    continue
                for x in (n.left, n.right):
                    if logic(x) and x.name not in bound and x.name not in told:
                        told.add(x.name)
                        self.err("rule-unbound", x.pos,
                                 f"{what}: logic variable '{x.name}' is a whole side of a conclusion but "
                                 f"does not occur in a premise, so the rule would conclude this comparison "
                                 f"of anything")
        for e in r.premises + r.conclusions:
            for c in a.conjuncts(e):
                inner = c.operand if isinstance(c, a.Unary) and c.op == "!" else c
                if logic(inner):
                    self.err("rule-bare-variable", c.pos,
                             f"{what}: '{_fmt(c)}' is a bare logic variable; a premise or conclusion is a "
                             f"comparison or a bool variable of the agent")
        seen: dict[str, tuple[str, Pos]] = {}
        for e in r.premises + r.conclusions:
            for n in a.walk(e):
                if not isinstance(n, a.Binary) or n.op in a.LOGIC_OPS:
                    continue
                for x, y in ((n.left, n.right), (n.right, n.left)):
                    t = self.typed.get(id(y), (None, None))[1]
                    if not logic(x) or t is None:
                        continue
                    if x.name not in seen:
                        seen[x.name] = (t, x.pos)
                    elif seen[x.name][0] != t:
                        t0, p0 = seen[x.name]
                        self.err("rule-variable-type", x.pos,
                                 f"{what}: logic variable '{x.name}' is {_show(t)} here but {_show(t0)} at "
                                 f"{_at(p0, x.pos)}; a logic variable has one type in a rule")

    def var_init(self, ag: a.Agent, v: a.Var, sc: _Scope) -> None:
        init = v.init
        if init is None:
            return
        if isinstance(init, a.Call) and init.agent in (None, ag.name) and ag.task(init.name) \
                and ag.function(init.name) is None:
            if init.args:
                self.err("arity", init.pos, f"'{init.name}' is a task of agent '{ag.name}' (run on each "
                                            f"read of '{v.name}'); a task takes no arguments")
            return
        t = self.ty(init, sc)
        vt = self.var_types.get((ag.name, v.name))
        if not _compat(vt, t):
            self.err(self._mix(vt, t), init.pos,
                     f"'{v.name}' is {_show(vt)} but its initial value '{_fmt(init)}' is {_show(t)}"
                     + self._mix_hint(vt, t))

    # -- tasks and recipes -------------------------------------------------
    def task(self, ag: a.Agent, t: a.Task, sc: _Scope) -> None:
        for e in t.pre:
            self.cond(e, sc, f"a pre-condition of task '{t.name}'")
        for e in t.post:
            self.cond(e, sc, f"a post-condition of task '{t.name}'")
        if not t.recipes:
            hint = (f"; add a recipe file in {ag.name}/{t.name}/" if ag.layout == "hyper"
                    else "; add one in its 'recipes = { ... }'")
            self.err("no-recipe", t.pos, f"task '{t.name}' of agent '{ag.name}' has no recipe{hint}")
        self._dups(t.recipes, "recipe", f"task '{t.name}'")
        for r in t.recipes:
            self.recipe(r, sc)

    def recipe(self, r: a.Recipe, sc: _Scope) -> None:
        pre = sc.fresh(last_error=True)
        for e in r.pre:
            self.cond(e, pre, f"a pre-condition of recipe '{r.name}'")
        for e in r.post:
            self.cond(e, sc.fresh(), f"a post-condition of recipe '{r.name}'")
        if r.prefer is not None:
            p = r.prefer
            lit = isinstance(p, a.IntLit) or (isinstance(p, a.Unary) and p.op == "-" and isinstance(p.operand, a.IntLit))
            if not lit:
                t = self.ty(p, sc.fresh())
                what = f"; '{_fmt(p)}' is {_show(t)}" if t not in (None, "int") else ""
                self.err("prefer", p.pos, f"prefer must be an integer literal such as 2{what}")
        self.block(r.body, sc.fresh())
        self.block(r.end, sc.fresh())

    def block(self, stmts: tuple[a.Stmt, ...], sc: _Scope) -> None:
        for s in stmts:
            self.stmt(s, sc)

    def bind(self, name: str, ty: Ty, kind: str, pos: Pos, sc: _Scope) -> None:
        if name in sc.locals:
            p = sc.locals[name][2]
            self.err("duplicate", pos, f"'{name}' is already bound by let at {_at(p, pos)}")
        elif sc.agent is not None and sc.agent.var(name) is not None:
            self.err("shadow", pos, f"let '{name}' would hide the context variable '{name}' of agent "
                                    f"'{sc.agent.name}'; choose another name")
        sc.locals[name] = (ty, kind, pos)

    def stmt(self, s: a.Stmt, sc: _Scope) -> None:
        if isinstance(s, a.Let):
            self.bind(s.name, self.ty(s.value, sc), "let", s.pos, sc)
        elif isinstance(s, a.Make):
            self.constraint(s.constraint, sc)
        elif isinstance(s, a.Ensure):
            self.constraint(s.constraint, sc)
            self.period(s.period, sc)
            if s.handle:
                self.bind(s.handle, HANDLE, "handle", s.pos, sc)
        elif isinstance(s, a.Set):
            self.set_stmt(s, sc)
        elif isinstance(s, (a.Wait, a.Assert)):
            kw = "wait" if isinstance(s, a.Wait) else "assert"
            self.cond(s.cond, sc, f"the condition of {kw}")
            self.period(s.period, sc)
        elif isinstance(s, a.Abort):
            bound = sc.locals.get(s.handle)
            if bound is None:
                self.err("abort", s.pos, f"abort {s.handle}: no 'let {s.handle} ensure(...)' before it in "
                                         f"this block binds '{s.handle}'")
            elif bound[1] != "handle":
                self.err("abort", s.pos, f"abort {s.handle}: '{s.handle}' is bound by let to a value; abort "
                                         f"takes a name bound by 'let {s.handle} ensure(...)'")
            elif s.handle in sc.aborted:
                # the request is released by the first abort: a second one would wait for a request
                # the activation no longer owns (the recipe would stop there for good)
                self.err("abort", s.pos, f"abort {s.handle}: '{s.handle}' is aborted already at "
                                         f"{_at(sc.aborted[s.handle], s.pos)}; a handle is aborted once")
            else:
                sc.aborted[s.handle] = s.pos
        elif isinstance(s, a.ExprStmt):
            self.ty(s.expr, sc)

    def set_stmt(self, s: a.Set, sc: _Scope) -> None:
        target = s.target
        vt: Ty = None
        me = sc.agent
        if isinstance(target, a.Remote) and (me is None or target.agent != me.name):
            owner = self.spec.agent(target.agent)
            v = owner.var(target.name) if owner is not None else None
            if v is not None and v.access == "controllable":
                how = f"write a controllable variable of another agent with 'make(... where {target} == value)'"
            elif v is not None:
                how = (f"it is {v.access}: only its agent writes it; send '{target.agent}' a constraint on it, "
                       f"'make({target} == value)', for one of its tasks to establish")
            else:
                how = f"agent '{target.agent}' has no such variable" if owner is not None else "no such agent"
            self.err("set-remote", target.pos,
                     f"set changes only this agent's own variables; '{target}' belongs to agent "
                     f"'{target.agent}' ({how})")
            self.ty(s.value, sc)
            return
        name = target.name
        if isinstance(target, a.Name) and name in sc.locals:
            vt, kind, _ = sc.locals[name]
            if kind == "handle":
                self.err("set-handle", target.pos, f"'{name}' is an ensure handle; it can only be aborted")
                return
        elif me is not None and me.var(name) is not None:
            vt = self.var_types.get((me.name, name))
        else:
            self.err("unknown-variable", target.pos,
                     f"unknown variable '{name}' in agent '{sc.name}'"
                     + _did_you_mean(name, [x.name for x in me.vars]) if me else
                     f"unknown variable '{name}'")
        t = self.ty(s.value, sc)
        if not _compat(vt, t):
            self.err(self._mix(vt, t), s.value.pos, f"cannot set '{name}' ({_show(vt)}) to "
                                                    f"'{_fmt(s.value)}' ({_show(t)})" + self._mix_hint(vt, t))

    def period(self, e: Optional[a.Expr], sc: _Scope) -> None:
        if e is None:
            return
        t = self.ty(e, sc)
        if t is not None and t != "int":
            self.err(self._mix("int", t), e.pos,
                     f"a period is an int number of milliseconds; '{_fmt(e)}' is {_show(t)}")

    def cond(self, e: a.Expr, sc: _Scope, what: str) -> None:
        t = self.ty(e, sc)
        if t is not None and t != "bool":
            self.err("not-bool", e.pos, f"{what} must be a bool condition; '{_fmt(e)}' is {_show(t)}")

    # -- constraints -------------------------------------------------------
    def constraint(self, c: a.Constraint, sc: _Scope) -> None:
        self.cond(c.expr, sc, "a constraint")
        me = sc.name
        named = c.agents()
        targets = set(named) if named else ({me} if me else set())
        target: Optional[a.Agent] = None
        if len(targets) > 1:
            self.err("constraint-agents", c.pos, f"a constraint is sent to one agent, but this one names "
                                                 f"{', '.join(sorted(targets))}")
        elif not targets:
            self.err("constraint-agents", c.pos, "a request names the agent it is sent to: write 'agent::var'")
        else:
            target = self.agents.get(next(iter(targets)))
        for p in c.where:
            before = len(self.errors)
            lt, rt = self.ty(p.left, sc), self.ty(p.right, sc)
            if target is None or len(self.errors) > before:
                continue
            writes = [side for side in (p.left, p.right) if self._controllable(side, target, sc)]
            pair = f"{_fmt(p.left)} == {_fmt(p.right)}"
            if len(writes) == 2:
                self.err("where", p.pos, f"both sides of '{pair}' are controllable variables of agent "
                                         f"'{target.name}'; one side is the variable to write, the other its value")
            elif not writes:
                other = next((v for v in (self._target_var(side, target, sc) for side in (p.left, p.right))
                              if v is not None), None)
                if other is not None:
                    self.err("where", p.pos, f"'{target.name}::{other.name}' is {other.access}, not controllable: "
                                             f"a where pair writes a controllable variable of agent '{target.name}'")
                else:
                    self.err("where", p.pos, f"'{pair}' writes no controllable variable of agent "
                                             f"'{target.name}': one side of a where pair must be "
                                             f"'{target.name}::var' with var controllable")
            elif not _compat(lt, rt) and not self._literal_of_newtype(p, lt, rt, writes[0]):
                self.err(self._mix(lt, rt), p.pos, f"the where pair '{pair}' sets {_show(lt)} "
                                                   f"to {_show(rt)}" + self._mix_hint(lt, rt))

    def _literal_of_newtype(self, p: a.WherePair, lt: Ty, rt: Ty, var_side: a.Expr) -> bool:
        """A where pair giving a newtype variable a literal of its representation (``base::goal ==
        3.0`` for a ``meters = newtype double``): a literal has no type of its own, and there is no
        other way to write a newtype's value in a request."""
        value = p.right if var_side is p.left else p.left
        var_t, val_t = (lt, rt) if var_side is p.left else (rt, lt)
        lit = value.operand if isinstance(value, a.Unary) and value.op == "-" else value
        if not isinstance(lit, (a.IntLit, a.DoubleLit, a.BoolLit, a.StringLit)) or not isinstance(var_t, str) \
                or "::" not in var_t:
            return False
        owner, _, name = var_t.partition("::")
        ag = self.agents.get(owner)
        decl = ag.type_decl(name) if ag is not None else None
        if not isinstance(decl, a.NewType):
            return False
        return _compat(self.resolve_type(decl.base, self.scope(ag)), val_t)

    def _target_var(self, side: a.Expr, target: a.Agent, sc: _Scope) -> Optional[a.Var]:
        if isinstance(side, a.Remote) and side.agent == target.name:
            return target.var(side.name)
        if isinstance(side, a.Name) and sc.agent is target and side.name not in sc.locals:
            return target.var(side.name)
        return None

    def _controllable(self, side: a.Expr, target: a.Agent, sc: _Scope) -> bool:
        v = self._target_var(side, target, sc)
        return v is not None and v.access == "controllable"

    # -- expressions -------------------------------------------------------
    @staticmethod
    def _mix(x: Ty, y: Ty) -> str:
        return "int-double" if {x, y} == {"int", "double"} else "type"

    @staticmethod
    def _mix_hint(x: Ty, y: Ty) -> str:
        if {x, y} == {"int", "double"}:
            return "; int and double never mix: an int is written 1, a double 1.0"
        return ""

    def ty(self, e: a.Expr, sc: _Scope) -> Ty:
        """The type of ``e`` in scope ``sc``, recorded for the compiler (:class:`CheckedSpec`)."""
        t = self._type(e, sc)
        self.typed[id(e)] = (e, t)
        return t

    def _type(self, e: a.Expr, sc: _Scope) -> Ty:
        if isinstance(e, a.BoolLit):
            return "bool"
        if isinstance(e, a.IntLit):
            return "int"
        if isinstance(e, a.DoubleLit):
            return "double"
        if isinstance(e, a.StringLit):
            return STRLIT
        if isinstance(e, a.Name):
            return self.name(e, sc)
        if isinstance(e, a.Remote):
            return self.remote(e, sc)
        if isinstance(e, a.Call):
            return self.call(e, sc)
        if isinstance(e, a.Field):
            return self.field(e, sc)
        if isinstance(e, a.Unary):
            return self.unary(e, sc)
        if isinstance(e, a.Binary):
            return self.binary(e, sc)
        if isinstance(e, a.LastError):
            if not sc.last_error:
                self.err("last-error", e.pos, "last_error?(...) may only be used in the pre-conditions of a recipe")
            self.cond(e.constraint, sc.fresh(last_error=False), "the argument of last_error?")
            return "bool"
        raise TypeError(f"not an expression: {e!r}")  # pragma: no cover

    def name(self, e: a.Name, sc: _Scope) -> Ty:
        if e.name in sc.locals:
            t, kind, _ = sc.locals[e.name]
            if kind == "handle":
                self.err("handle-value", e.pos, f"'{e.name}' is an ensure handle; it can only be aborted")
                return None
            return t
        ag = sc.agent
        if ag is not None and ag.var(e.name) is not None:
            return self.var_types.get((ag.name, e.name))
        if sc.logic and e.name[:1].isupper():
            return None
        if ag is None:
            self.err("unknown-variable", e.pos, f"unknown variable '{e.name}': a request names its "
                                                f"variables with their agent, 'agent::{e.name}'")
        elif e.name.lower() in ("true", "false"):
            self.err("unknown-variable", e.pos, f"unknown variable '{e.name}' in agent '{ag.name}' (the booleans "
                                                f"are written '{e.name.lower()}' and '{'false' if e.name.lower() == 'true' else 'true'}')")
        else:
            self.err("unknown-variable", e.pos, f"unknown variable '{e.name}' in agent '{ag.name}'"
                     + _did_you_mean(e.name, [x.name for x in ag.vars] + list(sc.locals)))
        return None

    def remote(self, e: a.Remote, sc: _Scope) -> Ty:
        target = self.agent_ref(e.agent, e.pos, sc)
        if target is None:
            return None
        v = target.var(e.name)
        if v is None:
            self.err("unknown-variable", e.pos, f"agent '{e.agent}' has no variable '{e.name}'"
                     + _did_you_mean(e.name, [x.name for x in target.vars]))
            return None
        if v.access == "private" and e.agent != sc.name:
            self.err("private", e.pos, f"'{e}' is private to agent '{e.agent}'; other agents may use only its "
                                       f"controllable and readable variables")
            return None
        return self.var_types.get((target.name, e.name))

    def call(self, e: a.Call, sc: _Scope) -> Ty:
        arg_types = [self.ty(x, sc) for x in e.args]
        ag = sc.agent
        sig = None
        if e.agent is not None:
            owner = self.agent_ref(e.agent, e.pos, sc)
            if owner is None:
                return None
            if owner.function(e.name) is None:
                if owner.task(e.name) is not None:
                    self.err("task-call", e.pos, self._task_call_msg(e.qualified, owner.name))
                else:
                    self.err("unknown-function", e.pos, f"agent '{owner.name}' exports no function '{e.name}'")
                return None
            sig = self.fn_sigs.get((owner.name, e.name))
        else:
            found = self.spec.resolve_function(ag, e) if ag is not None else [
                (b.name, b.function(e.name)) for b in self.spec.agents if b.function(e.name)]
            if ag is not None:
                found = [(o, f) for o, f in found if o in sc.visible]
            if len(found) > 1:
                owners = ", ".join(o for o, _ in found)
                self.err("ambiguous", e.pos, f"function '{e.name}' is exported by agents {owners}; "
                                             f"write {found[0][0]}::{e.name}(...)")
                return None
            if found:
                sig = self.fn_sigs.get((found[0][0], e.name))
            elif e.name in a.BUILTINS:
                res, params = a.BUILTINS[e.name]
                sig = (res, list(params))
            elif ag is not None and ag.task(e.name) is not None:
                self.err("task-call", e.pos, self._task_call_msg(e.name, ag.name))
                return None
            elif e.name in _CALL_KEYWORDS:
                self.err("unknown-function", e.pos, f"'{e.name}(...)' is a statement, not a function: it has no value "
                                                    f"to use in an expression" + (
                                                        "; only an ensure gives a handle, 'let h ensure(...)'"
                                                        if e.name == "make" else ""))
                return None
            else:
                names = [f.name for b in self.spec.agents if b.name in sc.visible for f in b.functions]
                self.err("unknown-function", e.pos, f"unknown function '{e.name}'"
                         + (f": agent '{ag.name}' declares no such function or task, and no imported "
                            f"agent exports one" if ag is not None else "")
                         + _did_you_mean(e.name, names + list(a.BUILTINS) + list(_CALL_KEYWORDS)))
                return None
        if sig is None:  # pragma: no cover - every declared function has a signature
            return None
        res, params = sig
        if len(params) != len(arg_types):
            n = len(params)
            self.err("arity", e.pos, f"function '{e.qualified}' takes {n} argument{'s' if n != 1 else ''}, "
                                     f"not {len(arg_types)}")
            return res
        for i, (x, pt, at) in enumerate(zip(e.args, params, arg_types), 1):
            if not _compat(pt, at):
                self.err(self._mix(pt, at), x.pos, f"argument {i} of '{e.qualified}' must be {_show(pt)}; "
                                                   f"'{_fmt(x)}' is {_show(at)}" + self._mix_hint(pt, at))
        return res

    @staticmethod
    def _task_call_msg(name: str, agent: str) -> str:
        return (f"'{name}' is a task of agent '{agent}', not a function; a task runs when a constraint "
                f"needs it (make/ensure), or on each read of a variable initialised with it")

    def field(self, e: a.Field, sc: _Scope) -> Ty:
        t = self.ty(e.base, sc)
        if t is None:
            return None
        fields = self.structs.get(t)
        if fields is None:
            self.err("field", e.pos, f"'{_fmt(e.base)}' is {_show(t)}, which has no fields")
            return None
        if e.name not in fields:
            self.err("field", e.pos, f"struct {t} has no field '{e.name}' (its fields: "
                                     f"{', '.join(reversed(list(fields))) or 'none'})")
            return None
        return fields[e.name]

    def unary(self, e: a.Unary, sc: _Scope) -> Ty:
        t = self.ty(e.operand, sc)
        if t is None:
            return "bool" if e.op == "!" else None
        if e.op == "!":
            if t != "bool":
                self.err("type", e.pos, f"'!' needs a bool; '{_fmt(e.operand)}' is {_show(t)}")
            return "bool"
        if t not in _NUMERIC:
            self.err("type", e.pos, f"'-' needs an int or a double; '{_fmt(e.operand)}' is {_show(t)}")
            return None
        return t

    def binary(self, e: a.Binary, sc: _Scope) -> Ty:
        lt, rt = self.ty(e.left, sc), self.ty(e.right, sc)
        op = e.op
        if op in a.LOGIC_OPS:
            for side, t in ((e.left, lt), (e.right, rt)):
                if t is not None and t != "bool":
                    self.err("type", side.pos, f"'{op}' needs bool operands; '{_fmt(side)}' is {_show(t)}")
            return "bool"
        if op in a.ARITH_OPS or op in ("<", "<=", ">", ">="):
            result = lt if op in a.ARITH_OPS else "bool"
            if lt is None or rt is None:  # already reported: do not cascade
                if op in a.ARITH_OPS:
                    return lt if lt is not None else rt
                return "bool"
            if lt in _NUMERIC and rt in _NUMERIC:
                if lt != rt:
                    self.err("int-double", e.op_pos, f"'{op}' mixes int and double ('{_fmt(e.left)}' is {lt}, "
                                                      f"'{_fmt(e.right)}' is {rt}); there is no implicit "
                                                      f"conversion: an int is written 1, a double 1.0")
                    return None if op in a.ARITH_OPS else "bool"
                return result
            self.err("type", e.op_pos, f"'{op}' needs two ints or two doubles, not {_show(lt)} and {_show(rt)}")
            return None if op in a.ARITH_OPS else "bool"
        # == and !=
        if not _compat(lt, rt) and getattr(e, "implied", False) and rt == "bool":
            self.err(self._mix(lt, rt), e.op_pos,
                     f"'{_fmt(e.left)}' is {_show(lt)}, not bool: a variable alone in a constraint means "
                     f"'{_fmt(e.left)} == true' ('!x' means 'x == false'); compare it with a value of its type")
        elif not _compat(lt, rt):
            self.err(self._mix(lt, rt), e.op_pos,
                     f"cannot compare {_show(lt)} with {_show(rt)} in '{_fmt(e)}'"
                     + self._mix_hint(lt, rt))
        return "bool"


@dataclass
class CheckedSpec:
    """A spec that passed the static checks, with what the checks found out about it: what the
    compiler consumes (it never re-runs a checker).

    ``var_types`` and ``fn_sigs`` are keyed by (agent, name); ``structs`` by ``agent::T`` gives
    each field's type; :meth:`type_of` is the type of any expression of the spec (or of a request
    checked with :func:`check_request`) in the scope where it occurs."""

    spec: a.Spec
    var_types: dict
    fn_sigs: dict
    structs: dict
    typed: dict = field(default_factory=dict, repr=False)

    def __repr__(self) -> str:
        return f"<checked spec of {', '.join(ag.name for ag in self.spec.agents)}: {len(self.typed)} typed expressions>"

    def type_of(self, e: a.Expr) -> Ty:
        got = self.typed.get(id(e))
        if got is None or got[0] is not e:
            raise KeyError(f"the static checks typed no expression {format_expr(e)!r} (at {e.pos})")
        return got[1]

    def with_types(self, typed: dict) -> "CheckedSpec":
        """A copy that also knows the types in ``typed`` (a request's, from :func:`typed_request`)."""
        return CheckedSpec(self.spec, self.var_types, self.fn_sigs, self.structs, {**self.typed, **typed})

    def same_type(self, new: a.Expr, old: a.Expr) -> None:
        """``new`` (an expression rewritten from ``old``, e.g. with its names qualified) has ``old``'s type."""
        if id(old) in self.typed:
            self.typed[id(new)] = (new, self.typed[id(old)][1])


def _checked(c: "_Checker") -> CheckedSpec:
    return CheckedSpec(c.spec, c.var_types, c.fn_sigs, c.structs, c.typed)


def spec_errors(spec: a.Spec) -> list[CheckError]:
    """Every problem the static checks find in ``spec``, sorted by position."""
    return _Checker(spec).run()


def check_spec(spec: a.Spec) -> CheckedSpec:
    """The checked spec; raise :class:`SpecCheckError` listing every problem of ``spec`` if there is any."""
    c = _Checker(spec)
    errors = c.run()
    if errors:
        raise SpecCheckError(errors)
    return _checked(c)


def request_errors(spec: a.Spec, request: a.Constraint) -> list[CheckError]:
    """Problems of a request (a constraint from outside the agents): names are ``agent::var``."""
    return _check_request(spec, request).result()


def _check_request(spec: a.Spec, request: a.Constraint) -> "_Checker":
    c = _Checker(spec)
    for ag in c.agents.values():
        c.declarations(ag)
    c.errors.clear()  # the spec's own problems are check_spec's business
    c.constraint(request, _Scope(None, frozenset(c.agents)))
    return c


def check_request(spec: a.Spec, request: Union[a.Constraint, str]) -> a.Constraint:
    """Check a request (parsed, or text to parse) against ``spec``; raise :class:`SpecCheckError` if wrong."""
    return typed_request(spec, request)[0]


def typed_request(spec: Union[a.Spec, CheckedSpec], request: Union[a.Constraint, str]) \
        -> tuple[a.Constraint, dict]:
    """The checked request and the types of its expressions (``id -> (expr, type)``, the form of
    :attr:`CheckedSpec.typed`); raise :class:`SpecCheckError` if it is wrong."""
    if isinstance(request, str):
        request = parse_constraint(request, "<request>")   # (compile.REQUEST_TAG)
    c = _check_request(spec.spec if isinstance(spec, CheckedSpec) else spec, request)
    errors = c.result()
    if errors:
        raise SpecCheckError(errors)
    return request, c.typed
