"""Conformance of the abstraction: robot runs are paths of the model the explorer checks.

The explorer never calls the robot: each primitive is a set of declared
outcomes, and it branches on them. That is sound for a robot only if

1. every concrete result the robot produces falls into a declared outcome
   (the outcome's ``covers`` predicate, written next to it), and
2. the robot's whole run, with each functional-layer answer replaced by the
   outcome it falls into, is a path of the compiled model's state space: at
   every step the model can take the same rule.

:func:`replay_on_model` checks (2) for one robot trace and reports the first
step where the robot did something the model does not allow, with both
sides. :func:`conform` runs N seeded simulations with random fault draws and
reports, per primitive, which outcomes the robot produced, which never
occurred (a warning: the explorer considers behaviour this robot may never
show) and which results no outcome covers (an error: the model is unsound for
this robot).

Matching a robot step to a model step is by rule name, and among the model's
enabled steps with that name, by the facts consumed and produced, printed,
with fresh names and numbers ignored: the model's values differ where an
outcome's representative value stands for the robot's concrete one.
"""

from __future__ import annotations

import random
import re
from pathlib import Path
from dataclasses import dataclass, field
from typing import Callable, Optional

from ..clf.printer import show
from ..clf.terms import Const, Root
from ..errors import Pos, RoarError
from ..explore.replay import match_renaming, read_as, returned_values
from .activity import CallResult
from .sim import classify

__all__ = ["best_match", "Divergence", "ModelReplay", "replay_on_model", "conform", "ConformReport", "RunSummary"]

#: steps a robot run takes outside the model's rules, as pairs that leave the model state unchanged
TIMING_RULES = ("poll_sleep", "poll_wake")


@dataclass
class Divergence:
    step: int
    rule: str
    reason: str
    robot: list          # what the robot did (lines)
    model: list          # what the model allows there (lines)

    def lines(self) -> list[str]:
        out = [f"step {self.step} ({self.rule}): {self.reason}", "  robot:"]
        out += [f"    {x}" for x in self.robot]
        out.append("  model:")
        out += [f"    {x}" for x in self.model]
        return out


@dataclass
class ModelReplay:
    steps: int                       # robot steps replayed
    divergence: Optional[Divergence]
    outcomes: list                   # (step, function, outcome) of every functional-layer answer
    final: object = None             # the model's state after the last step (when it replayed)

    def ended(self) -> Optional[str]:
        """How the outside request (R0) ends in the replayed model state: a final state's name
        (success, failure, ...), or "unfinished"; None when it did not replay."""
        if self.final is None:
            return None
        from ..roar.run import outside_request_state
        return outside_request_state(self.final)

    @property
    def ok(self) -> bool:
        return self.divergence is None


_FRESH = re.compile(r"[A-Za-z_][A-Za-z0-9_']*#\d+")
_NUM = re.compile(r"(?<![A-Za-z_#])-?\d+(?:\.\d+)?(?:/\d+)?")


def _shape(text: str) -> str:
    return _NUM.sub("N", _FRESH.sub("#", text))


def _printed(step) -> tuple[list, list]:
    return ([show(f) for _m, f in step.consumed if type(f) is Root],
            [show(f) for _m, f in step.produced if type(f) is Root])


def _differing(want: tuple, got: tuple) -> tuple[list, list]:
    """The consumed and produced facts of two printed steps that the other lacks (fresh names
    compared by their hint: each side numbers its own), as lines for a divergence."""
    robot, model = [], []
    for label, w, g in (("consumed", want[0], got[0]), ("produced", want[1], got[1])):
        ws, gs = [_FRESH.sub("#", x) for x in w], [_FRESH.sub("#", x) for x in g]
        robot += [f"{label}: {x}" for x in _unmatched(w, ws, gs)]
        model += [f"{label}: {x}" for x in _unmatched(g, gs, ws)]
    return robot, model


def _unmatched(facts: list, keys: list, others: list) -> list:
    """The facts whose key is not among ``others`` (each key of ``others`` matching once)."""
    left = list(others)
    out = []
    for x, k in zip(facts, keys):
        if k in left:
            left.remove(k)
        else:
            out.append(x)
    return out


