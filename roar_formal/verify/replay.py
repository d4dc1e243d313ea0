"""Replaying a trace against the model the user names: a ``.clf`` file or a ROAR spec.

A trace is data (docs/trust.md): the model comes from the caller (the
command line's ``--model``), never from a path the trace names, and nothing
the trace says is imported or executed. The sources' fingerprint recorded in
the trace must match the model's, unless ``force``. The steps themselves are
replayed by :func:`roar_formal.explore.replay.replay_steps`; a run's trace
(``roar-verify run --trace``) replays on the abstract model compiled with the
run's options (crashes, time), each answer of the functional layer as the
declared outcome rule that gives the same answer (see :class:`_Replayed`).
"""

from __future__ import annotations

import re
from fractions import Fraction
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.program import Program
from ..clf.query import show_context
from ..errors import Pos, RoarError
from ..explore.replay import (FRESH_NAME, ReplayResult, match_renaming, reads_as, replay_steps, returned_values,
                              start_index, trace_name)
from ..explore.system import ClfSystem, Options
from .claims import claim_groups, confirm_claim
from ..roar.compile import CRASH_RULES, CompiledModel, compile_spec
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
    if header.get("kind") == RUN_KIND:
        reg = run_registry(spec_ast, reg)
    # the options the counterexample's model was compiled with, as its header records them
    compiled = compile_spec(spec_ast, request, registry=reg, functional="abstract",
                            crashes=header_crashes(path, header), time=header_timing(path, header))
    return compiled.program(), compiled


#: the header's ``kind`` of a run's trace (roar/traces.py)
RUN_KIND = "roar-run"


def run_registry(spec_ast, reg):
    """The registry a run's trace replays with: ``reg`` without the entries that abstract the
    read of a task-initialised variable (``agent::var``). A run reads such a variable by running
    its task (the abstraction is for exploration only), and so does the model it replays on;
    the primitives keep their declared outcomes."""
    if reg is None:
        return None
    from ..roar.functional import Registry
    reads = {f"{ag.name}::{var}" for ag in spec_ast.agents for var in ag.task_initialised()}
    if not reads & set(reg.names()):
        return reg
    out = Registry(builtins=False)
    for name in reg.names():
        p = reg.get(name)
        if name not in reads:
            out.register(name, p.fn, p.outcomes, replace=True, max_failures=p.max_failures, fair=p.fair)
    return out


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
    # a run's model arms every agent named from the start, and the runner takes each crash at
    # the step --crash gave (roar/run.py, crash_setup); a check's model decides a crash plan
    return Crashes(tuple(agents), bound, header.get("kind") == RUN_KIND) if agents else None


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
    lines: list[int] = []
    header, records = read_trace(path, lines)
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
        def make_system(prog: Program, begin: Context) -> ClfSystem:
            return ClfSystem(prog, begin, Options())
    replayed = _Replayed(path, header, records, compiled, on_step, lines)
    try:
        res = replay_steps(path, program, start, replayed.steps(), replayed.on_step, notes, replayed.wrap(make_system),
                           stands_for=replayed.stands_for)
    except RoarError as exc:
        raise replayed.locate(replayed.explain(exc)) from None
    if replayed.abstracted:
        res.notes.append(f"{replayed.abstracted} answer(s) of the functional layer are no declared outcome's value "
                         f"and were read as the declared outcome that covers them (the values the outcomes "
                         f"stand for: {', '.join(f'{a} as {b}' for a, b in replayed.stands_for.items()) or 'the same'})")
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
        _same_events(path, records, lines, steps, bool(replayed.stands_for or replayed.opaque))
        requests = {lab: {"agent": a, "constraint": t} for lab, (a, t) in sorted(
            nar.req_info.items(), key=lambda kv: (len(kv[0]), kv[0]))}
        labels = (nar.labels, nar.req_info)
    decided = confirm_claim(path, header, res, compiled)
    if decided is None and compiled is not None and header.get("kind") == RUN_KIND:
        decided = _confirm_run(header, res, labels)
    confirmed, why = decided if decided is not None else _confirm(header, res, compiled)
    return TraceReplay(header, res, compiled, steps, requests, confirmed, why, labels)


