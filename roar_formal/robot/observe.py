"""Conditions on the robot's state: a small expression language for invariants over a run.

A property file writes, for example::

    !contact                                         # the base never touches anything
    gripper == "open" && near("table", 0.5) => !holding

:func:`parse_condition` parses and type-checks such a text (a condition
must be true or false), :func:`check_condition` checks the names it uses
against a scenario (places, doors, objects; a gripper or a pan unit when
it reads one), and :meth:`RobotCondition.holds` evaluates it on a
:class:`~roar_formal.robot.robot.Robot` as it is now.
:meth:`RobotCondition.explain` lists what it read, with the values now.

Operators, loosest first: ``=>`` (implication, right-associative), ``||``,
``&&``, the comparisons ``== != < <= > >=`` (they do not chain), ``+ -``,
``* /``, then the unary ``!`` and ``-``. Literals: numbers, ``"strings"``,
``true``, ``false``. Names are the observables of :data:`OBSERVABLES`.
``&&``, ``||`` and ``=>`` evaluate their right side only when needed.

Every mistake in the text is a :class:`~roar_formal.errors.RoarError` at
the file, line and column inside the string where it is, computed from
where the string starts in the user's file; no lark or Python exception
gets out. The same holds for errors found while evaluating (a division by
zero, a place the robot's scenario lacks).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from typing import Any, Callable, Optional

from lark import Lark, Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from ..errors import Pos, RoarError, SyntaxError_, TypeError_
from .scenario import did_you_mean

__all__ = ["RobotCondition", "parse_condition", "check_condition", "OBSERVABLES"]

#: the states of the path follower (``Robot.follow_state``)
FOLLOW_STATES = ("idle", "following", "waiting", "arrived", "blocked")
GRIPPER_STATES = ("open", "closed")
#: deeper nesting is refused (the checker and the evaluator recurse)
MAX_DEPTH = 200

BOOL, NUM, STR = "bool", "num", "str"
_TYPE_WORDS = {BOOL: "a truth value", NUM: "a number", STR: "a string"}

# ---------------------------------------------------------------- the observables


@dataclass(frozen=True)
class _Param:
    kind: str   # "num", or the kind of name a quoted string must be: "place" | "door" | "object"
    what: str   # for messages: "the radius in m"
    shape: str  # in the signature: r, "place"


@dataclass(frozen=True)
class _Observable:
    name: str
    type: str
    doc: str
    params: Optional[tuple[_Param, ...]] = None   # None: a bare name; (): a function of no arguments
    needs: Optional[str] = None                   # "gripper" | "ptu"
    domain: Optional[tuple[str, ...]] = None      # the strings a string observable can be

    @property
    def signature(self) -> str:
        if self.params is None:
            return self.name
        return f"{self.name}({', '.join(p.shape for p in self.params)})"


_PLACE = _Param("place", "a place of the scenario", '"place"')
_OBJECT = _Param("object", "an object of the scenario", '"object"')
_RADIUS = _Param(NUM, "the radius in m", "r")
_TABLE = (
    _Observable("t", NUM, "simulated time (s)"),
    _Observable("x", NUM, "the base's true x (m)"),
    _Observable("y", NUM, "the base's true y (m)"),
    _Observable("heading", NUM, "the base's true heading (degrees, -180 to 180)"),
    _Observable("speed", NUM, "the base's linear speed (m/s, never negative)"),
    _Observable("contact", BOOL, "the chassis touches something (wall, obstacle, door, object) now"),
    _Observable("bumps", NUM, "contacts of the chassis begun so far"),
    _Observable("following", STR, "the path follower's state: " + ", ".join(f'"{s}"' for s in FOLLOW_STATES),
                domain=FOLLOW_STATES),
    _Observable("lidar_up", BOOL, "the lidar delivered a scan within its last two periods"),
    _Observable("gripper", STR, 'the jaws: "closed" once they have shut, "open" otherwise (needs a gripper)',
                needs="gripper", domain=GRIPPER_STATES),
    _Observable("holding", BOOL, "the gripper holds an object (needs a gripper)", needs="gripper"),
    _Observable("held", STR, 'the name of the object held, "" when none (needs a gripper)', needs="gripper"),
    _Observable("pan", NUM, "the pan unit's angle (degrees; needs a pan unit)", needs="ptu"),
    _Observable("pan_target", NUM, "the angle the pan unit is commanded to (degrees; needs a pan unit)",
                needs="ptu"),
    _Observable("door_open", BOOL, "the door is open now",
                params=(_Param("door", "a door of the scenario", '"door"'),)),
    _Observable("dist", NUM, "distance (m) from the base's true position to a place", params=(_PLACE,)),
    _Observable("near", BOOL, "the base is within r m of a place", params=(_PLACE, _RADIUS)),
    _Observable("inside", BOOL, "the base's true position is in the rectangle (corners in any order)",
                params=tuple(_Param(NUM, f"{c} in m", c) for c in ("x0", "y0", "x1", "y1"))),
    _Observable("object_x", NUM, "x of an object's centre (m)", params=(_OBJECT,)),
    _Observable("object_y", NUM, "y of an object's centre (m)", params=(_OBJECT,)),
    _Observable("object_near", BOOL, "an object's centre is within r m of a place",
                params=(_OBJECT, _PLACE, _RADIUS)),
)
_BY_NAME = {o.name: o for o in _TABLE}

#: observable name -> a one-line description, with its arguments when it is a function
OBSERVABLES: dict[str, str] = {o.name: f"{o.signature}: {o.doc}" for o in _TABLE}

_LITERAL_NAMES = ("true", "false")
_WORD_OPERATORS = {"and": "&&", "or": "||", "not": "!", "implies": "=>"}


# ---------------------------------------------------------------- the syntax tree

# positions inside the text: (line, column), both 1-based
RelPos = tuple[int, int]


class _Node:
    pos: RelPos           # where the node starts
    depth: int = 1


@dataclass
class _Num(_Node):
    value: float
    text: str
    pos: RelPos


@dataclass
class _Str(_Node):
    value: str
    pos: RelPos


@dataclass
class _Bool(_Node):
    value: bool
    pos: RelPos


@dataclass
class _Name(_Node):
    name: str
    pos: RelPos


@dataclass
class _Call(_Node):
    name: str
    args: list
    pos: RelPos
    depth: int = 1


@dataclass
class _Unary(_Node):
    op: str
    operand: Any
    pos: RelPos
    depth: int = 1


@dataclass
class _Binary(_Node):
    op: str
    left: Any
    right: Any
    op_pos: RelPos
    pos: RelPos
    depth: int = 1


# ---------------------------------------------------------------- the grammar

_GRAMMAR = r"""
?start: impl
?impl: or_
     | or_ IMPLIES impl              -> binary
