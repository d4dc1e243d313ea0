"""Task-tree models in TOML: message classes, what each handler issues, the
temporal constraints among the issued messages, duration bounds, and claims.

    [model]      name, root (a class), description
    [sizes]      how far to unroll repetitions and chains (e.g. arcs = 2)
    [durations]  name = [lo, hi] in seconds; `dispatch` is the delay from a
                 message being ready to its handler starting
    [classes.C]  kind (query|goal|command|monitor), agent, work (a duration:
                 the handler's own time), children = [{name, class, repeat? | chain?}],
                 constraints = [{relation, first, second}] between children
    [[claims]]   name, about (a class), says, holds (see claims.py), expect
                 (proved|refuted); a claim with `bound` is metric: it must hold for
                 all durations within bounds exactly when the bound holds

A child with ``repeat = "n"`` is issued n times (``arc[1]`` .. ``arc[n]``;
constraints may say ``arc[k]`` and ``arc[k+1]``); a child with ``chain = "n"``
has the parent's own class and is issued until the chain is n long (the
Ambler's recursive Take Step).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, Optional

from ..errors import Pos, RoarError
from .trace_events import DECLARATIONS
from .vocabulary import KINDS

EXPECTATIONS = ("proved", "refuted")


@dataclass(frozen=True)
class Slot:
    """A message a handler issues: its local name and class, maybe repeated or chained."""

    name: str
    cls: str
    repeat: Optional[str] = None
    chain: Optional[str] = None


@dataclass(frozen=True)
class Constraint:
    relation: str  # seq_ach | precedes | delay_planning
    first: str  # a child name, maybe indexed: "leg", "arc[k]", "arc[k+1]"
    second: str


@dataclass(frozen=True)
class MessageClass:
    name: str
    kind: str
    work: str
    agent: Optional[str]
    slots: tuple[Slot, ...]
    constraints: tuple[Constraint, ...]

    def slot(self, name: str) -> Optional[Slot]:
        return next((s for s in self.slots if s.name == name), None)


@dataclass(frozen=True)
class Claim:
    name: str
    about: str
    says: str
    holds: str
    expect: str
    bound: Optional[str] = None
    pos: Optional[Pos] = None

    @property
    def metric(self) -> bool:
        return self.bound is not None


@dataclass(frozen=True)
class Model:
    name: str
    root: str
    description: str
    sizes: dict[str, int]
    durations: dict[str, tuple[Fraction, Fraction]]
    classes: dict[str, MessageClass]
    claims: tuple[Claim, ...]
    file: str = "<model>"


class _Source:
    """The TOML text, for locating errors by the line of a key or table."""

    def __init__(self, text: str, file: str):
        self.lines, self.file = text.splitlines(), file

    def pos(self, *needles: str) -> Pos:
        for needle in needles:
            for number, line in enumerate(self.lines, start=1):
                col = line.find(needle)
                if col >= 0:
                    return Pos(self.file, number, col + 1)
        return Pos(self.file, 1, 1)

    def fail(self, message: str, *needles: str) -> RoarError:
        return RoarError(message, self.pos(*needles))


_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_REF = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(\[(k|k\+1)\])?$")


def _table(data: dict, key: str, src: _Source, where: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise src.fail(f"expected [{where}] to be a table", f"{key}")
    return value


def _list(data: dict, key: str, src: _Source, where: str) -> list:
    value = data.get(key, [])
    if not isinstance(value, list):
        raise src.fail(f"expected {where}.{key} to be an array", f"{key} =", where)
    return value


def _text(data: dict, key: str, src: _Source, where: str, default: Optional[str] = None) -> str:
    value = data.get(key, default)
    if not isinstance(value, str) or not value:
        raise src.fail(f"expected {where}.{key} to be a non-empty string", f"{key} =", where)
    return value


def _durations(data: dict, src: _Source) -> dict[str, tuple[Fraction, Fraction]]:
    out = {}
    for name, bounds in _table(data, "durations", src, "durations").items():
        ok = (isinstance(bounds, list) and len(bounds) == 2
              and all(isinstance(b, (int, float)) and not isinstance(b, bool) and math.isfinite(b) for b in bounds))
        if not ok:
            raise src.fail(f"expected durations.{name} = [lo, hi] (two finite numbers)", f"{name} =")
        lo, hi = (Fraction(str(b)) for b in bounds)
        if not 0 < lo <= hi:
            raise src.fail(f"expected 0 < lo <= hi in durations.{name}, got [{lo}, {hi}]", f"{name} =")
        out[name] = (lo, hi)
    if "dispatch" not in out:
        raise src.fail("expected durations.dispatch = [lo, hi]: the delay from ready to handled", "[durations]")
    return out


def _slot(raw: Any, cls: str, src: _Source, sizes: dict[str, int]) -> Slot:
    where = f"classes.{cls}.children"
    if not isinstance(raw, dict):
        raise src.fail(f"expected each of {where} to be a table {{name, class}}", f"[classes.{cls}]")
    name, child = _text(raw, "name", src, where), _text(raw, "class", src, where)
    repeat, chain = raw.get("repeat"), raw.get("chain")
    for key, size in (("repeat", repeat), ("chain", chain)):
        if size is not None and size not in sizes:
            raise src.fail(f"{where}: {key} = {size!r} is not in [sizes]", f'"{size}"', f"[classes.{cls}]")
    if repeat and chain:
        raise src.fail(f"{where}: child {name} cannot both repeat and chain", f'"{name}"')
    if chain and child != cls:
        raise src.fail(f"{where}: chained child {name} must be a {cls}, like its parent", f'"{name}"')
    return Slot(name, child, repeat, chain)


def _constraint(raw: Any, cls: str, slots: dict[str, Slot], src: _Source) -> Constraint:
    where = f"classes.{cls}.constraints"
    if not isinstance(raw, dict):
        raise src.fail(f"expected each of {where} to be a table {{relation, first, second}}", f"[classes.{cls}]")
    relation = _text(raw, "relation", src, where)
    if relation not in DECLARATIONS:
        raise src.fail(f"{where}: relation must be one of {', '.join(DECLARATIONS)}, got {relation!r}",
                       f'"{relation}"')
    ends = [_text(raw, k, src, where) for k in ("first", "second")]
    for ref in ends:
        m = _REF.match(ref)
        if not m or m.group(1) not in slots:
            raise src.fail(f"{where}: {ref!r} is not a child of {cls}", f'"{ref}"')
        if bool(m.group(2)) != bool(slots[m.group(1)].repeat):
            raise src.fail(f"{where}: {ref!r}: index a child exactly when it repeats ([k] or [k+1])", f'"{ref}"')
    return Constraint(relation, *ends)


def _class(name: str, raw: Any, src: _Source, sizes: dict[str, int], durations: dict) -> MessageClass:
    where = f"classes.{name}"
    if not isinstance(raw, dict):
        raise src.fail(f"expected [{where}] to be a table", f"[{where}]")
    kind = _text(raw, "kind", src, where)
    if kind not in KINDS:
        raise src.fail(f"{where}.kind must be one of {', '.join(KINDS)}, got {kind!r}", f"[{where}]")
    work = _text(raw, "work", src, where)
    if work not in durations:
        raise src.fail(f"{where}.work = {work!r} is not in [durations]", f'"{work}"')
    slots = tuple(_slot(s, name, src, sizes) for s in _list(raw, "children", src, where))
    by_name = {s.name: s for s in slots}
    if len(by_name) != len(slots):
        raise src.fail(f"{where}: two children share a name", f"[{where}]")
    constraints = tuple(_constraint(c, name, by_name, src) for c in _list(raw, "constraints", src, where))
    agent = raw.get("agent")
    return MessageClass(name, kind, work, agent if isinstance(agent, str) else None, slots, constraints)


def _claim(raw: Any, classes: dict, src: _Source) -> Claim:
    if not isinstance(raw, dict):
        raise src.fail("expected each [[claims]] entry to be a table", "[[claims]]")
    name = _text(raw, "name", src, "claims")
    pos = src.pos(f'"{name}"')
    about = _text(raw, "about", src, f"claims.{name}")
    if about not in classes:
        raise RoarError(f"claim {name}: about = {about!r} is not a class", pos)
    expect = raw.get("expect", "proved")
    if expect not in EXPECTATIONS:
        raise RoarError(f"claim {name}: expect must be proved or refuted, got {expect!r}", pos)
    bound = raw.get("bound")
    if bound is not None and not isinstance(bound, str):
        raise RoarError(f"claim {name}: bound must be a string", pos)
    return Claim(name, about, raw.get("says", ""), _text(raw, "holds", src, f"claims.{name}"), expect, bound, pos)


def _check_shape(model: Model, src: _Source) -> None:
    """Classes exist, queries issue nothing, commands issue only queries, no unbounded recursion."""
    for c in model.classes.values():
        for s in c.slots:
            if s.cls not in model.classes:
                raise src.fail(f"classes.{c.name}: child {s.name} has unknown class {s.cls!r}", f'"{s.cls}"')
            child_kind = model.classes[s.cls].kind
            if c.kind == "query" or (c.kind in ("command", "monitor") and child_kind != "query"):
                raise src.fail(f"classes.{c.name}: a {c.kind} may not issue the {child_kind} {s.name} "
                               "(queries issue nothing; commands and monitors only queries)", f"[classes.{c.name}]")
    if model.root not in model.classes:
        raise src.fail(f"model.root = {model.root!r} is not a class", "root")

    def visit(name: str, trail: tuple[str, ...]) -> None:
        if name in trail:
            raise src.fail(f"classes issue each other without end: {' -> '.join(trail + (name,))}; "
                           "use chain for recursion", f"[classes.{name}]")
        for s in model.classes[name].slots:
            if not s.chain:
                visit(s.cls, trail + (name,))

    visit(model.root, ())


def parse_model(text: str, file: str = "<model>") -> Model:
    src = _Source(text, file)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"at line (\d+), column (\d+)", str(exc))
        pos = Pos(file, int(m.group(1)), int(m.group(2))) if m else Pos(file, 1, 1)
        raise RoarError(f"malformed TOML: {str(exc).split(' (at line')[0]}", pos) from None
    except (RecursionError, ValueError) as exc:   # nested too deeply; a number past the int-string limit
        from ..inputs import toml_limit_error
        raise toml_limit_error(exc, text, file, "malformed TOML") from None
    head = _table(data, "model", src, "model")
    sizes = _table(data, "sizes", src, "sizes")
    for key, value in sizes.items():
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise src.fail(f"expected sizes.{key} to be a positive integer", f"{key} =")
    durations = _durations(data, src)
    raw_classes = _table(data, "classes", src, "classes")
    classes = {n: _class(n, raw, src, sizes, durations) for n, raw in raw_classes.items()}
    claims = tuple(_claim(c, classes, src) for c in _list(data, "claims", src, "claims"))
    model = Model(_text(head, "name", src, "model"), _text(head, "root", src, "model"),
                  head.get("description", ""), dict(sizes), durations, classes, claims, file)
    _check_shape(model, src)
    return model


def load_model(path) -> Model:
    """Read and validate a model file."""
    path = Path(path)
    from ..inputs import check_input_file
    check_input_file(path, Pos(str(path), 1, 1))
    if path.suffix in (".roar", ".ability", ".clf"):
        what = "a .clf program" if path.suffix == ".clf" else "a ROAR spec"
        raise RoarError(f"{path} is {what}; a TCA model is a task-tree TOML file (as models/ambler/ambler.toml): "
                        "its messages, their parents and the SeqAch declarations (docs/tca.md). To check a "
                        "spec's runs against the axioms, write a trace (run --trace) and give it to tca-check",
                        Pos(str(path), 1, 1))
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise RoarError(f"cannot read model: {exc.strerror}", Pos(str(path), 1, 1)) from None
    except UnicodeDecodeError as exc:
        line = exc.object[: exc.start].count(b"\n") + 1
        col = exc.start - (exc.object.rfind(b"\n", 0, exc.start) + 1) + 1
        raise RoarError(f"model is not UTF-8 text: {exc.reason}", Pos(str(path), line, col)) from None
    return parse_model(text, str(path))
