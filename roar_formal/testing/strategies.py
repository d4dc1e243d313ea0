"""Hypothesis strategies for CLF terms and programs, agent specs, requests, fault schedules and paths.

Every strategy shrinks towards small, readable examples: fewer agents, tasks,
recipes and statements, the first kind of statement (``set``), literals
before variables, the first enabled step of a state, the first call of a
primitive. Generated specs and models print as code that rebuilds them
(``AgentSpec.from_text('''...''')``), so a falsifying example can be pasted
into a test.

* :func:`specs` -- agent specs (single-file layout) that pass the static
  checks, with every kind of statement (:data:`STATEMENT_KINDS`); size knobs
  bound agents, tasks, recipes and statements;
* :func:`requests` -- requests a given spec accepts; :func:`spec_requests`
  -- a generated spec with one of its requests;
* :func:`fault_schedules` -- lists of ``--fault`` values for a spec's functions;
* :func:`paths` -- paths through a model's state space from its start state;
* :func:`clf_terms` and :func:`clf_programs` -- well-typed terms of a type,
  and small programs (rules and a start state), over a given signature.

Generated specs use the types ``bool`` and ``int`` (no ``double``, strings,
structs or rules) and one file: what the checks and the compiler treat
alike for every type is exercised, and the examples stay readable.
"""

from __future__ import annotations

import dataclasses
from pathlib import PurePath
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Optional, Union

from hypothesis import strategies as st
from hypothesis.errors import InvalidArgument

from ..errors import RoarError
from .api import AgentSpec, ClfModel, ScheduledFault, variable_value

__all__ = ["STATEMENT_KINDS", "statement_kinds", "specs", "requests", "spec_requests", "fault_schedules",
           "paths", "ModelPath", "clf_terms", "clf_programs"]

#: the statement kinds of a recipe body; "call" is an expression statement (a function call)
STATEMENT_KINDS = ("set", "let", "make", "ensure", "wait", "assert", "abort", "call")

_AGENTS = ("arm", "base", "cam", "door")
_CONTROLLABLE = (("goal", "int"), ("mode", "bool"))
_READABLE = (("done", "bool"), ("level", "int"), ("ready", "bool"))
_PRIVATE = (("busy", "bool"), ("tries", "int"))
_TASKS = ("work", "prepare", "finish")
_RECIPES = ("direct", "careful", "fallback")
_LIT = {"bool": st.sampled_from(["true", "false"]), "int": st.integers(0, 3).map(str)}


def statement_kinds(spec: Union[AgentSpec, Any]) -> Counter:
    """How many statements of each kind (:data:`STATEMENT_KINDS`) a spec's recipes hold."""
    from ..roar import ast as a
    tree = spec.ast if isinstance(spec, AgentSpec) else spec
    kinds = {a.Set: "set", a.Let: "let", a.Make: "make", a.Ensure: "ensure", a.Wait: "wait",
             a.Assert: "assert", a.Abort: "abort", a.ExprStmt: "call"}
    out: Counter = Counter()
    for n in a.walk(tree):
        k = kinds.get(type(n))
        if k is not None:
            out[k] += 1
    return out


# ---------------------------------------------------------------------------- agent specs


@dataclass
class _Agent:
    name: str
    controllable: tuple
    readable: tuple
    private: tuple
    function: Optional[str]

    def own(self, ty: str) -> list[str]:
        return [v for v, t in self.controllable + self.readable + self.private if t == ty]

    def writable(self) -> list[tuple[str, str]]:
        return list(self.readable + self.private)


@dataclass
class _Block:
    """What a statement may use: the locals bound so far, the ensure handles not yet aborted, and
    the where variable each constraint of the spec writes (shared by all blocks: the compiler
    wants one constraint always sent with the same where variables)."""

    agent: _Agent
    others: list
    wheres: dict = field(default_factory=dict)
    locals: dict = field(default_factory=dict)
    handles: list = field(default_factory=list)