?or_: and_
    | or_ OROR and_                  -> binary
?and_: cmp
     | and_ ANDAND cmp               -> binary
?cmp: sum
    | sum (EQ | NE | LT | LE | GT | GE) sum  -> binary
?sum: prod
    | sum (PLUS | MINUS) prod        -> binary
?prod: unary
     | prod (STAR | SLASH) unary     -> binary
?unary: atom
      | (BANG | MINUS) unary         -> unary
?atom: NUMBER                        -> number
     | STRING                        -> string
     | NAME                          -> name
     | NAME _LPAR [args] _RPAR       -> call
     | _LPAR impl _RPAR
args: impl (_COMMA impl)*

IMPLIES: "=>"
OROR: "||"
ANDAND: "&&"
EQ: "=="
NE: "!="
LE: "<="
GE: ">="
LT: "<"
GT: ">"
PLUS: "+"
MINUS: "-"
STAR: "*"
SLASH: "/"
BANG: "!"
_LPAR: "("
_RPAR: ")"
_COMMA: ","
NUMBER: /(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?/
STRING: /"(?:[^"\\\n]|\\[^\n])*"/
NAME: /[A-Za-z_][A-Za-z0-9_]*/
%ignore /[ \t\r\n]+/
"""

_OPERATOR_TERMINALS = {"IMPLIES", "OROR", "ANDAND", "EQ", "NE", "LE", "GE", "LT", "GT", "PLUS", "MINUS",
                       "STAR", "SLASH"}
_TERMINAL_WORDS = {"NUMBER": "a number", "STRING": "a string", "NAME": "a name", "_LPAR": "'('",
                   "_RPAR": "')'", "_COMMA": "','", "BANG": "'!'"}


def _p(tok: Token) -> RelPos:
    return (tok.line or 1, tok.column or 1)


class _Build(Transformer):
    """Bottom-up (inline with the LALR parser): the tree and each node's depth, without recursion."""

    def number(self, c):
        tok = c[0]
        return _Num(float(tok), str(tok), _p(tok))

    def string(self, c):
        tok = c[0]
        return _Str(re.sub(r"\\(.)", lambda m: {"n": "\n", "t": "\t"}.get(m.group(1), m.group(1)), tok[1:-1]),
                    _p(tok))

    def name(self, c):
        tok = c[0]
        if str(tok) in _LITERAL_NAMES:
            return _Bool(str(tok) == "true", _p(tok))
        return _Name(str(tok), _p(tok))

    def call(self, c):
        tok, args = c[0], (c[1] if len(c) > 1 and c[1] is not None else [])
        return _Call(str(tok), args, _p(tok), 1 + max((a.depth for a in args), default=0))

    def args(self, c):
        return list(c)

    def unary(self, c):
        op, operand = c
        return _Unary(str(op), operand, _p(op), operand.depth + 1)

    def binary(self, c):
        left, op, right = c
        return _Binary(str(op), left, right, _p(op), left.pos, max(left.depth, right.depth) + 1)


