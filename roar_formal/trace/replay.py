"""Replaying a trace against its model, one engine step at a time.

Each recorded step must be an enabled step of the current state (same rule,
same facts consumed and produced, compared as printed multisets); the replay
applies it with the engine's general driver. A counterexample found by any
backend therefore doubles as an independent check: it must replay on the
plain engine. A lasso's cycle must come back to the state where it started.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.program import Program
from ..clf.query import show_context
from ..clf.signature import ExecDirective
from ..clf.state import canonical_key
from ..errors import RoarError
from ..explore.system import ClfSystem, Options
from .format import read_trace


@dataclass
class ReplayResult:
    steps: int
    states: list[Context]
    cycle_closes: Optional[bool]  # None when the trace is not a lasso


def replay(path: str | Path, on_step: Optional[Callable[[int, dict, Context], None]] = None,
           model: Optional[str] = None) -> ReplayResult:
    header, steps = read_trace(path)
    if header.get("spec") and not model:
        # a counterexample of a job on a ROAR spec: compile the spec as the explorer did
        from ..roar.commands import functional_module, load_registry
        from ..roar.compile import compile_spec
        from ..roar.parser import load_spec
        spec = Path(header["spec"])
        fn = header.get("functional")
        reg = load_registry(functional_module(spec, Path(fn) if fn else None))
        program = compile_spec(load_spec(spec), header.get("request", ""), registry=reg,
                               functional="abstract").program()
    else:
        model_path = model or header.get("model")
        if not model_path:
            raise RoarError(f"{path}: the trace names no model; pass --model")
        program = Program.from_file(model_path)
    execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
    start_index = int(header.get("start", 1))
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
        nxt = None
        for succ in system.successors(state):
            if succ.label != rec.get("rule"):
                continue
            d = system.describe_step(succ.step)
            m = _match_renaming(want, (d["consumed"], d["produced"]), names)
            if m is not None:
                names = m
                nxt = succ.state
                break
        if nxt is None:
            enabled = sorted({s.label for s in system.successors(state)})
            raise RoarError(
                f"{path}: step {rec['step']} ({rec.get('rule')}) cannot be replayed: no such enabled step",
                None, [f"enabled rules here: {', '.join(enabled) or 'none (quiescent)'}",
                       "state: " + "; ".join(show_context(state))])
        state = nxt
        states.append(state)
        if on_step is not None:
            on_step(int(rec["step"]), rec, state)
    closes = None
    if loop_start is not None:
        closes = canonical_key(loop_start) == canonical_key(state)
        if not closes:
            raise RoarError(f"{path}: the lasso's cycle does not return to the state where it started")
    return ReplayResult(len(steps), states, closes)


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
