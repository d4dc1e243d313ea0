"""Printing ROAR spec ASTs back to source text.

``format_spec`` writes the single-file layout (``.roar``); ``hyper_files``
writes one agent in hyper's folder layout (``NAME.ability``, ``NAME/TASK.task``,
``NAME/TASK/RECIPE.recipe``). Expressions get the fewest parentheses that
keep their meaning, so parsing the output gives back an equal AST (positions
aside).
"""

from __future__ import annotations

import math
from typing import Iterable, Optional

from . import ast as a

__all__ = [
    "format_expr", "format_constraint", "format_stmt", "format_recipe", "format_task",
    "format_agent", "format_spec", "format_type", "hyper_files", "PREC",
]

# Binding strength of each level (higher binds tighter).
_OR, _AND, _CMP, _SUM, _PROD, _UNARY, _POSTFIX, _ATOM = range(1, 9)
PREC = {"||": _OR, "&&": _AND, "+": _SUM, "-": _SUM, "*": _PROD, "/": _PROD,
        **{op: _CMP for op in a.COMPARISONS}}

_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r"}


def string_literal(s: str) -> str:
    """A string as the spec language writes it: quoted, with its escapes."""
    return '"' + "".join(_ESCAPES.get(ch, ch) for ch in s) + '"'


def _double(x: float) -> str:
    if math.isnan(x) or math.isinf(x):
        raise ValueError(f"{x} has no literal in the spec language")
    text = repr(float(x))
    if "e" in text or "E" in text:
        mant, exp = text.lower().split("e")
        if "." not in mant:
            mant += ".0"
        text = f"{mant}e{exp}"
    elif "." not in text:
        text += ".0"
    return text


def _level(e: a.Expr) -> int:
    if isinstance(e, a.Binary):
        return PREC[e.op]
    if isinstance(e, a.Unary):
        return _UNARY
    if isinstance(e, a.Field):
        return _POSTFIX
    if isinstance(e, (a.IntLit, a.DoubleLit)) and e.value < 0:
        return _UNARY  # printed with a leading '-'
    return _ATOM


def format_expr(e: a.Expr) -> str:
    """The expression with the fewest parentheses that keep its meaning."""
    return _fmt(e)


def _wrap(e: a.Expr, need: int) -> str:
    s = _fmt(e)
    return f"({s})" if _level(e) < need else s


def _fmt(e: a.Expr) -> str:
    if isinstance(e, a.BoolLit):
        return "true" if e.value else "false"
    if isinstance(e, a.IntLit):
        return str(e.value)
    if isinstance(e, a.DoubleLit):
        return _double(e.value)
    if isinstance(e, a.StringLit):
        return string_literal(e.value)
    if isinstance(e, a.Name):
        return e.name
    if isinstance(e, a.Remote):
        return f"{e.agent}::{e.name}"
    if isinstance(e, a.Call):
        return f"{e.qualified}({', '.join(_fmt(x) for x in e.args)})"
    if isinstance(e, a.LastError):
        return f"last_error?({_fmt(e.constraint)})"
    if isinstance(e, a.Field):
        return f"{_wrap(e.base, _POSTFIX)}.{e.name}"
    if isinstance(e, a.Unary):
        inner = _wrap(e.operand, _UNARY)
        if e.op == "-" and inner.startswith("-"):
            inner = f"({inner})"
        return f"{e.op}{inner}"
    if isinstance(e, a.Binary):
        if e.implied and isinstance(e.right, a.BoolLit):   # as written: the variable alone
            return _fmt(e.left) if e.right.value else "!" + _wrap(e.left, _UNARY)
        p = PREC[e.op]
        if p == _CMP:  # comparisons do not chain: both sides strictly tighter
            return f"{_wrap(e.left, p + 1)} {e.op} {_wrap(e.right, p + 1)}"
        return f"{_wrap(e.left, p)} {e.op} {_wrap(e.right, p + 1)}"
    raise TypeError(f"not an expression: {e!r}")


def format_constraint(c: a.Constraint) -> str:
    text = format_expr(c.expr)
    if c.where:
        text += " where " + " && ".join(
            f"{_wrap(p.left, _CMP + 1)} == {_wrap(p.right, _CMP + 1)}" for p in c.where)
    return text


def format_stmt(s: a.Stmt) -> str:
    if isinstance(s, a.Let):
        return f"let {s.name} {format_expr(s.value)}"
    if isinstance(s, a.Set):
        return f"set {format_expr(s.target)} {format_expr(s.value)}"
    if isinstance(s, a.Make):
        return f"make({format_constraint(s.constraint)})"
    if isinstance(s, a.Ensure):
        period = f", {format_expr(s.period)}" if s.period is not None else ""
        text = f"ensure({format_constraint(s.constraint)}{period})"
        return f"let {s.handle} {text}" if s.handle else text
    if isinstance(s, (a.Wait, a.Assert)):
        kw = "wait" if isinstance(s, a.Wait) else "assert"
        period = f", {format_expr(s.period)}" if s.period is not None else ""
        return f"{kw}({format_expr(s.cond)}{period})"
    if isinstance(s, a.Abort):
        return f"abort {s.handle}"
    if isinstance(s, a.ExprStmt):
        return format_expr(s.expr)
    raise TypeError(f"not a statement: {s!r}")


def format_type(t: a.TypeRef) -> str:
    return str(t)


def _conds(exprs: Iterable[a.Expr]) -> str:
    items = " ".join("{" + format_expr(e) + "}" for e in exprs)
    return "{ " + items + " }" if items else "{ }"