@functools.cache
def _parser() -> Lark:
    return Lark(_GRAMMAR, parser="lalr", lexer="contextual", transformer=_Build(), maybe_placeholders=True)


# ---------------------------------------------------------------- locations


@dataclass(frozen=True)
class _Where:
    """Where the condition's text starts in the user's file."""

    file: str
    line: int
    col: int

    def at(self, pos: RelPos) -> Pos:
        line, col = pos
        if line == 1:
            return Pos(self.file, self.line, self.col + col - 1)
        return Pos(self.file, self.line + line - 1, col)


def _end(text: str) -> RelPos:
    lines = text.split("\n")
    return (len(lines), len(lines[-1]) + 1)


# ---------------------------------------------------------------- syntax errors


def _found(tok: Token) -> str:
    if tok.type == "$END":
        return "end of the condition"
    if tok.type == "NAME":
        return f"name '{tok}'"
    if tok.type == "NUMBER":
        return f"number {tok}"
    if tok.type == "STRING":
        return f"string {tok}"
    return f"'{tok}'"


def _expected(names: set[str]) -> str:
    names = set(names)
    parts: list[str] = []
    if {"NAME", "NUMBER", "_LPAR"} <= names:
        parts.append("an expression")
        names -= {"NAME", "NUMBER", "STRING", "_LPAR", "BANG", "MINUS"}
    ops = names & _OPERATOR_TERMINALS
    if len(ops) >= 3:
        parts.append("an operator")
        names -= ops | {"_LPAR"}
    for n in sorted(names - {"$END"}):
        if n in _TERMINAL_WORDS:
            parts.append(_TERMINAL_WORDS[n])
        else:
            lit = _literal(n)
            parts.append(f"'{lit}'" if lit else n.lower())
    if "$END" in names:
        parts.append("the end of the condition")
    if not parts:
        return "nothing more"
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " or " + parts[-1]


@functools.cache
def _literals() -> dict[str, str]:
    return {t.name: t.pattern.value for t in _parser().terminals if t.pattern.type == "str"}


def _literal(name: str) -> Optional[str]:
    return _literals().get(name)


def _syntax_error(e: UnexpectedInput, text: str, where: _Where) -> RoarError:
    if isinstance(e, UnexpectedToken):
        tok = e.token
        pos = _end(text) if tok.type == "$END" else _p(tok)
        try:
            expected = set(e.interactive_parser.accepts())
        except Exception:  # pragma: no cover - lark internals changed: its own estimate
            expected = set(e.expected or ())
        msg = f"unexpected {_found(tok)}; expected {_expected(expected)}"
        hint = _hint(tok, expected, text, _previous(e))
        return SyntaxError_(msg + (f" ({hint})" if hint else ""), where.at(pos))
    if isinstance(e, UnexpectedCharacters):
        return SyntaxError_(_bad_character(text[e.pos_in_stream:]), where.at((e.line, e.column)))
    if isinstance(e, UnexpectedEOF):  # pragma: no cover - LALR reports the end as a token
        return SyntaxError_("unexpected end of the condition", where.at(_end(text)))
    return SyntaxError_(f"cannot read the condition: {e}", where.at((1, 1)))  # pragma: no cover


def _previous(e: UnexpectedToken):
    """What was read just before the unexpected token (a node or a token), if lark tells."""
    try:
        stack = e.interactive_parser.parser_state.value_stack
        return stack[-1] if stack else None
    except AttributeError:  # pragma: no cover - lark internals changed
        return None


