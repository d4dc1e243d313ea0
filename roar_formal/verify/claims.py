"""What a counterexample claims, written into its trace, and re-decided when it is replayed.

A trace is data: replay does not open the job that produced it. So the trace carries its claim
(the property's formula in the spec's terms, the progress that livelock waits for, the fairness it
was decided under) in its header, and replay re-decides that claim on the replayed states of the
model the user names: a lasso must close, be fair (no agent enabled all along the cycle, or under
strong fairness anywhere on it, that never moves) and miss its goal on every state; a path must
end as the property says (R0 failed, a predicate broken, a run that ends without its goal).
"""

from __future__ import annotations

from typing import Optional

from ..errors import Pos, RoarError
from ..explore.replay import ReplayResult
from ..roar.compile import CompiledModel
from ..roar.explore import PROGRESS_RULES
from ..roar.props import (MISSION_COMPLETION, MISSION_FAILURE, held_tasks, incompatible_held,
                          incompatible_pairs, parse_formula, step_events, view_of)

__all__ = ["claim_groups", "confirm_claim", "trace_claim"]


def trace_claim(job, prop: str) -> dict:
    """The claim of a counterexample of ``prop`` found by ``job``, for its trace's header."""
    props = job.props
    claim: dict = {}
    if prop == "livelock":
        claim["fairness"] = "strong" if props.strong else "weak"
        if props.spec_progress:
            claim["progress"] = [f.text for f in props.spec_progress]
        else:
            claim["progress_rules"] = list(props.progress) or (list(PROGRESS_RULES) if job.is_roar else [])
    elif prop == "mission-completion":
        claim.update(fairness="weak", formula=MISSION_COMPLETION)
    elif prop == "mission-failure":
        claim["formula"] = MISSION_FAILURE
    elif prop in props.temporal:
        claim.update(fairness="strong" if prop in props.temporal_strong else "weak",
                     formula=props.temporal[prop].text)
    elif prop == "incompatible-tasks":   # the declared pairs; none: those the spec's post-conditions make
        claim["incompatible"] = [[a, b] for (a, _pa), (b, _pb) in props.incompatible_pairs]
    elif prop == "deadlock" and props.accept:   # final states the job accepts are no deadlock
        claim["accept"] = props.accept
    elif prop == "invariant":
        if props.spec_always or props.spec_never:
            claim.update(always=[f.text for f in props.spec_always], never=[f.text for f in props.spec_never])
        if props.never:   # CLF patterns (a .clf model's, or next to predicates on a spec)
            claim["never_patterns"] = [pat for pat, _pos in props.never]
    if claim and not job.is_roar:   # a .clf model's processes (a spec's are its agents)
        claim["groups"] = props.fairness
    return claim


GROUPINGS = ("first-argument", "rule", "none")


def claim_groups(path, header: dict) -> Optional[str]:
    """The fairness grouping a ``.clf`` counterexample was found under (None: the default)."""
    claim = header.get("claim")
    g = claim.get("groups") if isinstance(claim, dict) else None
    if g is not None and g not in GROUPINGS:
        raise RoarError(f'expected "claim.groups" in the trace header to be one of {", ".join(GROUPINGS)}',
                        Pos(str(path), 1, 1))
    return g


def _texts(claim: dict, key: str, path) -> list[str]:
    v = claim.get(key, [])
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise RoarError(f'expected "claim.{key}" in the trace header to be a list of strings', Pos(str(path), 1, 1))
    return v


def _pairs(claim: dict, path) -> list:
    v = claim.get("incompatible")
    if not isinstance(v, list) or not all(isinstance(x, list) and len(x) == 2 and all(isinstance(y, str) for y in x)
                                          for x in v):
        raise RoarError('expected "claim.incompatible" in the trace header to be a list of pairs of task names',
                        Pos(str(path), 1, 1))
    return v


def _formula(text, path, temporal: bool = True):
    if not isinstance(text, str):
        raise RoarError('expected "claim.formula" in the trace header to be a string', Pos(str(path), 1, 1))
    try:
        return parse_formula(text, temporal=temporal)
    except RoarError as e:
        raise RoarError(f"the trace's claim: {e.message}", Pos(str(path), 1, 1)) from None


