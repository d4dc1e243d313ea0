"""Specs on the reference robot: lockstep simulation, conformance to the model, replay on the robot.

Oracles: every simulated run is re-taken on the engine's enumerator (each
agent step must be an enabled step of the run-mode model with the same rule
and facts); every robot trace must replay on the abstract model the explorer
checks; the conflict model's livelock counterexample comes from the explorer
itself.
"""

from __future__ import annotations

import json
import math
import re

import pytest

from roar_formal.clf.context import LIN
from roar_formal.clf.printer import show
from roar_formal.clf.terms import Root
from roar_formal.robot.setup import prepare
from roar_formal.robot.conform import replay_on_model
from roar_formal.robot.onrobot import replay_on_robot
from roar_formal.robot.report import step_records, write_robot_trace
from roar_formal.robot.robot import Robot
from roar_formal.robot.sim import simulate
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import parse_fault
from roar_formal.trace.format import read_trace

from repo import ROOT
MODELS = ROOT / "models"
SCEN = MODELS / "scenarios"
DOOR_REQ = "base::arrived == true where base::gx == 9.0 && base::gy == 3.0"

_CACHE: dict = {}


def setup(spec: str, request: str, scenario: str):
    key = (spec, request, scenario)
    if key not in _CACHE:
        _CACHE[key] = prepare(MODELS / spec, request, SCEN / scenario)
    return _CACHE[key]


def sim(spec, request, scenario, seed=0, faults=(), **kw):
    spec_ast, model, binding, sc = setup(spec, request, scenario)
    return simulate(model, binding.robot, sc, seed=seed, faults=list(faults), **kw)


def abstract_model(spec, request, scenario):
    spec_ast, model, binding, sc = setup(spec, request, scenario)
    key = ("abstract",) + (spec, request, scenario)
    if key not in _CACHE:
        _CACHE[key] = compile_spec(spec_ast, request, registry=binding.abstract, functional="abstract")
    return _CACHE[key], binding


def door(faults=(), seed=0):
    return sim("door_nav.roar", DOOR_REQ, "door.toml", seed=seed, faults=faults)


# ---------------------------------------------------------------- determinism


def test_one_seed_gives_one_run_bit_for_bit():
    a, b = door(("door_closes",), seed=3), door(("door_closes",), seed=3)
    assert step_records(a) == step_records(b)
    assert a.robot.trajectory == b.robot.trajectory
    assert a.robot.world.base.odometry == b.robot.world.base.odometry


def test_another_seed_gives_another_odometry():
    a, b = door(seed=3), door(seed=4)
    assert a.robot.world.base.odometry != b.robot.world.base.odometry
    # the noise is small: both still arrive
    assert a.ok and b.ok


def test_a_robot_snapshot_continues_bit_for_bit():
    spec_ast, model, binding, sc = setup("door_nav.roar", DOOR_REQ, "door.toml")
    r = Robot(sc, seed=2, faults=["door_closes"])
    r.follow(r.plan_to((9.0, 3.0)))
    for _ in range(300):
        r.step()
    data = r.snapshot()
    for _ in range(250):
        r.step()
    again = Robot.restore(data)
    for _ in range(250):
        again.step()
    assert again.world.base.pose == r.world.base.pose
    assert again.world.base.odometry == r.world.base.odometry
    assert again.trajectory == r.trajectory and again.follow_state == r.follow_state


