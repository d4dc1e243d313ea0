"""Properties in the spec's own terms: state predicates, mission properties, a small temporal layer.

A predicate is written over what a spec names (``docs/checking.md``, "Properties in the
spec's terms"):

* agent variables with the spec's expressions: ``arm::holding == true && gripper::closed == false``,
  ``ptu::heading != 0``, ``base::pose.x < 3`` (``|| && == != < <= > >= + - * / !``, unary ``-``,
  literals, fields; no function calls);
* the job's request: ``request R0 finished`` (``request R0 STATUS``, ``in`` optional);
* requests an agent handles: ``agent planner in temporary-failure``, ``agent ptu idle``;
* tasks: ``task arm::pick running`` (``running``, ``paused``, ``active``, ``idle``);
* events, read on a step (``[invariant] never``, ``[livelock] progress``): ``primitive base::follow
  starts`` (or ``ends``; ``primitive base starts`` for any primitive of base), ``constraint sent to
  gripper``;
* request statuses: ``sent pending running paused temporary-failure succeeded failed finished live``
  (``success``/``failure`` are accepted for ``succeeded``/``failed``).

On top, three temporal forms (one per property): ``always P``, ``eventually P`` and
``P leads-to Q``, decided on the explored graph under weak fairness per agent (the fairness of
livelock), with lasso counterexamples. A predicate reads one state of the compiled model; it is
evaluated on the state decoded by :func:`view_of` (the variables' ``contains`` facts, the
requests' ``rq``/``rs`` facts, the activations' ``act``/``rstat`` facts).

Parsing needs no model (syntax errors are located when a property file is read); names are
resolved against the compiled model when a job runs (:meth:`Formula.bind`), with the file,
line and column of the string and a did-you-mean.
"""

from __future__ import annotations

import heapq
import re
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, Optional

import numpy as np
from lark import Lark, Transformer, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken, VisitError

from ..errors import Pos, RoarError, did_you_mean

#: an empty error context: the logic layer found no task (nothing was tried)
NO_TASK = "empty: no task of the target agent can handle it (nothing was tried)"

__all__ = ["parse_formula", "looks_like_spec", "Formula", "View", "view_of", "REQUEST_STATUSES",
           "TASK_STATUSES", "SpecChecks", "check_eventually", "check_always"]

GRAMMAR = r"""
start: formula
?formula: ALWAYS disj                -> always
        | EVENTUALLY disj            -> eventually
        | disj LEADSTO disj          -> leads_to
        | disj                       -> state
?disj: conj
     | disj OROP conj                -> binop
?conj: cmp
     | conj ANDOP cmp                -> binop
?cmp: sum
    | sum CMPOP sum                  -> binop
?sum: prod
    | sum ADDOP prod                 -> binop
?prod: unary
     | prod MULOP unary              -> binop
?unary: postfix
      | NOT unary                    -> unop
      | ADDOP unary                  -> unop
?postfix: atom
        | postfix "." NAME           -> field
?atom: QNAME                         -> var
     | NAME                          -> bare
     | INT                           -> int_lit
     | DOUBLE                        -> double_lit
     | STRING                        -> string_lit
     | TRUE                          -> true_lit
     | FALSE                         -> false_lit
     | "(" disj ")"
     | REQUEST REQREF IN? WORD       -> request
     | AGENT NAME IN? WORD           -> agent
     | TASK QNAME IN? WORD           -> task
     | PRIMITIVE (QNAME | NAME) WORD -> primitive
     | CONSTRAINT WORD TO NAME       -> constraint_sent

ALWAYS: "always"
EVENTUALLY: "eventually"
LEADSTO: "leads-to"
REQUEST: "request"
AGENT: "agent"
TASK: "task"
IN: "in"
PRIMITIVE: "primitive"
CONSTRAINT: "constraint"
TO: "to"
TRUE: "true"
FALSE: "false"
OROP: "||"
ANDOP: "&&"
CMPOP: "==" | "!=" | "<=" | ">=" | "<" | ">"
ADDOP: "+" | "-"
MULOP: "*" | "/"
NOT: "!"
QNAME.2: /[A-Za-z_][A-Za-z0-9_]*::[A-Za-z_][A-Za-z0-9_]*/
REQREF: /R[0-9]+/
NAME: /[A-Za-z_][A-Za-z0-9_]*/
WORD: /[a-z][a-z-]*[a-z]/
DOUBLE: /[0-9]+\.[0-9]+([eE][+-]?[0-9]+)?/
INT: /[0-9]+/
STRING: /"([^"\\\n]|\\.)*"/
%ignore /[ \t\r\n]+/
"""

REQUEST_STATUSES = ("sent", "pending", "running", "paused", "temporary-failure", "succeeded", "failed",
                    "finished", "live")
_STATUS_SYNONYMS = {"success": "succeeded", "failure": "failed", "temporary_failure": "temporary-failure"}
#: the request states (run.STATE_NAMES) each status word stands for
_STATUS_STATES = {"sent": {"sent"}, "pending": {"pending"}, "running": {"running"}, "paused": {"paused"},
                  "temporary-failure": {"temporary failure"}, "succeeded": {"success"}, "failed": {"failure"},
                  "finished": {"success", "failure"},
                  "live": {"sent", "pending", "running", "paused", "temporary failure"}}
AGENT_STATUSES = REQUEST_STATUSES + ("idle",)
TASK_STATUSES = ("running", "paused", "active", "idle")
_TOKEN_WORDS = {"QNAME": "a variable (agent::var)", "NAME": "a name", "INT": "a number", "DOUBLE": "a number",
                "STRING": "a string", "WORD": "a status word", "REQREF": "R0", "CMPOP": "a comparison",
                "ADDOP": "'+' or '-'", "MULOP": "'*' or '/'", "OROP": "'||'", "ANDOP": "'&&'", "NOT": "'!'",
                "LPAR": "'('", "RPAR": "')'", "DOT": "'.'", "ALWAYS": "'always'", "EVENTUALLY": "'eventually'",
                "LEADSTO": "'leads-to'", "REQUEST": "'request'", "AGENT": "'agent'", "TASK": "'task'",
                "IN": "'in'", "TRUE": "'true'", "FALSE": "'false'", "$END": "the end of the property"}

_PARSER: Optional[Lark] = None


def _parser() -> Lark:
    global _PARSER
    if _PARSER is None:
        _PARSER = Lark(GRAMMAR, parser="lalr", propagate_positions=True, maybe_placeholders=False)
    return _PARSER


# ---------------------------------------------------------------- syntax tree


@dataclass(frozen=True)
class Node:
    kind: str          # var bare lit field binop unop request agent task
    col: int           # 1-based column in the property string
    args: tuple = ()
    text: str = ""     # the source text of the node


