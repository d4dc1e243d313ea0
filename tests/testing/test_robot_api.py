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


def test_replay_takes_a_robot_run_and_a_loaded_spec(tmp_path):
    """rf.replay on a robot run's trace replays it on the abstract model as the command line does
    (it used to send it to the engine replayer, which refused a valid trace), and takes the spec
    loaded as well as its path; an edited fact is refused with the step and the facts."""
    import json
    spec = roar_formal.load_spec(ROOT / "models" / "door_nav.roar")
    report = spec.run("base::arrived == true where base::gx == 9.0 && base::gy == 3.0",
                      scenario=ROOT / "models" / "scenarios" / "door.toml", seed=0)
    trace = report.save_trace(tmp_path / "door.jsonl")
    by_path = roar_formal.replay(trace, ROOT / "models" / "door_nav.roar")
    by_spec = roar_formal.replay(trace, spec)
    assert by_path.steps == by_spec.steps > 100 and by_path.confirmed is True
    assert by_path.outcomes == by_spec.outcomes and by_path.outcomes[0][1] == "planner::compute_path"
    lines = trace.read_text(encoding="utf-8").splitlines()
    header, records = json.loads(lines[0]), [json.loads(x) for x in lines[1:]]
    k = next(i for i, r in enumerate(records) if any("(vnum 9)" in f for f in r.get("consumed", [])))
    records[k]["consumed"] = [f.replace("(vnum 9)", "(vnum 8)") for f in records[k]["consumed"]]
    bad = tmp_path / "bad.jsonl"
    bad.write_text("\n".join(json.dumps(x) for x in [header, *records]) + "\n", encoding="utf-8")
    with pytest.raises(RoarError) as info:
        roar_formal.replay(bad, spec)
    text = info.value.format()
    assert f"step {records[k]['step']}" in text and "(vnum 8)" in text and "other facts" in text