def _atom(draw, ty: str, b: _Block) -> str:
    options = [None] + b.agent.own(ty) + [n for n, t in b.locals.items() if t == ty]
    options += [f"{o.name}::{v}" for o in b.others for v, t in o.readable if t == ty]
    pick = draw(st.sampled_from(options))
    return draw(_LIT[ty]) if pick is None else pick


def _expr(draw, ty: str, b: _Block, depth: int = 1) -> str:
    """An expression of type ``ty``: an atom, or (shrinking away) one operator over atoms."""
    shape = draw(st.integers(0, 2)) if depth > 0 else 0
    if shape == 0:
        return _atom(draw, ty, b)
    if ty == "int":
        return f"{_atom(draw, 'int', b)} + {_atom(draw, 'int', b)}"
    if shape == 1:
        op = draw(st.sampled_from(["==", "<", "!="]))
        return f"{_atom(draw, 'int', b)} {op} {draw(_LIT['int'])}"
    return f"{_atom(draw, 'bool', b)} && {_atom(draw, 'bool', b)}"


def _constraint(draw, b: _Block, agents: list) -> str:
    """``t::v == lit`` sent to agent t (possibly the sender), with an optional where clause
    writing one of t's controllable variables."""
    t = draw(st.sampled_from(agents))
    var, ty = draw(st.sampled_from(t.readable))
    text = f"{t.name}::{var} == {draw(_LIT[ty])}"
    if text not in b.wheres:
        b.wheres[text] = draw(st.sampled_from(t.controllable)) if t.controllable and draw(st.booleans()) else None
    where = b.wheres[text]
    if where is not None:
        c, cty = where
        text += f" where {t.name}::{c} == {draw(_LIT[cty])}"
    return text


@st.composite
def _statement(draw, b: _Block, agents: list) -> str:
    """One statement (each its own span of choices, so that the shrinker can delete it whole)."""
    # abort only of a live handle; weighted up then, or it would be rare (it needs a `let h ensure` first)
    kinds = ["set", "let", "make", "ensure", "wait", "assert", "call"] + (["abort"] * 3 if b.handles else [])
    kind = draw(st.sampled_from(kinds))
    if kind == "set":
        var, ty = draw(st.sampled_from(b.agent.writable()))
        return f"set {var} {_expr(draw, ty, b)};"
    if kind == "let":
        ty = draw(st.sampled_from(["int", "bool"]))
        name = f"l{sum(1 for n in b.locals if n.startswith('l'))}"
        text = f"let {name} {_expr(draw, ty, b)};"
        b.locals[name] = ty
        return text
    if kind == "make":
        return f"make({_constraint(draw, b, agents)});"
    if kind == "ensure":
        c = _constraint(draw, b, agents)
        period = f", {draw(st.sampled_from([100, 50]))}" if draw(st.booleans()) else ""
        if draw(st.booleans()):
            h = f"h{sum(1 for n in b.locals if n.startswith('h'))}"
            b.handles.append(h)
            b.locals[h] = "handle"
            return f"let {h} ensure({c}{period});"
        return f"ensure({c}{period});"
    if kind in ("wait", "assert"):
        period = f", {draw(st.sampled_from([100, 50]))}" if draw(st.booleans()) else ""
        return f"{kind}({_expr(draw, 'bool', b)}{period});"
    if kind == "abort":
        h = draw(st.sampled_from(b.handles))
        b.handles.remove(h)
        return f"abort {h};"
    fn = b.agent.function
    return f"{fn}({_expr(draw, 'int', b)});" if fn else "now();"


def _decls(vars_: tuple, init: bool) -> str:
    defaults = {"bool": "false", "int": "0"}
    text = " ".join(f"{t} {v}" + (f" = {defaults[t]}" if init else "") + ";" for v, t in vars_)
    return f"{{ {text} }}" if text else "{ }"