def test_a_base_that_gives_up_waiting_says_for_what():
    """The safety stop halts the base at the closed door; after WAIT_LIMIT it gives up, and the
    follow's result says why and where the obstacle was (the door's face, at x = 6)."""
    from roar_formal.robot.robot import WAIT_LIMIT, FollowPath
    _spec, _model, _binding, sc = setup("door_nav.roar", DOOR_REQ, "door.toml")
    r = Robot(sc, seed=2, faults=["door_closes"])
    follow = FollowPath(r.plan_to((9.0, 3.0)))
    assert follow.start(r) is None
    res = None
    while res is None and r.time < 30:
        r.step()
        res = follow.tick(r)
    assert res is not None and res.failed and res.status == "blocked"
    assert res.detail["why"] == "obstacle ahead"
    assert abs(res.detail["ox"] - 5.95) < 0.1 and abs(res.detail["oy"] - 3.0) < 0.6
    assert WAIT_LIMIT <= res.detail["waited"] < WAIT_LIMIT + 0.1
    assert r.world.base.pose[0] < 6.0 - sc.robot.radius   # (it stopped in front of the door)


def test_a_run_on_the_robot_lists_the_calls_that_failed():
    """The end of a robot run counts the calls that failed, by function and status."""
    from roar_formal.testing import load_spec
    run = load_spec(MODELS / "door_nav.roar").run(DOOR_REQ, scenario=SCEN / "door.toml", faults=["door_closes"])
    failed = [c for c in run.robot.calls if c.result.failed]
    assert failed and {c.function for c in failed} == {"planner::compute_path"}
    text = run.format()
    assert "  calls that did not succeed on the robot:\n" in text
    assert (f"    planner::compute_path no_path: {len(failed)} times, the last at t = {failed[-1].t_end:.2f} s"
            in text)
    # a read answering false did not fail: path_blocked() and at_goal() are not listed
    assert "path_blocked" not in text.split("calls that did not succeed")[1]


# ---------------------------------------------------------------- the door scenario


def _first(events, pred, after=0):
    for k, e in enumerate(events):
        if k >= after and pred(e):
            return k
    return None


def test_door_closes_the_planner_fails_the_base_pauses_and_resumes_and_arrives():
    res = door(("door_closes",))
    evs = res.events
    t = lambda e: res.times[e.step - 1]
    tf = _first(evs, lambda e: e.kind == "state" and e.agent == "planner" and e.data.get("to") == "temporary failure")
    assert tf is not None and t(evs[tf]) >= 4.0          # not before the door closes
    paused = _first(evs, lambda e: e.kind == "pause" and e.agent == "base", tf)
    resumed = _first(evs, lambda e: e.kind == "resume" and e.agent == "base", paused)
    assert paused is not None and resumed is not None and tf <= paused < resumed
    # while the door is closed the planner finds no path; once it opens it does
    no_path = [c for c in res.calls if c.function == "planner::compute_path" and c.outcome == "no_path"]
    assert no_path and all(4.0 <= c.t_end <= 14.5 for c in no_path)
    last_plan = max(c.t_end for c in res.calls if c.function == "planner::compute_path" and c.outcome == "planned")
    assert last_plan >= 14.0
    assert res.ok and res.end == "quiescent"
    x, y, _ = res.robot.world.base.pose
    assert math.hypot(x - 9.0, y - 3.0) < 0.25
    # the base waited in front of the door: it never crossed it while closed
    assert all(px < 6.0 for t_, px, _py, _th in res.robot.trajectory if 4.5 <= t_ <= 14.0)


def test_door_that_stays_closed_never_lets_the_robot_arrive():
    res = door(("door_stays_closed",))
    assert not res.ok and res.outcome == "running" and res.end == "horizon"
    assert res.robot.time == pytest.approx(res.robot.horizon, abs=0.02)
    assert max(px for _t, px, _py, _th in res.robot.trajectory) < 6.0


def test_slip_makes_the_odometry_over_read():
    req = "base::arrived == true where base::gx == 8.0 && base::gy == 1.0"
    dry = sim("door_nav.roar", req, "slip.toml")
    wet = sim("door_nav.roar", req, "slip.toml", faults=["slip"])
    assert dry.ok and wet.ok            # both believe they arrived
    xd, xw = dry.robot.world.base.pose[0], wet.robot.world.base.pose[0]
    assert xd > 7.75 and xw < xd - 0.2  # on the spill the wheels spun: the robot stopped short
    assert wet.robot.world.base.odometry[0] > xw + 0.2


