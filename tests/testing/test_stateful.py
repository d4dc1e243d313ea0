"""RoarMachine: hypothesis drives the executable model; invariants and built-in checks fail with the run.

Shrinking a stateful run takes ~15 s for the docs' example, so these tests run the generate phase
only (finding is what they check; the docs' excerpt of a shrunk run is checked line by line where
it does not depend on how far shrinking went).
"""

import importlib.util
import inspect
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis.stateful import invariant, run_state_machine_as_test

from roar_formal import RoarError
from roar_formal.testing import RoarMachine, load_spec

FIND = settings(max_examples=60, phases=[Phase.generate], database=None, deadline=None, derandomize=True,
                stateful_step_count=100, suppress_health_check=list(HealthCheck))
PASS = settings(FIND, max_examples=8)


def failure(machine, how=FIND) -> str:
    """The failure of a machine run: the message, its notes (the run, hypothesis' steps)."""
    with pytest.raises(AssertionError) as e:
        run_state_machine_as_test(machine, settings=how)
    return "\n".join([str(e.value), *getattr(e.value, "__notes__", [])])


@pytest.fixture(scope="module")
def docs_machine(examples):
    path = examples / "pick_machine" / "test_pick_machine.py"
    spec = importlib.util.spec_from_file_location("docs_pick_machine", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.PickMachine


def test_the_docs_machine_finds_the_busy_gripper(docs_machine, docs_shows):
    out = failure(docs_machine)
    assert out.startswith("the gripper is still busy when all is done")
    assert re.search(r"after \d+ steps; the run, one ROAR event a line:", out)
    assert "Draw" in out and "(outcome): 'gripper::close_jaws -> failure'" in out
    docs_shows("pick_machine", "AssertionError: " + out)


def test_the_docs_machine_passes_on_the_fixed_spec(docs_machine, examples):
    class Fixed(docs_machine):
        spec = load_spec(examples / "pick_fixed" / "pick.roar")

    run_state_machine_as_test(Fixed, settings=PASS)


def test_a_deadlock_is_found_by_the_built_in_check(models):
    class Mutual(RoarMachine):
        spec = models / "faulty" / "mutual_make.roar"       # a path works too
        request = "arm::started == true"

    out = failure(Mutual)
    assert out.startswith("deadlock: nothing can move, but a request is not final or a recipe is still live")
    assert "make R2 to arm: arm::parked == true" in out
    # who waits for whom, as `roar-verify check` explains a deadlock's final state
    assert "wait-for cycle: arm -> door -> arm" in out
    assert "door waits for arm: open_door.swing waits for R2 (arm::parked == true)" in out
    # a statement's step is drawn with the statement and its line (read off the spec's text here)
    lines = (models / "faulty" / "mutual_make.roar").read_text(encoding="utf-8").splitlines()
    for text in ("make(door::open == true)", "make(arm::parked == true)"):
        line = next(i for i, x in enumerate(lines, 1) if text in x)
        assert re.search(rf"\(step\): 'st\d+_make: {re.escape(text)} \(line {line}\)'", out), text


def test_the_built_in_checks_run_before_the_subclass_invariants(models):
    # Hypothesis runs invariants in the order of their names: one named to come first still
    # sees the built-in deadlock check fail before it
    class Mutual(RoarMachine):
        spec = models / "faulty" / "mutual_make.roar"
        request = "arm::started == true"

        @invariant()
        def a_user_check_failing_at_the_end(self):
            assert not self.quiescent, "the user's check"

    out = failure(Mutual)
    assert out.startswith("deadlock: nothing can move"), out[:200]


def test_never_patterns_and_one_engine_step_a_rule(examples):
    class NoFailure(RoarMachine):
        spec = load_spec(examples / "pick" / "pick.roar")
        request = "cell::lifted == true"
        never = ["rs R s_failure"]
        granularity = "step"

    out = failure(NoFailure)
    assert out.startswith("invariant violated: a reachable state matches the forbidden pattern 'rs R s_failure'")
    assert "close_jaws() = false" in out


def test_helpers_read_the_state_and_mistakes_are_reported(examples):
    seen = []

    class Reader(RoarMachine):
        spec = load_spec(examples / "pick_fixed" / "pick.roar")
        request = "cell::lifted == true"

        @invariant()
        def read(self):
            seen.append((self.value("cell::lifted"), self.quiescent, self.final))
            if self.quiescent:
                assert self.final and self.value("gripper::holding") is True
                with pytest.raises(RoarError, match="no variable 'cell::nope'"):
                    self.value("cell::nope")

    run_state_machine_as_test(Reader, settings=PASS)
    assert (False, False, False) in seen and (True, True, True) in seen

    class Unset(RoarMachine):
        spec = examples / "pick" / "pick.roar"

    with pytest.raises(RoarError, match="set the class attributes 'spec'"):
        Unset()

    class Odd(Reader):
        granularity = "rule"

    with pytest.raises(RoarError, match="granularity must be 'event' or 'step'"):
        Odd()

    line = inspect.currentframe().f_lineno + 3   # a bad pattern is reported where the class writes it

    class BadPattern(Reader):
        never = ["nosuch X"]

    with pytest.raises(RoarError, match="invariant pattern 'nosuch X': unknown type family 'nosuch'") as e:
        BadPattern()
    assert (e.value.pos.file, e.value.pos.line) == (__file__, line)


@pytest.mark.parametrize("predicate", ["gripper::busy == true && gripper::holding == true",
                                       "gripper::busy == true && cell::lifted == true"])
def test_never_predicates_in_the_spec_terms_agree_with_the_explorer(examples, predicate):
    """``never`` takes predicates in the spec's terms, as ``explore(never=...)`` and job files do;
    the explorer's verdict on the same predicate is the oracle."""
    spec = load_spec(examples / "pick_fixed" / "pick.roar")
    verdict = spec.explore("cell::lifted == true", never=[predicate]).verdicts["invariant"]

    class Machine(RoarMachine):
        request = "cell::lifted == true"
        never = [predicate]
    Machine.spec = spec

    if verdict.status == "violated":
        out = failure(Machine)
        assert out.startswith(f"invariant violated: a reachable state satisfies never {predicate!r}: ")
        assert "gripper::busy = true" in out
    else:
        assert verdict.status == "holds"
        run_state_machine_as_test(Machine, settings=PASS)


def test_never_names_no_event_in_a_machine(examples):
    class Events(RoarMachine):
        spec = load_spec(examples / "pick_fixed" / "pick.roar")
        request = "cell::lifted == true"
        never = ["primitive gripper::close_jaws starts"]

    with pytest.raises(RoarError, match="names an event"):
        Events()


def test_a_mistake_in_a_never_predicate_is_located_where_it_is_written(examples):
    class Typo(RoarMachine):
        spec = load_spec(examples / "pick_fixed" / "pick.roar")
        request = "cell::lifted == true"
        never = ["gripper::busy == true && gripper::holdin == true"]

    line = inspect.currentframe().f_lineno - 2
    with pytest.raises(RoarError) as e:
        Typo()
    text = 'never = ["gripper::busy == true && gripper::holdin == true"]'
    col = text.index("gripper::holdin") + 1 + len('        ')
    assert "has no variable 'holdin' (did you mean 'holding'?)" in e.value.message
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == (__file__, line, col)


def test_steps_no_agent_takes_are_drawn_as_the_framework():
    """An aborted activation's pending call still answers; the step that drops the answer is no
    agent's: hypothesis draws it under "framework", not under a rule name posing as an agent.
    Every reachable state's steps, as the machine offers them, are walked (no luck involved)."""
    class Aborting(RoarMachine):
        spec = Path(__file__).parent / "data" / "abort_pending_call.roar"
        request = "planner::done == true"

    setup = Aborting()._s
    by_agent: dict = {}
    seen = {setup.system.key(setup.start)}
    todo = [((), setup.start)]
    while todo:
        path, state = todo.pop()
        for k, (choice, agent, outcome) in enumerate(setup.enabled(path, state)):
            if outcome is None:
                by_agent.setdefault(agent, set()).add(choice.rule)
            nxt = setup.successor(path, state, k)[0]
            key = setup.system.key(nxt)
            if key not in seen:
                seen.add(key)
                todo.append((path + (k,), nxt))
    assert set(by_agent) == {"planner", "w", "framework"}
    assert by_agent["framework"] == {"drop_result"}