def _block(stmts: tuple[a.Stmt, ...], ind: str) -> list[str]:
    if not stmts:
        return ["{ }"]
    return ["{"] + [f"{ind}  {format_stmt(s)};" for s in stmts] + [f"{ind}}}"]


def _recipe_lines(r: a.Recipe, ind: str, name: Optional[str]) -> list[str]:
    head = f"{name} = recipe {{" if name is not None else "recipe {"
    out = [ind + head]
    i2 = ind + "  "
    if r.pre:
        out.append(f"{i2}pre = {_conds(r.pre)}")
    if r.post:
        out.append(f"{i2}post = {_conds(r.post)}")
    if r.prefer is not None:
        out.append(f"{i2}prefer = {format_expr(r.prefer)}")
    for kw, stmts in (("body", r.body), ("end", r.end)):
        if stmts or kw == "body":
            lines = _block(stmts, i2)
            out.append(f"{i2}{kw} = {lines[0]}")
            out.extend(lines[1:])
    out.append(ind + "}")
    return out


def format_recipe(r: a.Recipe, indent: int = 0) -> str:
    return "\n".join(_recipe_lines(r, " " * indent, r.name))


def _task_lines(t: a.Task, ind: str, with_recipes: bool) -> list[str]:
    out = [f"{ind}{t.name} = task {{"]
    i2 = ind + "  "
    out.append(f"{i2}pre = {_conds(t.pre)}")
    out.append(f"{i2}post = {_conds(t.post)}")
    if with_recipes and t.recipes:
        out.append(f"{i2}recipes = {{")
        for r in t.recipes:
            out.extend(_recipe_lines(r, i2 + "  ", r.name))
        out.append(f"{i2}}}")
    out.append(ind + "}")
    return out


def format_task(t: a.Task, indent: int = 0, with_recipes: bool = True) -> str:
    return "\n".join(_task_lines(t, " " * indent, with_recipes))


def _var(v: a.Var) -> str:
    init = f" = {format_expr(v.init)}" if v.init is not None else ""
    return f"{v.type} {v.name}{init};"


def _group(items: list[str], ind: str) -> list[str]:
    if not items:
        return [ind + "{ }"]
    if len(items) == 1 and len(items[0]) < 60:
        return [f"{ind}{{ {items[0]} }}"]
    return [ind + "{"] + [f"{ind}  {x}" for x in items] + [ind + "}"]


def _type_decl(t: a.TypeDecl) -> str:
    if isinstance(t, a.StructType):
        fields = " ".join(f"{f.type} {f.name};" for f in t.fields)
        return f"{t.name} = struct {{ {fields} }};" if fields else f"{t.name} = struct {{ }};"
    if isinstance(t, a.NewType):
        return f"{t.name} = newtype {t.base};"
    return f"{t.name} = opaquetype;"


def _function(f: a.Function) -> str:
    params = ", ".join(f"{p.type} {p.name}" if p.name else str(p.type) for p in f.params)
    return f"{f.result} {f.name}({params});"


def _rule(r: a.Rule) -> str:
    prem = ", ".join(format_expr(e) for e in r.premises)
    concl = ", ".join(format_expr(e) for e in r.conclusions)
    return f"{r.name} = {prem} |- {concl};" if prem else f"{r.name} = |- {concl};"


def _agent_lines(ag: a.Agent, with_tasks: bool) -> list[str]:
    out = [f"{ag.name} = ability {{"]
    out.append("  context = {")
    for vs in (ag.controllable, ag.readable, ag.private):
        out.extend(_group([_var(v) for v in vs], "    "))
    out.append("  }")
    if ag.types or ag.functions or ag.rules:
        out.append("  export = {")
        out.extend(_group([_type_decl(t) for t in ag.types], "    "))
        out.extend(_group([_function(f) for f in ag.functions], "    "))
        out.extend(_group([_rule(r) for r in ag.rules], "    "))
        out.append("  }")
    if with_tasks and ag.tasks:
        out.append("  tasks = {")
        for t in ag.tasks:
            out.extend(_task_lines(t, "    ", True))
        out.append("  }")
    out.append("}")
    return out


def format_agent(ag: a.Agent, with_tasks: bool = True) -> str:
    return "\n".join(_agent_lines(ag, with_tasks))


def format_spec(spec: a.Spec) -> str:
    """The whole spec in the single-file layout (imports of other files are kept)."""
    paths: list[str] = []
    for ag in spec.agents:
        for imp in ag.imports:
            if imp.path not in paths:
                paths.append(imp.path)
    head = [f"import {string_literal(p)}" for p in paths]
    body = ["\n".join(_agent_lines(ag, True)) for ag in spec.agents]
    return "\n\n".join((["\n".join(head)] if head else []) + body) + "\n"


def hyper_files(ag: a.Agent) -> dict[str, str]:
    """One agent in hyper's layout: ``{relative path: text}``.

    Imports are written as given; each task goes to ``NAME/TASK.task`` and its
    recipes, in order, to ``NAME/TASK/recipes.recipe``. (The loader reads task
    files in file-name order, so tasks come back sorted by name.)
    """
    head = "".join(f"import {string_literal(i.path)}\n" for i in ag.imports)
    files = {f"{ag.name}.ability": head + format_agent(ag, with_tasks=False) + "\n"}
    for t in ag.tasks:
        files[f"{ag.name}/{t.name}.task"] = format_task(t, with_recipes=False) + "\n"
        if t.recipes:
            text = "\n\n".join(format_recipe(r) for r in t.recipes)
            files[f"{ag.name}/{t.name}/recipes.recipe"] = text + "\n"
    return files