def test_lidar_dropout_makes_mana_nav_take_its_fallback_recipe():
    req = "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0"
    ok = sim("mana_nav.roar", req, "lidar_dropout.toml")
    out = sim("mana_nav.roar", req, "lidar_dropout.toml", faults=["lidar_dropout"])
    recipes = lambda r: [e.data["recipe"] for e in r.events if e.kind == "recipe"]
    assert "on_map" in recipes(ok) and "straight_line" not in recipes(ok)
    assert "straight_line" in recipes(out)
    assert ok.ok and out.ok
    for r in (ok, out):
        x, y, _ = r.robot.world.base.pose
        assert math.hypot(x - 3.0, y - 4.0) < 0.2


def test_the_cup_slips_out_of_a_weak_grip_and_the_mission_starts_again():
    good = sim("pick_place.roar", "carrier::delivered == true", "gripper.toml")
    weak = sim("pick_place.roar", "carrier::delivered == true", "gripper.toml", faults=["weak_grip"])
    assert good.ok and good.robot.world.gripper.holding is None   # put down on the table
    cup = good.robot.world.objects["cup"].position
    assert math.hypot(cup[0] - 6.5, cup[1] - 3.75) < 0.6
    assert not weak.ok
    checks = [c for c in weak.calls if c.function == "gripper::has_object"]
    assert checks and all(c.outcome == "no" for c in checks)
    assert weak.robot.world.gripper.drops >= 1


def test_a_loop_that_takes_no_time_is_stopped_and_said():
    res = sim("pick_place.roar", "carrier::delivered == true", "gripper.toml",
              prim_faults=[parse_fault("go_to")])
    assert res.end == "zero-time loop" and not res.ok
    assert res.robot.time < 0.01


# ---------------------------------------------------------------- the runs are engine runs


_FRESH = re.compile(r"[A-Za-z_][A-Za-z0-9_']*#\d+")


def _lines(facts):
    return [show(f) for _m, f in facts if type(f) is Root]


def _rename(want: list, got: list, ren: dict):
    """Do the printed facts ``want`` (the simulation's) equal ``got`` (the enumerator's) up to a
    consistent renaming of fresh names? The extended renaming, or None."""
    if len(want) != len(got):
        return None
    shape = lambda t: _FRESH.sub("#", t)
    ren = dict(ren)
    images = set(ren.values())
    # pair facts of one shape by the names already paired; new names sort last on both sides
    w_key = lambda t: _FRESH.sub(lambda m: ren.get(m.group(0), "~"), t)
    g_key = lambda t: _FRESH.sub(lambda m: m.group(0) if m.group(0) in images else "~", t)
    ws = sorted(want, key=lambda t: (shape(t), w_key(t)))
    gs = sorted(got, key=lambda t: (shape(t), g_key(t)))
    for w, g in zip(ws, gs):
        if shape(w) != shape(g):
            return None
        for a, b in zip(_FRESH.findall(w), _FRESH.findall(g)):
            if ren.setdefault(a, b) != b:
                return None
    return ren


