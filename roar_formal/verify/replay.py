"""Replaying a trace against the model the user names: a ``.clf`` file or a ROAR spec.

A trace is data (docs/trust.md): the model comes from the caller (the
command line's ``--model``), never from a path the trace names, and nothing
the trace says is imported or executed. The sources' fingerprint recorded in
the trace must match the model's, unless ``force``. The steps themselves are
replayed by :func:`roar_formal.explore.replay.replay_steps`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.program import Program
from ..clf.query import show_context
from ..errors import Pos, RoarError
from ..explore.replay import ReplayResult, replay_steps, start_index
from ..explore.system import ClfSystem, Options
from .claims import claim_groups, confirm_claim
from ..roar.compile import CompiledModel, compile_spec
from ..roar.explore import PROGRESS_RULES, RoarSystem, path_narration, roar_final, sequential_pairs
from ..roar.report import decode_state, step_changes
from ..roar.functional import functional_module, load_registry
from ..roar.spec import load_spec
from ..roar.sources import spec_fingerprint
from ..trace.fingerprint import check_fingerprint, clf_fingerprint, shown
from ..trace.format import read_trace

__all__ = ["ReplayResult", "TraceReplay", "load_replay_model", "load_replay_target", "need_model", "replay",
           "replay_trace"]


CLI_MODEL = ("pass --model SPEC (the ROAR spec, whose functional-layer module next to it is used) "
             "or --model FILE.clf")


def need_model(path, header: dict, how: str = CLI_MODEL) -> RoarError:
    """A replay without a model: the error, with ``how`` to name one (the command line's or the API's way)."""
    named = header.get("spec") or header.get("model")
    kind = "spec" if header.get("spec") else "model"
    notes = ["a trace is data: replay never opens, imports or runs the files a trace names "
             "(see docs/trust.md)"]
    if named:
        notes.append(f"this trace was recorded on the {kind} {shown(named)}"
                     + (f" with the functional-layer module {shown(header['functional'])}"
                        if header.get("functional") else ""))
    where = "on the command line" if how == CLI_MODEL else "to replay on"
    return RoarError(f"{path}: replay needs the model {where}: {how}", None, notes)


#: the confirmation of a trace that claims nothing (a run's trace): only its steps were checked
NOTHING_CLAIMED = "every step is a step of the model"


def load_replay_target(path, header: dict, model, functional=None, force: bool = False,
                       notes: Optional[list[str]] = None) -> tuple[Program, Optional[CompiledModel]]:
    """The program to replay ``path`` on: ``model`` is a ``.clf`` file, or a ROAR spec compiled
    (abstract primitives) on the request the header records, with ``functional`` or the
    functional-layer module found next to the spec. The fingerprint is checked before the
    functional-layer module is imported."""
    notes = notes if notes is not None else []
    if model is None:
        raise need_model(path, header)
    model = Path(model)
    if model.suffix == ".clf":
        if not model.is_file():
            raise RoarError(f"--model {model}: no such file")
        check_fingerprint(path, header, clf_fingerprint(model), force, notes)
        return Program.from_file(model), None
    request = header.get("request")
    if not isinstance(request, str) or not request.strip():
        raise RoarError(f"{path}: --model {model} is a ROAR spec, but the trace records no request "
                        '("request" in its header) to compile it on', Pos(str(path), 1, 1))
    spec_ast = load_spec(model)
    fn = functional_module(model, Path(functional) if functional is not None else None)
    check_fingerprint(path, header, spec_fingerprint(model, spec_ast, fn), force, notes)
    reg = load_registry(fn)
    # the options the counterexample's model was compiled with, as its header records them
    compiled = compile_spec(spec_ast, request, registry=reg, functional="abstract",
                            crashes=header_crashes(path, header), time=header_timing(path, header))
    return compiled.program(), compiled


def header_crashes(path, header: dict):
    """The crashes a trace's header records (``crash``, ``max_crashes``: a job's [faults]), or None."""
    from ..roar.compile import Crashes
    agents, bound = header.get("crash"), header.get("max_crashes", 1)
    if agents is None:
        return None
    if not isinstance(agents, list) or not all(isinstance(x, str) for x in agents) or \
            isinstance(bound, bool) or not isinstance(bound, int) or bound < 1:
        raise RoarError(f"{path}: the trace's header records crashes it cannot mean ('crash' is a list of agent "
                        f"names, 'max_crashes' a whole number from 1)", Pos(str(path), 1, 1))
    return Crashes(tuple(agents), bound) if agents else None


def header_timing(path, header: dict):
    """The time mode a trace's header records (``time``, ``wait_timeout``), or None (untimed)."""
    from ..roar.compile import TIME_MODES, Timing
    mode, timeout = header.get("time"), header.get("wait_timeout")
    if mode is None and timeout is None:
        return None
    if mode not in TIME_MODES or (timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, int)
                                                            or timeout < 1 or mode != "timed")):
        raise RoarError(f"{path}: the trace's header records a time mode it cannot mean ('time' is "
                        f"{' or '.join(TIME_MODES)}; 'wait_timeout' a whole number of ms, timed only)",
                        Pos(str(path), 1, 1))
    timing = Timing(mode, timeout)
    return timing if timing else None


def load_replay_model(path, header: dict, model, functional=None, force: bool = False,
                      notes: Optional[list[str]] = None) -> Program:
    """The program of :func:`load_replay_target`."""
    return load_replay_target(path, header, model, functional, force, notes)[0]


