"""The abstract syntax of the ROAR agent spec language.

Every node is a frozen dataclass with a source position ``pos`` (a
:class:`~roar_formal.errors.Pos`). Positions, and a few other bits of
provenance (whether an expression was written in parentheses, which layout an
agent came from), are excluded from equality and hashing: two specs are equal
when they say the same thing, whichever file or layout they were read from.

The tree is syntactic: names are not resolved (``pos`` in a recipe is a
:class:`Name`, ``planner::ready`` a :class:`Remote`); :mod:`.checks` resolves
and type-checks them. The helpers below are what a compiler needs on top of
the bare tree (constraint targets, constraint domains, sequential ``make``
pairs, the variables a task's post-conditions mention, ...).

Shape, top down::

    Spec(agents, warnings)
    Agent(name, controllable, readable, private, types, functions, rules, tasks, imports)
      Var(name, type, init, access)              access: controllable | readable | private
      StructType(name, fields) | NewType(name, base) | OpaqueType(name)
      Function(name, result, params)             params: Param(type, name | None)
      Rule(name, premises, conclusions)
      Task(name, pre, post, recipes)             pre/post: tuples of Expr (one conjunct each)
        Recipe(name, pre, post, prefer, body, end)
          Let | Set | Make | Ensure | Wait | Assert | Abort | ExprStmt
          Make/Ensure hold a Constraint(expr, where) with WherePair(left, right)
      Import(path, agents)
    Expr: IntLit DoubleLit StringLit BoolLit Name Remote Call Field Unary Binary LastError
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Iterator, Literal, Optional, Union

from ..errors import Pos

NOPOS = Pos("<none>", 0, 0)

#: The three classes of context variables, in the order they are declared.
ACCESS = ("controllable", "readable", "private")
Access = Literal["controllable", "readable", "private"]

#: Base types of the language.
BASE_TYPES = ("bool", "int", "double", "string", "identifier")


def _pos() -> Pos:
    return field(default=NOPOS, compare=False, repr=False, kw_only=True)


@dataclass(frozen=True)
class Node:
    """Base of all nodes: a position, excluded from equality."""

    pos: Pos = _pos()

    def children(self) -> Iterator["Node"]:
        """The direct sub-nodes, in field order."""
        for f in dataclasses.fields(self):
            if not f.compare:
                continue
            v = getattr(self, f.name)
            if isinstance(v, Node):
                yield v
            elif isinstance(v, tuple):
                for x in v:
                    if isinstance(x, Node):
                        yield x


def walk(node: Node) -> Iterator[Node]:
    """Every node of a tree, pre-order (the node itself first)."""
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        stack.extend(reversed(list(n.children())))


# ---------------------------------------------------------------------------
# Expressions
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Expr(Node):
    #: written between parentheses (kept for diagnostics, not compared)
    parens: bool = field(default=False, compare=False, repr=False, kw_only=True)


@dataclass(frozen=True)
class IntLit(Expr):
    value: int


@dataclass(frozen=True)
class DoubleLit(Expr):
    value: float


@dataclass(frozen=True)
class StringLit(Expr):
    value: str


@dataclass(frozen=True)
class BoolLit(Expr):
    value: bool


@dataclass(frozen=True)
class Name(Expr):
    """An unqualified name: a local (``let``), a variable of the agent, or a logic variable in a rule."""

    name: str


@dataclass(frozen=True)
class Remote(Expr):
    """``agent::name``: a variable of a (possibly other) agent."""

    agent: str
    name: str

    def __str__(self) -> str:
        return f"{self.agent}::{self.name}"


@dataclass(frozen=True)
class Call(Expr):
    """``name(args)`` or ``agent::name(args)``: a function of the functional layer."""

    name: str
    args: tuple[Expr, ...] = ()
    agent: Optional[str] = None

    @property
    def qualified(self) -> str:
        return f"{self.agent}::{self.name}" if self.agent else self.name


@dataclass(frozen=True)
class Field(Expr):
    """``base.name``: a field of a struct value."""

    base: Expr
    name: str


@dataclass(frozen=True)
class Unary(Expr):
    op: Literal["!", "-"]
    operand: Expr


#: binary operators, by class
LOGIC_OPS = ("||", "&&")
COMPARISONS = ("==", "!=", "<", "<=", ">", ">=")
ARITH_OPS = ("+", "-", "*", "/")


@dataclass(frozen=True)
class Binary(Expr):
    op: str
    left: Expr
    right: Expr
    #: position of the operator itself (``pos`` is the start of the left operand)
    op_pos: Pos = _pos()
    #: written as the variable alone (a constraint ``x`` reads ``x == true``, ``!x`` reads
    #: ``x == false``): printed, and said in messages, as written
    implied: bool = field(default=False, compare=False)


@dataclass(frozen=True)
class LastError(Expr):
    """``last_error?(C)``: true when the last failure of this task was on constraint C."""

    constraint: Expr


def refs(e: Node) -> Iterator[Union[Name, Remote]]:
    """The variable references (``Name`` and ``Remote``) in a tree."""
    for n in walk(e):
        if isinstance(n, (Name, Remote)):
            yield n


def calls(e: Node) -> Iterator[Call]:
    for n in walk(e):
        if isinstance(n, Call):
            yield n


def conjuncts(e: Expr) -> list[Expr]:
    """Split a conjunction ``a && b && c`` into its conjuncts (parenthesised ones too)."""
    if isinstance(e, Binary) and e.op == "&&":
        return conjuncts(e.left) + conjuncts(e.right)
    return [e]


# ---------------------------------------------------------------------------
# Constraints and statements
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class WherePair(Node):
    """One ``a == b`` of a ``where`` clause: one side is a controllable variable of the target."""

    left: Expr
    right: Expr


@dataclass(frozen=True)
class Constraint(Node):
    """``C where a == b && ...``: a predicate sent to one agent, and the variables it sets first."""

    expr: Expr
    where: tuple[WherePair, ...] = ()

    def agents(self) -> frozenset[str]:
        """Agents named by ``agent::var`` in the predicate and the where clause."""
        return frozenset(r.agent for r in refs(self) if isinstance(r, Remote))

    def targets(self, own: Optional[str] = None) -> frozenset[str]:
        """The agents the constraint is sent to.

        That is the agents named in it; a constraint naming none (only local
        names) is sent to ``own``. The checks ensure there is exactly one.
        """
        named = self.agents()
        if named:
            return named
        return frozenset([own]) if own is not None else frozenset()

    def target(self, own: Optional[str] = None) -> Optional[str]:
        """The single target agent, or None when there is not exactly one."""
        t = self.targets(own)
        return next(iter(t)) if len(t) == 1 else None

    def writes(self, own: Optional[str] = None) -> dict[str, Expr]:
        """For a checked constraint: the controllable variable each where pair writes, with its value.

        Keys are the variable names (unqualified) of the target agent.
        """
        target = self.target(own)
        out: dict[str, Expr] = {}
        for p in self.where:
            for var, val in ((p.left, p.right), (p.right, p.left)):
                if isinstance(var, Remote) and var.agent == target:
                    out[var.name] = val
                    break
                if isinstance(var, Name) and target == own and own is not None:
                    out[var.name] = val
                    break
        return out


@dataclass(frozen=True)
class Stmt(Node):
    pass


@dataclass(frozen=True)
class Let(Stmt):
    """``let NAME expr``: a new local name."""

    name: str
    value: Expr


@dataclass(frozen=True)
class Set(Stmt):
    """``set NAME expr``: change a variable of the agent itself."""

    target: Union[Name, Remote]
    value: Expr


@dataclass(frozen=True)
class Make(Stmt):
    """``make(C where ...)``: send C and wait for success or failure (synchronous)."""

    constraint: Constraint


@dataclass(frozen=True)
class Ensure(Stmt):
    """``[let h] ensure(C where ... [, ms])``: send C and go on; C holds until aborted or the recipe ends."""

    constraint: Constraint
    period: Optional[Expr] = None
    handle: Optional[str] = None


@dataclass(frozen=True)
class Wait(Stmt):
    """``wait(expr [, ms])``: block until the predicate holds (re-checked every ms)."""

    cond: Expr
    period: Optional[Expr] = None


@dataclass(frozen=True)
class Assert(Stmt):
    """``assert(expr [, ms])``: fail the recipe when the predicate is false."""

    cond: Expr
    period: Optional[Expr] = None


@dataclass(frozen=True)
class Abort(Stmt):
    """``abort NAME``: abort the constraint of ``let NAME ensure(...)``."""

    handle: str


@dataclass(frozen=True)
class ExprStmt(Stmt):
    """A bare expression (typically a function call for its effect)."""

    expr: Expr


# ---------------------------------------------------------------------------
# Declarations
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class TypeRef(Node):
    """A type as written: a base type, a type of this agent, or ``agent::type``."""

    name: str
    agent: Optional[str] = None

    def __str__(self) -> str:
        return f"{self.agent}::{self.name}" if self.agent else self.name


@dataclass(frozen=True)
class Var(Node):
    """A context variable. An initialiser naming a task of the agent (``pos = get_pos()``)
    means that task runs on each read (see :meth:`Agent.reading_task`)."""

    name: str
    type: TypeRef
    init: Optional[Expr] = None
    access: Access = "private"


@dataclass(frozen=True)
class StructField(Node):
    name: str
    type: TypeRef


@dataclass(frozen=True)
class StructType(Node):
    name: str
    fields: tuple[StructField, ...] = ()


@dataclass(frozen=True)
class NewType(Node):
    """A distinct type with the representation of ``base`` (no implicit conversion)."""

    name: str
    base: TypeRef


@dataclass(frozen=True)
class OpaqueType(Node):
    """A type only the functional layer knows the inside of."""

    name: str


TypeDecl = Union[StructType, NewType, OpaqueType]


@dataclass(frozen=True)
class Param(Node):
    type: TypeRef
    name: Optional[str] = None


@dataclass(frozen=True)
class Function(Node):
    """A function of the functional layer, exported by an agent."""

    name: str
    result: TypeRef
    params: tuple[Param, ...] = ()


@dataclass(frozen=True)
class Rule(Node):
    """``name = premises |- conclusions;`` with capitalised names as universally quantified variables."""

    name: str
    premises: tuple[Expr, ...] = ()
    conclusions: tuple[Expr, ...] = ()


@dataclass(frozen=True)
class Recipe(Node):
    name: str
    pre: tuple[Expr, ...] = ()
    post: tuple[Expr, ...] = ()
    prefer: Optional[Expr] = None
    body: tuple[Stmt, ...] = ()
    end: tuple[Stmt, ...] = ()

    def statements(self) -> Iterator[Stmt]:
        """Body then end statements."""
        yield from self.body
        yield from self.end

    def constraints(self) -> Iterator[tuple[Stmt, Constraint]]:
        """Each ``make``/``ensure`` of body and end, with its constraint."""
        for s in self.statements():
            if isinstance(s, (Make, Ensure)):
                yield s, s.constraint

    def constraint_domain(self, own: Optional[str] = None) -> frozenset[str]:
        """The agents this recipe sends constraints to (through make and ensure).

        A constraint with only local names goes to ``own`` (counted when given).
        """
        out: set[str] = set()
        for _, c in self.constraints():
            out |= c.targets(own)
        return frozenset(out)

    def domain(self, own: Optional[str] = None) -> frozenset[str]:
        """Every agent the recipe needs: named anywhere in it (reads included), or sent a constraint."""
        out = {r.agent for r in refs(self) if isinstance(r, Remote)}
        out |= {c.agent for c in calls(self) if c.agent}
        out |= self.constraint_domain(own)
        if own is not None:
            out.discard(own)
        return frozenset(out)

    def sequential_pairs(self, strict: bool = False) -> list[tuple[Make, Make]]:
        """Consecutive ``make A; make B`` in one block (body, or end), for sequential achievement.

        By default B is the next ``make`` after A in the same block, whatever
        non-make statements stand between them (``make`` is synchronous, so A's
        subtree is done before B is sent). With ``strict=True`` only adjacent
        statements count.
        """
        pairs: list[tuple[Make, Make]] = []
        for block in (self.body, self.end):
            prev: Optional[Make] = None
            for s in block:
                if isinstance(s, Make):
                    if prev is not None:
                        pairs.append((prev, s))
                    prev = s
                elif strict:
                    prev = None
        return pairs

    def handles(self) -> dict[str, Ensure]:
        """Names bound by ``let h ensure(...)`` in the body."""
        return {s.handle: s for s in self.body if isinstance(s, Ensure) and s.handle}

    def preference(self) -> int:
        """The ``prefer`` value (0 when absent or not a literal)."""
        return int_value(self.prefer) if self.prefer is not None else 0


def int_value(e: Expr) -> int:
    """The value of an integer literal, possibly negated; 0 for anything else."""
    if isinstance(e, IntLit):
        return e.value
    if isinstance(e, Unary) and e.op == "-" and isinstance(e.operand, IntLit):
        return -e.operand.value
    return 0


def _var_names(exprs: tuple[Expr, ...], own: Optional[str]) -> frozenset[str]:
    out = set()
    for e in exprs:
        for r in refs(e):
            if isinstance(r, Name):
                out.add(r.name)
            elif r.agent == own:
                out.add(r.name)
            else:
                out.add(f"{r.agent}::{r.name}")
    return frozenset(out)


@dataclass(frozen=True)
class Task(Node):
    """A contract: pre-conditions and post-conditions (each a tuple of conjuncts), and the recipes that achieve it."""

    name: str
    pre: tuple[Expr, ...] = ()
    post: tuple[Expr, ...] = ()
    recipes: tuple[Recipe, ...] = ()

    def post_vars(self, own: Optional[str] = None) -> frozenset[str]:
        """Variables named in the post-conditions: own ones unqualified (``own::x`` is ``x``), others ``agent::x``."""
        return _var_names(self.post, own)

    def pre_vars(self, own: Optional[str] = None) -> frozenset[str]:
        return _var_names(self.pre, own)

    def recipe(self, name: str) -> Optional[Recipe]:
        return next((r for r in self.recipes if r.name == name), None)


@dataclass(frozen=True)
class Import(Node):
    """``import "file"``; ``agents`` are the agents that file declares (filled in by the loader)."""

    path: str
    agents: tuple[str, ...] = ()


@dataclass(frozen=True)
class Agent(Node):
    name: str
    controllable: tuple[Var, ...] = ()
    readable: tuple[Var, ...] = ()
    private: tuple[Var, ...] = ()
    types: tuple[TypeDecl, ...] = ()
    functions: tuple[Function, ...] = ()
    rules: tuple[Rule, ...] = ()
    tasks: tuple[Task, ...] = ()
    imports: tuple[Import, ...] = ()
    #: "roar" (single file: agents of one file see each other) or "hyper" (only imports are visible)
    layout: str = field(default="roar", compare=False, repr=False, kw_only=True)

    @property
    def vars(self) -> tuple[Var, ...]:
        return self.controllable + self.readable + self.private

    def var(self, name: str) -> Optional[Var]:
        return next((v for v in self.vars if v.name == name), None)

    def task(self, name: str) -> Optional[Task]:
        return next((t for t in self.tasks if t.name == name), None)

    def function(self, name: str) -> Optional[Function]:
        return next((f for f in self.functions if f.name == name), None)

    def type_decl(self, name: str) -> Optional[TypeDecl]:
        return next((t for t in self.types if t.name == name), None)

    def reading_task(self, var: Union[str, Var]) -> Optional[str]:
        """The task run on each read of ``var`` (its initialiser names a task of this agent), if any."""
        v = self.var(var) if isinstance(var, str) else var
        if v is None or not isinstance(v.init, Call) or v.init.args:
            return None
        c = v.init
        if c.agent not in (None, self.name) or self.function(c.name) is not None:
            return None
        return c.name if self.task(c.name) is not None else None

    def task_initialised(self) -> dict[str, str]:
        """``{var: task}`` for every variable whose reads run a task."""
        out = {}
        for v in self.vars:
            t = self.reading_task(v)
            if t is not None:
                out[v.name] = t
        return out

    def imported(self) -> frozenset[str]:
        return frozenset(a for i in self.imports for a in i.agents)


@dataclass(frozen=True)
class SpecWarning:
    """A diagnostic that does not stop loading (e.g. a hyper-compatibility warning)."""

    pos: Pos
    message: str

    def format(self) -> str:
        return f"{self.pos}: warning: {self.message}"

    def __str__(self) -> str:
        return self.format()


@dataclass(frozen=True)
class Spec(Node):
    agents: tuple[Agent, ...] = ()
    warnings: tuple[SpecWarning, ...] = field(default=(), compare=False, repr=False, kw_only=True)

    def agent(self, name: str) -> Optional[Agent]:
        return next((a for a in self.agents if a.name == name), None)

    def visible(self, agent: Union[str, Agent]) -> frozenset[str]:
        """Names of the agents ``agent`` may refer to: itself, its imports, and (single-file
        layout) every agent declared in the same file."""
        a = self.agent(agent) if isinstance(agent, str) else agent
        if a is None:
            return frozenset()
        out = {a.name} | set(a.imported())
        if a.layout == "roar":
            out |= {b.name for b in self.agents if b.layout == "roar" and b.pos.file == a.pos.file}
        return frozenset(out)

    def resolve_function(self, agent: Union[str, Agent], call: Call) -> list[tuple[str, Function]]:
        """The declarations a call may denote, as ``(owner agent, Function)``.

        ``agent::f`` denotes f of that agent; a plain ``f`` the agent's own f,
        else an f of a visible agent. More than one result means ambiguous;
        none means unknown (builtins are not included, see :data:`BUILTINS`).
        """
        a = self.agent(agent) if isinstance(agent, str) else agent
        if call.agent is not None:
            owner = self.agent(call.agent)
            f = owner.function(call.name) if owner else None
            return [(owner.name, f)] if f else []
        if a is not None:
            f = a.function(call.name)
            if f is not None:
                return [(a.name, f)]
            out = []
            for b in self.agents:
                if b.name != a.name and b.name in self.visible(a):
                    g = b.function(call.name)
                    if g is not None:
                        out.append((b.name, g))
            return out
        return [(b.name, b.function(call.name)) for b in self.agents if b.function(call.name)]


#: Functions every agent may call without declaring them: name -> (result type, parameter types).
BUILTINS: dict[str, tuple[str, tuple[str, ...]]] = {
    "now": ("int", ()),  # milliseconds since the agent started
}