def _hint(tok: Token, expected: set[str], text: str, previous) -> str:
    word = str(tok).lower() if tok.type == "NAME" else ""
    if word in _WORD_OPERATORS and ("ANDAND" in expected or "NAME" in expected):
        return f"write '{_WORD_OPERATORS[word]}' for '{tok}'"
    before = previous.name if isinstance(previous, _Name) else \
        str(previous) if isinstance(previous, Token) and previous.type == "NAME" else ""
    if before.lower() in _WORD_OPERATORS:
        return f"write '{_WORD_OPERATORS[before.lower()]}' for '{before}'"
    if tok.type in ("EQ", "NE", "LT", "LE", "GT", "GE") and "ANDAND" in expected:
        return "comparisons do not chain: write 'a < b && b < c'"
    if tok.type == "GT" and tok.start_pos and text[tok.start_pos - 1] == "-":
        return "implication is written '=>'"
    if tok.type == "$END" and "_RPAR" in expected:
        return "a '(' is not closed"
    if tok.type == "_RPAR" and "_RPAR" not in expected:
        return "there is no open '(' for this ')' to close"
    if tok.type == "_LPAR" and "ANDAND" in expected:
        return "only a name can be called; is an operator missing?"
    return ""


def _bad_character(rest: str) -> str:
    ch = rest[:1]
    if ch == '"':
        return "unterminated string: a string ends with '\"' on the same line"
    if ch == "&":
        return "'&' alone is not an operator; write '&&'"
    if ch == "|":
        return "'|' alone is not an operator; write '||'"
    if ch == "=":
        return "'=' alone is not an operator; compare with '==' (implication is '=>')"
    if ch == "'":
        return "strings are written in double quotes: \"...\""
    shown = repr(ch) if not ch.isprintable() or ch in "\\" else f"'{ch}'"
    return (f"illegal character {shown}; a condition is made of names, numbers, \"strings\", "
            f"parentheses and the operators => || && == != < <= > >= + - * / !")


# ---------------------------------------------------------------- type checking


def _describe(node) -> str:
    """A short phrase naming what a node is, for type errors."""
    if isinstance(node, _Name):
        return f"'{node.name}'"
    if isinstance(node, _Call):
        return f"'{node.name}(...)'"
    if isinstance(node, _Num):
        return node.text
    if isinstance(node, _Str):
        return f'"{node.value}"'
    if isinstance(node, _Bool):
        return "true" if node.value else "false"
    return "this expression"


