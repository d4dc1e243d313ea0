"""Replaying a trace against its model, one engine step at a time.

Each recorded step must be an enabled step of the current state (same rule,
same facts consumed and produced, compared as printed multisets); the replay
applies it with the engine's general driver. A counterexample found by any
backend therefore doubles as an independent check: it must replay on the
plain engine. A lasso's cycle must come back to the state where it started.

A trace is data (docs/trust.md): the model comes from the caller (the
command line's ``--model``), never from a path the trace names, and nothing
the trace says is imported or executed. The sources' fingerprint recorded by
``check`` must match the model's, unless ``force``.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.program import Program
from ..clf.query import show_context
from ..clf.signature import ExecDirective
from ..clf.state import canonical_key
from ..errors import Pos, RoarError
from ..explore.system import ClfSystem, Options
from .fingerprint import ALGORITHM, clf_fingerprint, differences, spec_fingerprint
from .format import read_trace


@dataclass
class ReplayResult:
    steps: int
    states: list[Context]
    cycle_closes: Optional[bool]  # None when the trace is not a lasso
    notes: list[str] = field(default_factory=list)  # e.g. no fingerprint recorded, or replayed despite one


def _shown(value) -> str:
    """A value read from a trace, quoted for a message (control characters escaped)."""
    return json.dumps(value, ensure_ascii=True) if isinstance(value, str) else json.dumps(str(value))


_PLAIN = re.compile(r"[A-Za-z0-9_'#.-]{1,200}")


def _name(value) -> str:
    """A step number or rule name read from a trace: as is when plain, else quoted."""
    text = str(value) if isinstance(value, int) and not isinstance(value, bool) else value
    return text if isinstance(text, str) and _PLAIN.fullmatch(text) else _shown(value)


def _need_model(path, header: dict) -> RoarError:
    named = header.get("spec") or header.get("model")
    kind = "spec" if header.get("spec") else "model"
    notes = ["a trace is data: replay never opens, imports or runs the files a trace names "
             "(see docs/trust.md)"]
    if named:
        notes.append(f"this trace was recorded on the {kind} {_shown(named)}"
                     + (f" with the functional-layer module {_shown(header['functional'])}"
                        if header.get("functional") else ""))
    return RoarError(f"{path}: replay needs the model on the command line: pass --model SPEC "
                     "(the ROAR spec, whose functional-layer module next to it is used) or --model FILE.clf",
                     None, notes)


def _check_fingerprint(path, header: dict, given: dict, force: bool, notes: list[str]) -> None:
    recorded = header.get("fingerprint")
    if not isinstance(recorded, dict) or not isinstance(recorded.get(ALGORITHM), str):
        notes.append("the trace records no fingerprint of its model's sources: it cannot be confirmed that "
                     "--model is the model it was recorded on")
        return
    if recorded[ALGORITHM] == given[ALGORITHM]:
        return
    what = differences(recorded, given) or ["the files differ"]
    rec_fn = [k.split(":", 1)[1] for k in (recorded.get("files") or {}) if str(k).startswith("functional:")]
    if rec_fn and not any(k.startswith("functional:") for k in given["files"]):
        what.append(f"the trace was recorded with the functional-layer module {_shown(rec_fn[0])}: if it is one "
                    "you trust, name it with --functional")
    if not force:
        raise RoarError(f"{path}: the model given with --model is not the one the trace was recorded on "
                        f"(fingerprint {given[ALGORITHM][:12]}, recorded {_shown(recorded[ALGORITHM][:12])})", None,
                        what + ["pass --force to replay it on this model anyway"])
    notes.append("replaying on a model other than the recorded one (--force): " + "; ".join(what))


def _start(path, header: dict) -> int:
    start = header.get("start", 1)
    if isinstance(start, bool) or not isinstance(start, int) or start < 1:
        raise RoarError(f'expected "start" in the trace header to be a whole number from 1, not {_shown(start)}',
                        Pos(str(path), 1, 1))
    return start


def load_replay_model(path, header: dict, model, functional=None, force: bool = False,
                      notes: Optional[list[str]] = None) -> Program:
    """The program to replay ``path`` on: ``model`` is a ``.clf`` file, or a ROAR spec compiled
    (abstract primitives) on the request the header records, with ``functional`` or the
    functional-layer module found next to the spec. The fingerprint is checked before the
    functional-layer module is imported."""
    notes = notes if notes is not None else []
    if model is None:
        raise _need_model(path, header)
    model = Path(model)
    if model.suffix == ".clf":
        if not model.is_file():
            raise RoarError(f"--model {model}: no such file")
        _check_fingerprint(path, header, clf_fingerprint(model), force, notes)
        return Program.from_file(model)
    from ..roar.commands import functional_module, load_registry
    from ..roar.compile import compile_spec
    from ..roar.parser import load_spec
    request = header.get("request")
    if not isinstance(request, str) or not request.strip():
        raise RoarError(f"{path}: --model {model} is a ROAR spec, but the trace records no request "
                        '("request" in its header) to compile it on', Pos(str(path), 1, 1))
    spec_ast = load_spec(model)
    fn = functional_module(model, Path(functional) if functional is not None else None)
    _check_fingerprint(path, header, spec_fingerprint(model, spec_ast, fn), force, notes)
    reg = load_registry(fn)
    return compile_spec(spec_ast, request, registry=reg, functional="abstract").program()


def replay(path: str | Path, on_step: Optional[Callable[[int, dict, Context], None]] = None,
           model: Optional[str | Path] = None, *, functional: Optional[str | Path] = None,
           force: bool = False) -> ReplayResult:
    """Replay the trace at ``path`` on ``model`` (a ``.clf`` file or a ROAR spec: see
    :func:`load_replay_model`). ``on_step(i, record, state)`` sees each step as the engine
    took it (rule, group, consumed, produced come from the engine, not from the file)."""
    header, steps = read_trace(path)
    notes: list[str] = []
    start_index = _start(path, header)
    program = load_replay_model(path, header, model, functional, force, notes)
    execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
    if start_index > len(execs):
        raise RoarError(f"{path}: start #{start_index} but the model has {len(execs)} #exec directive(s)")
    system = ClfSystem(program, program.start_context(execs[start_index - 1].start), Options())
    state = system.initial()
    states = [state]
    loop_start: Optional[Context] = None
    names: dict = {}  # fresh name in the trace -> fresh name in this replay (a bijection)
    for rec in steps:
        if rec.get("loop") and loop_start is None:
            loop_start = state
        want = (rec.get("consumed", []), rec.get("produced", []))
        if not all(isinstance(w, list) and all(isinstance(x, str) for x in w) for w in want):
            raise RoarError(f"{path}: step {_name(rec.get('step'))}: \"consumed\" and \"produced\" must be "
                            "lists of facts (strings)")
        nxt = None
        for succ in system.successors(state):
            if succ.label != rec.get("rule"):
                continue
            d = system.describe_step(succ.step)
            m = _match_renaming(want, (d["consumed"], d["produced"]), names)
            if m is not None:
                names = m
                nxt = succ
                break
        if nxt is None:
            enabled = sorted({s.label for s in system.successors(state)})
            raise RoarError(
                f"{path}: step {_name(rec.get('step'))} ({_name(rec.get('rule'))}) cannot be replayed: "
                "no such enabled step",
                None, [f"enabled rules here: {', '.join(enabled) or 'none (quiescent)'}",
                       "state: " + "; ".join(show_context(state))])
        state = nxt.state
        states.append(state)
        if on_step is not None:
            d = system.describe_step(nxt.step)
            taken = {"step": len(states) - 1, "rule": nxt.label, "group": nxt.group,
                     "consumed": d["consumed"], "produced": d["produced"], "loop": bool(rec.get("loop"))}
            on_step(len(states) - 1, taken, state)
    closes = None
    if loop_start is not None:
        closes = canonical_key(loop_start) == canonical_key(state)
        if not closes:
            raise RoarError(f"{path}: the lasso's cycle does not return to the state where it started")
    return ReplayResult(len(steps), states, closes, notes)


_FRESH = re.compile(r"[A-Za-z_][A-Za-z0-9_']*#\d+")


def _match_renaming(want: tuple, got: tuple, names: dict) -> Optional[dict]:
    """Do the recorded facts equal the replayed ones up to a consistent renaming of fresh
    names (``hint#id``)? Returns the extended renaming, or None."""
    for w, g in zip(want, got):
        if len(w) != len(g):
            return None
    ren = dict(names)
    used = set(ren.values())

    def shape(text: str) -> str:
        return _FRESH.sub("#", text)

    def assign(w_lines: list, g_lines: list) -> bool:
        if not w_lines:
            return True
        w = w_lines[0]
        for k, g in enumerate(g_lines):
            if shape(g) != shape(w):
                continue
            wn, gn = _FRESH.findall(w), _FRESH.findall(g)
            added = []
            ok = True
            for a, b in zip(wn, gn):
                if a in ren:
                    ok = ren[a] == b
                elif b in used:
                    ok = False
                else:
                    ren[a] = b
                    used.add(b)
                    added.append(a)
                if not ok:
                    break
            if ok and assign(w_lines[1:], g_lines[:k] + g_lines[k + 1:]):
                return True
            for a in added:
                used.discard(ren.pop(a))
        return False

    for w, g in zip(want, got):
        if not assign(list(w), list(g)):
            return None
    return ren