@dataclass
class Formula:
    """A parsed property: ``form`` is state, always, eventually or leads-to; ``p`` (and ``q``)."""

    text: str
    form: str
    p: Node
    q: Optional[Node] = None
    pos: Optional[Pos] = None      # where the string starts in its file (errors point inside it)
    # set by bind():
    pf: Optional[Callable] = None
    qf: Optional[Callable] = None
    shown: list = field(default_factory=list)   # what a violation prints: (label, View -> text)
    events: bool = False                         # names an event: evaluated on a step
    p_events: bool = False                       # p (q) names an event: it holds on a step, not in a state
    q_events: bool = False

    def at(self, col: int) -> Optional[Pos]:
        """The position of column ``col`` of the string in its file."""
        if self.pos is None:
            return None
        return Pos(self.pos.file, self.pos.line, self.pos.col + col - 1)

    def bind(self, model) -> "Formula":
        """Resolve names against a compiled model (located errors) and build the evaluators."""
        b = _Binder(model, self)
        self.pf, ty = b.expr(self.p)
        b.want_bool(self.p, ty)
        self.p_events, b.events = b.events, False
        if self.q is not None:
            self.qf, ty = b.expr(self.q)
            b.want_bool(self.q, ty)
        self.q_events = b.events
        self.shown = b.shown
        self.events = self.p_events or self.q_events
        if self.events and self.form == "always":
            raise RoarError(f"in property {self.text!r}: events (primitive ... starts, constraint sent to ...) "
                            "are steps, not states: write 'never' of an event in [invariant] never, or use "
                            "them with eventually / leads-to", self.at(1))
        return self

    def explain(self, view: "View") -> str:
        """The values of what the formula reads, in a state (for violation messages)."""
        return "; ".join(f"{label}{' =' if '::' in label and ' ' not in label else ':'} {fn(view)}"
                         for label, fn in self.shown)


def _src(text: str, meta) -> str:
    try:
        return text[meta.start_pos:meta.end_pos]
    except AttributeError:
        return ""


class _Build(Transformer):
    def __init__(self, text: str):
        super().__init__()
        self.text = text

    def _node(self, kind, meta, *args) -> Node:
        return Node(kind, meta.column if hasattr(meta, "column") else 1, tuple(args), _src(self.text, meta))

    @v_args(meta=True)
    def start(self, meta, c):
        return c[0]

    @v_args(meta=True)
    def always(self, meta, c):
        return ("always", c[1], None)

    @v_args(meta=True)
    def eventually(self, meta, c):
        return ("eventually", c[1], None)

    @v_args(meta=True)
    def leads_to(self, meta, c):
        return ("leads-to", c[0], c[2])

    @v_args(meta=True)
    def state(self, meta, c):
        return ("state", c[0], None)

    @v_args(meta=True)
    def binop(self, meta, c):
        return self._node("binop", meta, str(c[1]), c[0], c[2])

    @v_args(meta=True)
    def unop(self, meta, c):
        return self._node("unop", meta, str(c[0]), c[1])

    @v_args(meta=True)
    def field(self, meta, c):
        return self._node("field", meta, c[0], str(c[1]))

    @v_args(meta=True)
    def var(self, meta, c):
        a, v = str(c[0]).split("::")
        return self._node("var", meta, a, v)

    @v_args(meta=True)
    def bare(self, meta, c):
        return self._node("bare", meta, str(c[0]))

    @v_args(meta=True)
    def int_lit(self, meta, c):
        return self._node("lit", meta, int(str(c[0])), "int")

    @v_args(meta=True)
    def double_lit(self, meta, c):
        return self._node("lit", meta, Fraction(str(c[0])), "double")

    @v_args(meta=True)
    def string_lit(self, meta, c):
        s = str(c[0])[1:-1]
        out, i = [], 0
        while i < len(s):
            if s[i] == "\\" and i + 1 < len(s):
                out.append({"n": "\n", "t": "\t", "r": "\r"}.get(s[i + 1], s[i + 1]))
                i += 2
            else:
                out.append(s[i])
                i += 1
        return self._node("lit", meta, "".join(out), "string")

    @v_args(meta=True)
    def true_lit(self, meta, c):
        return self._node("lit", meta, True, "bool")

    @v_args(meta=True)
    def false_lit(self, meta, c):
        return self._node("lit", meta, False, "bool")

    def _status(self, meta, c, kind, allowed):
        word_tok = c[-1]
        word = _STATUS_SYNONYMS.get(str(word_tok), str(word_tok))
        if word not in allowed:
            raise _Located(f"unknown {kind} status '{word_tok}'{did_you_mean(str(word_tok), allowed)}; "
                           f"expected one of: {', '.join(allowed)}", word_tok.column)
        return word

    @v_args(meta=True)
    def request(self, meta, c):
        ref = c[1]
        if str(ref) != "R0":
            raise _Located(f"'request {ref}': only R0, the job's request, has a fixed name (other requests are "
                           f"numbered along each run); for the requests an agent handles write "
                           f"'agent NAME in STATUS'", ref.column)
        return self._node("request", meta, "R0", self._status(meta, c, "request", REQUEST_STATUSES))

    @v_args(meta=True)
    def agent(self, meta, c):
        return self._node("agent", meta, str(c[1]), self._status(meta, c, "agent", AGENT_STATUSES), c[1].column)

    @v_args(meta=True)
    def primitive(self, meta, c):
        name, word = str(c[1]), str(c[2])
        if word not in ("starts", "ends"):
            raise _Located(f"'primitive {name} {word}': a primitive event is 'starts' or 'ends'"
                           f"{did_you_mean(word, ['starts', 'ends'])}", c[2].column)
        agent, fn = name.split("::") if "::" in name else (name, None)
        return self._node("primitive", meta, agent, fn, word, c[1].column)

    @v_args(meta=True)
    def constraint_sent(self, meta, c):
        if str(c[1]) != "sent":
            raise _Located(f"expected 'constraint sent to AGENT', not 'constraint {c[1]}'", c[1].column)
        return self._node("sent", meta, str(c[3]), c[3].column)

    @v_args(meta=True)
    def task(self, meta, c):
        a, t = str(c[1]).split("::")
        return self._node("task", meta, a, t, self._status(meta, c, "task", TASK_STATUSES))


class _Located(Exception):
    def __init__(self, message: str, col: int):
        super().__init__(message)
        self.message, self.col = message, col


def _expected_words(names: set) -> str:
    names = set(names)
    parts = []
    if {"QNAME", "INT", "REQUEST"} <= names:
        parts.append("a predicate (agent::var, a literal, request/agent/task ...)")
        names -= {"QNAME", "NAME", "INT", "DOUBLE", "STRING", "TRUE", "FALSE", "REQUEST", "AGENT", "TASK",
                  "LPAR", "NOT", "ADDOP", "ALWAYS", "EVENTUALLY"}
    if {"CMPOP", "ANDOP"} <= names:
        parts.append("an operator")
        names -= {"CMPOP", "ANDOP", "OROP", "ADDOP", "MULOP", "DOT"}
    for n in sorted(names, key=lambda x: (x == "$END", x)):
        w = _TOKEN_WORDS.get(n, n.lower())
        if w not in parts:
            parts.append(w)
    if not parts:
        return "nothing more"
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " or " + parts[-1]