class _Checker:
    """Infers each node's type (parse time): every ill-typed or unknown thing is a located TypeError_."""

    def __init__(self, where: _Where):
        self.where = where

    def error(self, message: str, pos: RelPos) -> RoarError:
        return TypeError_(message, self.where.at(pos))

    def type(self, node) -> str:
        if isinstance(node, _Num):
            if not math.isfinite(node.value):
                raise self.error(f"the number {node.text} is too large", node.pos)
            return NUM
        if isinstance(node, _Str):
            return STR
        if isinstance(node, _Bool):
            return BOOL
        if isinstance(node, _Name):
            return self.name(node)
        if isinstance(node, _Call):
            return self.call(node)
        if isinstance(node, _Unary):
            t = self.type(node.operand)
            want = BOOL if node.op == "!" else NUM
            if t != want:
                what = "negates a condition" if node.op == "!" else "negates a number"
                raise self.error(f"'{node.op}' {what}, and {_describe(node.operand)} is {_TYPE_WORDS[t]}",
                                 node.pos)
            return want
        return self.binary(node)

    def name(self, node: _Name) -> str:
        obs = _BY_NAME.get(node.name)
        if obs is None:
            lower = node.name.lower()
            if lower in _LITERAL_NAMES:
                raise self.error(f"unknown name '{node.name}' (write '{lower}')", node.pos)
            if lower in _WORD_OPERATORS:
                raise self.error(f"unknown name '{node.name}' (write '{_WORD_OPERATORS[lower]}')", node.pos)
            hint = did_you_mean(node.name, list(_BY_NAME) + list(_LITERAL_NAMES)) or \
                f' (names of places, doors and objects are strings: "{node.name}")'
            raise self.error(f"unknown name '{node.name}'{hint}; observables: {', '.join(_BY_NAME)}", node.pos)
        if obs.params is not None:
            raise self.error(f"'{node.name}' is a function: write {obs.signature}", node.pos)
        return obs.type

    def call(self, node: _Call) -> str:
        obs = _BY_NAME.get(node.name)
        if obs is None:
            functions = [o.name for o in _TABLE if o.params is not None]
            raise self.error(f"unknown function '{node.name}'{did_you_mean(node.name, functions)}; "
                             f"functions: {', '.join(functions)}", node.pos)
        if obs.params is None:
            raise self.error(f"'{node.name}' is not a function: write {node.name}, without '()'", node.pos)
        if len(node.args) != len(obs.params):
            n = len(obs.params)
            raise self.error(f"{node.name} takes {n} argument{'s' if n != 1 else ''}, {obs.signature}; "
                             f"got {len(node.args)}", node.pos)
        for i, (arg, param) in enumerate(zip(node.args, obs.params)):
            nth = _ORDINALS[i] if len(obs.params) > 1 else "the"
            if param.kind == NUM:
                t = self.type(arg)
                if t != NUM:
                    raise self.error(f"{nth} argument of {node.name} is a number ({param.what}); "
                                     f"{_describe(arg)} is {_TYPE_WORDS[t]}", arg.pos)
            elif not isinstance(arg, _Str):
                hint = f' (write "{arg.name}" in quotes)' if isinstance(arg, _Name) and arg.name not in _BY_NAME \
                    else ""
                raise self.error(f"{nth} argument of {node.name} is the name of {param.what} in quotes, "
                                 f'such as "{_EXAMPLE[param.kind]}"{hint}', arg.pos)
        return obs.type

    def binary(self, node: _Binary) -> str:
        op = node.op
        lt = self.type(node.left)
        rt = self.type(node.right)
        if op in ("&&", "||", "=>"):
            for side, t in ((node.left, lt), (node.right, rt)):
                if t != BOOL:
                    raise self.error(f"'{op}' combines conditions, and {_describe(side)} is {_TYPE_WORDS[t]}"
                                     + _compare_hint(side, t), node.op_pos)
            return BOOL
        if op in ("==", "!="):
            if lt != rt:
                raise self.error(f"'{op}' compares values of one type: {_describe(node.left)} is "
                                 f"{_TYPE_WORDS[lt]} and {_describe(node.right)} is {_TYPE_WORDS[rt]}",
                                 node.op_pos)
            if lt == STR:
                self.string_domain(node.left, node.right)
                self.string_domain(node.right, node.left)
            return BOOL
        for side, t in ((node.left, lt), (node.right, rt)):
            if t != NUM:
                what = "compares numbers" if op in ("<", "<=", ">", ">=") else "works on numbers"
                raise self.error(f"'{op}' {what}, and {_describe(side)} is {_TYPE_WORDS[t]}", node.op_pos)
        if op == "/" and isinstance(node.right, _Num) and node.right.value == 0:
            raise self.error("division by zero", node.op_pos)
        return BOOL if op in ("<", "<=", ">", ">=") else NUM

    def string_domain(self, obs_side, literal) -> None:
        """``following == "walking"``: a string the observable can never be is a mistake."""
        if not isinstance(obs_side, _Name) or not isinstance(literal, _Str):
            return
        domain = _BY_NAME[obs_side.name].domain
        if domain and literal.value not in domain:
            raise self.error(f'{obs_side.name} is never "{literal.value}"{did_you_mean(literal.value, domain)}; '
                             f"it is one of: {', '.join(chr(34) + d + chr(34) for d in domain)}", literal.pos)


_ORDINALS = ("the first", "the second", "the third", "the fourth")
_EXAMPLE = {"place": "goal", "door": "d1", "object": "cup"}


def _compare_hint(node, t: str) -> str:
    if t == NUM and isinstance(node, (_Name, _Call)):
        return "; compare it with a number, e.g. '< 1.0'"
    if t == STR and isinstance(node, _Name):
        return "; compare it with a string, e.g. '== \"...\"'"
    return ""


# ---------------------------------------------------------------- evaluation

Reader = Callable[[Any], Any]


def _runtime_error(message: str, where: _Where, pos: RelPos) -> RoarError:
    return RoarError(message, where.at(pos))


def _gripper(robot, where: _Where, pos: RelPos):
    g = robot.world.gripper
    if g is None:
        raise _runtime_error(f"the robot of scenario '{robot.scenario.name}' has no gripper", where, pos)
    return g


