"""The trace events the TCA checks read, and a tolerant JSON Lines reader.

A trace is JSON Lines: one object per line. The records read here are

    {"event": "constraint_sent", "time": 3.5, "msg": "m7", "kind": "goal",
     "parent": "m3", "agent": "loco", "constraint": "at(x, 3)"}
    {"event": "started" | "ended" | "achieving_started" | "achieving_ended", "time": 4, "msg": "m7"}
    {"event": "seq_ach" | "precedes" | "delay_planning", "m1": "m7", "m2": "m8"}

``kind`` is one of query, goal, command, monitor; ``parent`` is absent or
null for a root; ``agent`` and ``constraint`` are optional. Every record may
carry ``step`` (an integer); a record without ``time`` uses its ``step`` as
its time. Declarations need no time. Other fields are ignored; records whose
``event`` is another name, or not a string (engine steps, the trace header,
engine event objects), are skipped, and so are blank lines.
Malformed input raises :class:`RoarError` at ``file:line:col``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from pathlib import Path
from typing import Iterable, Optional, Union

from ..errors import Pos, RoarError, json_message
from .vocabulary import KINDS

MARKS = ("started", "ended", "achieving_started", "achieving_ended")
DECLARATIONS = ("seq_ach", "precedes", "delay_planning")


@dataclass(frozen=True)
class Sent:
    """``constraint_sent``: a message issued (by the handler of ``parent``)."""

    msg: str
    kind: str
    parent: Optional[str]
    time: Fraction
    pos: Pos
    agent: Optional[str] = None
    constraint: Optional[str] = None


@dataclass(frozen=True)
class Mark:
    """A message starts or ends being handled, or being achieved."""

    what: str  # one of MARKS
    msg: str
    time: Fraction
    pos: Pos


@dataclass(frozen=True)
class Declared:
    """A temporal constraint the model declares between two messages."""

    relation: str  # one of DECLARATIONS
    m1: str
    m2: str
    pos: Pos
    time: Optional[Fraction] = None


Event = Union[Sent, Mark, Declared]


class _Record:
    """One parsed line, with located errors for missing or ill-typed fields."""

    def __init__(self, data: dict, text: str, file: str, line: int):
        self.data, self.text, self.file, self.line = data, text, file, line

    def pos(self, key: Optional[str] = None) -> Pos:
        col = self.text.find(f'"{key}"') + 1 if key else 0
        return Pos(self.file, self.line, max(col, 1))

    def fail(self, message: str, key: Optional[str] = None) -> RoarError:
        return RoarError(message, self.pos(key))

    def string(self, key: str, required: bool = True) -> Optional[str]:
        value = self.data.get(key)
        if value is None:
            if required:
                raise self.fail(f"expected a string field {key!r} in a {self.data['event']!r} record")
            return None
        if not isinstance(value, str) or not value:
            raise self.fail(f"expected field {key!r} to be a non-empty string, got {json.dumps(value, default=float)[:200]}", key)
        return value

    def time(self, required: bool = True) -> Optional[Fraction]:
        for key in ("time", "step"):
            value = self.data.get(key)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, Decimal)):
                raise self.fail(f"expected field {key!r} to be a number, got {json.dumps(value, default=str)}", key)
            if key == "step" and not isinstance(value, int):
                raise self.fail(f"expected field 'step' to be an integer, got {value}", key)
            if not _reasonable(value):
                shown = str(value) if len(str(value)) <= 40 else str(value)[:37] + "..."
                raise self.fail(f"expected field {key!r} to be a number below 10^{MAX_MAGNITUDE} in magnitude "
                                f"with at most {MAX_PLACES} decimal places, got {shown}", key)
            return Fraction(value)
        if required:
            raise self.fail(f"expected a number field 'time' (or 'step') in a {self.data['event']!r} record")
        return None


#: times and steps: below 10**MAX_MAGNITUDE in magnitude (nanoseconds since 1970 fit), at most
#: MAX_PLACES decimal places. Larger exponents are refused before any arithmetic: the exact
#: rational of ``1e999999999`` alone would take minutes and hundreds of megabytes.
MAX_MAGNITUDE = 20
MAX_PLACES = 30


def _reasonable(value: Union[int, Decimal]) -> bool:
    if isinstance(value, int):
        return abs(value) < 10 ** MAX_MAGNITUDE
    if not value.is_finite():
        return False
    if value.is_zero():
        return True
    if value.adjusted() >= MAX_MAGNITUDE:
        return False
    if value.as_tuple().exponent >= -MAX_PLACES:
        return True
    # trailing zeros do not count as places (0.50000...0)
    return len(value.as_tuple().digits) <= 4 * MAX_PLACES and value.normalize().as_tuple().exponent >= -MAX_PLACES


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_MAGNITUDE + 20:
        raise ValueError(f"an integer of {len(text)} digits is not a number a trace may hold")
    return int(text)


def _no_constants(name: str):
    raise ValueError(f"{name} is not a number a trace may hold")


def _parse(text: str, file: str, line: int) -> Optional[dict]:
    try:
        data = json.loads(text, parse_float=Decimal, parse_int=_bounded_int, parse_constant=_no_constants)
    except json.JSONDecodeError as exc:
        raise RoarError(f"malformed JSON: {json_message(exc)}; expected one JSON object per line",
                        Pos(file, line, exc.colno))
    except ValueError as exc:
        raise RoarError(f"malformed JSON: {exc}", Pos(file, line, 1))
    except RecursionError:
        raise RoarError("malformed JSON: nested too deeply", Pos(file, line, 1)) from None
    if not isinstance(data, dict):
        raise RoarError(f"expected a JSON object per line, got a {type(data).__name__}", Pos(file, line, 1))
    return data


def _event(rec: _Record) -> Optional[Event]:
    name = rec.data.get("event")
    if not isinstance(name, str):  # a plain engine step, a header, or an engine event object
        return None
    if name == "constraint_sent":
        kind = rec.string("kind")
        if kind not in KINDS:
            raise rec.fail(f"expected 'kind' to be one of {', '.join(KINDS)}, got {kind!r}", "kind")
        return Sent(rec.string("msg"), kind, rec.string("parent", required=False), rec.time(), rec.pos(),
                    rec.string("agent", required=False), rec.string("constraint", required=False))
    if name in MARKS:
        return Mark(name, rec.string("msg"), rec.time(), rec.pos())
    if name in DECLARATIONS:
        return Declared(name, rec.string("m1"), rec.string("m2"), rec.pos(), rec.time(required=False))
    return None


def parse_events(lines: Iterable[str], file: str = "<trace>") -> list[Event]:
    """The TCA events in ``lines``, in order; everything else is skipped."""
    events: list[Event] = []
    for number, text in enumerate(lines, start=1):
        if not text.strip():
            continue
        data = _parse(text.rstrip("\r\n"), file, number)
        event = _event(_Record(data, text, file, number))
        if event is not None:
            events.append(event)
    return events


def read_events(path: Union[str, Path]) -> list[Event]:
    """Read a JSON Lines trace file."""
    path = Path(path)
    from ..inputs import check_input_file
    check_input_file(path, Pos(str(path), 1, 1))
    try:
        with path.open(encoding="utf-8") as handle:
            return parse_events(handle, str(path))
    except OSError as exc:
        raise RoarError(f"cannot read trace: {exc.strerror}", Pos(str(path), 1, 1)) from None
    except UnicodeDecodeError as exc:
        raise RoarError(f"trace is not UTF-8 text: {exc.reason}", Pos(str(path), 1, 1)) from None


def _number(value: Fraction) -> Union[int, float]:
    return value.numerator if value.denominator == 1 else float(value)


def to_record(event: Event, step: Optional[int] = None) -> dict:
    """The JSON object for ``event`` (what a trace writer emits)."""
    head = {"step": step} if step is not None else {}
    if isinstance(event, Sent):
        rec = {**head, "time": _number(event.time), "event": "constraint_sent", "msg": event.msg,
               "kind": event.kind, "parent": event.parent}
        rec.update({k: getattr(event, k) for k in ("agent", "constraint") if getattr(event, k)})
        return rec
    if isinstance(event, Mark):
        return {**head, "time": _number(event.time), "event": event.what, "msg": event.msg}
    rec = {**head, "event": event.relation, "m1": event.m1, "m2": event.m2}
    if event.time is not None:
        rec["time"] = _number(event.time)
    return rec


def dumps(events: Iterable[Event]) -> str:
    """A JSON Lines text holding ``events`` with consecutive steps."""
    return "".join(json.dumps(to_record(e, i)) + "\n" for i, e in enumerate(events))