def test_every_agent_step_of_a_simulation_is_an_enabled_step_of_the_model():
    """Independent driver: re-take the run on the enumerator (Program.steps / successor), the
    functional layer's answers and the poll sleeps applied as the context edits they are."""
    from roar_formal.clf.terms import const
    res = door(("door_closes",), seed=1)
    prog = res.run.model.program()
    start = next(d for d in prog.sig.directives if hasattr(d, "start"))
    state = prog.start_context(start.start)
    ren: dict = {}
    asleep: dict = {}

    def find(text):
        text = _FRESH.sub(lambda m: ren.get(m.group(0), m.group(0)), text)
        return next(f for _m, f, _n in state.facts() if type(f) is Root and show(f) == text)

    for k, step in enumerate(res.run.steps.raw):
        if step.rule in ("functional_layer", "poll_sleep", "poll_wake"):
            nxt = state.copy()
            if step.rule == "functional_layer":
                pend = find(show(step.consumed[0][1]))
                nxt.remove_fact(pend, LIN)
                ans = step.produced[0][1]
                nxt.add_fact(const("return", ans.args[0], pend.args[2]) if ans.head.name == "return"
                             else const("callfail", pend.args[2]), LIN)
            elif step.rule == "poll_sleep":
                ctl = find(show(step.consumed[0][1]))
                asleep[show(step.consumed[0][1])] = ctl
                nxt.remove_fact(ctl, LIN)
            else:
                nxt.add_fact(asleep.pop(show(step.produced[0][1])), LIN)
            state = nxt
            continue
        want_c, want_p = _lines(step.consumed), _lines(step.produced)
        for choice in prog.steps(state):
            if choice.rule != step.rule:
                continue
            nxt, got = prog.successor(state, choice)
            r = _rename(want_c, _lines(got.consumed), ren)
            r = r if r is None else _rename(want_p, _lines(got.produced), r)
            if r is not None:
                ren, state = r, nxt
                break
        else:
            pytest.fail(f"step {k + 1} ({step.rule}) is not an enabled step of the model")
    assert not asleep


# ---------------------------------------------------------------- conformance


RUNS = [
    ("door_nav.roar", DOOR_REQ, "door.toml", ()),
    ("door_nav.roar", DOOR_REQ, "door.toml", ("door_closes",)),
    ("door_nav.roar", "base::arrived == true where base::gx == 8.0 && base::gy == 1.0", "slip.toml", ("slip",)),
    ("mana_nav.roar", "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0",
     "clear.toml", ()),
    ("mana_nav.roar", "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0",
     "lidar_dropout.toml", ("lidar_dropout",)),
    ("conflict.roar", "mission::done == true", "ptu_cable.toml", ()),
    ("spa_loop.roar", "exec::arrived == true where exec::goal == 7", "slip.toml", ()),
    ("pick_place.roar", "carrier::delivered == true", "gripper.toml", ()),
]


@pytest.mark.parametrize("spec,request_,scenario,faults", RUNS,
                         ids=[f"{s.split('.')[0]}-{sc.split('.')[0]}{'-' + '-'.join(f) if f else ''}"
                              for s, _r, sc, f in RUNS])
def test_every_scenario_run_is_covered_and_replays_on_the_abstract_model(tmp_path, spec, request_, scenario,
                                                                         faults):
    res = sim(spec, request_, scenario, faults=faults)
    assert res.end in ("quiescent", "horizon")
    assert res.calls and not res.uncovered(), [c.as_json() for c in res.uncovered()]
    # through the trace file: what a user would replay
    path = tmp_path / "run.jsonl"
    write_robot_trace(path, res, spec, request_, scenario)
    header, steps = read_trace(path)
    assert header["kind"] == "roar-robot-run" and header["scenario_fingerprint"]
    model, binding = abstract_model(spec, request_, scenario)
    rp = replay_on_model(model, binding.robot, steps)
    assert rp.ok, rp.divergence.lines()
    assert len(rp.outcomes) == len(res.calls)


def _door_trace(tmp_path):
    res = door(("door_closes",))
    path = tmp_path / "door.jsonl"
    write_robot_trace(path, res, "door_nav.roar", DOOR_REQ, "door.toml")
    return res, path


def _rewrite(path, steps, header, out):
    lines = [json.dumps(header)] + [json.dumps(s) for s in steps]
    out.write_text("\n".join(lines) + "\n")