def _score(want: tuple, got: tuple) -> tuple[int, int]:
    """(exact shape matches, same-shape-ignoring-values matches) between two printed steps."""
    exact = same = 0
    for w, g in zip(want, got):
        gs = [_FRESH.sub("#", x) for x in g]
        gv = [_shape(x) for x in g]
        for x in w:
            xs = _FRESH.sub("#", x)
            if xs in gs:
                gs.remove(xs)
                exact += 1
            if _shape(x) in gv:
                gv.remove(_shape(x))
                same += 1
    return exact, same


def check_records(records: list, file: str) -> None:
    """Refuse, at its line, a robot trace record whose fields do not have the types the replay reads
    (a trace is data from elsewhere: it is checked, never trusted)."""
    def fail(n: int, what: str) -> None:
        raise RoarError(f"robot trace record: {what}", Pos(file, n + 1, 1))

    for n, rec in enumerate(records, 1):
        if not isinstance(rec, dict):
            fail(n, "expected a JSON object")
        if not isinstance(rec.get("rule"), str):
            fail(n, "expected 'rule' to be a string")
        for key in ("consumed", "produced"):
            v = rec.get(key, [])
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                fail(n, f"expected '{key}' to be a list of strings")
        if not isinstance(rec.get("loop", False), bool):
            fail(n, "expected 'loop' to be true or false")
        ev = rec.get("event")
        if ev is not None and (not isinstance(ev, dict) or any(not isinstance(ev.get(k, ""), str)
                                                                for k in ("text", "agent", "kind"))):
            fail(n, "expected 'event' to be null or an object whose 'kind', 'agent' and 'text' are strings")
        call = rec.get("call")
        if call is None:
            continue
        if not isinstance(call, dict):
            fail(n, "expected 'call' to be an object")
        if not isinstance(call.get("function"), str):
            fail(n, "expected 'call.function' to be a string")
        if not isinstance(call.get("args", []), list):
            fail(n, "expected 'call.args' to be a list")
        if call.get("forced") is not None and not isinstance(call.get("forced"), str):
            fail(n, "expected 'call.forced' to be a string or null")
        res = call.get("result")
        if not isinstance(res, dict):
            fail(n, "expected 'call.result' to be an object")
        if not isinstance(res.get("failed", False), bool) or not isinstance(res.get("status", ""), str) \
                or not isinstance(res.get("detail") or {}, dict):
            fail(n, "expected 'call.result' to have 'failed' (true or false), 'status' (a string) and "
                    "'detail' (an object)")


def _failures_used_up(state, fc: Optional[str]) -> bool:
    """Is the failure budget of function ``fc`` (``fails_left fc N``, from max_failures) zero here?"""
    if fc is None:
        return False
    bag = state.index.get(Const("fails_left"))
    for f in (bag.items if bag else ()):
        if f.args and getattr(getattr(f.args[0], "head", None), "name", None) == fc:
            return getattr(getattr(f.args[1], "head", None), "name", None) == "z"
    return False