def confirm_claim(path, header: dict, res: ReplayResult, compiled: Optional[CompiledModel]) \
        -> Optional[tuple[Optional[bool], str]]:
    """Re-decide the header's claim on the replayed run: (True/False, why), or None when the trace
    records no claim (an older trace, or a property replay does not re-decide)."""
    claim = header.get("claim")
    if not isinstance(claim, dict) or not claim:
        return None
    fairness = claim.get("fairness", "weak")
    if fairness not in ("weak", "strong"):
        raise RoarError('expected "claim.fairness" in the trace header to be "weak" or "strong"', Pos(str(path), 1, 1))
    k = next((i for i, r in enumerate(res.records) if r.get("loop")), None)
    prop = header.get("property")
    if k is not None:
        unfair = _unfair(res, k, fairness == "strong")
        if unfair:
            return False, unfair
    try:
        if prop == "deadlock" and "accept" in claim:
            return _confirm_accept(claim["accept"], res, path)
        if compiled is None:
            return _confirm_clf(claim, res, k, path)
        return _confirm_spec(claim, prop, res, k, compiled, path)
    except RoarError as e:
        if e.pos is not None and e.pos.file == str(path):
            raise
        raise RoarError(f"the trace's claim does not fit this model: {e.message}", Pos(str(path), 1, 1)) from None


def _unfair(res: ReplayResult, k: int, strong: bool) -> Optional[str]:
    """Why the cycle from step ``k`` is not fair, or None: an agent (fairness group) enabled in
    every state of the cycle (weak) or in some state of it (strong) that never moves on it."""
    system = res.system
    moved = {r["group"] for r in res.records[k:]}
    always: Optional[set] = None
    some: set = set()
    for i in range(k, len(res.records)):
        groups = {s.group for s in system.successors(res.states[i])}
        always = groups if always is None else always & groups
        some |= groups
    idle = sorted((some if strong else (always or set())) - moved)
    if not idle:
        return None
    how = "enabled somewhere on the cycle (strong fairness)" if strong else "enabled in every state of the cycle"
    return (f"the cycle is not fair: {', '.join(idle)} {'is' if len(idle) == 1 else 'are'} {how} "
            f"but never {'moves' if len(idle) == 1 else 'move'}; a fair run leaves it")


def _never_patterns(claim: dict, res: ReplayResult, path) -> Optional[str]:
    """The forbidden CLF pattern of the claim the replayed final state matches, if any (None
    also when the claim names none)."""
    pats = _texts(claim, "never_patterns", path)
    program = getattr(res.system, "program", None)
    if not pats or program is None:
        return None
    from .models import make_never
    bad = make_never(program.sig, str(path), [(p, Pos(str(path), 1, 1)) for p in pats])
    why = bad(res.states[-1])
    return why.replace("a reachable state", "the final state", 1) if why else None


def _confirm_accept(text, res: ReplayResult, path) -> tuple[Optional[bool], str]:
    """A deadlock claimed under the job's accept pattern: the replayed end has no step and is
    not one of the final states the pattern accepts."""
    if not isinstance(text, str):
        raise RoarError('expected "claim.accept" in the trace header to be a string', Pos(str(path), 1, 1))
    enabled = res.system.successors(res.states[-1])
    if enabled:
        return False, (f"not a deadlock: {len(enabled)} step(s) are enabled where the replayed path ends "
                       f"({', '.join(sorted({s.label for s in enabled})[:5])})")
    from .models import make_accept
    try:
        accepted = make_accept(res.system.program, text, str(path))(res.states[-1])
    except RoarError as e:
        raise RoarError(f"the trace's claim: accept pattern {text!r}: {e.message}", Pos(str(path), 1, 1)) from None
    if accepted:
        return False, f"not a deadlock: the final state is one the job accepts (accept = {text!r})"
    return True, f"the final state is a deadlock: no step is enabled and it does not match accept = {text!r}"


def _confirm_clf(claim: dict, res: ReplayResult, k: Optional[int], path) -> Optional[tuple[Optional[bool], str]]:
    if "never_patterns" in claim:
        why = _never_patterns(claim, res, path)
        if why:
            return True, why
        return False, "the replayed path's final state matches none of the job's forbidden patterns"
    rules = _texts(claim, "progress_rules", path)
    if k is None or "progress_rules" not in claim:
        return None
    made = sorted({r["rule"] for r in res.records[k:] if r["rule"] in rules})
    if made:
        return False, f"the cycle makes progress ({', '.join(made)}): it is not a livelock"
    return True, "the cycle is fair, returns to where it started and makes no progress: a livelock"