@st.composite
def _agent_shape(draw, name: str, functions: bool) -> _Agent:
    return _Agent(name,
                  controllable=_CONTROLLABLE[:draw(st.integers(0, len(_CONTROLLABLE)))],
                  readable=_READABLE[:draw(st.integers(1, len(_READABLE)))],
                  private=_PRIVATE[:draw(st.integers(0, len(_PRIVATE)))],
                  function=f"probe_{name}" if functions and draw(st.booleans()) else None)


@st.composite
def _recipe(draw, name: str, ag: _Agent, agents: list, wheres: dict, post: str, max_statements: int) -> list[str]:
    others = [o for o in agents if o is not ag]
    b = _Block(ag, others, wheres)
    out = [f"        {name} = recipe {{"]
    if draw(st.booleans()):
        out.append(f"          pre = {{ {{{_expr(draw, 'bool', _Block(ag, others, wheres), 0)}}} }}")
    if draw(st.booleans()):
        out.append(f"          prefer = {draw(st.integers(-1, 2))}")
    body = draw(st.lists(_statement(b, agents), max_size=max_statements))
    if draw(st.booleans()):
        body.append(f"set {post};")
    out.append("          body = {")
    out += [f"            {x}" for x in body]
    out.append("          }")
    if draw(st.booleans()):
        var, ty = draw(st.sampled_from(ag.writable()))
        out.append(f"          end = {{ set {var} {draw(_LIT[ty])}; }}")
    out.append("        }")
    return out


@st.composite
def _task(draw, ti: int, ag: _Agent, agents: list, wheres: dict, max_recipes: int, max_statements: int) -> list[str]:
    others = [o for o in agents if o is not ag]
    post_var, post_ty = ag.readable[ti % len(ag.readable)]
    post_val = "true" if post_ty == "bool" else str(draw(st.integers(1, 3)))
    out = [f"    {_TASKS[ti]} = task {{"]
    if draw(st.booleans()):
        out.append(f"      pre = {{ {{{_expr(draw, 'bool', _Block(ag, others, wheres), 0)}}} }}")
    out.append(f"      post = {{ {{{post_var} == {post_val}}} }}")
    out.append("      recipes = {")
    for ri in range(draw(st.integers(1, max_recipes))):
        out += draw(_recipe(_RECIPES[ri], ag, agents, wheres, f"{post_var} {post_val}", max_statements))
    out += ["      }", "    }"]
    return out


@st.composite
def _spec_text(draw, min_agents: int, max_agents: int, max_tasks: int, max_recipes: int, max_statements: int,
               functions: bool) -> str:
    n = draw(st.integers(min_agents, max_agents))
    agents = [draw(_agent_shape(name, functions)) for name in _AGENTS[:n]]
    wheres: dict = {}
    out = []
    for ag in agents:
        out += [f"{ag.name} = ability {{", "  context = {", f"    {_decls(ag.controllable, False)}",
                f"    {_decls(ag.readable, True)}", f"    {_decls(ag.private, True)}", "  }"]
        if ag.function:
            out.append(f"  export = {{\n    {{ }}\n    {{ bool {ag.function}(int); }}\n    {{ }}\n  }}")
        out.append("  tasks = {")
        for ti in range(draw(st.integers(1, max_tasks))):
            out += draw(_task(ti, ag, agents, wheres, max_recipes, max_statements))
        out += ["  }", "}"]
    return "\n".join(out) + "\n"