def _ptu(robot, where: _Where, pos: RelPos):
    p = robot.world.ptu
    if p is None:
        raise _runtime_error(f"scenario '{robot.scenario.name}' has no pan unit", where, pos)
    return p


def _read_name(name: str, where: _Where, pos: RelPos) -> Reader:
    if name == "t":
        return lambda r: r.world.time
    if name == "x":
        return lambda r: r.world.base.body.position.x
    if name == "y":
        return lambda r: r.world.base.body.position.y
    if name == "heading":
        return lambda r: math.degrees(r.world.base.pose[2])
    if name == "speed":
        return lambda r: math.hypot(*r.world.base.body.velocity)
    if name == "contact":
        return lambda r: r.world.base.bumped
    if name == "bumps":
        return lambda r: r.world.base.bump_count
    if name == "following":
        return lambda r: r.follow_state
    if name == "lidar_up":
        return lambda r: bool(r.lidar_up())
    if name == "gripper":
        return lambda r: "closed" if _gripper(r, where, pos).closed else "open"
    if name == "holding":
        return lambda r: _gripper(r, where, pos).holding is not None
    if name == "held":
        return lambda r: _gripper(r, where, pos).holding or ""
    if name == "pan":
        return lambda r: _ptu(r, where, pos).angle_deg
    if name == "pan_target":
        return lambda r: _ptu(r, where, pos).target_deg
    raise AssertionError(name)  # pragma: no cover - the checker knows the names


def _place(robot, name: str, where: _Where, pos: RelPos) -> tuple[float, float]:
    places = robot.scenario.places
    if name not in places:
        raise _runtime_error(f"scenario '{robot.scenario.name}' has no place '{name}'{did_you_mean(name, places)}; "
                             f"places: {', '.join(places) or 'none'}", where, pos)
    return places[name]


def _object(robot, name: str, where: _Where, pos: RelPos):
    objects = robot.world.objects
    if name not in objects:
        raise _runtime_error(f"scenario '{robot.scenario.name}' has no object '{name}'"
                             f"{did_you_mean(name, objects)}; objects: {', '.join(objects) or 'none'}", where, pos)
    return objects[name].position


def _door(robot, name: str, where: _Where, pos: RelPos) -> bool:
    doors = [d.name for d in robot.scenario.doors]
    if name not in doors:
        raise _runtime_error(f"scenario '{robot.scenario.name}' has no door '{name}'{did_you_mean(name, doors)}; "
                             f"doors: {', '.join(doors) or 'none'}", where, pos)
    return robot.world.door_open(name)


def _distance(robot, place: str, where: _Where, pos: RelPos) -> float:
    px, py = _place(robot, place, where, pos)
    p = robot.world.base.body.position
    return math.hypot(p.x - px, p.y - py)


def _object_distance(robot, obj: str, place: str, where: _Where, opos: RelPos, ppos: RelPos) -> float:
    o = _object(robot, obj, where, opos)
    px, py = _place(robot, place, where, ppos)
    return math.hypot(o.x - px, o.y - py)


def _inside(robot, x0: float, y0: float, x1: float, y1: float) -> bool:
    p = robot.world.base.body.position
    return min(x0, x1) <= p.x <= max(x0, x1) and min(y0, y1) <= p.y <= max(y0, y1)