def _event_fields(ev: dict, loose: bool) -> dict:
    """What an event says that replay re-derives: all of it, except the value (and so the text)
    a functional-layer answer gave, which replay reads as the declared outcome covering it;
    ``loose``: some answer was read so, and values that flowed from it differ too."""
    if loose or ev.get("kind") == "primitive-end":
        return {k: v for k, v in ev.items() if k not in ("text", "value")}
    return ev


def _same_events(path, records: list[dict], lines: list[int], steps: list[dict], loose: bool) -> None:
    """The ROAR events a trace records at each step are those the model's step makes: a trace
    whose event fields were edited (or written for another spec) is refused at the first step
    where they differ, since ``tca-check`` and the reports read those fields."""
    for k, (rec, step) in enumerate(zip(records, steps)):
        if "event" not in rec:
            continue
        ev = rec["event"]
        recorded = [] if ev is None else ev.get("events") if isinstance(ev, dict) and ev.get("kind") == "several" \
            else [ev]
        if not isinstance(recorded, list) or not all(isinstance(e, dict) for e in recorded):
            raise RoarError(f"step {trace_name(rec.get('step'))}: \"event\" is neither null nor a ROAR event",
                            Pos(str(path), lines[k] if k < len(lines) else 1, 1))
        made = step["events"]
        if [_event_fields(e, loose) for e in recorded] != [_event_fields(e, loose) for e in made]:
            def said(evs):
                return "; ".join(shown(e.get("text", e.get("kind"))) for e in evs) or "no event"
            raise RoarError(f"step {trace_name(rec.get('step'))}: the trace records {said(recorded)}, but on this "
                            f"model the step makes {said(made)}: the trace's events do not describe its steps "
                            "(edited, or written for another spec)",
                            Pos(str(path), lines[k] if k < len(lines) else 1, 1))


#: the rule name a run's trace gives the functional layer's answers (roar/run.py: the runner's external step)
FUNCTIONAL_LAYER = "functional_layer"
#: facts an abstract outcome rule keeps besides the call and its writes (a ``max_failures`` budget)
_BUDGET = "fails_left "


