"""Running the ROAR models: ROAR-level traces under fixed seeds and faults, and the same run at the CLF level.

Every run is checked twice: its ROAR events (order, final states) against
what the spec says should happen, and its CLF steps against the engine's
enumerator (the explorer's driver, independent of the committed-choice
scheduler that made the run): each recorded step must be an enabled step of
the state before it, and the functional layer's answers the only steps from
outside the signature.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import pytest

from roar_formal.clf.printer import show
from roar_formal.clf.program import Program
from roar_formal.clf.terms import const
from roar_formal.errors import RoarError
from roar_formal.roar.functional import functional_module, load_registry
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.spec import load_spec
from roar_formal.roar.run import parse_fault, run_model
from repo import ROOT

MODELS = ROOT / "models"

DEMO = (MODELS / "demo_loco", "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5")
SPA = (MODELS / "spa_loop.roar", "exec::arrived == true where exec::goal == 7")
NAV = (MODELS / "mana_nav.roar", "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0")
CONFLICT = (MODELS / "conflict.roar", "mission::done == true")
STRICT = (MODELS / "conflict.roar", "mission::strict_done == true")


@lru_cache(maxsize=None)
def model(path: Path, request: str):
    reg = load_registry(functional_module(path, None))
    return compile_spec(load_spec(path), request, registry=reg, functional="python")


def run(case, seed=0, faults=()):
    path, request = case
    reg = load_registry(functional_module(path, None))   # a fresh simulation for each run
    return run_model(model(path, request), seed=seed, registry=reg, faults=[parse_fault(f) for f in faults],
                     max_steps=20_000)


def texts(res, kind=None, agent=None):
    return [e.text for e in res.events if (kind is None or e.kind == kind) and (agent is None or e.agent == agent)]


def index(res, pattern: str) -> int:
    """Position of the first event whose text matches ``pattern`` (a regex)."""
    for i, e in enumerate(res.events):
        if re.search(pattern, e.text):
            return i
    raise AssertionError(f"no event matches {pattern!r}:\n" + "\n".join(e.text for e in res.events))


# ---------------------------------------------------------------- the CLF-level oracle

_FRESH = re.compile(r"[A-Za-z_][A-Za-z0-9_']*#\d+")


def _match(want: list, got: list, ren: dict) -> dict | None:
    """Equal multisets of printed facts up to a consistent renaming of fresh names (``want`` -> ``got``)."""
    if len(want) != len(got):
        return None
    shape = lambda t: _FRESH.sub("#", t)
    if sorted(map(shape, want)) != sorted(map(shape, got)):
        return None

    def go(ws, gs, ren):
        if not ws:
            return ren
        w = ws[0]
        for k, g in enumerate(gs):
            if shape(g) != shape(w):
                continue
            r = dict(ren)
            used = set(r.values())
            ok = True
            for a, b in zip(_FRESH.findall(w), _FRESH.findall(g)):
                if a in r:
                    ok = r[a] == b
                elif b in used:
                    ok = False
                else:
                    r[a] = b
                    used.add(b)
                if not ok:
                    break
            if ok:
                out = go(ws[1:], gs[:k] + gs[k + 1:], r)
                if out is not None:
                    return out
        return None

    return go(list(want), list(got), ren)


def replay_on_enumerator(res) -> int:
    """Re-take every CLF step of a run through ``Program.steps``/``successor``; return the steps checked."""
    prog = res.model.program()
    start = next(d for d in prog.sig.directives if hasattr(d, "start"))
    ctx = prog.start_context(start.start)
    ren: dict = {}
    for i, (rule, consumed, produced) in enumerate(res.steps, 1):
        if i in res.external:
            pending, answer = res.external[i]
            want = show(pending)
            cand = [(m, f) for m, f, _n in ctx.facts() if show(f).startswith("pending ")]
            for _m, f in cand:
                r2 = _match([want], [show(f)], ren)
                if r2 is not None:
                    ren = r2
                    ctx.remove_fact(f, "lin")
                    ctx.add_fact(const(answer.head.name, *answer.args[:-1], f.args[2]), "lin")
                    break
            else:
                raise AssertionError(f"step {i}: no pending call {want}")
            continue
        for choice in prog.steps(ctx):
            if choice.rule != rule:
                continue
            nxt, step = prog.successor(ctx, choice)
            got_c = [show(f) for _m, f in step.consumed]
            got_p = [show(f) for _m, f in step.produced]
            r2 = _match(consumed, got_c, ren)
            r2 = _match(produced, got_p, r2) if r2 is not None else None
            if r2 is not None:
                ren, ctx = r2, nxt
                break
        else:
            raise AssertionError(f"step {i} ({rule}) is not an enabled step of the state before it")
    return len(res.steps)


# ---------------------------------------------------------------- demo_loco


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_demo_loco_subgoals_init_then_moves(seed):
    res = run(DEMO, seed)
    assert res.outcome == "success" and res.quiescent
    assert res.final["demo_loco::pos"] == 5 and res.final["demo_loco::init"] is True
    assert texts(res, "tasks") == ["R0: tasks init then move"]
    assert texts(res, "recipe")[:2] == ["R0: task init, recipe boot", "R0: task move, recipe direct"]
    # the sub-goal's recipe ends before the request runs (5.1: running = the recipe that handles it)
    assert index(res, r"R0: recipe boot done") < index(res, r"R0 pending -> running") < index(res, r"recipe direct done")
    # reading pos runs get_pos, which copies the simulated position
    assert index(res, r"simu_pos = 5") < index(res, r"task get_pos, recipe odometry") < index(res, r"::pos = 5")
    assert index(res, r"::goal = 5") < index(res, r"R0: task init")   # where values are written on acceptance


def test_demo_loco_run_is_a_run_of_the_engine():
    res = run(DEMO, 3)
    assert replay_on_enumerator(res) == len(res.steps) > 20


# ---------------------------------------------------------------- spa_loop (figure 3)


@pytest.mark.parametrize("seed", [0, 5])
def test_spa_loop_nominal(seed):
    res = run(SPA, seed)
    assert res.outcome == "success" and res.final["exec::arrived"] is True
    assert not texts(res, "pause")
    # exec aborts the plan when it arrives; the plan aborts the sensing it held (cleanup)
    assert index(res, r"abort R1 \(plan") < index(res, r"R1 running -> aborted")
    assert index(res, r"R2 running -> aborted")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_spa_loop_temporary_failure_pauses_exec_until_plan_runs_again(seed):
    res = run(SPA, seed, ["compute_plan:1"])
    assert res.outcome == "success" and res.quiescent
    i_fail = index(res, r"recipe from_scans ended: local failure at \d+:\d+ \(assert\(compute_plan\(goal\)\)\)")
    i_tf = index(res, r"R1 running -> temporary failure")
    i_pause = index(res, r"R0 running -> paused")
    # the emitter is told in the step where the request fails temporarily (figure 3)
    assert res.events[i_tf].step == res.events[i_pause].step
    i_tf = min(i_tf, i_pause)
    i_again = [i for i, e in enumerate(res.events) if e.text == "R1: task replan, recipe from_scans"][1]
    i_cont = index(res, r"R0 paused -> running")
    i_valid = [i for i, e in enumerate(res.events) if e.text == "plan::valid = true"][0]
    st = lambda i: res.events[i].step
    assert st(i_fail) < st(i_tf) <= st(i_pause) < st(i_again) <= st(i_cont) < st(i_valid)
    assert st(i_again) == st(i_cont)   # continue is delivered in the step that runs the recipe again
    i_pause, i_cont = min(i_pause, i_tf), max(i_cont, i_again)
    assert texts(res, "pause", "exec") == ["recipe follow paused"]
    assert texts(res, "resume", "exec") == ["recipe follow resumed"]
    # exec does not move while paused: no odometry reading between the pause and the continue
    assert not [e for e in res.events[i_pause:i_cont] if e.kind == "primitive-start" and e.agent == "exec"]
    assert replay_on_enumerator(res) == len(res.steps)


def test_spa_loop_fault_that_never_happens_is_an_error():
    with pytest.raises(RoarError, match="no such call happened"):
        run(SPA, 0, ["compute_plan:50"])


# ---------------------------------------------------------------- mana_nav (5.2)


def test_mana_nav_nominal_uses_the_map():
    res = run(NAV)
    assert res.outcome == "success"
    assert "R1: task plan, recipe on_map" in texts(res, "recipe") and "straight_line" not in " ".join(texts(res))
    # the chain of resources: locomotion -> planner -> mapper -> perception
    order = [index(res, p) for p in (r"make R1 to planner", r"make R2 to mapper", r"make R3 to perception",
                                     r"R3 running -> success", r"R2 running -> success", r"R1 running -> success",
                                     r"R0 running -> success")]
    assert order == sorted(order)


@pytest.mark.parametrize("seed", [0, 4])
def test_mana_nav_fallback_recipe_after_the_map_fails(seed):
    res = run(NAV, seed, ["lidar_ok"])
    assert res.outcome == "success" and res.final["locomotion::arrived"] is True
    i_on_map = index(res, r"R1: recipe on_map ended: constraint failed: mapper::map_ready == true")
    i_fallback = index(res, r"R1: task plan, recipe straight_line")
    assert index(res, r"R3 pending -> failure") < i_on_map < i_fallback < index(res, r"R0 running -> success")
    assert res.final["planner::traj"] != res.final.get("never")


FULL_CONTEXT = ["task failed: locomotion::goto",
                "constraint failed: planner::has_traj == true",
                "task failed: planner::plan",
                "constraint failed: perception::sonar_clear == true",
                "task failed: perception::check_sonar",
                "constraint failed: mapper::map_ready == true",
                "task failed: mapper::build_map",
                "constraint failed: perception::has_cloud == true",
                "task failed: perception::acquire"]


@pytest.mark.parametrize("seed", [0, 7])
def test_mana_nav_both_recipes_fail_and_the_failure_reaches_the_requester(seed):
    res = run(NAV, seed, ["lidar_ok", "sonar_ok"])
    assert res.outcome == "failure" and res.quiescent
    assert res.error_context == FULL_CONTEXT
    # the planner tried both recipes, then recomputed its task set (nothing else achieves has_traj)
    assert index(res, r"recipe on_map ended") < index(res, r"recipe straight_line ended") < index(res, r"R1 .* -> failure")
    assert res.final["locomotion::arrived"] is False
    # nothing is left running anywhere
    assert not [e for e in res.events if e.kind == "state" and e.text.endswith("running")][-1:] or \
        res.events[-1].kind == "state"
    assert replay_on_enumerator(res) == len(res.steps)


# ---------------------------------------------------------------- conflict (5.3)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_conflict_resolved_through_the_calling_context(seed):
    res = run(CONFLICT, seed)
    assert res.outcome == "success"
    assert res.final["ptu::heading"] == 120 and res.final["inspector::inspected"] is True
    # the ptu is held by the tracker's ensure (R2, kept committed after it succeeded) when the
    # inspector's make (R4) arrives; the tracker is asked for an alternative and switches recipe
    assert texts(res, "conflict") == ["R4 (ptu::heading == ptu::target) conflicts with R2, which holds the "
                                      "task it needs: asking the calling context of R2"]
    assert texts(res, "calling-context") == ["for R4: the emitter of R2 has an alternative: it reconfigures"]
    order = [index(res, p) for p in (r"ptu::heading = 30", r"make R4 to ptu", r"conflicts with R2",
                                     r"abort R2",   # the switched recipe's cleanup aborts what it held
                                     r"R2 .* -> aborted", r"ptu::target = 120",
                                     r"R4 running -> success", r"R0 running -> success")]
    assert order == sorted(order)
    assert index(res, r"conflicts with R2") < index(res, r"recipe with_ptu ended: switched away from ptu::heading")
    assert index(res, r"switched away") < index(res, r"R1: task track, recipe wide_angle") < index(res, r"R0 running -> success")
    # the rejected constraint wrote nothing: the target stays 30 until R4 is accepted
    writes = texts(res, "write", "ptu")
    assert writes.index("ptu::target = 120") > writes.index("ptu::heading = 30")


@pytest.mark.parametrize("seed", [0, 3])
def test_unresolvable_conflict_is_reported_as_an_error(seed):
    res = run(STRICT, seed)
    assert res.outcome == "failure" and res.quiescent
    assert texts(res, "calling-context") == [
        "for R4: the emitter of R2 has no alternative: asking its caller",
        "for R4: the emitter of R1 has no alternative: asking its caller",
        "for R4: the emitter of R0 is a request from outside: the conflict cannot be resolved"]
    assert res.error_context[-1] == ("concurrency: task ptu::point is held by another constraint, and no agent "
                                     "of its calling context has an alternative")
    assert res.error_context[0] == "task failed: mission::strict_patrol"


# ---------------------------------------------------------------- both levels


@pytest.mark.parametrize("case,faults", [(CONFLICT, ()), (STRICT, ()), (NAV, ("lidar_ok",))])
def test_every_roar_event_is_one_clf_step_of_the_run(case, faults):
    res = run(case, 2, faults)
    assert replay_on_enumerator(res) == len(res.steps)
    for e in res.events:
        rule, consumed, produced = res.steps[e.step - 1]
        if e.kind == "sent":
            assert re.fullmatch(r"st\d+_(make|ensure)", rule)
            assert any(p.startswith("rs ") and p.endswith(" s_sent") for p in produced)
        elif e.kind == "state":
            assert any(p.startswith("rs ") and p.endswith("s_" + {"temporary failure": "tempfail"}.get(
                e.data["to"], e.data["to"])) for p in produced) or rule.startswith("aborted")
        elif e.kind == "recipe":
            assert rule.startswith("recipe_chosen")
        elif e.kind == "write":
            var = e.data["var"].replace("::", "_")
            assert any(p.startswith(f"contains v_{var} ") for p in produced)
        elif e.kind == "primitive-start":
            assert re.fullmatch(r"st\d+_call", rule) and any(p.startswith("pending ") for p in produced)
        elif e.kind == "primitive-end":
            assert rule in ("primitive_end", "primitive_failed", "primitive_failed_check", "drop_result",
                            "drop_failure")


def test_runs_are_reproducible_under_a_seed():
    a, b = run(NAV, 11, ["lidar_ok"]), run(NAV, 11, ["lidar_ok"])
    assert [e.text for e in a.events] == [e.text for e in b.events]


def test_a_run_prints_its_steps_whatever_other_programs_declare():
    """Constants are interned by name, and miniml.clf declares ``contains`` with an implicit
    argument: a run's steps print ``contains CELL VALUE`` after it was loaded as before (the
    printing of a term once depended on the latest program declaring its constant)."""
    shape = lambda steps: [(r, sorted(_FRESH.sub("#", x) for x in c), sorted(_FRESH.sub("#", x) for x in ps))
                           for r, c, ps in steps]
    before = run(CONFLICT, 2).steps
    Program.from_file(ROOT / "models" / "clf" / "miniml.clf")
    after = run(CONFLICT, 2).steps
    assert any(p.startswith("contains v_ptu_heading ") for _r, _c, ps in after for p in ps)
    assert shape(after) == shape(before)
