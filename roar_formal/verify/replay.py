"""Replaying a trace against the model the user names: a ``.clf`` file or a ROAR spec.

A trace is data (docs/trust.md): the model comes from the caller (the
command line's ``--model``), never from a path the trace names, and nothing
the trace says is imported or executed. The sources' fingerprint recorded in
the trace must match the model's, unless ``force``. The steps themselves are
replayed by :func:`roar_formal.explore.replay.replay_steps`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.program import Program
from ..errors import Pos, RoarError
from ..explore.replay import ReplayResult, replay_steps, start_index
from ..roar.compile import compile_spec
from ..roar.functional import functional_module, load_registry
from ..roar.spec import load_spec
from ..roar.sources import spec_fingerprint
from ..trace.fingerprint import check_fingerprint, clf_fingerprint, shown
from ..trace.format import read_trace

__all__ = ["ReplayResult", "load_replay_model", "replay"]


def _need_model(path, header: dict) -> RoarError:
    named = header.get("spec") or header.get("model")
    kind = "spec" if header.get("spec") else "model"
    notes = ["a trace is data: replay never opens, imports or runs the files a trace names "
             "(see docs/trust.md)"]
    if named:
        notes.append(f"this trace was recorded on the {kind} {shown(named)}"
                     + (f" with the functional-layer module {shown(header['functional'])}"
                        if header.get("functional") else ""))
    return RoarError(f"{path}: replay needs the model on the command line: pass --model SPEC "
                     "(the ROAR spec, whose functional-layer module next to it is used) or --model FILE.clf",
                     None, notes)


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
        check_fingerprint(path, header, clf_fingerprint(model), force, notes)
        return Program.from_file(model)
    request = header.get("request")
    if not isinstance(request, str) or not request.strip():
        raise RoarError(f"{path}: --model {model} is a ROAR spec, but the trace records no request "
                        '("request" in its header) to compile it on', Pos(str(path), 1, 1))
    spec_ast = load_spec(model)
    fn = functional_module(model, Path(functional) if functional is not None else None)
    check_fingerprint(path, header, spec_fingerprint(model, spec_ast, fn), force, notes)
    reg = load_registry(fn)
    return compile_spec(spec_ast, request, registry=reg, functional="abstract").program()


def replay(path: str | Path, on_step: Optional[Callable[[int, dict, Context], None]] = None,
           model: Optional[str | Path] = None, *, functional: Optional[str | Path] = None,
           force: bool = False) -> ReplayResult:
    """Replay the trace at ``path`` on ``model`` (a ``.clf`` file or a ROAR spec: see
    :func:`load_replay_model`). ``on_step(i, record, state)`` sees each step as the engine
    took it."""
    header, steps = read_trace(path)
    notes: list[str] = []
    start = start_index(path, header)
    program = load_replay_model(path, header, model, functional, force, notes)
    return replay_steps(path, program, start, steps, on_step, notes)
