"""The testing library refuses what cannot have been meant, as the command line does: a fault that
names no function or matched no call; it reads `never` as a job file does; it checks by default what
`roar-verify check` checks on a spec."""

from __future__ import annotations

import inspect
import linecache

import pytest
from hypothesis import given, settings

from roar_formal import AgentSpec, RoarError, load_clf, load_spec
from roar_formal.testing import assert_invariant, assert_succeeds, fault_schedules
from roar_formal.testing.api import SPEC_DEFAULTS, ScheduledFault
from roar_formal.verify.jobs import SPEC_DEFAULTS as CHECK_DEFAULTS

REQUEST = "cell::lifted == true"
UNUSED = "no such call happened in this run (check the name and the call number)"


@pytest.fixture(scope="module")
def pick(examples) -> AgentSpec:
    return load_spec(examples / "pick_fixed" / "pick.roar")   # succeeds without faults; close_jaws is called once


def _line() -> int:
    return inspect.currentframe().f_back.f_lineno


# ------------------------------------------------------------------ faults


@pytest.mark.parametrize("fault", ["close_jaw", "close_jaw:1", "close_jaw=broken", "gripper::close_jaw:1"])
def test_a_fault_naming_no_function_is_an_error_with_a_did_you_mean(pick, fault):
    name = fault.split(":1")[0].split("=")[0]
    message = (f"--fault {fault}: the spec has no function '{name}' (did you "
               f"mean '{name}s'?); its functions: close_jaws (checked before the run)")
    with pytest.raises(RoarError) as e:
        assert_succeeds(pick, REQUEST, faults=[fault])
    assert e.value.message == message
    for strict in (None, False, True):   # whatever the strictness: it cannot match a call of any run
        with pytest.raises(RoarError) as e:
            pick.run(REQUEST, faults=[fault], strict_faults=strict)
        assert e.value.message == message


def test_a_fault_the_spec_cannot_use_is_located_where_the_test_writes_it(pick):
    """As a pattern or a predicate is: the test file, its line, the column inside the quotes."""
    line = _line() + 2
    with pytest.raises(RoarError) as e:
        assert_succeeds(pick, REQUEST, faults=["close_jaw:1"])
    text = linecache.getline(__file__, line)
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == (__file__, line, text.index('"close_jaw:1"') + 2)
    line = _line() + 2
    with pytest.raises(RoarError) as e:
        pick.run(REQUEST, faults=["close_jaws:5"])
    assert e.value.pos.line == line and e.value.message == f"--fault close_jaws:5: {UNUSED}"
    line = _line() + 2
    with pytest.raises(RoarError) as e:
        pick.explore(REQUEST, ["deadlok"])
    text = linecache.getline(__file__, line)
    assert (e.value.pos.line, e.value.pos.col) == (line, text.index('"deadlok"') + 2)


def test_a_fault_naming_nothing_close_has_no_did_you_mean(pick):
    with pytest.raises(RoarError) as e:
        pick.run(REQUEST, faults=["zzz:2"])
    assert e.value.message == ("--fault zzz:2: the spec has no function 'zzz'; "
                               "its functions: close_jaws (checked before the run)")


def test_a_fault_that_matched_no_call_is_the_command_lines_error(pick, run_cli):
    with pytest.raises(RoarError) as e:
        pick.run(REQUEST, faults=["close_jaws:5"])
    assert e.value.message == f"--fault close_jaws:5: {UNUSED}"
    code, _out, err = run_cli("run", pick.path, "-r", REQUEST, "--fault", "close_jaws:5")
    assert code == 2 and e.value.message in " ".join(err.split())
    with pytest.raises(RoarError) as e:   # the helper too: a test with it would check nothing
        assert_succeeds(pick, REQUEST, faults=["close_jaws:5", "close_jaws:1"])
    assert e.value.message == f"--fault close_jaws:5: {UNUSED}"


def test_strict_faults_false_is_the_opt_out(pick):
    run = pick.run(REQUEST, faults=["close_jaws:5"], strict_faults=False)
    assert run.ok and run.unused_faults == ("close_jaws:5",)
    assert assert_succeeds(pick, REQUEST, faults=["close_jaws:5"], strict_faults=False).unused_faults \
        == ("close_jaws:5",)