def specs(*, min_agents: int = 1, max_agents: int = 2, max_tasks: int = 2, max_recipes: int = 2,
          max_statements: int = 4, functions: bool = True) -> st.SearchStrategy[AgentSpec]:
    """Agent specs that pass the static checks, as :class:`AgentSpec` (their ``text`` is the
    source). Each agent has readable, and possibly controllable and private, ``bool``/``int``
    variables, possibly a function ``bool probe_AGENT(int)``, 1..``max_tasks`` tasks whose
    post-condition is ``var == value``, 1..``max_recipes`` recipes a task, and up to
    ``max_statements`` statements a body (plus, often, the ``set`` that meets the post-condition)."""
    if not 1 <= min_agents <= max_agents <= len(_AGENTS):
        raise InvalidArgument(f"need 1 <= min_agents <= max_agents <= {len(_AGENTS)}")
    if not 1 <= max_tasks <= len(_TASKS) or not 1 <= max_recipes <= len(_RECIPES) or max_statements < 0:
        raise InvalidArgument(f"need 1 <= max_tasks <= {len(_TASKS)}, 1 <= max_recipes <= {len(_RECIPES)}, "
                              f"max_statements >= 0")
    return _spec_text(min_agents, max_agents, max_tasks, max_recipes, max_statements, functions).map(
        lambda text: AgentSpec.from_text(text, name="generated"))


# ---------------------------------------------------------------------------- requests


_LITERALS = {"bool": ["true", "false"], "int": ["0", "1", "2", "3"], "double": ["0.0", "1.0"],
             "string": ['"a"'], "identifier": ['"a"']}


def _qualified(e, agent, every: bool = False):
    """``e`` with the agent's own unqualified names written ``agent::name`` (a request's form);
    ``every``: all unqualified names, as the compiler keys constraints."""
    from ..roar import ast as a
    if isinstance(e, a.Name) and (every or agent.var(e.name) is not None):
        return a.Remote(agent.name, e.name, pos=e.pos)
    changes = {}
    for f in dataclasses.fields(e):
        if not f.compare:
            continue
        v = getattr(e, f.name)
        if isinstance(v, a.Expr):
            changes[f.name] = _qualified(v, agent, every)
        elif isinstance(v, tuple) and v and all(isinstance(x, a.Expr) for x in v):
            changes[f.name] = tuple(_qualified(x, agent, every) for x in v)
    return dataclasses.replace(e, **changes) if changes else e


def _where_vars(spec: AgentSpec) -> dict:
    """(target, qualified predicate) -> the variables its where clause writes, for every make and
    ensure of the spec: a request with the same predicate must write the same ones (the compiler
    gives one constraint one where shape)."""
    from ..roar import ast as a
    from ..roar.pretty import format_expr
    out: dict = {}
    for ag in spec.ast.agents:
        for n in a.walk(ag):
            if isinstance(n, (a.Make, a.Ensure)):
                c = n.constraint
                target = c.target(ag.name)
                out.setdefault((target, format_expr(_qualified(c.expr, ag, every=True))), tuple(c.writes(ag.name)))
    return out


def _request_candidates(spec: AgentSpec) -> list[str]:
    from ..roar.checks import request_errors
    from ..roar.parser import parse_constraint
    from ..roar.pretty import format_expr
    used = _where_vars(spec)
    preds: list[tuple[str, str]] = []
    for ag in spec.ast.agents:
        for t in ag.tasks:
            for c in t.post:
                preds.append((ag.name, format_expr(_qualified(c, ag))))
        for v in ag.controllable + ag.readable:
            for lit in _LITERALS.get(v.type.name if v.type.agent is None else "", [])[:2]:
                preds.append((ag.name, f"{ag.name}::{v.name} == {lit}"))
    out = []
    for agent_name, p in dict.fromkeys(preds):
        ag = spec.ast.agent(agent_name)
        wheres = [("", ())] + [(f" where {agent_name}::{v.name} == {lit}", (v.name,)) for v in ag.controllable
                               for lit in _LITERALS.get(v.type.name if v.type.agent is None else "", [])[:2]]
        fixed = used.get((agent_name, p))
        for w, writes in wheres:
            if fixed is not None and writes != fixed:
                continue
            text = p + w
            try:
                if not request_errors(spec.ast, parse_constraint(text, "<request>")):
                    out.append(text)
            except RoarError:
                continue
    return out


def _spec_of(spec: Any, who: str) -> AgentSpec:
    """An :class:`AgentSpec`, or the spec at a path (as the helpers take one)."""
    if isinstance(spec, (str, PurePath)):
        from .api import load_spec
        return load_spec(spec)
    if not isinstance(spec, AgentSpec):
        raise InvalidArgument(f"{who} takes an AgentSpec or the path of a spec, not {type(spec).__name__}")
    return spec