class _Replayed:
    """The steps of a trace as :func:`replay_steps` takes them, and what replay says of the one
    it cannot take.

    A run's trace (``roar-verify run --trace``) records each answer of the functional layer as
    one external step (rule ``functional_layer``: the Python callable, a ``--fault`` or a
    declared outcome answered); the model replay rebuilds is the abstract one, where a call is
    answered by one of its primitive's declared outcome rules. Such a step replays as the
    outcome rule enabled on that call that produces the same answer (the same result and the
    same writes; the rule's failure budget, ``max_failures``, taken as the rule takes it); an
    answer that no declared outcome produces is refused, at its step. Iterating this object
    yields the steps one at a time: each is read against the state the replay has reached
    (``on_step`` tells it), before the next is asked for."""

    def __init__(self, path, header: dict, records: list[dict], compiled: Optional[CompiledModel],
                 on_step: Optional[Callable[[int, dict, Context], None]], lines: Optional[list[int]] = None):
        self.path = path
        self.lines = lines or []               # each record's line in the file
        self.index: Optional[int] = None       # the record being read
        self.header = header
        self.records = records
        self.compiled = compiled
        self.user_on_step = on_step
        self.system = None
        self.state: Optional[Context] = None   # the state the next step is taken from
        self.taken = 0                         # steps replayed so far
        self.current: Optional[dict] = None    # the step being replayed, as given to replay_steps
        self.opaque: dict[str, str] = {}       # an opaque value of the run -> the model's (see answer)
        self.stands_for: dict[str, str] = {}   # a value an answer gave -> the covering outcome's (see _covered)
        self.abstracted = 0                    # answers read as the outcome that covers them

    def wrap(self, make_system):
        def make(prog: Program, begin: Context):
            self.system = make_system(prog, begin)
            self.state = self.system.initial()
            return self.system
        return make

    def on_step(self, i: int, rec: dict, state: Context) -> None:
        self.taken, self.state = i, state
        if self.user_on_step is not None:
            self.user_on_step(i, rec, state)

    def steps(self) -> "_Replayed":
        return self

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self):
        for k, rec in enumerate(self.records):
            self.index = k
            if self.compiled is not None and rec.get("rule") == FUNCTIONAL_LAYER:
                if self.taken != k or self.system is None:   # replay_steps takes each step before the next
                    raise RuntimeError("replay: a functional-layer step read before the steps preceding it")
                rec = self.answer(rec)
            elif self.opaque:
                rec = self._unopaque(rec)
            self.current = rec
            yield rec

    def _unopaque(self, rec: dict) -> dict:
        """``rec`` with the opaque values the run's functional layer made (``vopq K``: a Python
        object the spec cannot look into) as the model's outcomes made them. (The values an
        outcome covers are not rewritten: a recorded fact is matched occurrence by occurrence,
        see ``reads_as``.)"""
        def swap(fact):
            if not isinstance(fact, str):
                return fact
            return _OPAQUE.sub(lambda m: self.opaque.get(m.group(0), m.group(0)), fact)
        return {**rec, **{k: [swap(f) for f in rec[k]] for k in ("consumed", "produced")
                          if isinstance(rec.get(k), list)}}

    # ------------------------------------------------------------ the functional layer's answers
    def answer(self, rec: dict) -> dict:
        """The functional-layer step ``rec`` as the declared outcome rule that gives its answer."""
        if not all(isinstance(rec.get(k, []), list) and all(isinstance(x, str) for x in rec.get(k, []))
                   for k in ("consumed", "produced")):
            return rec   # replay_steps says what is wrong with it
        rec = self._unopaque(rec)
        want = (rec.get("consumed", []), rec.get("produced", []))
        where = f"{self.path}: step {_step_name(rec)} ({FUNCTIONAL_LAYER}) cannot be replayed"
        calls = [f for f in want[0] if f.startswith("pending ")]
        if len(calls) != 1:
            raise RoarError(f"{where}: an answer of the functional layer consumes one pending call, and this step "
                            f"consumes {len(calls)}", None, [f"consumed: {'; '.join(want[0]) or 'nothing'}"])
        call = calls[0]
        fc = call.split()[1] if len(call.split()) > 1 else ""
        qual = self._function(fc)
        outcomes = []   # (successor, its facts without the budget, the budget facts)
        for succ in self.system.successors(self.state):
            if not succ.label.startswith("outcome_"):
                continue
            d = self.system.describe_step(succ.step)
            if not any(reads_as(_shape(call), _shape(f), self.stands_for) for f in d["consumed"]
                       if f.startswith("pending ")):
                continue   # an outcome of another call
            kept = tuple([f for f in d[k] if not f.startswith(_BUDGET)] for k in ("consumed", "produced"))
            budget = tuple([f for f in d[k] if f.startswith(_BUDGET)] for k in ("consumed", "produced"))
            outcomes.append((succ, kept, budget))
        for succ, kept, budget in outcomes:
            # an opaque value the call returns or writes (a Python object: the model's outcome makes
            # one that stands for any) is the outcome's, here and in the steps after
            made = _opaque_made(want[1], kept[1], self.opaque)
            if made is None:
                continue
            got = tuple([_OPAQUE.sub(lambda m: made.get(m.group(0), m.group(0)), f) for f in w] for w in want)
            if _same_facts(got, kept, self.stands_for):
                self.opaque.update(made)
                return {**rec, "rule": succ.label, "consumed": got[0] + budget[0], "produced": got[1] + budget[1]}
        covered = self._covered(rec, want, call, fc, outcomes)
        if covered is not None:
            return covered
        answer = [f for f in want[1]]
        declared = sorted(t.name for t in self.system.program.templates if t.name.startswith(f"outcome_{fc}_"))
        if not declared:
            raise RoarError(f"{where}: it answers a call of {qual}, which no declared outcome of this model answers",
                            None, [f"the call: {call}", *self._context()])
        if not outcomes:
            pending = [x for x in show_context(self.state) if x.startswith("pending ")]
            raise RoarError(f"{where}: the call it answers is not pending here", None,
                            [f"the call: {call}",
                             f"pending calls here: {'; '.join(pending) or 'none'}", *self._context()])
        enabled = {succ.label for succ, _k, _b in outcomes}
        notes = [f"the call: {call}", f"the recorded answer: {'; '.join(answer) or 'nothing'}",
                 "the declared outcomes enabled here answer: " + "; ".join(
                     f"{succ.label}: {', '.join(_renamed(f, kept[0], call) for f in kept[1])}"
                     for succ, kept, _b in outcomes)]
        spent = [x for x in declared if x not in enabled]
        budget = bool(spent) and f"{_BUDGET}{fc} z" in show_context(self.state)
        if spent:
            notes.append(f"declared outcomes not enabled here: {', '.join(spent)}"
                         + (" (the primitive's failure budget, max_failures, is spent: the run failed it more "
                            "often than the registry assumes)" if budget else ""))
        notes.append("a run's trace replays on the abstract model, where a primitive answers only with its "
                     "declared outcomes (the answers check explores)"
                     + ("" if budget else "; an answer of the Python function that none of them produces is "
                        "not a step of that model: declare an outcome that produces it"))
        raise RoarError(f"{where}: the recorded answer of {qual} is none that a declared outcome "
                        f"{'enabled here ' if budget else ''}produces", None, notes)

    def _covered(self, rec: dict, want: tuple, call: str, fc: str, outcomes: list) -> Optional[dict]:
        """The answer as the declared outcome that *covers* it (``Outcome.covers``, as a robot's
        results are classified: spa_loop's odometry answers 4 where the outcome ``moving`` stands
        for any position but the goal, written 3), or None. The answer's value is then read as
        the outcome's in this step and in the steps after (``stands_for``)."""
        if self.compiled is None or self.compiled.registry is None or fc not in self.compiled.functions:
            return None
        owner, name = self.compiled.functions[fc]
        prim = self.compiled.registry.lookup(name, owner)
        returned = returned_values(want[1])
        if prim is None or len(returned) != 1 or len(want[1]) != 1:
            return None   # (an answer that also writes cells: not abstracted)
        rty = self.compiled.fn_types.get(fc)
        value = _python_value(returned[0], rty, self.compiled)
        if value is _NO_VALUE:
            return None   # an opaque handle (the outcomes' own handles stand for it), or no value
        from ..roar.functional import misfit, type_table
        from ..robot.activity import CallResult
        from ..robot.sim import classify
        if misfit(value, rty, type_table(self.compiled.spec)) is not None:
            return None   # a value of another type than the function's: no outcome stands for it
        names = classify(prim.outcomes, CallResult(value), rty)
        for succ, kept, budget in outcomes:
            if succ.label not in {f"outcome_{fc}_{n}" for n in names} or len(kept[1]) != 1:
                continue
            model_v = returned_values(kept[1])
            if not model_v:
                continue
            if model_v[0] != returned[0] and returned[0].startswith("("):
                self.stands_for[returned[0]] = model_v[0]
            produced = [f"return {model_v[0]} {want[1][0].rsplit(' ', 1)[1]}"]
            self.abstracted += 1
            return {**rec, "rule": succ.label, "consumed": list(want[0]) + budget[0], "produced": produced + budget[1]}
        return None

    def _function(self, fc: str) -> str:
        owner, name = (self.compiled.functions.get(fc, (None, None)) if self.compiled is not None else (None, None))
        if name is None:
            return repr(fc)
        return f"'{owner}::{name}'" if owner else f"'{name}'"

    def _context(self) -> list[str]:
        enabled = sorted({s.label for s in self.system.successors(self.state)})
        return [f"enabled rules here: {', '.join(enabled) or 'none (quiescent)'}",
                "state: " + "; ".join(show_context(self.state))]

    # ------------------------------------------------------------ a step replay cannot take
    def locate(self, exc: RoarError) -> RoarError:
        """``exc`` at the line of the step being read, when it names no place of its own."""
        if self.index is not None and self.index < len(self.records):
            for k in range(self.index, -1, -1):   # the last gap in the numbering up to here
                here = self.records[k].get("step")
                before = self.records[k - 1].get("step") if k else 0
                if type(here) is int and type(before) is int and here > before + 1:
                    gap = f"{before + 1}" if here == before + 2 else f"{before + 1} to {here - 1}"
                    exc.notes.append(f"the trace has no step {gap}: a step missing from a trace makes the steps "
                                     "after it fail to replay")
                    break
        if exc.pos is not None or self.index is None or self.index >= len(self.lines):
            return exc
        prefix = f"{self.path}: "
        message = exc.message[len(prefix):] if exc.message.startswith(prefix) else exc.message
        return RoarError(message, Pos(str(self.path), self.lines[self.index], 1), exc.notes)

    def explain(self, exc: RoarError) -> RoarError:
        """``exc``, or, when the step's rule is enabled but on other facts, an error that says so."""
        if self.stands_for:
            exc.notes.append("earlier answers of the functional layer were read as the declared outcome that covers "
                             "them, and their values as the outcome's in the steps after ("
                             + ", ".join(f"{a} as {b}" for a, b in self.stands_for.items())
                             + "): a fact that held such a value for another reason reads differently too")
        rec = self.current
        if "no such enabled step" not in exc.message or rec is None or self.system is None or self.state is None:
            return exc
        same = [s for s in self.system.successors(self.state) if s.label == rec.get("rule")]
        if not same:
            return exc
        want = (rec.get("consumed", []), rec.get("produced", []))
        best = None
        for succ in same:
            d = self.system.describe_step(succ.step)
            diff = (_minus(want[0], d["consumed"]), _minus(d["consumed"], want[0]),
                    _minus(want[1], d["produced"]), _minus(d["produced"], want[1]))
            size = sum(len(x) for x in diff)
            if best is None or size < best[0]:
                best = (size, diff)
        size, (c_rec, c_here, p_rec, p_here) = best
        rule = _step_rule(rec)
        n = f"{len(same)} instance{'s' if len(same) != 1 else ''}"
        notes = []
        if size == 0:
            notes.append("the nearest instance consumes and produces the same facts up to fresh names, but its "
                         "fresh names do not correspond to those of the steps before it")
        else:
            for what, facts in (("consumed in the trace, not by the nearest instance", c_rec),
                                ("consumed by the nearest instance, not in the trace", c_here),
                                ("produced in the trace, not by the nearest instance", p_rec),
                                ("produced by the nearest instance, not in the trace", p_here)):
                if facts:
                    notes.append(f"{what}: {'; '.join(facts)}")
        if self.header.get("crash") is None and any(r.get("rule") in CRASH_RULES for r in self.records):
            notes.append("the trace takes crash steps, but its header records no crashes ('crash', "
                         "'max_crashes'), so the model replayed on has none: a trace written without them "
                         "(a run's, before they were recorded) needs them added to its header")
        return RoarError(f"{self.path}: step {_step_name(rec)} ({rule}) cannot be replayed: {rule} is enabled here "
                         f"({n}), but not on the facts the trace records", exc.pos, notes + exc.notes)