def test_a_generated_schedule_may_name_calls_the_run_never_makes(pick):
    run = pick.run(REQUEST, faults=[ScheduledFault("close_jaws:3")])
    assert run.ok and run.unused_faults == ("close_jaws:3",) and run.faults == ("close_jaws:3",)
    with pytest.raises(RoarError, match="close_jaws:3: no such call happened"):
        pick.run(REQUEST, faults=[ScheduledFault("close_jaws:3")], strict_faults=True)
    with pytest.raises(RoarError) as e:   # one written by hand beside it is still refused, alone
        pick.run(REQUEST, faults=[ScheduledFault("close_jaws:3"), "close_jaws:4"])
    assert e.value.message == f"--fault close_jaws:4: {UNUSED}"

    @settings(max_examples=10, deadline=None, database=None)
    @given(fault_schedules(pick, max_faults=2, max_call=3))
    def check(faults):
        assert all(isinstance(f, ScheduledFault) for f in faults)
        run = pick.run(REQUEST, faults=faults)   # no error: unused ones are listed
        assert set(run.unused_faults) <= set(faults)

    check()


# ------------------------------------------------------------------ never, in the spec's terms


def test_never_takes_predicates_in_the_specs_terms_as_a_job_file_does(pick):
    res = pick.explore(REQUEST, ["deadlock"], never=["gripper::holding == true && cell::lifted == false"])
    assert res.violated("invariant")
    assert res.verdict("invariant").message.startswith(
        "a reachable state satisfies never 'gripper::holding == true && cell::lifted == false': "
        "gripper::holding = true; cell::lifted = false")
    assert res.counterexample("invariant").kind == "path"
    assert pick.explore(REQUEST, ["deadlock"], never=["request R0 failed"]).holds("invariant")
    assert_invariant(pick, REQUEST, never=["cell::lifted == true && gripper::holding == false"])


def test_never_still_takes_clf_patterns(pick):
    res = pick.explore(REQUEST, ["deadlock"], never=["rs R s_failure"])
    assert res.holds("invariant")


def test_a_mistake_in_a_predicate_is_located_at_the_caller_with_a_did_you_mean(pick):
    line = _line() + 2
    with pytest.raises(RoarError) as e:
        pick.explore(REQUEST, ["deadlock"], never=["gripper::holdin == true"])
    assert e.value.pos.file == __file__ and e.value.pos.line == line
    assert e.value.pos.col == linecache.getline(__file__, line).index("gripper::holdin") + 1   # inside the string
    assert "agent 'gripper' has no variable 'holdin' (did you mean 'holding'?)" in e.value.message
    with pytest.raises(RoarError, match=r"unexpected character '='.*\(equality is '=='\)"):
        pick.explore(REQUEST, ["deadlock"], never=["cell::lifted = true"])


def test_a_clf_model_says_it_takes_clf_patterns(models):
    model = load_clf(models / "clf" / "arith.clf")
    with pytest.raises(RoarError, match="written in the spec's terms: it needs an agent spec"):
        model.explore(never=["cell::lifted == true"])


# ------------------------------------------------------------------ the default properties


def test_explore_checks_by_default_what_roar_verify_check_checks_on_a_spec(pick, run_cli):
    assert SPEC_DEFAULTS == tuple(CHECK_DEFAULTS) == ("deadlock", "mission-completion", "mission-failure")
    res = pick.explore(REQUEST)
    assert tuple(res.verdicts) == SPEC_DEFAULTS
    code, out, _err = run_cli("check", pick.path, "--request", REQUEST, "--no-traces")
    shown = [line.split(":")[0].strip() for line in out.splitlines() if "(a default property)" in line]
    assert code in (0, 1) and tuple(shown) == SPEC_DEFAULTS   # 1: a default property is violated
    for p in SPEC_DEFAULTS:
        assert res.verdict(p).message.endswith("(a default property)")
    with_never = pick.explore(REQUEST, never=["request R0 failed"])
    assert tuple(with_never.verdicts) == SPEC_DEFAULTS + ("invariant",)
    assert "livelock" in pick.explore(REQUEST, ["deadlock", "livelock"]).verdicts   # named, it is checked