def _target_of(target: Any, who: str) -> Union[AgentSpec, ClfModel]:
    """An :class:`AgentSpec` or :class:`ClfModel`, or the spec or model at a path."""
    if isinstance(target, (str, PurePath)):
        from .api import load
        return load(target)
    return target


def requests(spec: AgentSpec) -> st.SearchStrategy[str]:
    """Requests ``spec`` (an :class:`AgentSpec`, or a spec's path) accepts: a task's post-condition
    or ``agent::var == literal``, qualified, with or without a ``where`` clause writing a
    controllable variable. Shrinks towards the first task's post-condition of the first agent,
    without ``where``."""
    spec = _spec_of(spec, "requests()")
    cands = _request_candidates(spec)
    if not cands:
        raise InvalidArgument(f"{spec.name}: no request to generate: no task post-condition or variable of "
                              f"a base type that a request may name")
    return st.sampled_from(cands)


def spec_requests(**spec_options: Any) -> st.SearchStrategy[tuple[AgentSpec, str]]:
    """A generated spec (:func:`specs` with these options) and one of its requests."""
    return specs(**spec_options).flatmap(lambda s: st.tuples(st.just(s), requests(s)))


# ---------------------------------------------------------------------------- faults


def fault_schedules(spec: AgentSpec, *, max_faults: int = 3, max_call: int = 3, permanent: bool = False,
                    outcomes: bool = True) -> st.SearchStrategy[list[str]]:
    """Lists of ``--fault`` values for the functions ``spec`` declares: ``f:K`` (the K-th call
    fails, K up to ``max_call``), with ``permanent`` also ``f`` (every call fails), and with
    ``outcomes`` ``f:K=OUTCOME`` for the outcomes the functional layer declares. Shrinks towards
    the empty schedule, then one fault of the first call of the first function. The values are
    :class:`~roar_formal.testing.api.ScheduledFault` strings: a run lists one that matched no call
    (``f:3`` when f is called twice) in ``unused_faults`` rather than refusing it. ``spec`` is an
    :class:`AgentSpec` or a spec's path."""
    spec = _spec_of(spec, "fault_schedules()")
    counts = Counter(f for _a, f in spec.functions())
    reg = spec.registry() if outcomes else None
    faults: list[str] = []   # every fault the schedule may hold, simplest first (plain strings print well)
    for k in range(1, max_call + 1):
        for agent, f in spec.functions():
            faults.append(f"{f if counts[f] == 1 else f'{agent}::{f}'}:{k}")
    for agent, f in spec.functions():
        shown = f if counts[f] == 1 else f"{agent}::{f}"
        if permanent:
            faults.append(shown)
        prim = reg.lookup(f, agent) if reg is not None else None
        if prim is not None and prim.outcomes != _default_outcomes():
            faults += [f"{shown}:{k}={o.name}" for k in range(1, max_call + 1) for o in prim.outcomes]
    if not faults or max_faults == 0:
        return st.just([])
    return st.lists(st.sampled_from([ScheduledFault(f) for f in faults]), max_size=max_faults, unique=True)


def _default_outcomes():
    from ..roar.functional import DEFAULT_OUTCOMES
    return DEFAULT_OUTCOMES


# ---------------------------------------------------------------------------- paths