_OPAQUE = re.compile(r"\(vopq \d+\)")
_NO_VALUE = object()


def _python_value(printed: str, ty: Optional[str], model: CompiledModel):
    """The Python value of a printed answer of the spec's type ``ty`` (a number, a boolean, a
    string, a list, a struct as a dict by field name), or _NO_VALUE (an opaque handle, text
    that is no value)."""
    from ..clf.parser import parse_expr
    try:
        e = parse_expr(printed, "<trace>")
    except RoarError:
        return _NO_VALUE
    return _value_of(e, ty, model)


def _list_elements(e) -> Optional[list]:
    """The elements of a printed list ``vcons X (vcons Y vnil)`` (None: not a list)."""
    from ..clf import surface as S
    out = []
    while isinstance(e, S.App) and isinstance(e.fn, S.App) and isinstance(e.fn.fn, S.Id) and e.fn.fn.name == "vcons":
        out.append(e.fn.arg)
        e = e.arg
    return out if isinstance(e, S.Id) and e.name == "vnil" else None


def _value_of(e, ty: Optional[str], model: CompiledModel):
    """The Python value of a parsed printed value (see ``_python_value``)."""
    from ..clf import surface as S
    whole = e
    args = []
    while isinstance(e, S.App):
        args.append(e.arg)
        e = e.fn
    args.reverse()
    name = e.name if isinstance(e, S.Id) else None
    if name == "vnum" and len(args) == 1 and isinstance(args[0], (S.Num, S.One)):
        v = args[0].value if isinstance(args[0], S.Num) else Fraction(1)   # (`1` reads as CLF's unit)
        return int(v) if v.denominator == 1 and ty != "double" else v
    if name == "vbool" and len(args) == 1 and isinstance(args[0], S.Id) and args[0].name in ("tt", "ff"):
        return args[0].name == "tt"
    if name == "vstr" and len(args) == 1 and isinstance(args[0], S.Str):
        return args[0].value
    if name in ("vnil", "vcons"):
        elems = _list_elements(whole)
        vals = [_value_of(x, None, model) for x in elems] if elems is not None else [_NO_VALUE]
        return _NO_VALUE if _NO_VALUE in vals else vals
    if name == "vrec" and len(args) == 1:
        elems = _list_elements(args[0])
        fields = model.structs.get(ty) if ty is not None else None
        if elems is None or (fields is not None and len(fields) != len(elems)):
            return _NO_VALUE
        if fields is None:
            vals = [_value_of(x, None, model) for x in elems]
            return _NO_VALUE if _NO_VALUE in vals else tuple(vals)
        types = model.field_types.get(ty, {})
        got = {f: _value_of(x, types.get(f), model) for f, x in zip(fields, elems)}
        return _NO_VALUE if any(v is _NO_VALUE for v in got.values()) else got
    return _NO_VALUE


