"""The reference robot with two features of the functional layer (issue 14, part B):

* an initialiser that calls the functional layer (4.2: ``int start_x = odometry();``), run once
  when the agents start, before the request from outside is sent (``i_start``);
* a call in a task pre-condition (``pre = { {front_clear() == true} }``), evaluated by the logic
  layer through the functional layer before each decision (``lselect`` / the logic activation).

The spec, tests/robot/data/init_pre/init_pre.roar, binds ``odometry()`` to the robot's odometry
(a 50 ms sensor: an activity that takes simulated time) and ``front_clear()`` to its lidar (a read
of the latest scan). In scenario ``clear`` the robot starts at x = 1 with nothing ahead; in
``blocked`` at x = 4, a box 0.6 m ahead. Everything asserted is what the robot made: the initial
value read from its odometry, and the task the logic layer chose from what its lidar saw; on
``simulate``, conformance (the robot run is a path of the abstract model), robot-backed checking,
and a model counterexample replayed on the robot.
"""

from __future__ import annotations

import pytest

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import parse_fault
from roar_formal.robot.conform import replay_on_model
from roar_formal.robot.onrobot import replay_on_robot
from roar_formal.robot.report import write_robot_trace
from roar_formal.robot.setup import prepare
from roar_formal.robot.sim import simulate
from roar_formal.testing.api import load
from roar_formal.trace.format import read_trace

from repo import ROOT

DATA = ROOT / "tests" / "robot" / "data" / "init_pre"
SPEC = DATA / "init_pre.roar"
REQ = "base::done == true"
#: scenario -> (x the robot starts at, what its lidar sees ahead, the task chosen, route, outcome)
EXPECTED = {"clear": (1, True, "straight", 1, "success"), "blocked": (4, False, "around", 2, "failure")}

_SETUP: dict = {}


def setup(scenario: str):
    if scenario not in _SETUP:
        _SETUP[scenario] = prepare(SPEC, REQ, DATA / f"{scenario}.toml")
    return _SETUP[scenario]


def sim(scenario: str, faults=(), seed: int = 0):
    _ast, model, binding, sc = setup(scenario)
    return simulate(model, binding.robot, sc, seed=seed, prim_faults=[parse_fault(f) for f in faults])


def first(events, kind: str, text: str = "") -> int:
    return next(e.step for e in events if e.kind == kind and text in e.text)


# ---------------------------------------------------------------- simulate


@pytest.mark.parametrize("scenario", sorted(EXPECTED))
def test_the_initialiser_reads_the_robot_once_at_start(scenario):
    x, _clear, _task, _route, outcome = EXPECTED[scenario]
    res = sim(scenario)
    assert res.outcome == outcome and res.end == "quiescent"
    assert res.run.final["base::start_x"] == x          # the robot's odometry, not a default or a stub
    odo = [c for c in res.calls if c.function == "base::odometry"]
    assert len(odo) == 1                                # once, at start (a later decision does not call it)
    call = odo[0]
    assert call.n == 1 and call.agent == "base" and call.result.value == x and not call.forced
    assert call.outcome == ("west" if x < 3 else "east")
    # an activity on the robot: it took the sensor's 50 ms of simulated time, from t = 0
    assert call.t_start == 0.0 and call.t_end == pytest.approx(0.05)
    # ... and the request from outside was sent only once the initial value was written
    written = first(res.events, "write", f"base::start_x = {x}")
    sent = first(res.events, "state", "R0 sent -> pending")
    assert call.step_end < written < sent


def test_the_decision_depends_on_what_the_pre_condition_s_call_reads_on_the_robot():
    # clear: one decision, straight's and around's pre-conditions each call front_clear once
    res = sim("clear")
    assert res.ok and res.run.final["base::route"] == 1 and res.run.final["base::done"] is True
    looks = [c for c in res.calls if c.function == "base::front_clear"]
    assert len(looks) == 2 and all(c.result.value is True and c.outcome == "clear" and not c.forced for c in looks)
    tasks = [e for e in res.events if e.kind == "tasks"]
    assert [e.text for e in tasks] == ["R0: tasks straight"]
    assert all(c.step_end < tasks[0].step for c in looks)
    assert all(c.t_start == pytest.approx(0.05) for c in looks)   # after the start's 50 ms


def test_each_decision_calls_the_pre_conditions_again_on_the_robot():
    # blocked: the lidar sees the box, around is chosen; from x = 4 it fails (start_x < 3), its one
    # try is spent, and the logic layer decides again, reading the lidar again: no task is left
    res = sim("blocked")
    assert res.outcome == "failure" and res.end == "quiescent"
    assert res.run.final["base::route"] == 2 and res.run.final["base::done"] is False
    assert "task failed: base::around" in res.run.error_context
    looks = [c for c in res.calls if c.function == "base::front_clear"]
    assert len(looks) == 4 and all(c.result.value is False and c.outcome == "blocked" for c in looks)
    chose = first(res.events, "tasks", "R0: tasks around")
    failed = first(res.events, "recipe-end", "local failure")
    assert [c.step_end < chose for c in looks] == [True, True, False, False]
    assert all(failed < c.step_start for c in looks[2:])   # the second decision's calls


