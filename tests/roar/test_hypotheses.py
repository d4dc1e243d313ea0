"""Solutions under hypotheses (4.3): when no task entails a constraint directly, a task that
entails it under a hypothesis is a candidate, and the hypothesis is sub-goaled like an unmet
pre-condition ("these hypotheses are added to the list of constraints to handle")."""

from __future__ import annotations

from pathlib import Path

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.parser import parse_roar
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from repo import ROOT

DATA = Path(__file__).parent / "data"


def test_the_only_solution_under_a_hypothesis_sub_goals_it():
    m = compile_spec(load_spec(DATA / "hypothesis.roar"), "arm::pos == 5")
    assert m.candidates[m.request_cst] == [("arm", "move")]
    assert m.hypotheses[m.request_cst] == [("arm", "move", "arm::target == 5")]
    for seed in range(3):
        r = run_model(m, seed=seed)
        assert r.outcome == "success" and r.final == {"arm::pos": 5, "arm::target": 5}
        assert [e.text for e in r.events if e.kind == "tasks"] == ["R0: tasks aim then move"]


def test_a_hypothesis_that_already_holds_is_not_sub_goaled():
    text = (DATA / "hypothesis.roar").read_text().replace("int target = 0;", "int target = 5;")
    m = compile_spec(parse_roar(text, "h.roar"), "arm::pos == 5")
    assert m.hypotheses[m.request_cst] == [("arm", "move", "arm::target == 5")]
    r = run_model(m)
    assert r.outcome == "success" and r.final["arm::pos"] == 5
    assert [e.text for e in r.events if e.kind == "tasks"] == ["R0: tasks move"]


def test_a_hypothesis_nothing_establishes_leaves_no_plan():
    m = compile_spec(load_spec(ROOT / "models" / "faulty" / "aim.roar"), "arm::pos == 5")
    assert m.hypotheses[m.request_cst] == [("arm", "move", "arm::target == 5")]
    r = run_model(m)
    assert r.outcome == "failure" and r.error_context == []


def test_a_direct_solution_is_preferred_to_any_hypothesis():
    text = (DATA / "hypothesis.roar").read_text().replace(
        "    move = task {", "    jump = task {\n      pre = { }\n      post = { {pos == 5} }\n"
        "      recipes = {\n        r = recipe { body = { set pos 5; } }\n      }\n    }\n    move = task {")
    m = compile_spec(parse_roar(text, "h.roar"), "arm::pos == 5")
    assert m.candidates[m.request_cst] == [("arm", "jump")]
    assert m.request_cst not in m.hypotheses
    assert [e.text for e in run_model(m).events if e.kind == "tasks"] == ["R0: tasks jump"]
