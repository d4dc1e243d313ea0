"""The assertion helpers: a failure is the printed counterexample and a replayable trace; budgets."""

import shutil

import pytest

from roar_formal import Budget, RoarError, load, load_spec
from roar_formal.testing import (RoarAssertionError, TestSettings, assert_conforms, assert_invariant,
                                 assert_no_deadlock,
                                 assert_no_livelock, assert_sequential_achievement, assert_succeeds,
                                 current_settings, using_settings)
from roar_formal.trace.format import read_trace


@pytest.fixture
def traces(tmp_path):
    with using_settings(TestSettings(traces=tmp_path / "traces")):
        yield tmp_path / "traces"


def test_a_deadlock_fails_with_its_counterexample_and_a_trace(models, traces):
    spec = load_spec(models / "faulty" / "mutual_make.roar")
    with pytest.raises(RoarAssertionError) as e:
        assert_no_deadlock(spec, "arm::started == true")
    msg = str(e.value)
    assert msg.splitlines()[0] == f"deadlock violated on {spec.path}, request arm::started == true"
    assert "  deadlock: violated — deadlock reachable in 27 steps" in msg
    assert "     18. door         make R2 to arm: arm::parked == true" in msg
    assert "    final state:" in msg and "wait(door::open == true, 100): until a variable of door changes" in msg
    assert "    wait-for cycle: arm -> door -> arm" in msg
    assert e.value.trace == traces / "mutual_make.deadlock.jsonl" and e.value.trace.is_file()
    assert f"trace: {e.value.trace}  (roar-verify replay {e.value.trace} --model {spec.path})" in msg
    header, steps = read_trace(e.value.trace)
    assert header["property"] == "deadlock" and len(steps) == 27
    assert e.value.exploration.violated("deadlock")
    fixed = assert_no_deadlock(models / "faulty" / "mutual_make_fixed.roar", "arm::started == true")
    assert fixed.holds("deadlock")


def test_a_livelock_fails_with_its_lasso(models, traces):
    with pytest.raises(RoarAssertionError, match=r"(?s)livelock violated on .*retry_forever.roar.*"
                                                 r"-- cycle \(repeats forever\) --"):
        assert_no_livelock(models / "faulty" / "retry_forever.roar", "hand::holding == true")
    assert assert_no_livelock(models / "faulty" / "retry_bounded.roar", "hand::holding == true").holds("livelock")


def test_an_invariant_on_a_clf_model(models, traces):
    dl = load(models / "philosophers" / "dl.clf")
    assert assert_invariant(dl, never="fork F * busy F").holds("invariant")
    with pytest.raises(RoarAssertionError) as e:
        assert_invariant(dl, never=["at1 P * at1 Q"])
    assert "forbidden pattern 'at1 P * at1 Q' (reached in 2 steps)" in str(e.value)
    assert "      1. [p0] take_first\n      2. [p1] take_first" in str(e.value)
    with pytest.raises(RoarError, match="never=.* or exclusive_writes=True"):
        assert_invariant(dl)


def test_sequential_achievement(models, traces):
    spec = load_spec(models / "faulty" / "ordered_pick.roar", functional=models / "faulty" / "reliable_tools.py")
    with pytest.raises(RoarAssertionError, match="in cell.work.clamp_then_drill, a command of the subtree of "
                                                 r"'make\(drill::drilled == true\)' started before"):
        assert_sequential_achievement(spec, "cell::done == true", budget={"max_states": 3000})


UNDOCKED = """
mission = ability {
  context = { { } { bool done = false; } { } }
  tasks = {
    charge_up = task {
      post = { {done == true} }
      recipes = {
        dock_then_charge = recipe {
          body = {
            make(dock::docked == true);
            make(battery::full == true);
            set done true;
          }
        }
      }
    }
  }
}
dock = ability {
  context = { { } { bool docked = false; } { } }
  tasks = {
    do_dock = task { post = { {docked == true} } recipes = { approach = recipe { body = { set docked true; } } } }
    undock = task { post = { {docked == false} } recipes = { back_off = recipe { body = { set docked false; } } } }
  }
}
battery = ability {
  context = { { } { bool full = false; } { } }
  tasks = {
    charge = task {
      post = { {full == true} }
      recipes = { trickle = recipe { body = { set full true; make(dock::docked == false); } } }
    }
  }
}
"""