def test_a_result_no_outcome_covers_is_rejected_at_its_step(tmp_path):
    res, path = _door_trace(tmp_path)
    header, steps = read_trace(path)
    k = next(i for i, s in enumerate(steps) if s.get("call", {}).get("function") == "base::at_goal")
    steps[k]["call"]["result"]["value"] = "banana"
    model, binding = abstract_model("door_nav.roar", DOOR_REQ, "door.toml")
    rp = replay_on_model(model, binding.robot, steps)
    assert not rp.ok and rp.divergence.step == steps[k]["step"]
    assert "covered by no declared outcome" in rp.divergence.reason
    assert any("banana" in line for line in rp.divergence.robot)


def test_a_robot_failing_more_than_max_failures_allows_is_said_so(tmp_path):
    """The door run's planner finds no path many times; an abstraction that assumes it fails at
    most once (max_failures=1) cannot follow the robot at the second failure, and says why."""
    import importlib.util
    res, path = _door_trace(tmp_path)
    header, steps = read_trace(path)
    spec_ast, _model, binding, _sc = setup("door_nav.roar", DOOR_REQ, "door.toml")
    mod_spec = importlib.util.spec_from_file_location("door_nav_bound", MODELS / "door_nav.py")
    mod = importlib.util.module_from_spec(mod_spec)
    mod_spec.loader.exec_module(mod)
    reg = mod.registry()
    reg.register("compute_path", lambda gx, gy: True, outcomes=mod.OUTCOMES["compute_path"], replace=True,
                 max_failures=1)
    bounded = compile_spec(spec_ast, DOOR_REQ, registry=reg, functional="abstract")
    failed = [s["step"] for s in steps if s.get("call", {}).get("function") == "planner::compute_path"
              and s["call"]["result"]["failed"]]
    assert len(failed) >= 2
    rp = replay_on_model(bounded, binding.robot, steps)
    assert not rp.ok and rp.divergence.step == failed[1]
    assert ("the model cannot answer planner::compute_path with outcome no_path here: the abstraction allows "
            "planner::compute_path no more failing outcomes in this run (its max_failures is used up)"
            in rp.divergence.reason)
    plain, _binding = abstract_model("door_nav.roar", DOOR_REQ, "door.toml")
    assert replay_on_model(plain, binding.robot, steps).ok   # without the bound the run replays


def test_a_robot_step_the_model_does_not_allow_is_rejected_with_both_sides(tmp_path):
    res, path = _door_trace(tmp_path)
    header, steps = read_trace(path)
    # the lidar says the path is blocked, but the recorded run goes on polling as if it were clear
    k = next(i for i, s in enumerate(steps) if s.get("call", {}).get("function") == "planner::path_blocked"
             and s["call"]["result"]["value"] is False)
    steps[k]["call"]["result"]["value"] = True
    model, binding = abstract_model("door_nav.roar", DOOR_REQ, "door.toml")
    rp = replay_on_model(model, binding.robot, steps)
    assert not rp.ok and rp.divergence.step > steps[k]["step"]
    assert "cannot take this rule" in rp.divergence.reason
    assert rp.divergence.robot and any("enabled here" in x for x in rp.divergence.model)


def test_a_robot_trace_with_an_edited_fact_or_request_is_rejected_at_that_step(tmp_path):
    """The model's step is matched on the facts the trace records, not on the rule name alone: a
    value edited in one step, or a trace of another request, diverge there (they used to replay,
    the differences counted and never shown). A value the robot answered and an outcome stands
    for (mana_nav's, spa_loop's: other tests) is still read as the outcome's."""
    res, path = _door_trace(tmp_path)
    header, steps = read_trace(path)
    model, binding = abstract_model("door_nav.roar", DOOR_REQ, "door.toml")
    assert replay_on_model(model, binding.robot, steps).ok
    k = next(i for i, s in enumerate(steps) if any("(vnum 9)" in f for f in s.get("consumed", [])))
    edited = json.loads(json.dumps(steps))
    edited[k]["consumed"] = [f.replace("(vnum 9)", "(vnum 7)") for f in edited[k]["consumed"]]
    rp = replay_on_model(model, binding.robot, edited)
    assert not rp.ok and rp.divergence.step == steps[k]["step"]
    assert "other facts than the trace records" in rp.divergence.reason
    assert any("(vnum 7)" in x for x in rp.divergence.robot) and any("(vnum 9)" in x for x in rp.divergence.model)
    assert not any("(vnum 7)" in x for x in rp.divergence.model)   # only the facts that differ are shown
    # the same trace replayed on the model of another request (goal x = 4): the first step that
    # reads the goal diverges
    other, _ = abstract_model("door_nav.roar", DOOR_REQ.replace("9.0", "4.0"), "door.toml")
    rp = replay_on_model(other, binding.robot, steps)
    assert not rp.ok and "other facts" in rp.divergence.reason