def replay_on_model(abstract_model, registry, records: list[dict]) -> ModelReplay:
    """Replay robot trace step records on the abstract (exploration-mode) compiled model."""
    prog = abstract_model.program()
    start = next(d for d in prog.sig.directives if hasattr(d, "start"))
    state = prog.start_context(start.start)
    outcomes = []
    n = 0
    stands_for: dict = {}   # a value the robot answered (printed) -> the outcome's value for it
    # the robot's fresh names -> the model's, as the steps so far matched them: of two instances of
    # a rule that differ only by their names (two requests received), the one the robot took
    renaming: dict = {}
    for rec in records:
        n += 1
        rule = rec.get("rule")
        if rule in TIMING_RULES:
            continue
        want = (list(rec.get("consumed", [])), list(rec.get("produced", [])))
        choices = prog.steps(state)
        if rule == "functional_layer":
            call = rec.get("call")
            if not isinstance(call, dict) or not isinstance(call.get("result"), dict):
                return ModelReplay(n, Divergence(int(rec.get("step", n)), rule,
                                                 "a functional-layer step without its call record", want[0], []),
                                   outcomes)
            fname = str(call.get("function", "?"))
            owner, _, name = fname.rpartition("::")
            prim = registry.lookup(name, owner or None)
            fc = next((c for c, (o, nm) in abstract_model.functions.items() if nm == name and o == (owner or o)),
                      None)
            result = CallResult.from_json(call["result"])
            forced = call.get("forced")
            if forced:
                names = [str(forced).split(": ", 1)[-1]]
            elif prim is None:
                names = []
            else:
                names = classify(prim.outcomes, result, abstract_model.fn_types.get(fc))
            if not names:
                declared = ", ".join(o.name for o in prim.outcomes) if prim is not None else "none"
                return ModelReplay(n, Divergence(
                    int(rec.get("step", n)), rule,
                    f"the robot's result of {fname} is covered by no declared outcome",
                    [f"{fname}({', '.join(map(str, call.get('args', [])))}) -> {call['result']}"],
                    [f"declared outcomes of {fname}: {declared}"]), outcomes)
            labels = [f"outcome_{fc}_{o}" for o in names]
            cands = [c for c in choices if c.rule in labels]
            if not cands:
                why = ""
                if _failures_used_up(state, fc):
                    # the abstraction's bound on this primitive's failures (max_failures) is used up
                    why = (f": the abstraction allows {fname} no more failing outcomes in this run (its "
                           f"max_failures is used up); the robot fails more often than it assumes")
                return ModelReplay(n, Divergence(
                    int(rec.get("step", n)), rule,
                    f"the model cannot answer {fname} with outcome {names[0]} here{why}",
                    [f"{fname} -> {names[0]}"] + want[0],
                    [f"enabled here: {', '.join(sorted({c.rule for c in choices})) or 'nothing'}"]),
                    outcomes)
            called = ([x for x in want[0] if x.startswith("pending ")][:1], [])
            best = consistent_match(cands, state, prog, called, renaming, pending_only=True)
            if best is not None:
                renaming = best[2]
            else:
                best = best_match(cands, state, prog, want, by_pending=True)
            outcomes.append((n, fname, _oname(best[0].rule, fc)))
            # the value the robot answered and the one the outcome stands for it with: in the
            # steps after, the trace's facts hold the first where the model's hold the second
            _nxt, step = prog.successor(state, best[0])
            for robot_v, model_v in zip(returned_values(want[1]), returned_values(_printed(step)[1])):
                if robot_v != model_v and robot_v.startswith("("):
                    stands_for[robot_v] = model_v
            state = best[1]
            continue
        cands = [c for c in choices if c.rule == rule]
        if not cands:
            return ModelReplay(n, Divergence(
                int(rec.get("step", n)), str(rule), "the model cannot take this rule here",
                [f"consumed: {x}" for x in want[0]] + [f"produced: {x}" for x in want[1]],
                [f"enabled here: {', '.join(sorted({c.rule for c in choices})) or 'nothing (quiescent)'}"]),
                outcomes)
        got = consistent_match(cands, state, prog, want, renaming)
        if got is None and stands_for:
            read = tuple([read_as(x, stands_for) for x in w] for w in want)
            got = consistent_match(cands, state, prog, read, renaming)
        if got is not None:   # the robot's step, its names those of the steps before
            state, renaming = got[1], got[2]
            continue
        choice, nxt, exact = best_match(cands, state, prog, want)
        if not exact and stands_for:
            # the same up to the values the outcomes abstract (a position read as "moving")
            choice, nxt, exact = best_match(cands, state, prog, tuple([read_as(x, stands_for) for x in w]
                                                                       for w in want))
        if not exact:
            # the model takes this rule here, but not on the facts the trace records (a value, a
            # name or a fact edited, or a trace of another request): not a step of the model
            _nxt, step = prog.successor(state, choice)
            robot_only, model_only = _differing(want, _printed(step))
            return ModelReplay(n, Divergence(
                int(rec.get("step", n)), str(rule), "the model takes this rule on other facts than the trace records "
                "(the facts both have are left out)", robot_only, model_only), outcomes)
        state = nxt
    return ModelReplay(n, None, outcomes, state)