def parse_formula(text: str, pos: Optional[Pos] = None, temporal: bool = True) -> Formula:
    """Parse a property string; errors are RoarErrors at the column inside the string (``pos``: where
    the string starts in its file). ``temporal=False`` refuses the temporal forms (state predicates)."""
    def err(msg: str, col: int) -> RoarError:
        where = Pos(pos.file, pos.line, pos.col + col - 1) if pos is not None else Pos("<property>", 1, col)
        return RoarError(f"in property {text!r}: {msg}", where)

    try:
        tree = _parser().parse(text)
        form, p, q = _Build(text).transform(tree)
    except VisitError as exc:
        inner = exc.orig_exc
        if isinstance(inner, _Located):
            raise err(inner.message, inner.col) from None
        raise
    except UnexpectedToken as exc:
        tok = exc.token
        found = "end of the property" if tok.type == "$END" else f"'{tok}'"
        col = exc.column if isinstance(exc.column, int) and exc.column > 0 and tok.type != "$END" \
            else len(text.rstrip()) + 1
        msg = f"unexpected {found}; expected {_expected_words(set(exc.accepts or exc.expected))}"
        if tok.type == "NAME" or (tok.type == "WORD"):
            msg += hint_for_word(str(tok))
        msg += _hint_before(text, col, str(tok) if tok.type != "$END" else "")
        raise err(msg, col) from None
    except UnexpectedCharacters as exc:
        ch = text[exc.pos_in_stream] if exc.pos_in_stream < len(text) else ""
        msg = f"unexpected character {ch!r}"
        if exc.allowed:
            msg += f"; expected {_expected_words(set(exc.allowed))}"
        if ch == "=":
            msg += " (equality is '==')"
        elif ch in "&|":
            msg += f" (write '{ch}{ch}')"
        raise err(msg, exc.column) from None
    except UnexpectedInput as exc:   # pragma: no cover - LALR raises the two above
        raise err(str(exc).splitlines()[0], getattr(exc, "column", 1) or 1) from None
    if form != "state" and not temporal:
        raise err(f"'{form}' is a temporal form: write it under [temporal] (a state predicate goes here)", 1)
    return Formula(text, form, p, q, pos)


#: the words a property begins with or joins its parts by (a misspelt one is suggested)
_KEYWORDS = ("always", "eventually", "leads-to", "request", "agent", "task", "primitive", "constraint")


def _hint_before(text: str, col: int, found: str) -> str:
    """What the text before an unexpected token says went wrong: a nested temporal operator, a
    misspelt keyword read as a name, a function call."""
    before = text[:col - 1]
    temporal = re.findall(r"(?<![\w:-])(always|eventually|leads-to)(?![\w-])", text)
    if len(temporal) >= 2:
        return (f" ('{temporal[0]}' and '{temporal[1]}': temporal operators do not nest; a property is "
                "'always P', 'eventually P' or 'P leads-to Q', with P and Q state predicates)")
    if found == "(" and re.search(r"[A-Za-z_][\w]*(::[A-Za-z_]\w*)?\s*$", before):
        return (" (a property reads the spec's variables and ROAR events; it cannot call a function: "
                "'primitive agent::f starts' and 'primitive agent::f ends' are the events of a call)")
    last = re.search(r"(?<![\w:])([A-Za-z_][\w-]*)\s*$", before)
    if last and last.group(1) not in _KEYWORDS and did_you_mean(last.group(1), _KEYWORDS):
        return did_you_mean(last.group(1), _KEYWORDS)
    if re.fullmatch(r"[A-Za-z_][\w-]*", found) and found not in _KEYWORDS and not hint_for_word(found):
        return did_you_mean(found, _KEYWORDS)
    return ""


def hint_for_word(word: str) -> str:
    if word in ("and", "or", "not"):
        return f" (write {'&&' if word == 'and' else '||' if word == 'or' else '!'})"
    if word in ("leads", "leadsto", "leads_to"):
        return " (write 'leads-to')"
    return ""


def looks_like_spec(text: str) -> bool:
    """Is a ``[invariant] never`` / ``[livelock] progress`` string written in the spec's terms (as
    opposed to a CLF pattern or a rule glob)? It names ``agent::var``, or starts with a keyword of
    the property language, or uses a comparison or ``&&``/``||``. A CLF pattern never does: its
    atoms are ``family arg ...`` joined by ``*``."""
    t = text.strip()
    if "::" in t or any(op in t for op in ("==", "!=", "<", ">", "&&", "||")):
        return True
    first = t.lstrip("!( ").split(None, 1)[0] if t.lstrip("!( ") else ""
    return first in ("request", "agent", "task", "always", "eventually", "primitive", "constraint")


# ---------------------------------------------------------------- states, decoded


@dataclass
class View:
    """One state of the compiled model as the property language reads it."""

    values: dict          # (agent, var) -> Python value (run.value_of)
    r0: Optional[str]     # the job's request's state (run.STATE_NAMES), None when it is gone
    r0_ec: Optional[object]   # the CLF term of R0's error context when it failed (ecf)
    agent_states: dict    # agent -> set of request states it handles
    tasks: dict           # (agent, task) -> set of 'go' / 'paused' (one per activation)
    events: frozenset = frozenset()   # on a step: ('starts'|'ends', owner, function) and ('sent', agent)
    #: the live requests' committed tasks (only when asked for, see :func:`held_tasks`):
    #: request id -> (agent, constraint text, tuple of task names)
    held: Optional[dict] = None


def _view_key(v: View) -> tuple:
    """What a View holds, hashable: two Views with one key read alike in every predicate."""
    return (tuple(sorted((k, _frozen(x)) for k, x in v.values.items())), v.r0, v.r0_ec,
            tuple(sorted((a, tuple(sorted(st))) for a, st in v.agent_states.items())),
            tuple(sorted((t, tuple(sorted(st))) for t, st in v.tasks.items())), v.events,
            None if v.held is None else tuple(sorted(v.held.items(), key=lambda kv: repr(kv[0]))))


def _frozen(x):
    """A Python value of a variable, hashable and told apart by type (True is not 1)."""
    if isinstance(x, (list, tuple)):
        return (type(x).__name__, tuple(_frozen(y) for y in x))
    if isinstance(x, dict):
        return ("dict", tuple(sorted((k, _frozen(y)) for k, y in x.items())))
    return (type(x).__name__, x)


def step_events(model, step) -> frozenset:
    """The events of an engine step the property language names: a primitive starting (a ``pending``
    fact produced) or ending (one consumed), a constraint sent (a new ``rq`` fact)."""
    from . import vocabulary as V
    h = V.head_name
    out = set()
    for part in (getattr(step, "parts", None) or (step,)):
        consumed = [f for _m, f in part.consumed]
        old_reqs = {V.rq(f).request for f in consumed if h(f) == V.RQ}
        for _m, f in part.produced:
            k = h(f)
            if k == V.PENDING:
                fc = h(V.pending(f).fn)
                if fc in model.functions:
                    owner, name = model.functions[fc]
                    out.add(("starts", owner, name))
            elif k == V.RQ:
                q = V.rq(f)
                if q.request not in old_reqs:
                    agent = model.agents.get(h(q.agent))
                    if agent is not None:
                        out.add(("sent", agent))
        for f in consumed:
            if h(f) == V.PENDING:
                fc = h(V.pending(f).fn)
                if fc in model.functions:
                    owner, name = model.functions[fc]
                    out.add(("ends", owner, name))
    return frozenset(out)


