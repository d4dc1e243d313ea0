"""Parser and loader for the ROAR agent spec language (both layouts).

The grammar lives in ``spec.lark`` next to this module and is compiled once,
lazily, into a lark LALR(1) parser with the contextual lexer; the AST
(:mod:`.ast`) is built during parsing by an inline transformer. Every lark
error becomes a :class:`~roar_formal.errors.SyntaxError_` with a position and
a message in terms of the source text; no lark exception escapes.

Entry points:

* :func:`read_spec` reads a ``.roar`` file, a ``.ability`` file (hyper layout,
  with its task folder and imports) or a folder of ``.ability`` files (the
  static checks are :mod:`.checks`'; :func:`.spec.load_spec` runs both).
* :func:`parse_roar` parses single-file text; :func:`parse_expr` and
  :func:`parse_constraint` parse an expression or a request
  (``demo_loco::pos == demo_loco::goal where demo_loco::goal == 5``).
* :func:`hyper_compat_warnings` lists the expressions that hyper's grammar
  (where ``&&`` and ``||`` bound tighter than comparisons) reads differently.
"""

from __future__ import annotations

import contextvars
import dataclasses
import functools
import re
from importlib import resources
from os import PathLike
from pathlib import Path
from typing import Optional, Union

from lark import Lark, Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from ..errors import Pos, RoarError, SyntaxError_
from . import ast as a
from .pretty import format_expr

__all__ = [
    "read_spec", "parse_roar", "parse_expr", "parse_constraint", "parse_task", "parse_recipes",
    "hyper_compat_warnings", "HYPER_PREC",
]

_FILE: contextvars.ContextVar[str] = contextvars.ContextVar("roar_spec_file", default="<input>")


#: the longest number literal read (Python refuses to convert ints of more than 4,300 digits)
MAX_DIGITS = 1000


def _short_enough(tok: Token) -> None:
    if len(tok) > MAX_DIGITS:
        raise SyntaxError_(f"a number of {len(tok):,} characters: at most {MAX_DIGITS:,} are read", _tpos(tok))


def _tpos(tok: Token) -> Pos:
    return Pos(_FILE.get(), tok.line, tok.column)


_STRING_ESCAPES = {'"': '"', "\\": "\\", "n": "\n", "t": "\t", "r": "\r"}


def _unquote(tok: Token) -> str:
    body = str(tok)[1:-1]
    out: list[str] = []
    i = 0
    while i < len(body):
        ch = body[i]
        if ch == "\\":
            nxt = body[i + 1]
            if nxt not in _STRING_ESCAPES:
                p = _tpos(tok)
                raise SyntaxError_(f"unknown escape '\\{nxt}' in a string; the escapes are "
                                   f"\\\" \\\\ \\n \\t \\r", Pos(p.file, p.line, p.col + 1 + i))
            out.append(_STRING_ESCAPES[nxt])
            i += 2
        else:
            out.append(ch)
            i += 1
    return "".join(out)


def _fields(owner: str, items: list) -> dict[str, object]:
    """Collect ``(keyword, token, value)`` fields, refusing duplicates."""
    seen: dict[str, Token] = {}
    out: dict[str, object] = {}
    for key, tok, value in items:
        if key in seen:
            first = seen[key]
            raise SyntaxError_(f"'{key}' is given twice in {owner} (first at {first.line}:{first.column})",
                               _tpos(tok))
        seen[key] = tok
        out[key] = value
    return out


_CONTEXT_HELP = "{ controllable } { readable } { private }"
_EXPORT_HELP = "{ types } { functions } { rules }"
_EXPORT_KIND = {a.StructType: 0, a.NewType: 0, a.OpaqueType: 0, a.Function: 1, a.Rule: 2}
_EXPORT_WHAT = ["a type", "a function", "a rule"]
_EXPORT_GROUP = ["first", "second", "third"]