def _confirm_spec(claim: dict, prop, res: ReplayResult, k: Optional[int], m: CompiledModel, path):
    states = res.states
    views = [view_of(m, s) for s in states]

    def step_view(i):   # step i (0-based): its events, with the state it leaves
        from dataclasses import replace
        return replace(views[i], events=step_events(m, res.engine_steps[i]))

    n = len(res.records)
    if prop == "livelock" or "progress" in claim or "progress_rules" in claim:
        if k is None:
            return None
        fs = [_formula(t, path, temporal=False).bind(m) for t in _texts(claim, "progress", path)]
        rules = _texts(claim, "progress_rules", path)
        for i in range(k, n):
            if res.records[i]["rule"] in rules:
                return False, f"the cycle makes progress (step {i + 1}, {res.records[i]['rule']}): not a livelock"
            for f in fs:
                hit = f.pf(step_view(i)) if f.p_events else f.pf(views[i + 1])
                if hit:
                    return False, f"the cycle makes progress: {f.text!r} holds at step {i + 1}: not a livelock"
        return True, "the cycle is fair, returns to where it started and makes no progress: a livelock"
    if "incompatible" in claim:
        declared = [((a, None), (b, None)) for a, b in _pairs(claim, path)]
        why = incompatible_held(incompatible_pairs(m, declared, "the trace's claim"), held_tasks(m, states[-1]))
        if why:
            return True, f"in the final state {why}"
        return False, "in the replayed path's final state no two live requests hold incompatible tasks"
    if "always" in claim or "never" in claim or "never_patterns" in claim:
        end = views[-1]
        why = _never_patterns(claim, res, path)
        if why:
            return True, why
        for t in _texts(claim, "always", path):
            f = _formula(t, path, temporal=False).bind(m)
            if not f.pf(end):
                return True, f"the final state breaks always {t!r}: {f.explain(end)}"
        for t in _texts(claim, "never", path):
            f = _formula(t, path, temporal=False).bind(m)
            if f.p_events:
                if n and f.pf(step_view(n - 1)):
                    return True, f"the last step satisfies never {t!r}"
            elif f.pf(end):
                return True, f"the final state satisfies never {t!r}: {f.explain(end)}"
        return False, "the replayed path's final state breaks none of the job's invariants"
    if "formula" not in claim:
        return None
    f = _formula(claim["formula"], path).bind(m)
    if f.form in ("always", "state"):
        end = views[-1]
        if f.pf(end):
            return False, f"the replayed path's final state does not break {f.text!r}"
        return True, f"the final state breaks {f.text!r}: {f.explain(end)}"
    # eventually P, or P leads-to Q: positions are states (0..n) or steps (0..n-1) for events
    goal_f, goal_events = (f.qf, f.q_events) if f.form == "leads-to" else (f.pf, f.p_events)

    def goal_at(i):   # after position i the goal has been seen
        return goal_f(step_view(i)) if goal_events else goal_f(views[i])
    last = n - 1 if goal_events else n
    if f.form == "leads-to":
        p_at = [f.pf(step_view(i)) if f.p_events else f.pf(views[i]) for i in range(n if f.p_events else n + 1)]
        starts = [i + (1 if f.p_events else 0) for i, b in enumerate(p_at) if b]
        if not starts:
            return False, f"{f.p.text!r} never holds on the replayed run"
        begin = max(starts) if k is None else min(max(starts), k)
    else:
        begin = 0
    seen = [i for i in range(begin, last + 1) if goal_at(i)]
    what = f"{f.q.text!r}" if f.form == "leads-to" else f"{f.p.text!r}"
    if seen:
        return False, f"{what} holds at {'step' if goal_events else 'state'} {seen[0]} of the replayed run"
    if k is None:
        if res.system.successors(states[-1]):
            return False, f"the run does not end: {len(res.system.successors(states[-1]))} step(s) are enabled " \
                          f"at the end, so it may still reach {what}"
        return True, f"the run ends and {what} never holds: {f.explain(views[-1])}" if not goal_events \
            else f"the run ends and {what} never happens"
    return True, (f"the cycle is fair and returns to where it started, and {what} never holds on the way: "
                  f"the run can repeat it forever")