_PLAIN = re.compile(r"[A-Za-z0-9_'#.-]{1,200}")


def _same_facts(want: tuple, got: tuple, stands_for: Optional[dict] = None) -> bool:
    """Are the (consumed, produced) facts ``want`` those of ``got``, fresh names aside, under one
    renaming of them (one to one)? (Which fresh names of the replay the trace's stand for, across
    the steps, :func:`replay_steps` checks when it takes the step.)"""
    return match_renaming(want, got, {}, stands_for) is not None


def _opaque_made(recorded: list, produced: list, known: dict) -> Optional[dict]:
    """The opaque values an answer made, recorded -> the outcome's (facts aligned by their
    shape with opaque values aside), or None when they cannot correspond (another shape, a
    recorded value already standing for another)."""
    def blank(f):
        return _OPAQUE.sub("(vopq _)", _shape(f))
    if sorted(map(blank, recorded)) != sorted(map(blank, produced)):
        return None
    made: dict = {}
    for w, g in zip(sorted(recorded, key=blank), sorted(produced, key=blank)):
        for a, b in zip(_OPAQUE.findall(w), _OPAQUE.findall(g)):
            if known.get(a, made.get(a, b)) != b:
                return None
            if a not in known:
                made[a] = b
    return made


def _renamed(fact: str, consumed: list, call: str) -> str:
    """``fact``, produced by an outcome rule that consumed ``consumed``, with the fresh names of
    its pending call as the trace's ``call`` names them."""
    mine = next((f for f in consumed if f.startswith("pending ") and _shape(f) == _shape(call)), None)
    if mine is None:
        return fact
    ren = dict(zip(FRESH_NAME.findall(mine), FRESH_NAME.findall(call)))
    return FRESH_NAME.sub(lambda m: ren.get(m.group(0), m.group(0)), fact)