def replay(path: str | Path, on_step: Optional[Callable[[int, dict, Context], None]] = None,
           model: Optional[str | Path] = None, *, functional: Optional[str | Path] = None,
           force: bool = False) -> ReplayResult:
    """Replay the trace at ``path`` on ``model`` (a ``.clf`` file or a ROAR spec: see
    :func:`load_replay_target`). ``on_step(i, record, state)`` sees each step as the engine
    took it."""
    return replay_trace(path, model, functional=functional, force=force, on_step=on_step).result


@dataclass
class TraceReplay:
    """A trace replayed on the model the user named, read back in the model's own terms.

    ``steps``: per step (``step``, ``loop``, ``rule``, ``group``, ``events``, ``changes``), the
    events and variable changes being ROAR-level for a spec (empty for a ``.clf`` model);
    ``states``: the per-agent table (a spec) or the facts (a ``.clf`` model) after each step, on
    demand; ``confirmed``: whether the end of the replay shows again what the trace says it
    shows (None when the property is not one replay can re-decide), with ``confirmation``."""

    header: dict
    result: ReplayResult
    compiled: Optional[CompiledModel]
    steps: list[dict]
    requests: dict
    confirmed: Optional[bool]
    confirmation: str
    _labels: tuple = field(default=(), repr=False)

    def state_table(self, i: int) -> dict:
        """The state after step ``i`` (0: the start): per agent (spec) or ``{"facts": [...]}``."""
        ctx = self.result.states[i]
        if self.compiled is None:
            return {"facts": [x for x in show_context(ctx) if not x.startswith("!")]}
        labels, req_info = self._labels
        return decode_state(self.compiled, ctx, labels, req_info)["agents"]


def replay_trace(path: str | Path, model: Optional[str | Path], *, functional: Optional[str | Path] = None,
                 force: bool = False, on_step: Optional[Callable[[int, dict, Context], None]] = None) -> TraceReplay:
    """Replay the trace at ``path`` on ``model`` and read it back at the model's level: for a
    ROAR spec the ROAR events and variable changes of each step, the final per-agent table,
    and a confirmation of the trace's claim (a deadlock is still a deadlock, a lasso's cycle
    closes, the sequential-achievement pair is still broken)."""
    header, records = read_trace(path)
    notes: list[str] = []
    start = start_index(path, header)
    program, compiled = load_replay_target(path, header, model, functional, force, notes)
    pairs = []
    if compiled is not None:
        recorded = header.get("seq_pairs")
        wanted = {p[2] for p in (recorded if isinstance(recorded, list) else [])
                  if isinstance(p, list) and len(p) > 2 and isinstance(p[2], str)}
        kept = {p[2] for p in (recorded if isinstance(recorded, list) else [])
                if isinstance(p, list) and len(p) > 5 and p[5] is True and isinstance(p[2], str)}
        pairs = [p for p in sequential_pairs(compiled, kept=kept) if p.where in wanted]

        def make_system(prog: Program, begin: Context) -> RoarSystem:
            return RoarSystem(compiled, begin, Options(progress_rules=PROGRESS_RULES), pairs)
    elif claim_groups(path, header) is not None:   # the processes the .clf job was checked with
        groups = claim_groups(path, header)

        def make_system(prog: Program, begin: Context) -> ClfSystem:
            return ClfSystem(prog, begin, Options(fairness=groups))
    else:
        make_system = None
    res = replay_steps(path, program, start, records, on_step, notes, make_system)
    steps = [{"step": r["step"], "loop": r["loop"], "rule": r["rule"], "group": str(r["group"]),
              "events": [], "changes": []} for r in res.records]
    requests: dict = {}
    labels: tuple = ()
    if compiled is not None:
        events, nar = path_narration(compiled, res.states[0], res.engine_steps)
        for ev in events:
            steps[ev.step - 1]["events"].append(ev.as_json())
        for s, st in zip(steps, res.engine_steps):
            s["changes"] = step_changes(compiled, st)
        requests = {lab: {"agent": a, "constraint": t} for lab, (a, t) in sorted(
            nar.req_info.items(), key=lambda kv: (len(kv[0]), kv[0]))}
        labels = (nar.labels, nar.req_info)
    decided = confirm_claim(path, header, res, compiled)
    confirmed, why = decided if decided is not None else _confirm(header, res, compiled)
    return TraceReplay(header, res, compiled, steps, requests, confirmed, why, labels)


def _confirm(header: dict, res: ReplayResult, compiled: Optional[CompiledModel]) -> tuple[Optional[bool], str]:
    """Does the replayed end show what the trace claims? (None: not a claim replay decides.)"""
    prop = header.get("property")
    final = res.states[-1]
    if header.get("shape") == "lasso" or res.cycle_closes is not None:
        if res.cycle_closes:
            return True, "the cycle returns to the state where it started: the run can repeat it forever"
        return False, "the trace's cycle does not return to the state where it started"
    if prop == "deadlock":
        enabled = res.system.successors(final)
        if enabled:
            return False, (f"not a deadlock on this model: {len(enabled)} step(s) are enabled at the end "
                           f"({', '.join(sorted({s.label for s in enabled})[:5])})")
        if compiled is not None and roar_final(final):
            return False, "not a deadlock on this model: every request is in a final state at the end"
        return True, "the final state is a deadlock: no step is enabled and requests are left unfinished" \
            if compiled is not None else "the final state is a deadlock: no step is enabled"
    if prop == "sequential-achievement" and compiled is not None:
        why = res.system.sequence_reason(final)
        if why is None:
            return False, "the final state breaks no sequential-achievement pair on this model"
        return True, f"the sequential-achievement pair is still broken: {why}"
    if prop:
        return None, f"replay does not re-decide '{prop}' (its definition is in the job); every step is a step of the model"
    return None, NOTHING_CLAIMED