def replay_robot_trace(trace, header: dict, records: list, model, functional=None, force: bool = False) \
        -> tuple[ModelReplay, Optional[bool], str]:
    """A robot run's trace (``simulate --trace``) replayed on the abstract model of ``model`` (a
    spec): the replay, whether the trace's recorded outcome is how the request ends on the model
    (None when the trace records none or the replay stopped), and why not. A trace made from other
    sources than the spec's is refused unless ``force``."""
    from ..roar.compile import compile_spec
    from ..roar.sources import spec_files
    from ..roar.spec import load_spec
    from .binding import load_robot_binding
    from .report import sources_fingerprint
    spec_ast = load_spec(model)
    mine = sources_fingerprint(spec_files(spec_ast))
    theirs = header.get("spec_fingerprint")
    if theirs and theirs != mine and not force:
        named = header.get("spec")
        if isinstance(named, str) and Path(named).name != Path(model).name:
            raise RoarError(f"{trace}: the trace was made from {named}, not {model} (the sources differ): replay "
                            f"it on the spec it was made from, or pass --force to try it on this one")
        raise RoarError(f"{trace}: the trace was made from other sources than {model} (its fingerprint differs): "
                        f"it is stale; simulate again, or pass --force to replay it anyway")
    request = header.get("request")
    if not isinstance(request, str):
        raise RoarError(f"{trace}: the trace's header names no request (\"request\": \"...\")", Pos(str(trace), 1, 1))
    check_records(records, str(trace))
    binding = load_robot_binding(model, functional)
    abstract = compile_spec(spec_ast, request, registry=binding.abstract or binding.robot, functional="abstract")
    rp = replay_on_model(abstract, binding.robot, records)
    recorded, ended = header.get("outcome"), rp.ended()
    if not isinstance(recorded, str) or ended is None:
        return rp, None, ""
    if recorded != ended:
        return rp, False, (f"the trace records that its request ended in {recorded}, but on the model it ends "
                           f"{'in ' + ended if ended != 'unfinished' else ended}")
    return rp, True, f"the request ends in {ended}, as the trace records"


def _oname(rule: str, fc: str) -> str:
    return rule[len(f"outcome_{fc}_"):]


def consistent_match(cands, state, prog, want, names: dict, pending_only: bool = False):
    """The first candidate whose printed step is the robot's up to a renaming of fresh names
    consistent with ``names`` (the robot's names -> the model's, so far): ``(choice, next state,
    the renaming extended)``, or None. With ``pending_only``, only the call an outcome answers
    (its ``pending`` fact) is compared."""
    for c in cands:
        nxt, step = prog.successor(state, c)
        got = _printed(step)
        if pending_only:
            got = (got[0][:1], [])
        ren = match_renaming(want, got, names)
        if ren is not None:
            return c, nxt, ren
    return None


def best_match(cands, state, prog, want, by_pending: bool = False):
    """The candidate whose printed step is closest to the robot's: (choice, next state, exact?)."""
    best = None
    for c in cands:
        nxt, step = prog.successor(state, c)
        got = _printed(step)
        if by_pending:   # an outcome: compare the call it answers (the pending fact) only
            got = (got[0][:1], [])
            w = ([x for x in want[0] if x.startswith("pending ")][:1], [])
        else:
            w = want
        ex, same = _score(w, got)
        total = sum(len(x) for x in w)
        key = (ex, same)
        exact = ex == total and all(len(a) == len(b) for a, b in zip(w, got))
        if best is None or key > best[0]:
            best = (key, c, nxt, exact)
    return best[1], best[2], best[3]


# ---------------------------------------------------------------------- conformance runs


@dataclass
class RunSummary:
    seed: int
    faults: tuple
    outcome: str
    time: float
    calls: int
    uncovered: list                  # CallRecord
    divergence: Optional[Divergence]

    def as_json(self) -> dict:
        return {"seed": self.seed, "faults": list(self.faults), "outcome": self.outcome,
                "time": round(self.time, 4), "calls": self.calls,
                "uncovered": [c.as_json() for c in self.uncovered],
                "divergence": None if self.divergence is None else self.divergence.lines()}