@dataclass
class ModelPath:
    """A path from a model's start state: the engine's steps, the states they lead to, and, for a
    spec, the ROAR events they make."""

    rules: list[str]
    steps: list = field(repr=False)
    states: list = field(repr=False)       # len(steps) + 1 contexts, the start first
    quiescent: bool                         # the path ends in a state with no enabled step
    events: Optional[list] = field(default=None, repr=False)
    model: Any = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.rules)

    def facts(self, i: int = -1) -> list[str]:
        """The facts of state ``i`` of the path (the last by default), printed as CLF writes them."""
        from ..clf.query import show_context
        return show_context(self.states[i])

    def value(self, var: str, i: int = -1) -> object:
        """For a spec's path: the value of ``agent::var`` in state ``i`` (the last by default)."""
        if self.model is None:
            raise RoarError("value() reads a spec's variables: this is a path of a .clf model (read facts())")
        return variable_value(self.model, self.states[i], var, "the spec")

    def __repr__(self) -> str:
        end = ", then quiescent" if self.quiescent else ""
        if self.events is not None:   # a spec's path, in its terms: the ROAR events (the engine's rules say little)
            shown = "; ".join(f"{e.step}. {e.agent}: {e.text}" for e in self.events)
            return f"<path of {len(self.rules)} steps, its ROAR events: {shown or '(none)'}{end}>"
        return f"<path of {len(self.rules)} steps: {' '.join(self.rules) or '(none)'}{end}>"

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:
        """As Hypothesis prints a falsifying path: a spec's ROAR events one a line (on one line, a
        path of a few dozen events ran to a thousand characters)."""
        if not self.events:
            p.text(repr(self))
            return
        p.text(f"<path of {len(self.rules)} steps, its ROAR events:")
        with p.indent(4):
            for e in self.events:
                p.break_()
                p.text(f"{e.step}. {e.agent}: {e.text}")
            if self.quiescent:
                p.break_()
                p.text("then quiescent")
        p.text(">")


def _start_of(target: Union[AgentSpec, ClfModel], request: Optional[str]):
    if isinstance(target, AgentSpec):
        if request is None:
            raise InvalidArgument("paths through a spec's model need a request")
        from ..clf.signature import ExecDirective
        model = target.compile(request, "abstract")
        program = model.program()
        start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        return program, program.start_context(start_d.start), model
    if request is not None:
        raise InvalidArgument("a .clf model takes no request")
    return target.program, target.start_context(), None


def paths(target: Union[AgentSpec, ClfModel], request: Optional[str] = None, *,
          max_length: int = 40) -> st.SearchStrategy[ModelPath]:
    """Paths of up to ``max_length`` steps from the start state (a spec's compiled model, primitives
    as their declared outcomes, or a .clf model's ``#exec``), each step one of the state's enabled
    steps. Shrinks towards shorter paths and each state's first enabled step. ``target`` may also
    be the path of a spec or model."""
    target = _target_of(target, "paths()")
    cache: dict = {}

    @st.composite
    def draw_path(draw) -> ModelPath:
        if "start" not in cache:
            cache["start"] = _start_of(target, request)
        program, start, model = cache["start"]
        n = draw(st.integers(0, max_length))
        ctx, steps, states, rules = start, [], [start], []
        quiescent = False
        for _ in range(n):
            choices = program.steps(ctx)
            if not choices:
                quiescent = True
                break
            k = draw(st.integers(0, len(choices) - 1))
            ctx, step = program.successor(ctx, choices[k])
            steps.append(step)
            states.append(ctx)
            rules.append(step.rule)
        else:
            quiescent = not program.steps(ctx)
        events = None
        if model is not None:
            from ..roar.explore import path_events
            events = path_events(model, start, steps)
        return ModelPath(rules, steps, states, quiescent, events, model)

    return draw_path()


# ---------------------------------------------------------------------------- CLF


@dataclass
class _Sig:
    """The simple part of a signature: constructors of each base type, predicates and their argument types."""

    constructors: dict[str, list[tuple[str, list[str]]]]
    predicates: dict[str, list[str]]
    depth: dict[str, int]            # the smallest depth at which a type has a closed term
    text: str


_BUILTIN_TYPES = ("number", "string")


