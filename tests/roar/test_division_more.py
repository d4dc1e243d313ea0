"""A division by zero in the three places that still blocked (docs/semantics.md, Known gaps) is a
located failure, not a rule that never fires (which stopped the run silently and made the
explorer report a deadlock):

* in the arguments of a call a recipe statement, a recipe pre-condition or a start initialiser
  makes (the call site evaluates them): the call is not made, and the statement fails locally,
  the recipe is not acceptable, the request fails before it is sent, as with the same division
  outside a call;
* in a task pre-condition without a call (the decision's search evaluates it): it does not hold,
  and its task is not usable for this decision; a decision that finds no task puts the division
  in the request's error context;
* in the pre-condition of another recipe, which the calling-context search evaluates: that
  alternative is not acceptable.

Each spec has a twin whose divisor is not 0, which behaves as before."""

from __future__ import annotations

from pathlib import Path

import pytest

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from roar_formal.testing import load

from .division import DATA, check_explorer, check_run, check_twin, run_spec, twin

# spec, request, the error context of the run, the twin's edits (old, new), what the twin's run ends with
CASES = {
    "call_stmt": (
        "div_call_stmt.roar", "a::done == true",
        ["task failed: a::t",
         "local failure: a.t.r at 19:53: division by zero: d is 0 in set x twice(10 / d)"],
        [("int d = 0;", "int d = 2;")], {"a::done": True, "a::x": 10}),
    "call_pre": (
        "div_call_pre.roar", "a::done == true",
        ["task failed: a::t",
         "local failure: a.t.r at 18:31: division by zero: d is 0 in pre-condition ready(10 / d) == true"],
        [("int d = 0;", "int d = 2;")], {"a::done": True}),
    "call_start": (
        "div_call_start.roar", "a::done == true",
        ["local failure: a.. at 7:38: division by zero: d is 0 in initial value of a::per: half(12 / d)"],
        [("int d = 0;", "int d = 3;")], {"a::done": True, "a::per": 2}),
    "task_pre": (
        "div_task_pre.roar", "a::x == 1",
        ["local failure: a.go. at 14:21: division by zero: d is 0 in pre-condition of task go: 10 / d > 1"],
        [("int d = 0;", "int d = 2;")], {"a::x": 1}),
}

ALT = DATA / "div_alternative.roar"   # tracker's alternative recipe: pre-condition 100 / cams > 10



@pytest.mark.parametrize("case", sorted(CASES))
def test_the_run_ends_with_the_located_division(case):
    check_run(CASES[case])


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_explorer_finds_no_deadlock(case):
    check_explorer(CASES[case])


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_twin_with_a_nonzero_divisor_behaves_as_before(case, tmp_path):
    check_twin(CASES[case], tmp_path)


def test_a_call_made_by_a_statement_is_not_made():
    res = run_spec(DATA / "div_call_stmt.roar", "a::done == true")
    assert not any(e.kind == "primitive" for e in res.events), [e.text for e in res.events]
    assert res.final["a::x"] == 0   # nothing was written


def test_a_task_whose_pre_condition_cannot_be_evaluated_leaves_the_decision_to_another(tmp_path):
    """The decision comes: a task the search can use instead is chosen (no division recorded)."""
    path = twin("div_task_pre.roar", [(
        "  }\n}\n",
        "    slow = task {\n      pre = { }\n      post = { {x == 1} }\n"
        "      recipes = { r = recipe { body = { set x 1; } } }\n    }\n  }\n}\n")], tmp_path)
    res = run_spec(path, "a::x == 1")
    assert res.outcome == "success" and res.error_context == []
    assert "R0: tasks slow" in [e.text for e in res.events]
    ex = load(path).explore("a::x == 1", properties=["deadlock", "mission-failure"])
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "holds"