class _Build(Transformer):
    """Turns each grammar rule into an AST node as soon as it is reduced."""

    # -- files -------------------------------------------------------------
    def spec_file(self, c):
        imports = tuple(x for x in c if isinstance(x, a.Import))
        agents = tuple(x for x in c if isinstance(x, a.Agent))
        return imports, agents

    def task_file(self, c):
        return c[0]

    def anon_task(self, c):
        kw, _lb, *fields = c
        return self._task(kw, "", fields)

    def recipe_file(self, c):
        return tuple(c)

    def anon_recipe(self, c):
        kw, _lb, *fields = c
        return (self._recipe(kw, "", fields),)

    def lone_expr(self, c):
        return c[0]

    def lone_constraint(self, c):
        return c[0]

    def import_decl(self, c):
        return a.Import(_unquote(c[1]), pos=_tpos(c[0]))

    # -- agents --------------------------------------------------------------
    def agent_decl(self, c):
        name, _lb, *fields = c
        f = _fields(f"agent '{name}'", fields)
        ctl, rd, prv = f.get("context", ((), (), ()))
        types, funcs, rules = f.get("export", ((), (), ()))
        return a.Agent(str(name), ctl, rd, prv, types, funcs, rules, f.get("tasks", ()),
                       pos=_tpos(name))

    def context_field(self, c):
        kw, _lb, *groups = c
        if len(groups) not in (0, 3):
            where = groups[3][0] if len(groups) > 3 else kw
            raise SyntaxError_(
                f"a context has three groups, {_CONTEXT_HELP}, not {len(groups)} "
                f"(write {{ }} for an empty group)", _tpos(where))
        if not groups:
            return ("context", kw, ((), (), ()))
        out = tuple(tuple(dataclasses.replace(v, access=acc) for v in vs)
                    for acc, (_tok, vs) in zip(a.ACCESS, groups))
        return ("context", kw, out)

    def var_group(self, c):
        return c[0], tuple(c[1:])

    def var_decl(self, c):
        ty, name, *init = c
        return a.Var(str(name), ty, init[0] if init else None, pos=_tpos(name))

    def type_ref(self, c):
        if len(c) == 1:
            return a.TypeRef(str(c[0]), pos=_tpos(c[0]))
        return a.TypeRef(str(c[1]), str(c[0]), pos=_tpos(c[0]))

    def export_field(self, c):
        kw, _lb, *groups = c
        if len(groups) not in (0, 3):
            where = groups[3][0] if len(groups) > 3 else kw
            raise SyntaxError_(
                f"an export has three groups, {_EXPORT_HELP}, not {len(groups)} "
                f"(write {{ }} for an empty group)", _tpos(where))
        if not groups:
            return ("export", kw, ((), (), ()))
        for i, (_tok, items) in enumerate(groups):
            for item in items:
                k = _EXPORT_KIND[type(item)]
                if k != i:
                    raise SyntaxError_(
                        f"'{item.name}' is {_EXPORT_WHAT[k]}, but this is the {_EXPORT_GROUP[i]} export "
                        f"group; {_EXPORT_WHAT[k][2:]}s go in the {_EXPORT_GROUP[k]} group "
                        f"({_EXPORT_HELP})", item.pos)
        return ("export", kw, tuple(items for _tok, items in groups))

    def export_group(self, c):
        return c[0], tuple(c[1:])

    def struct_decl(self, c):
        name, _lb, *fields = c
        return a.StructType(str(name), tuple(fields), pos=_tpos(name))

    def struct_field(self, c):
        ty, name = c
        return a.StructField(str(name), ty, pos=_tpos(name))

    def newtype_decl(self, c):
        name, base = c
        return a.NewType(str(name), base, pos=_tpos(name))

    def opaque_decl(self, c):
        return a.OpaqueType(str(c[0]), pos=_tpos(c[0]))

    def func_decl(self, c):
        result, name, _lp, params = c
        return a.Function(str(name), result, params, pos=_tpos(name))

    def params(self, c):
        return tuple(c)

    def param(self, c):
        if len(c) == 1:
            return a.Param(c[0], pos=c[0].pos)
        return a.Param(c[0], str(c[1]), pos=c[0].pos)

    def rule_decl(self, c):
        name, premises, _ts, conclusions = c
        if not conclusions:
            raise SyntaxError_(f"rule '{name}' has no conclusion after '|-'", _tpos(_ts))
        return a.Rule(str(name), premises, conclusions, pos=_tpos(name))

    def expr_list(self, c):
        return tuple(c)

    def tasks_field(self, c):
        kw, _lb, *tasks = c
        return ("tasks", kw, tuple(tasks))

    # -- tasks and recipes -------------------------------------------------
    def _task(self, at: Token, name: str, fields):
        f = _fields(f"task '{name}'" if name else "this task", fields)
        return a.Task(name, f.get("pre", ()), f.get("post", ()), f.get("recipes", ()), pos=_tpos(at))

    def task_decl(self, c):
        name, _kw, _lb, *fields = c
        return self._task(name, str(name), fields)

    def field(self, c):
        kw, value = c
        return (str(kw), kw, value)

    def recipes_field(self, c):
        kw, _lb, *recipes = c
        return ("recipes", kw, tuple(recipes))

    def _recipe(self, at: Token, name: str, fields):
        f = _fields(f"recipe '{name}'" if name else "this recipe", fields)
        return a.Recipe(name, f.get("pre", ()), f.get("post", ()), f.get("prefer"),
                        f.get("body", ()), f.get("end", ()), pos=_tpos(at))

    def recipe_decl(self, c):
        name, _kw, _lb, *fields = c
        return self._recipe(name, str(name), fields)

    def conditions(self, c):
        return tuple(c[1:])

    def condition(self, c):
        return c[1]

    def block(self, c):
        return tuple(c[1:])

    # -- statements --------------------------------------------------------
    def let_stmt(self, c):
        kw, name, value = c
        return a.Let(str(name), value, pos=_tpos(kw))

    def let_ensure(self, c):
        kw, name, ens = c
        return dataclasses.replace(ens, handle=str(name), pos=_tpos(kw))

    def set_stmt(self, c):
        kw, name, value = c
        return a.Set(a.Name(str(name), pos=_tpos(name)), value, pos=_tpos(kw))

    def set_remote(self, c):
        kw, agent, name, value = c
        return a.Set(a.Remote(str(agent), str(name), pos=_tpos(agent)), value, pos=_tpos(kw))

    def make_call(self, c):
        kw, _lp, constraint = c
        return a.Make(constraint, pos=_tpos(kw))

    def ensure_call(self, c):
        kw, _lp, constraint, *period = c
        return a.Ensure(constraint, period[0] if period else None, pos=_tpos(kw))

    def wait_stmt(self, c):
        kw, _lp, cond, *period = c
        return a.Wait(cond, period[0] if period else None, pos=_tpos(kw))

    def assert_stmt(self, c):
        kw, _lp, cond, *period = c
        return a.Assert(cond, period[0] if period else None, pos=_tpos(kw))

    def abort_stmt(self, c):
        kw, name = c
        return a.Abort(str(name), pos=_tpos(kw))

    def expr_stmt(self, c):
        return a.ExprStmt(c[0], pos=c[0].pos)

    def constraint(self, c):
        """A constraint (a request, or what make and ensure send). A bare boolean variable ``x`` is
        read as ``x == true`` and ``!x`` as ``x == false``: the form tasks' post-conditions take,
        so that the logic layer finds the tasks that achieve it (it proves comparisons)."""
        expr = _as_comparison(c[0])
        if len(c) == 1:
            return a.Constraint(expr, pos=expr.pos)
        _expr, where_kw, clause = c
        pairs = []
        for conj in a.conjuncts(clause):
            if not (isinstance(conj, a.Binary) and conj.op == "=="):
                raise SyntaxError_(
                    f"'{format_expr(conj)}' is not a pair: a where clause is a list of "
                    f"'variable == value' pairs joined by '&&'", conj.pos)
            pairs.append(a.WherePair(conj.left, conj.right, pos=conj.pos))
        return a.Constraint(expr, tuple(pairs), pos=expr.pos)

    # -- expressions -------------------------------------------------------
    def binary(self, c):
        left, op, right = c
        return a.Binary(str(op), left, right, pos=left.pos, op_pos=_tpos(op))

    def unary(self, c):
        op, operand = c
        return a.Unary(str(op), operand, pos=_tpos(op))

    def field_access(self, c):
        base, _dot, name = c
        return a.Field(base, str(name), pos=base.pos)

    def int_lit(self, c):
        _short_enough(c[0])
        return a.IntLit(int(c[0]), pos=_tpos(c[0]))

    def double_lit(self, c):
        _short_enough(c[0])
        return a.DoubleLit(float(c[0]), pos=_tpos(c[0]))

    def string_lit(self, c):
        return a.StringLit(_unquote(c[0]), pos=_tpos(c[0]))

    def bool_lit(self, c):
        return a.BoolLit(c[0].type == "TRUE", pos=_tpos(c[0]))

    def name(self, c):
        return a.Name(str(c[0]), pos=_tpos(c[0]))

    def remote(self, c):
        return a.Remote(str(c[0]), str(c[1]), pos=_tpos(c[0]))

    def call(self, c):
        name, _lp, args = c
        return a.Call(str(name), args, pos=_tpos(name))

    def remote_call(self, c):
        agent, name, _lp, args = c
        return a.Call(str(name), args, str(agent), pos=_tpos(agent))

    def args(self, c):
        return tuple(c)

    def last_error(self, c):
        kw, _lp, expr = c
        return a.LastError(expr, pos=_tpos(kw))

    def paren(self, c):
        lp, expr = c
        return dataclasses.replace(expr, parens=True, pos=_tpos(lp))