def test_sequential_achievement_with_kept_agrees_with_a_property_file(tmp_path, traces):
    """Charging undocks the robot: the order of the sub-goals is kept (sequential achievement
    holds), but the first is undone. ``kept`` says so, as a property file's kept does."""
    from roar_formal.verify.check import run_job
    from roar_formal.verify.jobs import load_job
    spec_path = tmp_path / "undocked.roar"
    spec_path.write_text(UNDOCKED, encoding="utf-8")
    spec = load_spec(spec_path)
    recipe = "mission.charge_up.dock_then_charge"
    assert_sequential_achievement(spec, "mission::done == true", recipes=[recipe])
    with pytest.raises(RoarAssertionError, match=r"dock::docked == true no longer holds"):
        assert_sequential_achievement(spec, "mission::done == true", recipes=[recipe], kept=[recipe])
    with pytest.raises(RoarAssertionError, match=r"dock::docked == true no longer holds"):
        assert_sequential_achievement(spec, "mission::done == true", kept=True)
    (tmp_path / "p.toml").write_text(f'check = ["sequential-achievement"]\n[sequential-achievement]\n'
                                     f'kept = ["{recipe}"]\n', encoding="utf-8")
    (tmp_path / "j.toml").write_text('spec = "undocked.roar"\nrequest = "mission::done == true"\n'
                                     'properties = ["p.toml"]\n', encoding="utf-8")
    assert run_job(load_job(tmp_path / "j.toml")).verdicts["sequential-achievement"].status == "violated"
    with pytest.raises(RoarError, match="kept is True or a list of recipes"):
        assert_sequential_achievement(spec, "mission::done == true", kept=["dock_then_charge"])


def test_a_search_out_of_budget_fails_as_not_decided(models):
    ok = models / "philosophers" / "ok.clf"
    with pytest.raises(RoarAssertionError, match=r"deadlock not decided on .*ok.clf: no deadlock in \d+ states; "
                                                 r"search incomplete \(state budget of 10 reached\)"):
        assert_no_deadlock(ok, budget={"max_states": 10})
    assert assert_no_deadlock(ok, budget={"max_states": 10}, allow_incomplete=True).status("deadlock") == "incomplete"
    # the settings' budget applies unless the call gives one, key by key
    with using_settings(TestSettings(budget=Budget(max_states=10, max_seconds=60))):
        assert current_settings().budget.max_states == 10
        with pytest.raises(RoarAssertionError, match="not decided"):
            assert_no_deadlock(ok)
        assert assert_no_deadlock(ok, budget=Budget(max_states=100_000)).holds("deadlock")


def test_assert_succeeds_prints_the_run_and_writes_its_trace(examples, traces):
    spec = load_spec(examples / "pick" / "pick.roar")
    assert assert_succeeds(spec, "cell::lifted == true").ok
    with pytest.raises(RoarAssertionError) as e:
        assert_succeeds(spec, "cell::lifted == true", faults=["close_jaws:1"])
    lines = str(e.value).splitlines()
    assert lines[0] == "request cell::lifted == true ended in failure, not success"
    assert lines[1] == f"{spec.path}: request cell::lifted == true, faults close_jaws:1, seed 0"
    assert lines[-1] == f"  trace: {traces / 'pick.run.jsonl'}"
    assert e.value.run.outcome == "failure" and read_trace(e.value.trace)[0]["outcome"] == "failure"
    # a run cut by its step bound did not end: said so, with the bound (it said "ended in running")
    with pytest.raises(RoarAssertionError) as e:
        assert_succeeds(spec, "cell::lifted == true", max_steps=12)
    first = str(e.value).splitlines()[0]
    assert first.startswith("request cell::lifted == true did not finish within 12 steps (its request is ")


def test_a_target_needs_what_its_kind_needs(models, examples):
    with pytest.raises(RoarError, match="needs a request"):
        assert_no_deadlock(examples / "pick" / "pick.roar")
    with pytest.raises(RoarError, match="takes no request"):
        assert_no_deadlock(models / "clf" / "arith.clf", "x::y == 1")
    with pytest.raises(RoarError, match="'start' is for .clf models"):
        assert_no_deadlock(examples / "pick" / "pick.roar", "cell::lifted == true", start=2)
    with pytest.raises(TypeError, match="not int"):
        assert_no_deadlock(3)


def test_conformance_with_the_robot(models, tmp_path):
    req = "base::arrived == true where base::gx == 9.0 && base::gy == 3.0"
    door = models / "scenarios" / "door.toml"
    rep = assert_conforms(models / "door_nav.roar", req, door, runs=1, random_faults=False)
    assert rep.sound and len(rep.runs) == 1
    # the same spec, its binding declaring that no robot result is a successful plan
    shutil.copy(models / "door_nav.roar", tmp_path)
    module = (models / "door_nav.py").read_text(encoding="utf-8")
    (tmp_path / "door_nav.py").write_text(module.replace('PLANNED = Outcome("planned", True)',
                                                         'PLANNED = Outcome("planned", True, covers=lambda r: False)'),
                                          encoding="utf-8")
    with pytest.raises(RoarAssertionError, match=r"(?s)does not conform to the robot of .*door.toml.*NOT sound"):
        assert_conforms(tmp_path / "door_nav.roar", req, door, runs=1, random_faults=False)


def test_a_bad_clf_pattern_is_located_inside_its_quotes(models):
    # as a predicate in the spec's terms is: the column where the pattern starts on this line
    import inspect
    model = load(models / "philosophers" / "dl.clf")
    with pytest.raises(RoarError) as e:
        assert_invariant(model, never=["nosuchfamily P"])
    line = inspect.currentframe().f_lineno - 1
    text = open(__file__, encoding="utf-8").read().splitlines()[line - 1]
    assert e.value.pos.line == line and e.value.pos.col == text.index('"nosuchfamily P"') + 2
    assert "nosuchfamily" in e.value.message