def _simple_args(ty, end_is_type: bool) -> Optional[tuple[list[str], Any]]:
    """``A1 -> ... -> An -> R`` with every Ai a base type: ([A1..An], R); None when dependent or higher-order."""
    from ..clf.terms import Const, Imp, Root, Type
    args = []
    while isinstance(ty, Imp) and ty.mode == "!":
        d = ty.dom
        if not (isinstance(d, Root) and isinstance(d.head, Const) and not d.args):
            return None
        args.append(d.head.name)
        ty = ty.body
    if end_is_type:
        return (args, None) if isinstance(ty, Type) else None
    if isinstance(ty, Root) and isinstance(ty.head, Const) and not ty.args:
        return args, ty.head.name
    return None


def _signature(sig: Union[str, ClfModel, Any]) -> _Sig:
    from ..clf.program import Program
    if isinstance(sig, ClfModel):   # (a model made from text has it; its scratch file may not exist yet)
        program, text = sig.program, sig.text if sig.text is not None else sig.path.read_text(encoding="utf-8")
    elif isinstance(sig, Program):
        program, text = sig, None
    elif isinstance(sig, str):
        program, text = Program.from_text(sig, "<signature>"), sig
    else:
        raise InvalidArgument(f"a signature is CLF text, a ClfModel or a Program, not {type(sig).__name__}")
    families = {n: i for n, i in program.sig.consts.items() if i.is_family}
    base = {n for n, i in families.items() if _simple_args(i.classifier, True) == ([], None)}
    cons: dict[str, list] = {b: [] for b in base}
    for n, i in program.sig.consts.items():
        if i.is_family or i.implicit or i.definition is not None:
            continue
        shape = _simple_args(i.classifier, False)
        if shape is not None and shape[1] in base and all(x in base or x in _BUILTIN_TYPES for x in shape[0]):
            cons[shape[1]].append((n, shape[0]))
    depth: dict[str, int] = {"number": 0, "string": 0}
    changed = True
    while changed:   # least fixpoint: a type is inhabited at depth 1 + the deepest argument it needs
        changed = False
        for ty, cs in cons.items():
            for _n, args in cs:
                if all(x in depth for x in args):
                    d = 0 if not args else 1 + max(depth[x] for x in args)
                    if d < depth.get(ty, 1 << 30):
                        depth[ty] = d
                        changed = True
    preds = {}
    for n, i in families.items():
        shape = _simple_args(i.classifier, True)
        if shape is not None and all(x in depth for x in shape[0]) and n not in base | set(_BUILTIN_TYPES):
            preds[n] = shape[0]
    if text is None:   # a Program: its text is not kept; the simple declarations the programs drawn use
        arrow = lambda args, end: " -> ".join([*args, end])
        text = "\n".join([f"{b} : type." for b in base if b not in _BUILTIN_TYPES]
                         + [f"{n} : {arrow(args, ty)}." for ty, cs in cons.items() for n, args in cs]
                         + [f"{n} : {arrow(args, 'type')}." for n, args in preds.items()]) + "\n"
    return _Sig(cons, preds, depth, text)


def _term(draw, s: _Sig, ty: str, depth: int) -> str:
    if ty == "number":
        return str(draw(st.integers(0, 9)))
    if ty == "string":
        return '"' + draw(st.text("abc", max_size=3)) + '"'
    usable = [(n, args) for n, args in s.constructors[ty]
              if all(s.depth.get(x, 1 << 30) <= depth - 1 for x in args) and (args or True)]
    usable.sort(key=lambda c: len(c[1]))   # leaves first: shrinking goes towards them
    name, args = draw(st.sampled_from(usable))
    parts = [_term(draw, s, a, depth - 1) for a in args]
    return " ".join([name] + [p if " " not in p or p.startswith('"') else f"({p})" for p in parts])