def _as_comparison(e: a.Expr) -> a.Expr:
    """``x`` as ``x == true``, ``!x`` as ``x == false`` (a variable alone); any other expression as it is."""
    value = True
    if isinstance(e, a.Unary) and e.op == "!" and isinstance(e.operand, (a.Name, a.Remote)):
        e, value = e.operand, False
    if isinstance(e, (a.Name, a.Remote)):
        return a.Binary("==", e, a.BoolLit(value, pos=e.pos), pos=e.pos, op_pos=e.pos, implied=True)
    return e


_STARTS = ["spec_file", "task_file", "recipe_file", "lone_expr", "lone_constraint"]


@functools.cache
def _parser() -> Lark:
    grammar = resources.files(__package__).joinpath("spec.lark").read_text(encoding="utf-8")
    return Lark(grammar, parser="lalr", lexer="contextual", start=_STARTS,
                transformer=_Build(), maybe_placeholders=False)


@functools.cache
def _literals() -> dict[str, str]:
    """Terminal name -> its text, for the terminals that are fixed strings."""
    out = {}
    for t in _parser().terminals:
        if t.pattern.type == "str":
            out[t.name] = t.pattern.value
    return out


def _run(text: str, file: str, start: str):
    _check_comments(text, file)
    token = _FILE.set(file)
    try:
        return _parser().parse(text, start=start)
    except UnexpectedInput as e:
        err = _convert(e, text, file)
    finally:
        _FILE.reset(token)
    raise err from None