@dataclass
class ConformReport:
    spec: str
    scenario: str
    runs: list = field(default_factory=list)
    seen: dict = field(default_factory=dict)        # primitive -> {outcome: count}
    declared: dict = field(default_factory=dict)    # primitive -> [outcome names]

    @property
    def checked(self) -> bool:
        """Did the runs call the functional layer at all? Without a call there is nothing to conform."""
        return any(r.calls for r in self.runs)

    @property
    def sound(self) -> bool:
        return self.checked and all(not r.uncovered and r.divergence is None for r in self.runs)

    def never(self) -> dict:
        return {p: [o for o in outs if not self.seen.get(p, {}).get(o)] for p, outs in self.declared.items()
                if any(not self.seen.get(p, {}).get(o) for o in outs)}

    def as_json(self) -> dict:
        return {"spec": self.spec, "scenario": self.scenario, "sound": self.sound, "checked": self.checked,
                "runs": [r.as_json() for r in self.runs],
                "outcomes": {p: {o: self.seen.get(p, {}).get(o, 0) for o in outs}
                             for p, outs in self.declared.items()},
                "never": self.never()}

    def lines(self) -> list[tuple[str, str]]:
        out = [(f"conformance of {self.spec} on scenario {self.scenario}: {len(self.runs)} runs", "bold")]
        out.append(("outcomes the robot produced, per primitive:", ""))
        for p, outs in sorted(self.declared.items()):
            counts = ", ".join(f"{o} {self.seen.get(p, {}).get(o, 0)}" for o in outs)
            out.append((f"  {p}: {counts}", ""))
        for p, outs in sorted(self.never().items()):
            out.append((f"warning: {p}: the robot never produced {', '.join(outs)} "
                        f"(the explorer considers it; these runs never showed it)", "yellow"))
        for r in self.runs:
            for c in r.uncovered:
                out.append((f"error: seed {r.seed}: call {c.n} {c.function}({', '.join(map(str, c.args))}) at "
                            f"t = {c.t_end:.2f} s returned {c.result.as_json()}: no declared outcome covers it "
                            f"(the model is unsound for this robot)", "red"))
            if r.divergence is not None and not r.uncovered:
                out.append((f"error: seed {r.seed}: the robot run is not a path of the model:", "red"))
                out += [(f"  {x}", "red") for x in r.divergence.lines()]
        if not self.checked:
            out.append(("nothing checked: no run called a primitive on the robot (is the request one the spec "
                        "handles with its functional layer?)", "red"))
        else:
            out.append(("sound for these runs: every result covered, every run a path of the model" if self.sound
                        else "NOT sound: see the errors above", "green" if self.sound else "red"))
        return out


def conform(spec_ast, request: str, model, binding, scenario, runs: int = 10, seed: Optional[int] = None, always=(),
            random_faults: bool = True, max_steps: int = 200_000, spec_name: str = "spec",
            on_run: Optional[Callable[[int, RunSummary], None]] = None) -> ConformReport:
    """N seeded robot runs (random fault draws), each classified and replayed on the abstract model; run
    ``k`` has seed ``seed + k``, ``seed`` by default the scenario's."""
    if seed is None:
        seed = scenario.seed
    from ..roar.compile import compile_spec
    from .sim import simulate
    from .report import step_records

    abstract = compile_spec(spec_ast, request, registry=binding.abstract or binding.robot, functional="abstract")
    rep = ConformReport(spec_name, scenario.name)
    for owner, name in sorted(model.functions.values(), key=lambda x: (x[0] or "", x[1])):
        prim = binding.robot.lookup(name, owner)
        if prim is not None and name != "now":
            rep.declared[f"{owner}::{name}" if owner else name] = [o.name for o in prim.outcomes]
    draw = random.Random(seed)
    for k in range(runs):
        faults = list(always)
        if random_faults:
            for f in scenario.fault_names():
                if f not in faults and draw.random() < scenario.faults[f].probability:
                    faults.append(f)
        res = simulate(model, binding.robot, scenario, seed=seed + k, faults=faults, max_steps=max_steps)
        for c in res.calls:
            if c.outcome is not None and c.forced is None:
                rep.seen.setdefault(c.function, {})
                rep.seen[c.function][c.outcome] = rep.seen[c.function].get(c.outcome, 0) + 1
        rp = replay_on_model(abstract, binding.robot, step_records(res))
        summary = RunSummary(seed + k, tuple(faults), res.outcome, res.robot.time, len(res.calls),
                             res.uncovered(), rp.divergence)
        rep.runs.append(summary)
        if on_run:
            on_run(k, summary)
    return rep