class _Compiler:
    """The typed tree as nested closures over a robot; also records what each read is, for explain."""

    def __init__(self, where: _Where):
        self.where = where
        self.reads: list[tuple[str, Callable[[Any], str]]] = []   # (key, robot -> "name = value")
        self._keys: set[str] = set()

    def note(self, key: str, show: Callable[[Any], str]) -> None:
        if key not in self._keys:
            self._keys.add(key)
            self.reads.append((key, show))

    def compile(self, node) -> Reader:
        where = self.where
        if isinstance(node, (_Num, _Str, _Bool)):
            value = node.value
            return lambda r: value
        if isinstance(node, _Name):
            read = _read_name(node.name, where, node.pos)
            self.note(node.name, lambda r, n=node.name, f=read: f"{n} = {_show(f(r))}")
            return read
        if isinstance(node, _Call):
            return self.call(node)
        if isinstance(node, _Unary):
            f = self.compile(node.operand)
            if node.op == "!":
                return lambda r: not f(r)
            return lambda r: -f(r)
        a, b = self.compile(node.left), self.compile(node.right)
        op = node.op
        if op == "&&":
            return lambda r: a(r) and b(r)
        if op == "||":
            return lambda r: a(r) or b(r)
        if op == "=>":
            return lambda r: (not a(r)) or b(r)
        if op == "==":
            return lambda r: a(r) == b(r)
        if op == "!=":
            return lambda r: a(r) != b(r)
        if op == "<":
            return lambda r: a(r) < b(r)
        if op == "<=":
            return lambda r: a(r) <= b(r)
        if op == ">":
            return lambda r: a(r) > b(r)
        if op == ">=":
            return lambda r: a(r) >= b(r)
        if op == "+":
            return lambda r: a(r) + b(r)
        if op == "-":
            return lambda r: a(r) - b(r)
        if op == "*":
            return lambda r: a(r) * b(r)
        op_pos = node.op_pos

        def divide(r):
            d = b(r)
            if d == 0:
                raise _runtime_error("division by zero", where, op_pos)
            return a(r) / d
        return divide

    def call(self, node: _Call) -> Reader:
        where, name, args = self.where, node.name, node.args
        if name == "door_open":
            door, dpos = args[0].value, args[0].pos
            self.note(f"door_open:{door}", lambda r: f'door_open("{door}") = {_show(_door(r, door, where, dpos))}')
            return lambda r: _door(r, door, where, dpos)
        if name in ("dist", "near"):
            place, ppos = args[0].value, args[0].pos
            self.note(f"dist:{place}", lambda r: f'dist("{place}") = {_show(_distance(r, place, where, ppos))}')
            if name == "dist":
                return lambda r: _distance(r, place, where, ppos)
            radius = self.compile(args[1])
            return lambda r: _distance(r, place, where, ppos) <= radius(r)
        if name == "inside":
            c = [self.compile(a) for a in args]
            self.note("x", lambda r: f"x = {_show(r.world.base.body.position.x)}")
            self.note("y", lambda r: f"y = {_show(r.world.base.body.position.y)}")
            return lambda r: _inside(r, c[0](r), c[1](r), c[2](r), c[3](r))
        if name in ("object_x", "object_y"):
            obj, opos = args[0].value, args[0].pos
            axis = name[-1]
            self.note(name + ":" + obj,
                      lambda r: f'{name}("{obj}") = {_show(getattr(_object(r, obj, where, opos), axis))}')
            return lambda r: getattr(_object(r, obj, where, opos), axis)
        if name == "object_near":
            obj, opos, place, ppos = args[0].value, args[0].pos, args[1].value, args[1].pos
            radius = self.compile(args[2])
            self.note(f"object_dist:{obj}:{place}",
                      lambda r: f'distance of "{obj}" to "{place}" = '
                                f"{_show(_object_distance(r, obj, place, where, opos, ppos))}")
            return lambda r: _object_distance(r, obj, place, where, opos, ppos) <= radius(r)
        raise AssertionError(name)  # pragma: no cover - the checker knows the functions


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        text = f"{value:.3f}".rstrip("0").rstrip(".")
        return "0" if text == "-0" else text
    return str(value)


# ---------------------------------------------------------------- the public API


class RobotCondition:
    """A parsed, type-checked condition on the robot's state."""

    def __init__(self, text: str, tree, where: _Where):
        self.text = text
        self._tree = tree
        self._where = where
        compiler = _Compiler(where)
        self._eval = compiler.compile(tree)
        self._reads = compiler.reads

    @property
    def pos(self) -> Pos:
        """Where the condition starts in the user's file."""
        return Pos(self._where.file, self._where.line, self._where.col)

    @property
    def observables(self) -> tuple[str, ...]:
        """The names of the observables and functions it reads, in order of first use."""
        out: list[str] = []
        for node in _walk(self._tree):
            if isinstance(node, (_Name, _Call)) and node.name not in out:
                out.append(node.name)
        return tuple(out)

    def holds(self, robot) -> bool:
        """Is the condition true of ``robot`` (a :class:`~roar_formal.robot.robot.Robot`) now?"""
        try:
            return bool(self._eval(robot))
        except RecursionError:  # pragma: no cover - MAX_DEPTH keeps trees shallow
            raise RoarError("the condition is nested too deeply to evaluate", self.pos) from None

    def explain(self, robot) -> str:
        """What the condition reads, with the values now: ``contact = true, x = 3.02``."""
        parts = []
        for _, show in self._reads:
            try:
                parts.append(show(robot))
            except RoarError as exc:
                parts.append(f"<{exc.message}>")
        return ", ".join(parts)

    def __repr__(self) -> str:
        return f"RobotCondition({self.text!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, RobotCondition) and (self.text, self._where) == (other.text, other._where)

    def __hash__(self) -> int:
        return hash((self.text, self._where))

    def __reduce__(self):
        # closures do not pickle; the text does (a pickled condition is parsed again)
        w = self._where
        return (parse_condition, (self.text, w.file, w.line, w.col))


