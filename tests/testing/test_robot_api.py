"""The testing API on the robot: AgentSpec.explore_on_robot (robot-backed checking from pytest)."""

from __future__ import annotations


import pytest

import roar_formal
from roar_formal.errors import RoarError
from repo import ROOT

DATA = ROOT / "tests" / "robot" / "data" / "explore"


def test_explore_on_robot_finds_the_contact_and_passes_the_fixed_twin():
    spec = roar_formal.load(DATA / "bump.roar")
    bad = spec.explore_on_robot("base::done == true", DATA / "bump_wall.toml", ["deadlock"],
                                robot_never=["contact"])
    assert bad.violated("robot-invariant")
    assert "contact" in bad.verdict("robot-invariant").message
    good = spec.explore_on_robot("base::done == true", DATA / "bump_clear.toml", ["deadlock"],
                                 robot_never=["contact"])
    assert good.holds("robot-invariant") and good.holds("deadlock")


def test_explore_on_robot_fault_choices_and_quantisation():
    spec = roar_formal.load(DATA / "pair.roar")
    exact = spec.explore_on_robot("mission::done == true", DATA / "pair.toml", faults=["blind", "spill"],
                                  quantise="exact")
    none = spec.explore_on_robot("mission::done == true", DATA / "pair.toml", quantise="exact")
    # arming fault points is branching: more states than the run without them
    assert exact.result.graph.n_states > none.result.graph.n_states
    assert exact.holds("deadlock") and none.holds("deadlock")
    only_nudge = spec.explore_on_robot("mission::done == true", DATA / "pair.toml", faults={"spill": ["nudge"]},
                                       quantise={"position": 0.05})
    assert only_nudge.result.graph.complete


def test_explore_on_robot_bad_arguments_are_located_at_the_caller():
    spec = roar_formal.load(DATA / "bump.roar")
    with pytest.raises(RoarError) as e:
        spec.explore_on_robot("base::done == true", DATA / "bump_clear.toml", quantise="fine")
    assert e.value.pos is not None and e.value.pos.file == __file__
    with pytest.raises(RoarError, match="did you mean"):
        spec.explore_on_robot("base::done == true", DATA / "bump_clear.toml", robot_never=["contactt"])