# ---------------------------------------------------------------------------
# Public parsing functions
# ---------------------------------------------------------------------------


def parse_expr(text: str, file: str = "<input>") -> a.Expr:
    """Parse one expression."""
    return _run(text, file, "lone_expr")


def parse_constraint(text: str, file: str = "<input>") -> a.Constraint:
    """Parse a constraint (a request): ``expr [where a == b && ...]`` (see ``_Build.constraint``)."""
    return _run(text, file, "lone_constraint")


def parse_task(text: str, file: str = "<input>", name: str = "") -> a.Task:
    """Parse a hyper task file; an anonymous ``task { ... }`` takes ``name``."""
    t = _run(text, file, "task_file")
    return t if t.name else dataclasses.replace(t, name=name)


def parse_recipes(text: str, file: str = "<input>", name: str = "") -> tuple[a.Recipe, ...]:
    """Parse a hyper recipe file; an anonymous ``recipe { ... }`` takes ``name``."""
    rs = _run(text, file, "recipe_file")
    return tuple(r if r.name else dataclasses.replace(r, name=name) for r in rs)


def parse_roar(text: str, file: str = "<input>", *, hyper_compat: bool = False) -> a.Spec:
    """Parse single-file text (agents with nested tasks and recipes).

    Imports are kept as written (not loaded; see :func:`load_spec`) and given
    to every agent of the text. With ``hyper_compat`` the spec's warnings list
    the expressions hyper would read differently.
    """
    imports, agents = _run(text, file, "spec_file")
    agents = tuple(dataclasses.replace(ag, imports=imports) for ag in agents)
    spec = a.Spec(agents, pos=Pos(file, 1, 1))
    if hyper_compat:
        spec = dataclasses.replace(spec, warnings=tuple(hyper_compat_warnings(spec)))
    return spec


# ---------------------------------------------------------------------------
# Loading files and folders
# ---------------------------------------------------------------------------


def _read(path: Path, pos: Optional[Pos] = None, what: str = "read") -> str:
    name = str(path)
    from ..inputs import check_input_file
    check_input_file(path, pos)
    try:
        with open(path, encoding="utf-8-sig") as f:
            return f.read()
    except FileNotFoundError:
        raise RoarError(f"cannot {what} {name}: no such file", pos) from None
    except IsADirectoryError:
        raise RoarError(f"cannot {what} {name}: it is a folder", pos) from None
    except UnicodeDecodeError as e:
        raise RoarError(f"cannot {what} {name}: not valid UTF-8 (byte {e.start})", pos) from None
    except OSError as e:
        raise RoarError(f"cannot {what} {name}: {e.strerror or e}", pos) from None


def _listing(folder: Path) -> list[Path]:
    """A folder's entries, sorted by name, without hidden files and editor backups."""
    return sorted((p for p in folder.iterdir()
                   if not p.name.startswith(".") and not p.name.endswith("~")),
                  key=lambda p: p.name)


