"""Checking hand-written traces against the axioms and declared constraints."""

from __future__ import annotations

from pathlib import Path

import pytest

from roar_formal.tca.axioms import THEORY
from roar_formal.tca.check import BY_CONSTRUCTION, GROUNDED, check_trace
from roar_formal.tca.evaluate import LATE, UNKNOWN, compile_formula
from roar_formal.tca.tasktree import build_tree
from roar_formal.tca.trace_events import read_events

TRACES = Path(__file__).parent / "traces"


def check(name):
    return check_trace(TRACES / f"{name}.jsonl")


@pytest.mark.parametrize("name", ["seq_ach_ok", "delay_planning_ok", "truncated_ok", "engine_mixed"])
def test_conforming_traces_have_no_violation(name):
    report = check(name)
    assert report.ok, [v.explanation for v in report.violations]
    assert report.instances > 0


def test_sequential_achievement_violation_is_explained():
    report = check("seq_ach_violated")
    (v,) = report.violations
    assert v.rule == "seq_ach" and v.source == "theorem seq_ach_subtrees"
    assert v.messages == ("goto_a", "goto_b", "drive_a", "drive_b")
    assert "drive_a (goto_a > drive_a) ends at 5" in v.explanation
    assert "drive_b (goto_b > drive_b) starts at 4.5" in v.explanation
    assert "2 pair(s)" in v.explanation  # drive_a and watch_a both overlap drive_b
    assert 5 in v.lines  # the seq_ach declaration


def test_a_prefix_is_judged_on_what_it_showed():
    (v,) = check("truncated_violated").violations
    assert v.rule == "seq_ach" and "has not ended when the trace stops" in v.explanation


def test_planning_of_the_first_subtree_must_end_before_the_second_executes():
    """Commands are in order, yet goto_a's own handling (planning) ends at 5.5,
    after drive_b starts: axiom 7 puts it inside goto_a's achievement, which
    SeqAch orders before goto_b's. Only the solver sees it (goals' achievement
    is not in the trace)."""
    (v,) = check("goal_planning_late").violations
    assert v.source == "axioms together"
    assert set(v.rule.split("+")) == {"d_seq_ach", "a7_goal", "a8_nesting", "a7_command"}
    assert set(v.messages) == {"goto_a", "goto_b", "drive_b"}
    assert "5.5 <= ach.end(goto_a)" in v.explanation


def test_delay_planning_violation():
    (v,) = check("delay_planning_violated").violations
    assert "d_delay_planning" in v.rule and {"goto_a", "goto_b"} <= set(v.messages)


def test_declared_precedes_violation():
    (v,) = check("precedes_violated").violations
    assert v.rule == "a5_precedes" and v.messages == ("drive_a", "watch_a")
    assert "end(drive_a) = 5" in v.explanation and "start(watch_a) = 2.2" in v.explanation


def test_observed_achievement_intervals_are_checked_directly():
    report = check("achievement_observed_bad")
    assert report.residual == 0
    rules = {v.rule: v for v in report.violations}
    assert set(rules) == {"a7_command", "a8_nesting"}
    assert rules["a8_nesting"].messages == ("goto_a", "drive_a")
    assert "ach.end(drive_a) = 5" in rules["a8_nesting"].explanation


def test_ill_formed_tree_problems_are_reported():
    texts = [v.explanation for v in check("ill_formed").violations if v.rule == "well_formed"]
    for words in ("sent twice", "started twice", "ghost, which was never sent", "has end but no start",
                  "parent nobody", "cycle", "phantom"):
        assert any(words in t for t in texts), words


def test_child_sent_after_its_parent_was_handled(tmp_path):
    text = (TRACES / "seq_ach_ok.jsonl").read_text().replace(
        '"time": 3.0, "event": "constraint_sent", "msg": "drive_b"', '"time": 3.5, "event": "constraint_sent", "msg": "drive_b"')
    path = tmp_path / "late_child.jsonl"
    path.write_text(text)
    (v,) = check_trace(path).violations
    assert v.rule == "a1_sent_by_parent" and v.messages == ("goto_b", "drive_b")
    assert "sent(drive_b) = 3.5" in v.explanation and "end(goto_b) = 3" in v.explanation


def test_every_axiom_is_checked_or_holds_by_construction():
    names = {a.name for a in THEORY}
    assert set(GROUNDED) | set(BY_CONSTRUCTION) == names
    assert not set(GROUNDED) & set(BY_CONSTRUCTION)


def test_tree_numbering_gives_descendants():
    tree, problems = build_tree(read_events(TRACES / "seq_ach_ok.jsonl"))
    assert not problems
    assert tree.is_desc("nav", "drive_b") and tree.is_desc("goto_a", "q_map")
    assert not tree.is_desc("goto_a", "drive_b") and not tree.is_desc("nav", "nav")
    assert tree.path("nav", "drive_a") == ["nav", "goto_a", "drive_a"]


def test_three_valued_evaluation():
    import z3

    x, y = z3.Reals("x y")
    f = compile_formula(z3.Or(x < y, y < 0), [x, y])
    assert f((1, 2), None) is True
    assert f((UNKNOWN, -1), None) is True  # the other disjunct decides
    assert f((UNKNOWN, 1), None) is UNKNOWN
    assert f((LATE, 5), None) is False  # a time after the trace is above every known time
    assert compile_formula(x < y, [x, y])((3, LATE), None) is True