def _walk(node):
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        if isinstance(n, _Call):
            stack.extend(reversed(n.args))
        elif isinstance(n, _Unary):
            stack.append(n.operand)
        elif isinstance(n, _Binary):
            stack.extend((n.right, n.left))


def parse_condition(text: str, file: str = "<condition>", line: int = 1, col: int = 1) -> RobotCondition:
    """Parse and type-check a condition; ``file``, ``line``, ``col``: where ``text`` starts in the user's file."""
    where = _Where(str(file), int(line), int(col))
    if not isinstance(text, str):
        raise RoarError(f"a condition is a string, not {type(text).__name__}", where.at((1, 1)))
    if not text.strip():
        raise SyntaxError_("empty condition; expected an expression such as '!contact'", where.at((1, 1)))
    try:
        tree = _parser().parse(text)
    except UnexpectedInput as e:
        err = _syntax_error(e, text, where)
    else:
        err = None
    if err is not None:
        raise err from None
    deep = next((n for n in _walk(tree) if n.depth > MAX_DEPTH), None)
    if deep is not None:
        raise SyntaxError_(f"the condition is nested more than {MAX_DEPTH} deep", where.at(deep.pos))
    t = _Checker(where).type(tree)
    if t != BOOL:
        raise TypeError_(f"a condition must be true or false, and this is {_TYPE_WORDS[t]}"
                         " (compare it with something)", where.at(tree.pos))
    return RobotCondition(text, tree, where)


def check_condition(cond: RobotCondition, scenario, file: Optional[str] = None, line: Optional[int] = None,
                    col: Optional[int] = None) -> None:
    """Check the names ``cond`` uses against ``scenario``: its places, doors and objects exist, and it has
    a gripper (a pan unit) when the condition reads one. Errors point inside the condition's text, placed
    where it was parsed unless ``file``, ``line`` or ``col`` say otherwise."""
    w = cond._where
    where = _Where(w.file if file is None else str(file), w.line if line is None else int(line),
                   w.col if col is None else int(col))
    places = scenario.places
    doors = [d.name for d in scenario.doors]
    objects = [o.name for o in scenario.objects]
    known = {"place": (places, "place", "places"), "door": (doors, "door", "doors"),
             "object": (objects, "object", "objects")}
    for node in _walk(cond._tree):
        if isinstance(node, _Name):
            obs = _BY_NAME[node.name]
            if obs.needs == "gripper" and scenario.robot.gripper is None:
                raise TypeError_(f"'{node.name}' reads the gripper, and the robot of scenario '{scenario.name}' "
                                 f"has none (a [robot.gripper] table gives it one)", where.at(node.pos))
            if obs.needs == "ptu" and scenario.ptu is None:
                raise TypeError_(f"'{node.name}' reads the pan unit, and scenario '{scenario.name}' has none "
                                 f"(a [ptu] table gives it one)", where.at(node.pos))
        elif isinstance(node, _Call):
            for arg, param in zip(node.args, _BY_NAME[node.name].params):
                if param.kind in known:
                    names, what, plural = known[param.kind]
                    if arg.value not in names:
                        raise TypeError_(f"scenario '{scenario.name}' has no {what} '{arg.value}'"
                                         f"{did_you_mean(arg.value, names)}; {plural}: {', '.join(names) or 'none'}",
                                         where.at(arg.pos))
        elif isinstance(node, _Binary) and node.op in ("==", "!="):
            for side, other in ((node.left, node.right), (node.right, node.left)):
                if isinstance(side, _Name) and side.name == "held" and isinstance(other, _Str) \
                        and other.value and other.value not in objects:
                    raise TypeError_(f"held is never \"{other.value}\": scenario '{scenario.name}' has no object "
                                     f"'{other.value}'{did_you_mean(other.value, objects)}; objects: "
                                     f"{', '.join(objects) or 'none'}", where.at(other.pos))