class _Loader:
    def __init__(self):
        self.agents: list[a.Agent] = []
        self.warnings: list[a.SpecWarning] = []
        self.names: dict[Path, tuple[str, ...]] = {}  # file -> agents it declares

    def load(self, path: Path, at: Optional[Pos] = None) -> tuple[str, ...]:
        key = path.resolve()
        if key in self.names:
            return self.names[key]
        if path.suffix == ".ability":
            return self._ability(path, key, at)
        if path.suffix == ".roar":
            return self._roar(path, key, at)
        raise RoarError(f"cannot load {path}: a spec file ends in .ability (hyper layout) or .roar "
                        f"(single-file layout)", at)

    def _imports(self, path: Path, imports: tuple[a.Import, ...]) -> tuple[a.Import, ...]:
        out = []
        for imp in imports:
            target = path.parent / imp.path
            if not target.is_file():
                raise RoarError(f"cannot import \"{imp.path}\": there is no file {target}", imp.pos)
            names = self.load(target, imp.pos)
            out.append(dataclasses.replace(imp, agents=names))
        return tuple(out)

    def _roar(self, path: Path, key: Path, at: Optional[Pos]) -> tuple[str, ...]:
        text = _read(path, at, "import" if at else "read")
        imports, agents = _run(text, str(path), "spec_file")
        names = tuple(ag.name for ag in agents)
        self.names[key] = names
        index = len(self.agents)
        self.agents.extend(agents)
        imports = self._imports(path, imports)
        for i, ag in enumerate(agents):
            self.agents[index + i] = dataclasses.replace(ag, imports=imports, layout="roar")
        return names

    def _ability(self, path: Path, key: Path, at: Optional[Pos]) -> tuple[str, ...]:
        text = _read(path, at, "import" if at else "read")
        file = str(path)
        imports, agents = _run(text, file, "spec_file")
        if len(agents) != 1:
            where = agents[1].pos if len(agents) > 1 else Pos(file, *_end(text))
            raise SyntaxError_(f"a .ability file holds exactly one agent; {path.name} has {len(agents)}"
                               + ("" if agents else " (expected 'NAME = ability { ... }')"), where)
        ag = agents[0]
        if ag.name != path.stem:
            self.warnings.append(a.SpecWarning(
                ag.pos, f"agent '{ag.name}' is declared in {path.name}; hyper expects the file "
                        f"to be named {ag.name}.ability (its tasks are read from {path.stem}/)"))
        self.names[key] = (ag.name,)
        index = len(self.agents)
        self.agents.append(ag)
        tasks = ag.tasks + self._task_folder(path.parent / path.stem, ag.name)
        imports = self._imports(path, imports)
        self.agents[index] = dataclasses.replace(ag, tasks=tasks, imports=imports, layout="hyper")
        return (ag.name,)

    def _task_folder(self, folder: Path, agent: str) -> tuple[a.Task, ...]:
        if not folder.is_dir():
            return ()
        entries = _listing(folder)
        tasks: list[a.Task] = []
        stems: list[str] = []
        for p in entries:
            if p.is_file():
                t = parse_task(_read(p), str(p), name=p.stem)
                tasks.append(t)
                stems.append(p.stem)
        for d in entries:
            if not d.is_dir():
                continue
            i = next((i for i, t in enumerate(tasks) if t.name == d.name), None)
            if i is None:
                i = next((i for i, s in enumerate(stems) if s == d.name), None)
            if i is None:
                known = ", ".join(t.name for t in tasks) or "none"
                raise RoarError(f"recipe folder {d} matches no task of agent '{agent}' "
                                f"(its tasks: {known}); a task NAME's recipes go in {folder}/NAME/",
                                Pos(str(d), 1, 1))
            recipes: list[a.Recipe] = []
            for f in _listing(d):
                if f.is_dir():
                    raise RoarError(f"{f} is a folder; a task's recipe folder holds recipe files only",
                                    Pos(str(f), 1, 1))
                recipes.extend(parse_recipes(_read(f), str(f), name=f.stem))
            tasks[i] = dataclasses.replace(tasks[i], recipes=tasks[i].recipes + tuple(recipes))
        return tuple(tasks)


def read_spec(path: Union[str, PathLike], *, hyper_compat: bool = False) -> a.Spec:
    """Parse a spec: a ``.roar`` file, a ``.ability`` file, or a folder of ``.ability`` files
    (the static checks are :mod:`.checks`'; :func:`roar_formal.roar.spec.load_spec` runs both).

    A ``.ability`` file brings its task folder (``NAME/``, recipes in
    ``NAME/TASK/``) and the files it imports; a folder loads every ``.ability``
    file in it (or, when it has none, every ``.roar`` file). With ``hyper_compat``
    the spec's ``warnings`` include every expression that hyper's grammar reads
    differently.
    """
    p = Path(path)
    loader = _Loader()
    if p.is_dir():
        files = [f for f in _listing(p) if f.suffix == ".ability" and f.is_file()]
        files = files or [f for f in _listing(p) if f.suffix == ".roar" and f.is_file()]
        if not files:
            raise RoarError(f"{p} holds no .ability or .roar file")
        for f in files:
            loader.load(f)
    elif not p.exists():
        raise RoarError(f"cannot read {p}: no such file or folder")
    else:
        loader.load(p)
    spec = a.Spec(tuple(loader.agents), pos=Pos(str(p), 1, 1))
    warnings = list(loader.warnings)
    if hyper_compat:
        warnings += hyper_compat_warnings(spec)
    return dataclasses.replace(spec, warnings=tuple(sorted(warnings, key=_wkey)))


def _wkey(w: a.SpecWarning):
    return (w.pos.file, w.pos.line, w.pos.col, w.message)


# ---------------------------------------------------------------------------
# hyper compatibility: '&&' and '||' bound tighter than comparisons
# ---------------------------------------------------------------------------

#: hyper's binding strengths (higher binds tighter): comparisons loosest, then ||, &&, + -, * /.
HYPER_PREC = {"||": 2, "&&": 3, "+": 4, "-": 4, "*": 5, "/": 5, **{op: 1 for op in a.COMPARISONS}}