def test_a_failed_initialiser_call_leaves_the_default_and_the_request_is_sent():
    res = sim("clear", faults=["odometry"])
    assert res.ok and res.run.final["base::start_x"] == 0       # the int default, not the robot's 1
    (call,) = [c for c in res.calls if c.function == "base::odometry"]
    assert call.forced == "fault: failure" and call.result.failed and call.result.value is None
    assert call.t_end == 0.0                                    # the robot was not asked
    assert first(res.events, "state", "R0 sent -> pending") > call.step_end
    assert res.run.final["base::route"] == 1


def test_a_forced_pre_condition_call_decides_as_its_outcome_says():
    # on the clear scenario, front_clear forced to its failing outcome (false) at every call: the
    # robot's own reading (true) is not asked for, the logic layer chooses around, which succeeds
    # from x = 1
    res = sim("clear", faults=["front_clear"])
    assert res.ok and res.run.final["base::route"] == 2
    looks = [c for c in res.calls if c.function == "base::front_clear"]
    assert len(looks) == 2 and all(c.forced == "fault: blocked" for c in looks)
    # the call record holds what the agents received (false), as the events show it
    assert all(c.result.value is False and not c.result.failed for c in looks)
    assert [e.text for e in res.events if e.kind == "primitive-end" and "front_clear" in e.text] == \
        ["front_clear() = false"] * 2
    # only the second call forced: straight's reads the robot (true), around's is false: both
    # tasks are possible, and the first, straight, is chosen
    res = sim("clear", faults=["front_clear:2"])
    assert res.ok and res.run.final["base::route"] == 1


def test_simulate_on_the_command_line(roar_cli):
    code, out, err = roar_cli("simulate", SPEC, "-s", DATA / "blocked.toml", "-r", REQ)
    assert code == 1 and "Traceback" not in err, (out, err)
    assert "base::start_x = 4" in out and "R0: tasks around" in out and out.count("front_clear() = false") == 4
    assert out.index("base::start_x = 4") < out.index("R0 sent -> pending") < out.index("front_clear()")
    assert "request failure" in out and "task failed: base::around" in out


# ---------------------------------------------------------------- the abstraction: conform, check, replay


@pytest.mark.parametrize("scenario", sorted(EXPECTED))
def test_the_robot_run_is_a_path_of_the_abstract_model(tmp_path, scenario):
    res = sim(scenario)
    path = tmp_path / "run.jsonl"
    write_robot_trace(path, res, str(SPEC), REQ, str(DATA / f"{scenario}.toml"))
    _header, steps = read_trace(path)
    _ast, _model, binding, _sc = setup(scenario)
    abstract = compile_spec(load(SPEC).ast, REQ, registry=binding.abstract, functional="abstract")
    rp = replay_on_model(abstract, binding.robot, steps)
    assert rp.ok, rp.divergence.lines()
    assert len(rp.outcomes) == len(res.calls) == (3 if scenario == "clear" else 5)


@pytest.mark.parametrize("scenario", sorted(EXPECTED))
def test_robot_backed_checking_decides_on_the_robot_s_readings(scenario):
    """The search over (CLF state, robot state): the initial value is the robot's in every state,
    and the route the other scenario takes is never reached (the abstract model reaches both)."""
    x, _clear, _task, route, outcome = EXPECTED[scenario]
    spec = load(SPEC)
    scen = DATA / f"{scenario}.toml"
    other = 2 if route == 1 else 1
    e = spec.explore_on_robot(REQ, scen, ["deadlock", "mission-failure"],
                              never=[f"contains v_base_route (vnum {other})"])
    assert e.holds("deadlock") and e.holds("invariant"), e.verdict("invariant").message
    assert e.violated("mission-failure") == (outcome == "failure")
    e = spec.explore_on_robot(REQ, scen, ["deadlock"], never=[f"contains v_base_start_x (vnum {4 if x == 1 else 1})"])
    assert e.holds("invariant")
    e = spec.explore(REQ, ["deadlock"], never=[f"contains v_base_route (vnum {other})"])   # the abstract model
    assert e.violated("invariant")


def test_a_model_counterexample_through_both_features_replayed_on_the_robot(tmp_path):
    """The explorer's shortest way to a failure after going around: odometry east at start, the
    lidar blocked at the first decision, then, at the second, blocked and clear (the model's two
    reads are independent, so no task is left). The blocked robot takes it up to that last read
    and diverges there (at one instant its lidar reads blocked twice); the clear one diverges at
    the start, its odometry reading west."""
    spec = load(SPEC)
    e = spec.explore(REQ, ["deadlock"], never=["rs R s_failure * contains v_base_route (vnum 2)"])
    assert e.violated("invariant")
    _h, records = read_trace(e.counterexample("invariant").save(tmp_path))
    _ast, model, binding, sc = setup("blocked")
    on = replay_on_robot(model, binding.robot, sc, records)
    assert not on.realised
    assert "needs base::front_clear() to end 'clear'" in on.message and "(blocked)" in on.message, on.message
    assert [(c.function, c.outcome) for c in on.calls] == \
        [("base::odometry", "east")] + [("base::front_clear", "blocked")] * 4
    _ast, model, binding, sc = setup("clear")
    on = replay_on_robot(model, binding.robot, sc, records)
    assert not on.realised and on.steps == 1
    assert "needs base::odometry() to end 'east'" in on.message and "(west)" in on.message, on.message