def held_tasks(model, ctx) -> dict:
    """The task tree each live request has committed (4.3), read from its agent's mask: request id
    -> (agent, constraint text, task names). A commitment appends, for its request, each committed
    task followed by the tasks incompatible with it (the framework's ``with_incompat``); the committed
    ones are read by skipping, after each, as many entries as the spec makes incompatible with it.
    Entries of a request that failed, was aborted or is gone are not a commitment; a held ensure
    (succeeded, still in force) keeps its tasks."""
    from ..clf.terms import Const
    from . import vocabulary as V
    from .run import STATE_NAMES, list_items
    h = V.head_name
    bag = ctx.index.get(Const(V.RQ))
    about = {q.request: model.csts.get(h(q.cst), ("", "?"))[1] for q in (map(V.rq, bag.items) if bag else ())}
    bag = ctx.index.get(Const(V.RS))
    final = {x.request for x in (map(V.rs, bag.items) if bag else ())
             if STATE_NAMES.get(h(x.state)) in ("failure", "aborted")}   # a held ensure has succeeded
    out = {}
    bag = ctx.index.get(Const(V.MASK))
    for mk in (map(V.mask, bag.items) if bag else ()):
        agent = model.agents.get(h(mk.agent), h(mk.agent))
        by_request: dict = {}
        for e in list_items(mk.entries):
            ent = V.vpair(e)     # vpair (vtsk T) (vreq R)
            by_request.setdefault(V.unwrap(ent.second), []).append(model.tasks.get(h(V.unwrap(ent.first))))
        for r, items in by_request.items():
            if r in final or r not in about:
                continue
            committed, i = [], 0
            while i < len(items) and items[i] is not None:
                task = items[i][1]
                committed.append(task)
                i += 1 + len(model.incompatible.get((agent, task), ()))
            out[r] = (agent, about[r], tuple(committed))
    return out


def view_of(model, ctx, held: bool = False) -> View:
    from ..clf.terms import Const
    from . import vocabulary as V
    from .run import STATE_NAMES, value_of

    def facts(fam, decode):
        bag = ctx.index.get(Const(fam))
        return list(map(decode, bag.items)) if bag else []

    h = V.head_name
    values = {}
    for c in facts(V.CONTAINS, V.contains):
        cell = h(c.cell)
        if cell in model.cells:
            values[model.cells[cell]] = value_of(c.value)
    states = {x.request: STATE_NAMES.get(h(x.state), h(x.state)) for x in facts(V.RS, V.rs)}
    r0 = r0_id = None
    agent_states: dict = {}
    for q in facts(V.RQ, V.rq):
        st = states.get(q.request)
        if h(q.emitter) == "itop":
            r0, r0_id = st, q.request
        agent = model.agents.get(h(q.agent))
        if agent is not None and st is not None:
            agent_states.setdefault(agent, set()).add(st)
    ec = None
    if r0 == "failure":
        ec = next((e.ec for e in facts(V.ECF, V.ecf) if e.request is r0_id or e.request == r0_id), None)
    paused = {z.inst for z in facts(V.RSTAT, V.rstat) if h(z.pause) != "go"}
    tasks: dict = {}
    for a in facts(V.ACT, V.act):
        t = model.tasks.get(h(a.task))
        if t is not None:
            tasks.setdefault(t, set()).add("paused" if a.inst in paused else "go")
    return View(values, r0, ec, agent_states, tasks, held=held_tasks(model, ctx) if held else None)


def _event_text(e) -> str:
    if e[0] == "sent":
        return f"constraint sent to {e[1]}"
    return f"primitive {e[1] + '::' if e[1] else ''}{e[2]} {e[0]}"


# ---------------------------------------------------------------- names and types


_NUM = ("int", "double")


def _fmt(v) -> str:
    from .run import format_value
    return format_value(v)