def clf_terms(signature: Union[str, ClfModel, Any], type_name: str, *, max_depth: int = 3) -> st.SearchStrategy[str]:
    """Closed terms of a base type of ``signature`` (CLF text, a ClfModel or a Program), as CLF
    text: constants applied to terms of their argument types, numbers and strings for the
    built-in types, nested at most ``max_depth`` deep. Dependent and higher-order constants
    are left out. Shrinks towards the type's first constant without arguments."""
    s = _signature(signature)
    if type_name in _BUILTIN_TYPES:
        return st.composite(lambda draw: _term(draw, s, type_name, 0))()
    if type_name not in s.constructors:
        raise InvalidArgument(f"{type_name!r} is not a base type (a family of kind 'type') of the signature; "
                              f"its base types: {', '.join(sorted(s.constructors)) or 'none'}")
    if s.depth.get(type_name, 1 << 30) > max_depth:
        raise InvalidArgument(f"type {type_name!r} has no closed term of depth at most {max_depth}")
    return st.integers(s.depth[type_name], max_depth).flatmap(
        lambda d: st.composite(lambda draw: _term(draw, s, type_name, d))())


@st.composite
def _program_text(draw, s: _Sig, max_rules: int, max_premises: int, max_conclusions: int, max_facts: int,
                  max_depth: int, persistent: bool) -> str:
    preds = sorted(s.predicates)
    rules = []
    for k in range(draw(st.integers(1, max_rules))):
        bound: dict[str, str] = {}   # variable -> its type

        def arg(ty: str, binding: bool) -> str:
            options = ["term"] + [v for v, t in bound.items() if t == ty] + (["fresh"] if binding else [])
            pick = draw(st.sampled_from(options))
            if pick == "term":
                return _term(draw, s, ty, max(max_depth, s.depth[ty]))
            if pick == "fresh":
                v = f"X{len(bound)}"
                bound[v] = ty
                return v
            return pick

        def atom(binding: bool) -> str:
            p = draw(st.sampled_from(preds))
            parts = [arg(ty, binding) for ty in s.predicates[p]]
            return " ".join([p] + [x if " " not in x or x.startswith('"') else f"({x})" for x in parts])

        prem = [atom(True) for _ in range(draw(st.integers(1, max_premises)))]
        if persistent and len(prem) > 1 and draw(st.booleans()):
            prem[0] = "!" + prem[0]
        concl = [atom(False) for _ in range(draw(st.integers(0, max_conclusions)))]
        rules.append(f"r{k} : {' * '.join(prem)} -o {{{' * '.join(concl) or '1'}}}.")
    start = [atom_ for atom_ in (_ground_atom(draw, s, preds, max_depth)
                                 for _ in range(draw(st.integers(1, max_facts))))]
    if persistent and draw(st.booleans()):
        start.append("!" + _ground_atom(draw, s, preds, max_depth))
    return s.text.rstrip() + "\n\n" + "\n".join(rules) + "\n#exec * " + " * ".join(start) + ".\n"


def _ground_atom(draw, s: _Sig, preds: list, max_depth: int) -> str:
    p = draw(st.sampled_from(preds))
    parts = [_term(draw, s, ty, max(max_depth, s.depth[ty])) for ty in s.predicates[p]]
    return " ".join([p] + [x if " " not in x or x.startswith('"') else f"({x})" for x in parts])


def clf_programs(signature: str, *, max_rules: int = 4, max_premises: int = 2, max_conclusions: int = 2,
                 max_facts: int = 4, max_depth: int = 1, persistent: bool = True) -> st.SearchStrategy[ClfModel]:
    """Small programs over ``signature`` (CLF text declaring types, constants and predicates):
    the signature, then forward rules ``rK : P * Q -o {R * S}.`` over its predicates (arguments
    are closed terms of depth at most ``max_depth``, or variables bound by the premises), then an
    ``#exec`` start state of ground facts. As :class:`ClfModel` (start: that ``#exec``)."""
    s = _signature(signature)
    if not s.predicates:
        raise InvalidArgument("the signature declares no predicate (a family 'p : A1 -> ... -> type' over "
                              "inhabited base types) to write rules with")
    return _program_text(s, max_rules, max_premises, max_conclusions, max_facts, max_depth, persistent).map(
        lambda text: ClfModel.from_text(text, name="program", check=False))