def _flatten(root: a.Binary) -> tuple[list[a.Expr], list[str], object]:
    """Leaves, operators and shape of the operator chain at ``root``.

    The chain stops at parenthesised sub-expressions and non-binary nodes
    (both grammars read those the same way). The shape is a nested tuple
    ``(op, left, right)`` over leaf indices.
    """
    leaves: list[a.Expr] = []
    ops: list[str] = []

    def go(e: a.Expr, top: bool):
        if isinstance(e, a.Binary) and (top or not e.parens):
            left = go(e.left, False)
            ops.append(e.op)
            right = go(e.right, False)
            return (e.op, left, right)
        leaves.append(e)
        return len(leaves) - 1

    shape = go(root, True)
    return leaves, ops, shape


def _climb(ops: list[str], prec: dict[str, int]):
    """Shape of ``leaf0 op0 leaf1 op1 ...`` read with ``prec``, every level left-associative."""
    pos = [0, 0]  # next leaf, next op

    def parse(min_prec: int):
        left = pos[0]
        pos[0] += 1
        while pos[1] < len(ops) and prec[ops[pos[1]]] >= min_prec:
            op = ops[pos[1]]
            pos[1] += 1
            right = parse(prec[op] + 1)
            left = (op, left, right)
        return left

    return parse(0)


def _render(shape, leaves: list[a.Expr], top: bool = True) -> str:
    if isinstance(shape, int):
        leaf = leaves[shape]
        text = format_expr(leaf)
        return f"({text})" if isinstance(leaf, a.Binary) else text
    op, l, r = shape
    text = f"{_render(l, leaves, False)} {op} {_render(r, leaves, False)}"
    return text if top else f"({text})"


def hyper_compat_warnings(node: a.Node) -> list[a.SpecWarning]:
    """Where hyper's grammar would read an expression of ``node`` differently from ours.

    hyper gave ``&&`` and ``||`` a tighter binding than the comparisons
    (``a < b && c < d`` was ``a < (b && c) < d``). Each warning is at the start
    of the expression and shows both readings. ``where`` clauses are lists of
    pairs in both grammars, so only the two sides of each pair are examined.
    """
    out: list[a.SpecWarning] = []

    def visit(n: a.Node):
        if isinstance(n, a.Binary):
            leaves, ops, ours = _flatten(n)
            theirs = _climb(ops, HYPER_PREC)
            if theirs != ours:
                out.append(a.SpecWarning(n.pos, (
                    f"hyper reads this as '{_render(theirs, leaves)}' because '&&' and '||' bound "
                    f"tighter than comparisons in its grammar; here it means "
                    f"'{_render(ours, leaves)}'. Add parentheses to mean the same in both")))
            for leaf in leaves:
                visit(leaf)
        else:
            for ch in n.children():
                visit(ch)

    visit(node)
    return sorted(out, key=_wkey)


# ---------------------------------------------------------------------------
# Error messages
# ---------------------------------------------------------------------------

_EXPR_START = {"ID", "INT", "DOUBLE", "STRING", "TRUE", "FALSE", "LPAR", "BANG", "MINUS", "LAST_ERROR"}
_OPERATORS = {"OROR", "ANDAND", "CMPOP", "PLUS", "MINUS", "STAR", "SLASH", "DOT"}
_STATEMENTS = {"LET", "SET", "MAKE", "ENSURE", "WAIT", "ASSERT", "ABORT"}
_KEYWORDS = {"let", "set", "make", "ensure", "wait", "assert", "abort"}
#: control statements of other languages, which a spec writer may try in a recipe body
_NO_CONTROL = {"if", "while", "for", "else", "loop", "until"}
#: statements a spec writer may expect that the language leaves to the framework (why, said with the hint)
_NO_STATEMENT = {
    "pause": "a recipe is paused by the framework, when a constraint it holds is in temporary failure; "
             "to stop what a handle asks for, 'abort h'",
    "resume": "a paused recipe resumes when its constraint holds again",
    "continue": "a paused recipe resumes when its constraint holds again",
    "return": "a recipe ends after its last statement; its task's post-conditions say what it achieved",
    "retry": "a failed recipe is retried, or another one chosen, by the framework (pre-conditions bound it)",
    "fail": "'assert(false)' fails the recipe",
    "send": "a constraint is sent with 'make(...)' or 'ensure(...)'",
}
_CLOSERS = ["_SEMI", "_RBRACE", "_RPAR", "_COMMA", "_EQ", "_DCOLON"]
_OPENER_OF = {"_RBRACE": "LBRACE", "_RPAR": "LPAR"}
_CLOSER_OF = {v: k for k, v in _OPENER_OF.items()}
_IGNORED = {"WS", "LINE_COMMENT", "BLOCK_COMMENT"}
_WORDS = {
    "ID": "a name", "INT": "an integer", "DOUBLE": "a double", "STRING": "a string",
    "CMPOP": "a comparison", "LAST_ERROR": "'last_error?'",
}


def _found(tok: Token) -> str:
    if tok.type == "$END":
        return "end of file"
    if tok.type == "ID":
        return f"name '{tok}'"
    if tok.type in ("INT", "DOUBLE"):
        return f"number {tok}"
    if tok.type == "STRING":
        return f"string {tok}"
    if tok.type in _literals() and str(tok).isalpha():
        return f"keyword '{tok}'"
    return f"'{tok}'"


