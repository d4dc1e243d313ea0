"""What a new user of the library wrote first (a trial): one string where a list is expected
means a list of that one item, not of its characters; the strategies take a spec's path as the
helpers do; a run's lines can be indexed."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis.errors import InvalidArgument
from repo import ROOT

import roar_formal as rf
from roar_formal.testing.strategies import fault_schedules, requests

SPEC = ROOT / "models" / "faulty" / "camera_retry.roar"
REQUEST = "camera::taken == true"


def test_one_string_is_one_fault_and_one_property():
    spec = rf.load_spec(SPEC)
    one = spec.run(REQUEST, faults="snap:1")
    assert one.faults == spec.run(REQUEST, faults=["snap:1"]).faults == ("snap:1",)
    assert one.outcome == spec.run(REQUEST, faults=["snap:1"]).outcome
    ex = spec.explore(REQUEST, "deadlock", budget={"max_states": 200})
    assert list(ex.verdicts) == ["deadlock"]


def test_a_runs_lines_can_be_indexed():
    run = rf.load_spec(SPEC).run(REQUEST)
    lines = run.lines()
    assert str(lines[-1]) == lines[-1].text == list(lines)[-1].text
    assert [x.text for x in lines[:2]] == [x.text for x in list(lines)[:2]]


@settings(max_examples=5, deadline=None)
@given(fault_schedules(str(SPEC)), requests(SPEC))
def test_the_strategies_take_a_spec_s_path(schedule, request):
    assert all(f.split(":")[0].split("=")[0] in {"snap"} or "::" in f for f in schedule)
    assert "==" in request


def test_a_strategy_given_something_else_says_what_it_takes():
    with pytest.raises(InvalidArgument, match="takes an AgentSpec or the path of a spec, not int"):
        fault_schedules(42)