def test_a_robot_traces_recorded_outcome_is_confirmed(tmp_path, capsys):
    """replay says NOT CONFIRMED (exit 1) when the header's outcome is not how the request ends
    on the model (it said nothing); and steps out of order are refused when the trace is read."""
    from roar_formal.cli import main
    _res, path = _door_trace(tmp_path)
    header, steps = read_trace(path)

    def replay(p):
        try:
            main(["replay", str(p), "--model", str(MODELS / "door_nav.roar")])
            return 0, capsys.readouterr()
        except SystemExit as exc:
            return exc.code, capsys.readouterr()
    code, out = replay(path)
    assert code == 0 and "NOT CONFIRMED" not in out.out, out
    assert header["outcome"] == "success"
    bad = tmp_path / "bad.jsonl"
    _rewrite(path, steps, {**header, "outcome": "failure"}, bad)
    code, out = replay(bad)
    assert code == 1 and "NOT CONFIRMED: the trace records that its request ended in failure, but on the model " \
                          "it ends in success" in " ".join(out.out.split())
    swapped = list(steps)
    swapped[30], swapped[31] = swapped[31], swapped[30]
    _rewrite(path, swapped, header, bad)
    code, out = replay(bad)
    assert code == 2 and f"step {steps[30]['step']} comes after step {steps[31]['step']}" in out.err


# ---------------------------------------------------------------- a counterexample on the robot


def test_the_conflict_livelock_happens_on_the_robot_only_with_the_cable(tmp_path, checker_job):
    from roar_formal.verify.check import save_counterexample

    res = checker_job("conflict.toml")
    assert res.verdicts["livelock"].status == "violated"
    trace = save_counterexample(res, "livelock", tmp_path)
    _header, records = read_trace(trace)
    assert any(r.get("loop") for r in records)
    spec_ast, model, binding, sc = setup("conflict.roar", "mission::done == true", "ptu_cable.toml")
    with_cable = replay_on_robot(model, binding.robot, sc, records, faults=["cable"], loops=3)
    assert with_cable.realised, with_cable.lines[-5:]
    assert with_cable.steps == with_cable.total
    ptu = with_cable.robot.world.ptu
    assert ptu.angle_deg < 25.0          # stopped by the cable short of the 30 degrees asked for
    blocked = [c for c in with_cable.calls if c.outcome == "blocked"]
    assert len(blocked) >= 3
    free = replay_on_robot(model, binding.robot, sc, records, faults=[], loops=3)
    assert not free.realised
    assert "blocked" in free.message and "turned" in free.message
    # the lasso's stem alone, as a path: a deadlock's must leave the robot stuck where it ends (the
    # run goes on here), a safety property's is realised once its last state is reached
    stem = [r for r in records if not r.get("loop")]
    as_deadlock = replay_on_robot(model, binding.robot, sc, stem, faults=["cable"])
    assert not as_deadlock.realised and "goes on" in as_deadlock.message
    as_safety = replay_on_robot(model, binding.robot, sc, stem, faults=["cable"], stuck=False)
    assert as_safety.realised and as_safety.steps == as_safety.total == len(stem)
    assert "every step of the counterexample happened on the robot" in as_safety.message