def _expected(names: set[str]) -> str:
    names = set(names) - _IGNORED
    lits = _literals()
    parts: list[str] = []
    if {"LET", "SET", "MAKE"} <= names:
        parts.append("a statement")
        names -= _STATEMENTS | _EXPR_START
    if {"ID", "INT", "LPAR"} <= names:
        parts.append("an expression")
        names -= _EXPR_START
    if len(names & _OPERATORS) >= 3:
        parts.append("an operator")
        names -= _OPERATORS
    for n in ("ID", "INT", "DOUBLE", "STRING"):
        if n in names:
            parts.append(_WORDS[n])
            names.discard(n)
    for n in _CLOSERS:
        if n in names:
            parts.append(f"'{lits[n]}'")
            names.discard(n)
    for n in sorted(names - {"$END"}):
        parts.append(_WORDS.get(n) or (f"'{lits[n]}'" if n in lits else n.lower()))
    if "$END" in names:
        parts.append("end of file")
    if not parts:
        return "nothing more here"
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " or " + parts[-1]


def _accepted(e: UnexpectedToken) -> set[str]:
    ip = getattr(e, "interactive_parser", None)
    if ip is not None:
        try:
            return set(ip.accepts()) - _IGNORED
        except Exception:  # pragma: no cover - fall back on lark's estimate
            pass
    return set(e.expected or ()) - _IGNORED


def _stack(e: UnexpectedInput) -> list:
    ip = getattr(e, "interactive_parser", None)
    try:
        return list(ip.parser_state.value_stack) if ip is not None else []
    except AttributeError:  # pragma: no cover - lark internals changed
        return []


def _prev_line(stack: list) -> Optional[int]:
    """Line of the last token on the stack (the end of what was read before the error)."""
    for v in reversed(stack):
        if isinstance(v, Token):
            return v.end_line or v.line
        if isinstance(v, a.Node):
            return None
    return None


def _hints(e: UnexpectedToken, expected: set[str]) -> list[str]:
    tok = e.token
    stack = _stack(e)
    toks = [v for v in stack if isinstance(v, Token)]
    hints: list[str] = []
    prev = stack[-1] if stack else None

    if tok.type == "CMPOP" and len(stack) >= 2 and isinstance(stack[-2], Token) and stack[-2].type == "CMPOP":
        hints.append("comparisons do not chain: write 'a < b && b < c'")
    if tok.type == "_EQ" and "CMPOP" in expected:
        var = prev.name if isinstance(prev, a.Name) else (
            str(prev) if isinstance(prev, Token) and prev.type == "ID" else None)
        if "_SEMI" in expected and var is not None:
            hints.append(f"to change a variable write 'set {var} value'; to compare, '=='")
        else:
            hints.append("compare with '=='; a single '=' only names a declaration")
    if isinstance(prev, Token) and prev.type == "ID" and str(prev) == "import" and "_EQ" in expected:
        hints.append("imports come before the first agent")
    if isinstance(prev, Token) and prev.type == "ID" and str(prev) in ("ability", "task", "recipe") \
            and "_EQ" in expected:
        hints.append(f"declare it as 'NAME = {prev} {{ ... }}'")

    if expected == {"LBRACE", "_RBRACE"} and tok.type in _EXPR_START:
        hints.append("each condition goes in its own braces: pre = { {a == 1} {b < 2} }")
    if expected == {"LBRACE", "_RBRACE"} and tok.type in ("_SEMI", "_COMMA"):
        hints.append(f"conditions are not separated by '{tok}': pre = {{ {{a == 1}} {{b < 2}} }}")
    # a statement the language does not have: `if (c) { ... }`, `while (c) { ... }`
    control = [v for v in stack[-5:] if (isinstance(v, Token) and v.type == "ID" and str(v) in _NO_CONTROL)
               or (isinstance(v, a.Call) and v.name in _NO_CONTROL and v.agent is None)]
    if control and tok.type == "LBRACE":
        word = str(control[-1]) if isinstance(control[-1], Token) else control[-1].name
        hints.append(f"the spec language has no '{word}': a recipe body is a sequence of statements; choose "
                     "between behaviours with several recipes (their pre-conditions pick one) or wait for a "
                     "condition with 'wait(...)'")
    # a misspelt statement keyword (`sett x true`): a name where a statement starts, then a name
    if isinstance(prev, Token) and prev.type == "ID" and str(prev) in _NO_STATEMENT and "_SEMI" in expected:
        hints.append(f"the spec language has no '{prev}' statement: {_NO_STATEMENT[str(prev)]}; the statements "
                     f"are {', '.join(sorted(_KEYWORDS))}")
    elif isinstance(prev, Token) and prev.type == "ID" and tok.type == "ID" and "_SEMI" in expected:
        import difflib
        close = difflib.get_close_matches(str(prev), sorted(_KEYWORDS), n=1, cutoff=0.6)
        if close:
            hints.append(f"did you mean '{close[0]}'?")

    # Unclosed or unmatched brackets (closed pairs may still be on the stack, unreduced).
    open_: list[Token] = []
    for t in toks:
        if t.type in _CLOSER_OF:
            open_.append(t)
        elif t.type in _OPENER_OF and open_ and open_[-1].type == _OPENER_OF[t.type]:
            open_.pop()
    if tok.type in _OPENER_OF:
        opener = _OPENER_OF[tok.type]
        if not any(t.type == opener for t in open_):
            hints.append(f"there is no open '{_literals()[opener]}' for this '{tok}' to close")
    elif open_ and not hints and _CLOSER_OF[open_[-1].type] in expected and (
            tok.type in ("$END", "_RBRACE", "_RPAR", "_SEMI", "_COMMA")):
        o = open_[-1]
        hints.append(f"the '{o}' at {o.line}:{o.column} is not closed")

    if "_SEMI" in expected and not hints:
        line = _prev_line(stack)
        if tok.type in ("_RBRACE", "$END") or tok.type in _STATEMENTS or (
                (line is None or line < tok.line) and not isinstance(prev, Token)):
            hints.append("is the ';' ending the previous statement or declaration missing?")
    return hints


