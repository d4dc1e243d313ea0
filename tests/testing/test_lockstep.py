"""RoarMachine with a scenario: the model and the reference robot driven in lockstep.

The robot side is the robot-backed explorer's transition system (robot.explore.RobotSystem): the
agents' steps, then launches of the pending calls (hypothesis draws their order and which fault
points to arm) and the physics advancing. Every step is taken on the model too; the test fails at
the first step where the two disagree. Oracles: on pair.roar (tests/robot/data/explore/) the
robot-backed explorer finds no disagreement either (its runs replay on the model, test_sim.py), so
the machine must pass, and its runs must reach every declared outcome (the fault points make
`look` and `nudge` fail); a copy of the spec that does not declare `look`'s failure must be caught
at the call the `blind` fault point makes fail.
"""

from __future__ import annotations

import inspect
import shutil

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis.stateful import invariant, run_state_machine_as_test

from roar_formal import RoarError
from roar_formal.testing import RoarMachine, load_spec
from repo import ROOT

DATA = ROOT / "tests" / "robot" / "data" / "explore"
REQUEST = "mission::done == true"
RUNS = settings(max_examples=8, phases=[Phase.generate], database=None, deadline=None, derandomize=True,
                stateful_step_count=50, suppress_health_check=list(HealthCheck))


class PairOnRobot(RoarMachine):
    spec = load_spec(DATA / "pair.roar")
    request = REQUEST
    scenario = DATA / "pair.toml"
    faults = ["blind", "spill"]


def test_model_and_robot_agree_on_the_pair_with_its_fault_points():
    seen: dict[str, set] = {"answers": set(), "robot": set(), "final": set()}
    times: list[float] = []

    class Watched(PairOnRobot):
        @invariant()
        def robot_and_model_move_together(self):
            # every answer the robot gave is an outcome step of the model, narrated as a ROAR event
            answered = [e for e in self.events if e.kind == "primitive-end"]
            launched = sum(e.text.count("()") for e in self.robot_events if e.text.startswith("launch"))
            assert len(answered) <= launched
            times.append(self.robot_time)

        def teardown(self):
            seen["answers"].update(e.text for e in self.events if e.kind == "primitive-end")
            seen["robot"].update(e.text.split(" (t =")[0] for e in self.robot_events)
            if self.quiescent:
                seen["final"].add((self.final, self.value("mission::done")))

    run_state_machine_as_test(Watched, settings=RUNS)
    # the robot decided every outcome, and each of the four declared ones happened
    assert seen["answers"] == {"look() = true", "look() = false", "nudge() = true", "nudge() = false"}
    assert "advance" in seen["robot"]
    assert any(r.startswith("launch left::look(); fault ") and "blind" in r for r in seen["robot"])
    assert any(r.startswith("launch right::nudge()") for r in seen["robot"])
    # runs ran to the end: the mission succeeded, or failed for good after a fault
    assert (True, True) in seen["final"]
    assert max(times) > 0.5    # the physics advanced


def test_an_answer_the_model_does_not_declare_is_a_disagreement(tmp_path, docs_shows):
    for name in ("pair.roar", "pair.toml"):
        shutil.copy(DATA / name, tmp_path / name)
    source = (DATA / "pair.py").read_text(encoding="utf-8")
    narrowed = source.replace('LOOK = [Outcome("up", True), Outcome("down", False)]', 'LOOK = [Outcome("up", True)]')
    assert narrowed != source
    (tmp_path / "pair.py").write_text(narrowed, encoding="utf-8")

    class Narrow(RoarMachine):   # the model says the lidar is always up; with `blind` it is not
        spec = load_spec(tmp_path / "pair.roar")
        request = REQUEST
        scenario = tmp_path / "pair.toml"
        faults = ["blind"]

    with pytest.raises(AssertionError) as e:
        run_state_machine_as_test(Narrow, settings=settings(RUNS, max_examples=40))
    out = "\n".join([str(e.value), *getattr(e.value, "__notes__", [])])
    assert out.startswith("the robot and the model disagree: the robot's left::look() returned "
                          "{'value': False, 'failed': False, 'status': 'done', 'detail': {}} at t = ")
    assert "which no declared outcome of left::look covers (declared: up)" in out
    # the run shows the robot's steps among the ROAR events, up to the call that disagreed
    run = out[out.index("the run, one ROAR event a line:"):].splitlines()
    assert any("robot        launch left::look(); fault blind armed" in x for x in run)
    assert "look()" in "\n".join(run)
    docs_shows("pair_lockstep", out)
    # without the fault point the robot never leaves the declared outcomes
    class NarrowNoFault(Narrow):
        faults = ()

    run_state_machine_as_test(NarrowNoFault, settings=settings(RUNS, max_examples=4))


def test_the_scenario_and_fault_points_are_checked_where_the_class_is_written():
    line = inspect.currentframe().f_lineno + 2

    class Typo(PairOnRobot):
        faults = ["blindd"]

    with pytest.raises(RoarError, match="fault point 'blindd' is not in scenario 'pair'") as e:
        Typo()
    assert (e.value.pos.file, e.value.pos.line) == (__file__, line)

    class NoScenario(PairOnRobot):
        scenario = DATA / "nowhere.toml"

    with pytest.raises(RoarError, match="nowhere.toml"):
        NoScenario()