def test_a_sub_goal_whose_pre_condition_cannot_be_evaluated(tmp_path):
    """The division is in the pre-condition of a sub-goal's task (prep, which establishes go's
    pre-condition): prep is not usable, so neither is go, and the request fails with prep's
    division located."""
    path = twin("div_task_pre.roar", [
        ("{ int x; }", "{ int x; bool ready; }"),
        ("pre = { {10 / d > 1} }", "pre = { {ready == true} }"),
        ("  }\n}\n",
         "    prep = task {\n      pre = { {10 / d > 1} }\n      post = { {ready == true} }\n"
         "      recipes = { r = recipe { body = { set ready true; } } }\n    }\n  }\n}\n")], tmp_path)
    res = run_spec(path, "a::x == 1")
    assert res.quiescent and res.outcome == "failure"
    assert res.error_context == ["local failure: a.prep. at 19:21: division by zero: d is 0 in pre-condition "
                                 "of task prep: 10 / d > 1"]
    assert load(path).explore("a::x == 1", properties=["deadlock"]).verdicts["deadlock"].status == "holds"
    fixed = tmp_path / "fixed.roar"   # (the twin: d = 2)
    fixed.write_text(path.read_text().replace("int d = 0;", "int d = 2;"))
    res = run_spec(fixed, "a::x == 1")
    assert res.outcome == "success" and res.final["a::ready"] is True and res.final["a::x"] == 1
    assert "R0: tasks prep then go" in [e.text for e in res.events]


def _verdicts(path: Path, seeds: int = 4):
    model = compile_spec(load_spec(path), "mission::done == true")
    out = []
    for seed in range(seeds):
        r = run_model(model, seed=seed)
        out.append((r, [e.text.split(": ", 1)[1] for e in r.events if e.kind == "calling-context"]))
    return out


def test_an_alternative_whose_pre_condition_cannot_be_evaluated_is_not_acceptable():
    for r, verdicts in _verdicts(ALT):
        # as with alt_unacceptable.roar: the search goes up to the outside
        assert verdicts == ["the emitter of R2 has no alternative: asking its caller",
                            "the emitter of R1 has no alternative: asking its caller",
                            "the emitter of R0 is a request from outside: the conflict cannot be resolved"]
        assert r.quiescent and r.outcome == "failure"
        assert r.error_context[-1] == ("concurrency: task ptu::point is held by another constraint, and no "
                                       "agent of its calling context has an alternative")
        assert not any(e.kind == "recipe" and "wide_angle" in e.text for e in r.events)
    ex = load(ALT).explore("mission::done == true", properties=["deadlock", "mission-failure"])
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "violated"


def test_the_alternative_twin_with_a_nonzero_divisor_reconfigures(tmp_path):
    twin = tmp_path / ALT.name
    twin.write_text(ALT.read_text().replace("int cams = 0;", "int cams = 5;"))
    for r, verdicts in _verdicts(twin):
        assert verdicts == ["the emitter of R2 has an alternative: it reconfigures"]
        assert r.outcome == "success", r.error_context
        assert any(e.kind == "recipe" and "wide_angle" in e.text for e in r.events)
    ex = load(twin).explore("mission::done == true", properties=["deadlock", "mission-failure"])
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "holds"


@pytest.mark.parametrize("spec, req, rules", [
    ("div_call_stmt.roar", "a::done == true", ["st2_call_diva"]),
    ("div_call_pre.roar", "a::done == true", ["st3_call_diva"]),
    ("div_call_start.roar", "a::done == true", ["st3_call_diva"]),
])
def test_the_call_sites_have_division_rules(spec, req, rules):
    model = compile_spec(load_spec(DATA / spec), req)
    names = {line.split(" : ", 1)[0] for line in model.text.splitlines() if " : " in line}
    assert set(rules) <= names
    # the statement's own rule no longer names a divisor of the call's arguments
    assert not any(n.endswith("_set_diva") for n in names)


def test_the_decision_records_the_pre_condition_division():
    text = compile_spec(load_spec(DATA / "div_task_pre.roar"), "a::x == 1").spec_text
    for name in ("select_c1_a", "reselect_c1_a"):   # (the decision's two rules)
        rule = text.split(f"\n{name} : ", 1)[1].split("}.", 1)[0]
        assert "!dec_zero D " in rule and "(h_dec D) EC1 F " in rule
    plain = compile_spec(load_spec(DATA / "divide_by_zero.roar"), "a::done == true").spec_text
    assert "dec_zero" not in plain and "ec_opt" not in plain   # (only a spec that needs it)


@pytest.mark.parametrize("case", ["call_pre", "call_stmt", "task_pre"])
def test_with_crashes_the_division_rules_still_fire(case):
    """With the agent that may crash, every compiled rule is guarded by its epoch: the rule of a
    division in a pre-condition call's arguments reads the checker itself, and is guarded once."""
    name, request, _ec, _edits, _values = CASES[case]
    ex = load(DATA / name).explore(request, properties=["deadlock", "mission-failure"], crash=["a"])
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "violated"