def _shape(fact: str) -> str:
    return FRESH_NAME.sub("#", fact)


def _minus(a: list, b: list) -> list:
    """The facts of ``a`` not in ``b`` (a multiset difference, fresh names aside)."""
    left = [_shape(x) for x in b]
    out = []
    for x in a:
        if _shape(x) in left:
            left.remove(_shape(x))
        else:
            out.append(x)
    return out


def _step_name(rec: dict) -> str:
    return trace_name(rec.get("step"))


def _step_rule(rec: dict) -> str:
    return trace_name(rec.get("rule"))


def _confirm_run(header: dict, res: ReplayResult, labels: tuple) -> Optional[tuple[bool, str]]:
    """A run's trace claims how its request ended (``outcome``): does the replay end so too?"""
    from ..roar.run import outside_request_state
    recorded = header.get("outcome")
    if not isinstance(recorded, str) or not labels:
        return None
    ended = outside_request_state(res.states[-1])
    if ended != recorded:
        return False, (f"the run's trace records that its request ended {_ending(recorded)}, but replayed it "
                       f"ends {_ending(ended)}")
    request = header.get("request")
    return True, (f"the request{f' {request}' if isinstance(request, str) else ''} ends {_ending(ended)}, "
                  f"as the run recorded")


def _ending(outcome: str) -> str:
    from ..roar.run import STATE_NAMES
    if outcome == "unfinished":
        return outcome
    return f"in {outcome if outcome in STATE_NAMES.values() else shown(outcome)}"