class _Binder:
    """Resolves a formula's names against a compiled model and builds its evaluator."""

    def __init__(self, model, formula: Formula):
        self.m = model
        self.f = formula
        self.shown: list = []
        self.agents = sorted(set(model.agents.values()))
        self.vars: dict = {}
        for cell, (a, v) in model.cells.items():
            self.vars[(a, v)] = model.cell_types.get(cell)
        self.tasks = set(model.tasks.values())
        self.events = False   # does the formula name an event (then it reads a step, not a state)?

    def error(self, node: Node, msg: str, col: Optional[int] = None) -> RoarError:
        return RoarError(f"in property {self.f.text!r}: {msg}", self.f.at(col or node.col))

    def show(self, label: str, fn) -> None:
        if label not in [x for x, _ in self.shown]:
            self.shown.append((label, fn))

    def want_bool(self, node: Node, ty) -> None:
        if ty not in ("bool", None):
            raise self.error(node, f"'{node.text}' is {ty}, not a condition (compare it: '{node.text} == ...')")

    def agent_name(self, node: Node, a: str, col: Optional[int] = None) -> None:
        if a not in self.agents:
            raise self.error(node, f"unknown agent '{a}'{did_you_mean(a, self.agents)}; the agents are: "
                             f"{', '.join(self.agents)}", col)

    def expr(self, n: Node):
        k = n.kind
        if k == "lit":
            v, ty = n.args
            return (lambda _v, v=v: v), ty
        if k == "bare":
            name = n.args[0]
            owners = sorted(a for (a, v) in self.vars if v == name)
            hint = f"; did you mean '{owners[0]}::{name}'?" if len(owners) == 1 else \
                (f"; agents with a variable '{name}': {', '.join(owners)}" if owners else "")
            raise self.error(n, f"'{name}' is not qualified: variables are written agent::var{hint}")
        if k == "var":
            a, v = n.args
            self.agent_name(n, a)
            if (a, v) not in self.vars:
                names = sorted(x for (ag, x) in self.vars if ag == a)
                raise self.error(n, f"agent '{a}' has no variable '{v}'{did_you_mean(v, names)}; its variables: "
                                 f"{', '.join(names) or 'none'}")
            key = (a, v)
            self.show(f"{a}::{v}", lambda view, key=key: _fmt(view.values.get(key, "?")))
            return (lambda view, key=key: view.values.get(key)), self.vars[key]
        if k == "field":
            inner, fname = n.args
            fn, ty = self.expr(inner)
            names = self.m.structs.get(ty)
            if names is None:
                raise self.error(n, f"'{inner.text}' is {ty or 'not a struct'}, it has no field '{fname}'")
            if fname not in names:
                raise self.error(n, f"type {ty} has no field '{fname}'{did_you_mean(fname, names)}; its fields: "
                                 f"{', '.join(names)}")
            i = names.index(fname)
            fty = self.m.field_types.get(ty, {}).get(fname)
            return (lambda view, fn=fn, i=i: _index(fn(view), i)), fty
        if k == "unop":
            op, x = n.args
            fn, ty = self.expr(x)
            if op == "!":
                self.want_bool(x, ty)
                return (lambda view, fn=fn: _not(fn(view))), "bool"
            if ty not in _NUM + (None,):
                raise self.error(n, f"'-' needs a number, and '{x.text}' is {ty}")
            return (lambda view, fn=fn: _neg(fn(view))), ty
        if k == "binop":
            op, x, y = n.args
            fx, tx = self.expr(x)
            fy, ty = self.expr(y)
            return self.binop(n, op, x, y, fx, tx, fy, ty)
        if k == "request":
            _r0, status = n.args
            want = _STATUS_STATES[status]
            text = self.m.csts.get(self.m.request_cst, ("?", "?"))[1]
            self.show(f"request R0 ({text})", lambda view: view.r0 or "gone")
            return (lambda view, want=want: view.r0 in want), "bool"
        if k == "agent":
            a, status, col = n.args
            self.agent_name(n, a, col)
            self.show(f"agent {a}", lambda view, a=a: ", ".join(
                sorted(view.agent_states.get(a, ()))) or "no request")
            if status == "idle":
                live = _STATUS_STATES["live"]
                return (lambda view, a=a: not (view.agent_states.get(a, set()) & live)), "bool"
            want = _STATUS_STATES[status]
            return (lambda view, a=a, want=want: bool(view.agent_states.get(a, set()) & want)), "bool"
        if k == "primitive":
            a, fn, word, col = n.args
            self.events = True
            fns = sorted({(o, x) for o, x in self.m.functions.values()}, key=str)
            if fn is None:
                owners = sorted({o for o, _x in fns if o})
                if a not in self.agents:
                    raise self.error(n, f"unknown agent '{a}'{did_you_mean(a, self.agents)}; the agents are: "
                                     f"{', '.join(self.agents)}", col)
                if a not in owners:   # the event could never happen: a property that checks nothing
                    raise self.error(n, f"agent '{a}' exports no function the spec calls, so 'primitive {a} "
                                     f"{word}' never happens; the agents whose primitives are called: "
                                     f"{', '.join(owners) or 'none'}", col)
                return (lambda view, a=a, word=word: any(e[0] == word and e[1] == a for e in view.events)), "bool"
            self.agent_name(n, a, col)
            names = sorted(x for o, x in fns if o == a)
            if fn not in names:
                raise self.error(n, f"agent '{a}' exports no function '{fn}' the spec calls{did_you_mean(fn, names)}"
                                 f"; its functions: {', '.join(names) or 'none'}", col)
            key = (word, a, fn)
            return (lambda view, key=key: key in view.events), "bool"
        if k == "sent":
            a, col = n.args
            self.events = True
            self.agent_name(n, a, col)
            return (lambda view, a=a: ("sent", a) in view.events), "bool"
        if k == "task":
            a, t, status = n.args
            self.agent_name(n, a, n.col + 5)
            if (a, t) not in self.tasks:
                names = sorted(x for (ag, x) in self.tasks if ag == a)
                raise self.error(n, f"agent '{a}' has no task '{t}'{did_you_mean(t, names)}; its tasks: "
                                 f"{', '.join(names) or 'none'}", n.col + 5)
            key = (a, t)
            self.show(f"task {a}::{t}", lambda view, key=key: _task_text(view.tasks.get(key)))
            test = {"running": lambda s: "go" in s, "paused": lambda s: "paused" in s,
                    "active": lambda s: bool(s), "idle": lambda s: not s}[status]
            return (lambda view, key=key, test=test: test(view.tasks.get(key, ()))), "bool"
        raise AssertionError(k)   # pragma: no cover

    def binop(self, n, op, x, y, fx, tx, fy, ty):
        if op in ("&&", "||"):
            self.want_bool(x, tx)
            self.want_bool(y, ty)
            if op == "&&":
                return (lambda view: _and(fx(view), fy(view))), "bool"
            return (lambda view: _or(fx(view), fy(view))), "bool"
        if op in ("==", "!="):
            if tx is not None and ty is not None and tx != ty and not (tx in _NUM and ty in _NUM) and \
                    not {tx, ty} <= {"string", "identifier"}:
                raise self.error(n, f"'{x.text}' is {tx} and '{y.text}' is {ty}: they cannot be equal")
            eq = op == "=="
            return (lambda view: _eq(fx(view), fy(view), eq)), "bool"
        if op in ("<", "<=", ">", ">="):
            for e, t in ((x, tx), (y, ty)):
                if t not in _NUM + (None,):
                    raise self.error(e, f"'{op}' compares numbers, and '{e.text}' is {t}")
            cmp = {"<": lambda a, b: a < b, "<=": lambda a, b: a <= b, ">": lambda a, b: a > b,
                   ">=": lambda a, b: a >= b}[op]
            return (lambda view: _num2(cmp, fx(view), fy(view))), "bool"
        if op == "+" and (tx in ("string", "identifier") or ty in ("string", "identifier")):
            return (lambda view: _concat(fx(view), fy(view))), "string"
        for e, t in ((x, tx), (y, ty)):
            if t not in _NUM + (None,):
                raise self.error(e, f"'{op}' needs numbers, and '{e.text}' is {t}")
        rty = "int" if tx == "int" and ty == "int" else ("double" if tx and ty else None)
        if op == "/":
            intdiv = rty == "int"
            return (lambda view: _div(fx(view), fy(view), intdiv)), rty
        f = {"+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b}[op]
        return (lambda view: _num2(f, fx(view), fy(view))), rty


def _task_text(s) -> str:
    if not s:
        return "idle"
    return ", ".join(sorted("running" if x == "go" else "paused" for x in s))


# Evaluation: a value missing from the state (None) makes comparisons false, like an unset variable.
def _index(v, i):
    return v[i] if isinstance(v, (tuple, list)) and i < len(v) else None


def _not(v):
    return None if v is None else not v


def _neg(v):
    return -v if isinstance(v, (int, Fraction)) and not isinstance(v, bool) else None


def _and(a, b):
    return bool(a) and bool(b)


def _or(a, b):
    return bool(a) or bool(b)


def _eq(a, b, eq: bool) -> bool:
    if a is None or b is None:
        return False
    same = (a == b) and (isinstance(a, bool) == isinstance(b, bool))
    return same if eq else not same


def _isnum(v) -> bool:
    return isinstance(v, (int, Fraction)) and not isinstance(v, bool)


def _num2(f, a, b):
    if not (_isnum(a) and _isnum(b)):
        return None
    r = f(a, b)
    if isinstance(r, Fraction) and r.denominator == 1:
        return int(r)
    return r


def _div(a, b, intdiv: bool):
    if not (_isnum(a) and _isnum(b)) or b == 0:
        return None
    q = Fraction(a) / Fraction(b)
    if intdiv:
        return int(q)   # truncated toward zero, as the spec's o_idiv
    return int(q) if q.denominator == 1 else q


def _concat(a, b):
    return a + b if isinstance(a, str) and isinstance(b, str) else None


# ---------------------------------------------------------------- temporal checks on a graph


def check_always(g, prop: str, holds: np.ndarray, why: Callable[[int], str]):
    """``always P``: the shortest path to a state where P is false (states in BFS order)."""
    from ..explore.properties import Counterexample, Verdict, incomplete_note
    bad = np.flatnonzero(~holds[:g.n_states])
    if len(bad):
        s = int(bad[0])
        cx = Counterexample("path", g.path_to(s), final_state=s)
        reason = why(s)
        return Verdict(prop, "violated", f"{reason} (reached in {len(cx.prefix)} steps)", cx, {"reason": reason})
    if not g.complete:
        return incomplete_note(prop, g)
    return Verdict(prop, "holds", f"no violation in {g.n_states:,} states")


def check_eventually(g, prop: str, target: np.ndarray, seeds: np.ndarray, why_end: Callable[[int], str],
                     why_cycle: Callable[[int, int], str], holds_text: str, cut: Optional[np.ndarray] = None,
                     strong: bool = False, target_edges: Optional[np.ndarray] = None):
    """Every fair run from a seed state reaches a ``target`` state (``seeds``: P and not Q for
    ``P leads-to Q``; the start state for ``eventually Q``). Fairness per group, as livelock:
    weak (a group enabled all along a cycle moves on it), or with ``strong`` strong (a group
    enabled anywhere on a cycle moves on it; Emerson-Lei pruning). ``target_edges``: the goal is
    a step (an event) rather than a state: a run reaches it by taking one of those edges.

    A violation is a seed, then a path of non-target states to a quiescent state (the run ends
    without the target) or to a fair cycle of non-target states (a lasso). The counterexample
    minimises the path's length (to the seed by the BFS parent pointers, then inside the region).
    Only expanded states are used, so a violation found in a partial graph is real. ``cut`` marks
    states without successors that are not the end of a run (a robot-backed search's horizon)."""
    from ..explore.properties import (Counterexample, Verdict, cycle_tour, fair_components, incomplete_note,
                                      strong_fair_components, strongly_connected)
    n = g.n_states
    a = g.arrays()
    src, dst, grp = a["src"], a["dst"], a["group"]
    expanded = np.asarray(g.expanded, dtype=bool)
    depth = np.asarray(g.depth, dtype=np.int64)
    target = target[:n]
    hit = np.zeros(len(src), dtype=bool) if target_edges is None else np.asarray(target_edges[:len(src)], dtype=bool)
    seeds = np.flatnonzero(seeds[:n] & ~target)
    if len(seeds) == 0:
        if not g.complete:
            return incomplete_note(prop, g)
        return Verdict(prop, "holds", holds_text)
    # multi-source shortest paths through non-target states (unit steps, seeds start at their depth)
    order = np.argsort(src, kind="stable")
    starts = np.searchsorted(src[order], np.arange(n + 1))
    INF = np.iinfo(np.int64).max
    dist = np.full(n, INF, dtype=np.int64)
    via = np.full(n, -1, dtype=np.int64)
    heap = []
    for s in seeds.tolist():
        dist[s] = depth[s]
        heap.append((int(depth[s]), s))
    heapq.heapify(heap)
    while heap:
        d, u = heapq.heappop(heap)
        if d > dist[u] or not expanded[u]:
            continue
        for e in order[starts[u]:starts[u + 1]].tolist():
            v = int(dst[e])
            if target[v] or hit[e] or d + 1 >= dist[v]:
                continue
            dist[v] = d + 1
            via[v] = e
            heapq.heappush(heap, (d + 1, v))
    region = dist < INF
    outdeg = np.bincount(src, minlength=n)
    best = None   # (length, kind, state, cycle info)
    ends = np.flatnonzero(region & expanded & (outdeg == 0) & (~cut[:n] if cut is not None else True))
    if len(ends):
        e0 = int(ends[np.argmin(dist[ends])])
        best = (int(dist[e0]), "end", e0, None)
    inner = region[src] & region[dst] & expanded[src] & expanded[dst] & ~hit
    isrc, idst = src[inner], dst[inner]
    if len(isrc) and strong:
        found = strong_fair_components(g, inner, src, dst, grp, expanded & region)
        if found is not None:
            member, fair, ci, enabled, comp, cand_edges = found
            fm = np.flatnonzero(member & np.isin(comp, fair))
            entry = int(fm[np.argmin(dist[fm])])
            if best is None or dist[entry] < best[0]:
                c = comp[entry]
                best = (int(dist[entry]), "cycle", entry,
                        (cand_edges[ci == c], set(np.flatnonzero(enabled[c]).tolist())))
    elif len(isrc):
        comp = strongly_connected(n, isrc, idst)
        internal = comp[isrc] == comp[idst]
        cand_edges = np.flatnonzero(inner)[internal]
        if len(cand_edges):
            member, fair, ci, always = fair_components(g, comp, expanded & region, cand_edges, src, grp)
            if len(fair):
                fm = np.flatnonzero(member & np.isin(comp, fair))
                entry = int(fm[np.argmin(dist[fm])])
                if best is None or dist[entry] < best[0]:
                    c = comp[entry]
                    best = (int(dist[entry]), "cycle", entry,
                            (cand_edges[ci == c], set(np.flatnonzero(always[c]).tolist())))
    if best is None:
        if not g.complete:
            return incomplete_note(prop, g)
        return Verdict(prop, "holds", holds_text)
    _, kind, s, extra = best
    tail = []
    u = s
    while via[u] >= 0:
        tail.append(int(via[u]))
        u = int(src[via[u]])
    tail.reverse()
    prefix = g.path_to(u) + tail
    if kind == "end":
        cx = Counterexample("path", prefix, final_state=s)
        reason = why_end(s)
        return Verdict(prop, "violated", f"{reason} (reached in {len(prefix)} steps)", cx,
                       {"reason": reason, "seed": u})
    edges_c, req = extra
    cycle = cycle_tour(g, s, edges_c, req, src, dst, grp, strong)
    cx = Counterexample("lasso", prefix, cycle, final_state=s)
    reason = why_cycle(s, len(cycle))
    names = sorted({g.groups.names[int(grp[e])] for e in cycle})
    kind = "a strongly fair cycle" if strong else "a fair cycle"
    return Verdict(prop, "violated", f"{reason}: {kind} of {len(cycle)} steps reached in {len(prefix)} "
                   f"steps (agents moving: {', '.join(names)})", cx, {"reason": reason, "seed": u})


# ---------------------------------------------------------------- a job's spec-level properties


MISSION_COMPLETION = "eventually request R0 succeeded"
MISSION_FAILURE = "always !request R0 failed"


def incompatible_pairs(model, declared: list, where: str = "the job") -> dict:
    """The pairs property ``incompatible-tasks`` checks: agent -> {frozenset({t, u}): how they are
    incompatible}. ``declared`` ([incompatible-tasks] pairs: ((text, Pos), (text, Pos)) of
    'agent::task' names) is checked against the spec's tasks; when empty, every pair the spec's
    post-conditions make incompatible (4.3), and none is an error (a check of nothing)."""
    derived = {(a, t, u) for (a, t), us in model.incompatible.items() for u in us}
    out: dict = {}
    if not declared:
        if not derived:
            raise RoarError(f"{where}: incompatible-tasks has nothing to check: no two tasks of one agent "
                            "have contradicting post-conditions in this spec; name the tasks that must never "
                            "be held together with [incompatible-tasks] pairs = [[\"agent::task\", "
                            "\"agent::task\"]]")
        for a, t, u in derived:
            out.setdefault(a, {})[frozenset((t, u))] = "their post-conditions contradict"
        return out
    tasks = set(model.tasks.values())
    agents = sorted({a for a, _t in tasks} | set(model.agents.values()))
    for pair in declared:
        names = []
        for text, pos in pair:
            a, _sep, t = text.partition("::")
            if a not in agents:
                raise RoarError(f"unknown agent '{a}'{did_you_mean(a, agents)}; the agents are: "
                                f"{', '.join(agents)}", pos)
            if (a, t) not in tasks:
                own = sorted(x for (ag, x) in tasks if ag == a)
                raise RoarError(f"agent '{a}' has no task '{t}'{did_you_mean(t, own)}; its tasks: "
                                f"{', '.join(own) or 'none'}", pos)
            names.append((a, t))
        (a, t), (b, u) = names
        if a != b:
            raise RoarError(f"'{a}::{t}' and '{b}::{u}' belong to two agents: tasks are incompatible within "
                            "one agent, which commits them (4.3)", pair[1][1])
        if t == u:
            raise RoarError(f"'{a}::{t}' is paired with itself: two requests holding one task is a "
                            "concurrency issue the framework always resolves, not an incompatibility",
                            pair[1][1])
        out.setdefault(a, {})[frozenset((t, u))] = (
            "their post-conditions contradict" if (a, t, u) in derived else
            "declared incompatible; the spec's post-conditions do not contradict, so nothing masks one "
            "while the other is held")
    return out


def incompatible_held(pairs: dict, held: dict) -> Optional[str]:
    """Two live requests of one agent holding tasks of ``pairs`` (:func:`incompatible_pairs`), said
    in the spec's terms, or None; ``held`` is :func:`held_tasks` of the state."""
    by_agent: dict = {}
    for r, (agent, text, tasks) in held.items():
        by_agent.setdefault(agent, []).append((text, tasks))
    for agent, known in pairs.items():
        live = by_agent.get(agent, [])
        for i, (c1, ts1) in enumerate(live):
            for c2, ts2 in live[i + 1:]:
                for t in ts1:
                    for u in ts2:
                        how = known.get(frozenset((t, u)))
                        if how is not None and t != u:
                            both = f"{agent} holds {t} for one live request ({c1}) and {u} for another ({c2}) at once"
                            return f"{both}: {t} and {u} are {how}" if how.startswith("declared") else \
                                f"{both}, although {how}"
    return None


class SpecChecks:
    """The properties of a job on a spec written in the spec's terms, bound to its compiled model:
    the [invariant] always/never predicates, the [temporal] formulas, mission-completion,
    mission-failure and livelock progress predicates. ``decide`` gives their verdicts on a graph
    whose state ``sid`` is the CLF context ``ctx_of(sid)``."""

    def __init__(self, props, model):
        self.model = model
        self.props = props
        self.always = [f.bind(model) for f in getattr(props, "spec_always", [])]
        never = [f.bind(model) for f in getattr(props, "spec_never", [])]
        self.temporal = {name: f.bind(model) for name, f in getattr(props, "temporal", {}).items()}
        for f in self.temporal.values():
            if f.form == "state" and f.events:
                raise RoarError(f"in property {f.text!r}: an event alone is not a temporal property: write "
                                "'eventually EVENT', 'P leads-to EVENT', or 'never EVENT' in [invariant] never",
                                f.at(1))
        self.strong_temporal = set(getattr(props, "temporal_strong", ()))   # decided under strong fairness
        progress = [f.bind(model) for f in getattr(props, "spec_progress", [])]
        for f in self.always:
            if f.events:
                raise RoarError(f"in property {f.text!r}: events (primitive ... starts, constraint sent to ...) "
                                "are steps: write them in [invariant] never or [livelock] progress", f.at(1))
        self.never = [f for f in never if not f.events]
        self.never_steps = [f for f in never if f.events]      # read on a step: its events, the state it leaves
        self.progress = [f for f in progress if not f.events] + [f for f in progress if f.events]
        self._state_progress = [f for f in progress if not f.events]
        self._step_progress = [f for f in progress if f.events]
        self.completion = parse_formula(MISSION_COMPLETION).bind(model)
        self.failure = parse_formula(MISSION_FAILURE).bind(model)
        self.request_text = model.csts.get(model.request_cst, ("?", "?"))[1]
        self.incompatible = incompatible_pairs(model, getattr(props, "incompatible_pairs", []),
                                               props.sources[0] if props.sources else "the job") \
            if "incompatible-tasks" in props.check else {}
        self._views: list = []
        self._key = None
        #: state id -> is it cut off without being the end of a run (robot-backed: the horizon)?
        self.cut: Optional[Callable[[int], bool]] = None

    @property
    def in_use(self) -> bool:
        """Does the job check a predicate or a temporal property in the spec's terms? Partial-order
        reduction is not used then. (Livelock progress predicates are no obstacle: a fair cycle of
        the reduced graph is one of the system, its states are real, and a "holds" under weak
        fairness is confirmed by an unreduced search, verify/check.py ``_search``.)"""
        return bool(self.always or self.never or self.never_steps or set(self.props.check) & self.handles)

    @property
    def handles(self) -> set:
        """The property names decided here (besides 'invariant')."""
        return {"mission-completion", "mission-failure", "incompatible-tasks"} | set(self.temporal)

    def views(self, g, ctx_of) -> list:
        """The decoded states (cached while the same explorer grows)."""
        if self._key is not ctx_of:
            self._key, self._views, self._view_ids = ctx_of, [], {}
        held = bool(self.incompatible)
        shared = self._view_ids
        while len(self._views) < g.n_states:
            v = view_of(self.model, ctx_of(len(self._views)), held)
            # most states read alike (the same values, request and task states): one View each
            # (kept for every state visited, a View of its own was 2.4 KB a state, more than
            # the search kept for the state itself)
            self._views.append(shared.setdefault(_view_key(v), v))
        return self._views

    def values(self, fn, views) -> np.ndarray:
        return np.fromiter((bool(fn(v)) for v in views), dtype=bool, count=len(views))

    def progress_graph(self, g, ctx_of, step_of=None):
        """The graph with its progress flags replaced: a step is progress when it leads to a state
        where one of the state predicates holds, or when an event predicate holds on it."""
        from dataclasses import replace
        views = self.views(g, ctx_of)
        good = np.zeros(len(views), dtype=bool)
        for f in self._state_progress:
            good |= self.values(f.pf, views)
        a = g.arrays()
        prog = good[a["dst"]]
        if self._step_progress:
            prog = prog | self.step_values(self._step_progress, g, views, step_of)
        return replace(g, progress=prog.astype(np.int8))

    def step_view(self, views, g, step_of, e: int) -> View:
        from dataclasses import replace
        return replace(views[int(g.src[e])], events=step_events(self.model, step_of(e)))

    def step_values(self, formulas, g, views, step_of) -> np.ndarray:
        """On every edge: does one of ``formulas`` (with events) hold on it?"""
        if step_of is None:
            raise RoarError("events in properties need the explored steps")   # pragma: no cover
        out = np.zeros(g.n_edges, dtype=bool)
        for e in range(g.n_edges):
            v = self.step_view(views, g, step_of, e)
            out[e] = any(f.pf(v) for f in formulas)
        return out

    def decide(self, p: str, g, ctx_of, clf_bad: Optional[Callable[[int], Optional[str]]] = None, step_of=None):
        """The verdict of ``p`` on graph ``g``; for 'invariant', ``clf_bad`` is the CLF never patterns'
        test (a state matching one is a violation too); ``step_of(e)`` is the engine step of edge e
        (event predicates read it)."""
        from ..explore.properties import check_states
        if p == "invariant" and self.never_steps:
            return self._invariant_with_steps(g, ctx_of, clf_bad, step_of)
        if p == "invariant" and not (self.always or self.never):
            return check_states(g, p, clf_bad)
        views = self.views(g, ctx_of)
        if p == "invariant":
            def why(s):
                if clf_bad is not None:
                    r = clf_bad(s)
                    if r:
                        return r
                v = views[s]
                for f in self.always:
                    if not f.pf(v):
                        return f"a reachable state breaks always {f.text!r}: {f.explain(v)}"
                for f in self.never:
                    if f.pf(v):
                        return f"a reachable state satisfies never {f.text!r}: {f.explain(v)}"
                return None
            return check_states(g, p, why)
        if p == "incompatible-tasks":
            return check_states(g, p, lambda sid: incompatible_held(self.incompatible, views[sid].held))
        if p == "mission-failure":
            bad = self.values(self.failure.pf, views)

            def why(s):
                from .run import describe_ec
                ec = views[s].r0_ec
                ctx = ("; ".join(describe_ec(ec, self.model)) or NO_TASK) if ec is not None else "none recorded"
                return f"request R0 ({self.request_text}) fails; error context (most recent first): {ctx}"
            return check_always(g, p, bad, why)
        if p == "mission-completion":
            return self._eventually(p, g, views, self.completion, None)
        if p in self.temporal:
            f = self.temporal[p]
            if f.form == "always":
                ok = self.values(f.pf, views)
                return check_always(g, p, ok, lambda s: f"a reachable state breaks {f.text!r}: "
                                    f"{f.explain(views[s])}")
            strong = p in self.strong_temporal
            if f.form == "eventually":
                return self._eventually(p, g, views, f, None, strong, step_of)
            if f.form == "leads-to":
                return self._eventually(p, g, views, f, f, strong, step_of)
            ok = self.values(f.pf, views)   # a bare state predicate: it holds in every reachable state
            return check_always(g, p, ok, lambda s: f"a reachable state breaks {f.text!r}: {f.explain(views[s])}")
        raise KeyError(p)

    def _invariant_with_steps(self, g, ctx_of, clf_bad, step_of):
        """Invariants with event predicates: the shortest path to a bad state, or through a bad step
        (a step whose events, with the state it leaves, satisfy a never predicate)."""
        from ..explore.properties import Counterexample, Verdict
        saved, self.never_steps = self.never_steps, []
        try:
            by_state = self.decide("invariant", g, ctx_of, clf_bad) if (self.always or self.never or clf_bad) \
                else None
        finally:
            self.never_steps = saved
        views = self.views(g, ctx_of)
        depth = np.asarray(g.depth, dtype=np.int64)
        best = None
        for e in range(g.n_edges):   # edges are recorded in the order their sources were expanded (BFS)
            src = int(g.src[e])
            if best is not None and depth[src] + 1 >= best[0]:
                break
            v = self.step_view(views, g, step_of, e)
            for f in self.never_steps:
                if f.pf(v):
                    best = (int(depth[src]) + 1, e, f, v)
                    break
        if best is not None and (by_state is None or by_state.status != "violated" or
                                 best[0] < len(by_state.counterexample.prefix)):
            _d, e, f, v = best
            prefix = g.path_to(int(g.src[e])) + [e]
            cx = Counterexample("path", prefix, final_state=int(g.dst[e]))
            events = ", ".join(_event_text(x) for x in sorted(v.events)) or "none"
            why = f"a step satisfies never {f.text!r}: its events: {events}; in the state it leaves: {f.explain(v)}"
            return Verdict("invariant", "violated", f"{why} (reached in {len(prefix)} steps)", cx, {"reason": why})
        if by_state is not None and (by_state.status == "violated" or not g.complete):
            return by_state
        if not g.complete:
            from ..explore.properties import incomplete_note
            return incomplete_note("invariant", g)
        return Verdict("invariant", "holds", f"no violation in {g.n_states:,} states and {g.n_edges:,} steps")

    def edge_values(self, fn, g, views, step_of) -> np.ndarray:
        """On every edge: does ``fn`` hold on that step (the state it leaves, and its events)?"""
        if step_of is None:
            raise RoarError("events in properties need the explored steps")   # pragma: no cover
        return np.fromiter((bool(fn(self.step_view(views, g, step_of, e))) for e in range(g.n_edges)),
                           dtype=bool, count=g.n_edges)

    def _eventually(self, p, g, views, f: Formula, leads: Optional[Formula], strong: bool = False, step_of=None):
        qf = f.qf if leads is not None else f.pf
        goal_event = f.q_events if leads is not None else f.p_events
        target_edges = None
        if goal_event:   # the goal is a step: reached by taking an edge on which it holds
            target = np.zeros(len(views), dtype=bool)
            target_edges = self.edge_values(qf, g, views, step_of)
        else:
            target = self.values(qf, views)
        if leads is None:
            seeds = np.zeros(len(views), dtype=bool)
            seeds[0] = True
            what = "R0 never succeeds" if f is self.completion else f"never {f.p.text!r}"
        else:
            if f.p_events:   # after the step on which P holds: the states those steps reach
                seeds = np.zeros(len(views), dtype=bool)
                hit = self.edge_values(f.pf, g, views, step_of)
                dst = np.asarray(g.arrays()["dst"])
                seeds[dst[hit][dst[hit] < len(views)]] = True
            else:
                seeds = self.values(f.pf, views)
            what = f"after {f.p.text!r}, never {f.q.text!r}"
        goal = f.q.text if leads is not None else f.p.text

        def why_end(s):
            v = views[s]
            if f is self.completion:
                if v.r0 == "failure":
                    from .run import describe_ec
                    ctx = ("; ".join(describe_ec(v.r0_ec, self.model)) or NO_TASK) if v.r0_ec is not None \
                        else "none recorded"
                    return f"a run ends with request R0 ({self.request_text}) failed; error context: {ctx}"
                return f"a run ends with request R0 ({self.request_text}) {v.r0 or 'gone'}, not succeeded"
            return f"a run ends without {goal!r} ({what})" + ("" if goal_event else f": {f.explain(v)}")

        def why_cycle(s, k):
            v = views[s]
            if f is self.completion:
                return f"request R0 ({self.request_text}) never succeeds: it stays {v.r0 or 'gone'} on a run " \
                       f"that repeats forever"
            return f"{what} on a run that repeats forever" + ("" if goal_event else f" ({f.explain(v)})")
        fair = f"under {'strong' if strong else 'weak'} fairness per agent"
        if leads is None:
            holds = f"every fair run reaches {goal!r} ({fair}; {g.n_states:,} states)"
        else:
            holds = f"every fair run from {f.p.text!r} reaches {goal!r} ({fair}; {g.n_states:,} states)"
        cut = None
        if self.cut is not None:
            cut = np.fromiter((bool(self.cut(i)) for i in range(len(views))), dtype=bool, count=len(views))
        verdict = check_eventually(g, p, target, seeds, why_end, why_cycle, holds, cut, strong, target_edges)
        if leads is not None and verdict.status == "holds" and not seeds[:g.n_states].any():
            # no run ever meets the trigger: the property checked nothing
            verdict.message = (f"vacuously: no reachable state {'follows a step where' if f.p_events else 'satisfies'}"
                               f" {f.p.text!r} ({g.n_states:,} states)")
            verdict.details["vacuous"] = f"{f.p.text!r} is never reached"
        return verdict