def _glued(e: UnexpectedToken, file: str) -> Optional[SyntaxError_]:
    """A keyword glued to the name after it (`prefered`, `bodys`): the contextual lexer, where
    only keywords may stand, read `prefer` and then `ed`. Said as the whole word the user wrote."""
    tok = e.token
    stack = _stack(e)
    prev = stack[-1] if stack else None
    if not (isinstance(prev, Token) and tok.type == "ID" and prev.type in _literals()
            and str(prev).isidentifier() and getattr(prev, "end_pos", None) == tok.start_pos):
        return None
    return SyntaxError_(f"unexpected name '{prev}{tok}' (did you mean '{prev}'?)",
                        Pos(file, prev.line or 1, prev.column or 1))


def _convert(e: UnexpectedInput, text: str, file: str) -> SyntaxError_:
    if isinstance(e, UnexpectedToken):
        glued = _glued(e, file)
        if glued is not None:
            return glued
        tok = e.token
        expected = _accepted(e)
        if tok.type == "$END":
            line, col = _end(text)
        else:
            line, col = tok.line, tok.column
        msg = f"unexpected {_found(tok)}; expected {_expected(expected)}"
        hints = _hints(e, expected)
        if hints:
            msg += " (" + "; ".join(hints) + ")"
        return SyntaxError_(msg, Pos(file, line or 1, col or 1))
    if isinstance(e, UnexpectedCharacters):
        return SyntaxError_(_bad_characters(e, text), Pos(file, e.line, e.column))
    if isinstance(e, UnexpectedEOF):  # pragma: no cover - not raised by LALR
        return SyntaxError_("unexpected end of file", Pos(file, *_end(text)))
    return SyntaxError_(f"syntax error: {e}", Pos(file, getattr(e, "line", 1) or 1,  # pragma: no cover
                                                   getattr(e, "column", 1) or 1))


def _bad_characters(e: UnexpectedCharacters, text: str) -> str:
    rest = text[e.pos_in_stream:]
    ch = rest[:1]
    if ch == '"':
        return "unterminated string: a string ends with '\"' on the same line"
    if ch == "&":
        return "'&' alone is not an operator; write '&&'"
    if ch == "|":
        return "'|' alone is not an operator; write '||' (or '|-' in a rule)"
    if ch == ":":
        return "':' alone is not an operator; a remote name is written 'agent::name'"
    if ch == "?":
        return "'?' only appears in 'last_error?'"
    shown = repr(ch) if not ch.isprintable() or ch in "'\\" else f"'{ch}'"
    return (f"illegal character {shown}; names are made of letters, digits and '_', "
            f"and start with a letter or '_'")


def _end(text: str) -> tuple[int, int]:
    lines = text.split("\n")
    return len(lines), len(lines[-1]) + 1


_SCAN = re.compile(r'"(?:[^"\\\n]|\\[^\n])*"?|//[^\n]*|/\*|[^"/]+|/')


def _check_comments(text: str, file: str) -> None:
    """Report an unterminated ``/*`` comment at its start (lark would see '/' and '*')."""
    if "/*" not in text:
        return
    i = 0
    while i < len(text):
        m = _SCAN.match(text, i)
        tok = m.group(0)
        if tok == "/*":
            end = text.find("*/", i + 2)
            if end < 0:
                line = text.count("\n", 0, i) + 1
                col = i - (text.rfind("\n", 0, i) + 1) + 1
                raise SyntaxError_("unterminated comment: '/*' has no matching '*/'", Pos(file, line, col))
            i = end + 2
        else:
            i = m.end()