def _confirm(header: dict, res: ReplayResult, compiled: Optional[CompiledModel]) -> tuple[Optional[bool], str]:
    """Does the replayed end show what the trace claims? (None: not a claim replay decides.)"""
    prop = header.get("property")
    final = res.states[-1]
    if header.get("shape") == "lasso" or res.cycle_closes is not None:
        if res.cycle_closes and prop and not header.get("claim"):
            return None, (f"the cycle returns to the state where it started, but the trace records no claim "
                          f"(\"claim\" in its header), so whether it breaks '{prop}' is not re-decided: the "
                          "counterexamples check writes carry their claim")
        if res.cycle_closes:
            return True, "the cycle returns to the state where it started: the run can repeat it forever"
        return False, "the trace's cycle does not return to the state where it started"
    if prop == "deadlock":
        enabled = res.system.successors(final)
        if enabled:
            return False, (f"not a deadlock: {len(enabled)} step(s) are enabled where the replayed path ends "
                           f"({', '.join(sorted({s.label for s in enabled})[:5])})")
        if compiled is not None and roar_final(final):
            return False, "not a deadlock: every request is in a final state where the replayed path ends"
        return True, "the final state is a deadlock: no step is enabled and requests are left unfinished" \
            if compiled is not None else "the final state is a deadlock: no step is enabled"
    if prop == "sequential-achievement" and compiled is not None:
        why = res.system.sequence_reason(final)
        if why is None:
            return False, "the replayed path's final state breaks no sequential-achievement pair"
        return True, f"the sequential-achievement pair is still broken: {why}"
    if prop:
        return None, f"replay does not re-decide '{prop}' (its definition is in the job); every step is a step of the model"
    return None, NOTHING_CLAIMED


def model_task_tree(path: str | Path, model: str | Path, *, functional: Optional[str | Path] = None,
                    force: bool = False) -> list:
    """The TCA task-tree events of a trace as the spec says them (``tca-check --model``): the trace
    is replayed on ``model``, and each step's ROAR events and the sequential-achievement pairs
    are the model's, not the file's; only the steps' times are read from the trace."""
    from ..tca.roar_runs import task_tree_events
    rep = replay_trace(path, model, functional=functional, force=force)
    if rep.compiled is None:
        raise RoarError(f"--model {model}: tca-check reads a task tree from a ROAR spec's trace; "
                        "this is a CLF model")
    records = read_trace(path)[1]
    header = {**rep.header, "seq_pairs": [[p.a, p.b, p.where, p.a_text, p.b_text]
                                          for p in sequential_pairs(rep.compiled)]}
    derived = []
    for rec, step in zip(records, rep.steps):
        evs = step["events"]
        derived.append({"step": step["step"], "time": rec.get("time"),
                        "event": (evs[0] if len(evs) == 1 else {"kind": "several", "events": evs}) if evs else None})
    return task_tree_events(header, derived, str(path))
