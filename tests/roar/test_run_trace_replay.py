"""A run's trace (``roar-verify run --trace``) replays on the model: each answer of the functional
layer as the declared outcome rule that gives it, a run with crashes on the model compiled with
them, a timed run on the timed model; an answer no declared outcome gives is refused at its step
(verify/replay.py)."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from roar_formal.errors import RoarError
from roar_formal.testing import load_spec, replay
from roar_formal.verify.replay import replay_trace

from repo import ROOT

MODELS = ROOT / "models"
CONFLICT = (MODELS / "conflict.roar", "mission::done == true")
CAMERA = (MODELS / "faulty" / "camera_bounded.roar", "camera::taken == true")
MUTUAL = (MODELS / "faulty" / "mutual_make_fixed.roar", "arm::started == true")
TIMED = (ROOT / "tests" / "roar" / "data" / "timed_same.roar", "door::open == true")
ABSTRACT_READ = (ROOT / "tests" / "roar" / "data" / "abstract_read.roar", "loco::arrived == true")


def _records(path: Path) -> tuple[dict, list[dict]]:
    lines = path.read_text().splitlines()
    return json.loads(lines[0]), [json.loads(x) for x in lines[1:]]


def _write(path: Path, header: dict, records: list[dict]) -> None:
    path.write_text("\n".join(json.dumps(x) for x in [header, *records]) + "\n")


def _cli_run_and_replay(roar_cli, tmp_path, case, *options):
    spec, request = case
    trace = tmp_path / "run.jsonl"
    code, out, err = roar_cli("run", spec, "-r", request, "--trace", trace, *options)
    assert code in (0, 1) and "trace written to" in out, err
    code, out, err = roar_cli("replay", trace, "--model", spec)
    assert code == 0, err
    header, records = _records(trace)
    assert f"replayed {len(records)} steps: every step is a step of the model" in out
    assert f"confirmed: the request {request} ends in {header['outcome']}, as the run recorded" in out
    return trace, header, records, out


def test_run_with_primitives_replays_each_answer_as_its_outcome(roar_cli, tmp_path):
    trace, header, records, out = _cli_run_and_replay(roar_cli, tmp_path, CONFLICT)
    answered = [r["step"] for r in records if r["rule"] == "functional_layer"]
    assert len(answered) == 2 and header["outcome"] == "success"
    rep = replay(trace, CONFLICT[0])   # the library: the same replay
    assert rep.steps == len(records) and rep.confirmed is True
    back = replay_trace(trace, CONFLICT[0])
    assert [back.steps[i - 1]["rule"] for i in answered] == ["outcome_f_ptu_turn_to_turned"] * 2
    # the narration reads the outcome steps as the run's: the primitive ends as it did
    assert "turn_to(30) = true" in out and "turn_to(120) = true" in out


def test_run_with_a_forced_fault_replays(roar_cli, tmp_path):
    trace, header, records, out = _cli_run_and_replay(roar_cli, tmp_path, CAMERA, "--fault", "snap:1")
    assert header["faults"] == ["snap:1"]
    back = replay_trace(trace, CAMERA[0])
    rules = [back.steps[r["step"] - 1]["rule"] for r in records if r["rule"] == "functional_layer"]
    assert rules[0] == "outcome_f_camera_snap_blurred" and "outcome_f_camera_snap_sharp" in rules
    # and through the library, from a run the library made
    spec = load_spec(CONFLICT[0])
    report = spec.run(CONFLICT[1], faults=["turn_to:1"])
    path = report.save_trace(tmp_path / "lib.jsonl")
    rep = replay(path, CONFLICT[0])
    assert rep.confirmed is True
    assert replay_trace(path, CONFLICT[0]).steps[33]["rule"] == "outcome_f_ptu_turn_to_blocked"


def test_run_with_a_crash_records_it_and_replays(roar_cli, tmp_path):
    trace, header, records, out = _cli_run_and_replay(roar_cli, tmp_path, MUTUAL, "--crash", "door@10")
    assert header["crash"] == ["door"] and header["max_crashes"] == 1
    assert any(r["rule"] == "crash" for r in records) and header["outcome"] == "failure"
    back = replay_trace(trace, MUTUAL[0])
    assert back.compiled.crashes.agents == ("door",) and back.compiled.crashes.scheduled
    rep = replay(trace, MUTUAL[0])
    assert rep.confirmed is True and rep.steps == len(records)


def test_a_crash_the_header_does_not_record_says_the_instance_differs(roar_cli, tmp_path):
    trace, header, records, _out = _cli_run_and_replay(roar_cli, tmp_path, MUTUAL, "--crash", "door@10")
    del header["crash"], header["max_crashes"]
    old = tmp_path / "old.jsonl"
    _write(old, header, records)
    with pytest.raises(RoarError) as err:
        replay(old, MUTUAL[0])
    text = err.value.format()
    assert "step 9 (st1_make) cannot be replayed: st1_make is enabled here (1 instance), but not on the facts" in text
    assert "no such enabled step" not in text
    assert "consumed in the trace, not by the nearest instance: cep a_door" in text
    assert "its header records no crashes" in text


def test_timed_run_replays(roar_cli, tmp_path):
    trace, header, records, out = _cli_run_and_replay(roar_cli, tmp_path, TIMED, "--time", "timed")
    assert header["time"] == "timed"
    back = replay_trace(trace, TIMED[0])
    assert back.compiled.timing and back.confirmed is True


def test_a_read_abstracted_for_exploration_runs_its_task_on_replay(roar_cli, tmp_path):
    """The registry's ``agent::var`` entry abstracts a read for exploration only: a run runs the
    task, and the model a run's trace replays on does too."""
    _trace, _header, records, _out = _cli_run_and_replay(roar_cli, tmp_path, ABSTRACT_READ)
    assert not any(r["rule"] == "functional_layer" for r in records)


def _tampered(tmp_path) -> tuple[Path, int]:
    spec = load_spec(CONFLICT[0])
    path = spec.run(CONFLICT[1]).save_trace(tmp_path / "run.jsonl")
    header, records = _records(path)
    k = next(i for i, r in enumerate(records) if r["rule"] == "functional_layer")
    records[k]["produced"] = [re.sub(r"^return \(vbool tt\)", "return (vnum 7)", f) for f in records[k]["produced"]]
    assert records[k]["produced"][0].startswith("return (vnum 7) d#")
    bad = tmp_path / "tampered.jsonl"
    _write(bad, header, records)
    return bad, records[k]["step"]


def test_an_answer_no_outcome_gives_is_refused_at_its_step(roar_cli, tmp_path):
    bad, n = _tampered(tmp_path)
    with pytest.raises(RoarError) as err:
        replay(bad, CONFLICT[0])
    text = err.value.format()
    assert f"step {n} (functional_layer) cannot be replayed: the recorded answer of 'ptu::turn_to' is none " \
           "that a declared outcome produces" in text
    assert "the recorded answer: return (vnum 7) d#" in text
    assert "outcome_f_ptu_turn_to_turned: return (vbool tt)" in text
    assert "outcome_f_ptu_turn_to_blocked: return (vbool ff)" in text
    code, out, err_text = roar_cli("replay", bad, "--model", CONFLICT[0])
    assert code == 2 and f"step {n} (functional_layer) cannot be replayed" in err_text


def test_an_answer_beyond_the_failure_budget_is_refused(tmp_path):
    shutil.copy(MODELS / "faulty" / "retry_forever.roar", tmp_path / "grip.roar")
    (tmp_path / "grip.py").write_text(
        "from roar_formal.roar.functional import Outcome, Registry\n\n"
        "def registry():\n    reg = Registry()\n"
        "    reg.register('grip', lambda: True, outcomes=[Outcome('closed', True), Outcome('slipped', False)],"
        " max_failures=1)\n    return reg\n")
    spec = load_spec(tmp_path / "grip.roar")
    ok = spec.run("hand::holding == true", faults=["grip:1"]).save_trace(tmp_path / "one.jsonl")
    assert replay(ok, tmp_path / "grip.roar").confirmed is True   # one failure: within the budget
    two = spec.run("hand::holding == true", faults=["grip:1", "grip:2"]).save_trace(tmp_path / "two.jsonl")
    with pytest.raises(RoarError) as err:
        replay(two, tmp_path / "grip.roar")
    text = err.value.format()
    assert "(functional_layer) cannot be replayed: the recorded answer of 'hand::grip' is none that a declared " \
           "outcome enabled here produces" in text
    assert "failure budget, max_failures, is spent" in text


def test_timed_run_with_primitives_a_fault_and_a_crash_replays(roar_cli, tmp_path):
    _trace, header, records, _out = _cli_run_and_replay(roar_cli, tmp_path, CONFLICT, "--time", "timed",
                                                        "--fault", "turn_to:2", "--crash", "ptu@40")
    assert header["time"] == "timed" and header["crash"] == ["ptu"]
    assert {"functional_layer", "crash", "back"} <= {r["rule"] for r in records}


def test_an_opaque_value_of_the_run_stands_as_the_outcomes(tmp_path):
    """A Python object a primitive returns (an opaque type: the spec cannot look into it) is the
    run's ``vopq K``; the declared outcome makes one of its own, which stands for any: the run's
    replays as the outcome's, in the steps that pass it on as well."""
    (tmp_path / "cam.roar").write_text(CAM_SPEC)
    (tmp_path / "cam.py").write_text(
        "from roar_formal.roar.functional import Outcome, Registry\n\n"
        "def registry():\n    reg = Registry()\n"
        "    reg.register('snap', lambda: object(), outcomes=[Outcome('image', True)])\n"
        "    reg.register('store', lambda img: True, outcomes=[Outcome('stored', True), Outcome('full', False)])\n"
        "    return reg\n")
    path = load_spec(tmp_path / "cam.roar").run("cam::done == true").save_trace(tmp_path / "run.jsonl")
    assert "(vopq 1)" in path.read_text()
    rep = replay(path, tmp_path / "cam.roar")
    assert rep.confirmed is True


CAM_SPEC = """cam = ability {
  context = {
    { }
    { bool done = false; img last; }
    { }
  }
  export = {
    { img = opaquetype; }
    { img snap(); bool store(img); }
    { }
  }
  tasks = {
    shoot = task {
      pre = { }
      post = { {done == true} }
      recipes = {
        once = recipe {
          body = {
            set last snap();
            assert(store(last));
            set done true;
          }
        }
      }
    }
  }
}
"""


def test_an_answer_an_outcome_covers_replays_as_that_outcome(tmp_path):
    """spa_loop's odometry answers the robot's position (1, 2, ... 6 as it moves) where the
    declared outcome 'moving' stands for any position but the goal, written 3: each such answer
    replays as the outcome that covers it, its value read as the outcome's in the steps after,
    and replay says so (the trace was refused at its first odometry answer)."""
    spec = load_spec(ROOT / "models" / "spa_loop.roar")
    run = spec.run("exec::arrived == true where exec::goal == 7")
    assert run.ok
    trace = run.save_trace(tmp_path / "spa.jsonl")
    rep = replay(trace, ROOT / "models" / "spa_loop.roar")
    assert rep.confirmed is True and rep.steps == run.clf_steps
    note = " ".join(rep.notes)
    assert "were read as the declared outcome that covers them" in note and "(vnum 1) as (vnum 3)" in note
    # an answer no outcome covers is still refused (the goal's outcome covers 7 only, 'moving' all
    # but 7: a bool where a number is declared is covered by none)
    header, *lines = trace.read_text(encoding="utf-8").splitlines()
    records = [json.loads(x) for x in lines]
    k = next(i for i, r in enumerate(records) if r["rule"] == "functional_layer"
             and r["produced"][0].startswith("return (vnum 1) "))
    records[k]["produced"] = [records[k]["produced"][0].replace("(vnum 1)", "(vbool tt)")]
    bad = tmp_path / "bad.jsonl"
    bad.write_text("\n".join([header] + [json.dumps(r) for r in records]) + "\n", encoding="utf-8")
    with pytest.raises(RoarError, match="is none that a declared outcome"):
        replay(bad, ROOT / "models" / "spa_loop.roar")


def test_a_run_with_struct_and_opaque_answers_replays(tmp_path):
    """mana_nav's planner returns a Python tuple for an opaque ``trajectory`` (a handle the
    model's outcome stands for, not a record), and odometry a point struct that the outcome
    ``en_route`` covers (written (0, 0) by the model) while the run's robot is at (0.6, 0.8):
    the run's trace replays step for step and confirms the outcome. The distance answered then
    (4.2, 3.2, ...: 'far', written 5 by the model) is read as 5 only where the answer went, not
    in the goal (3, 4) the same facts hold (a blanket rewrite read the goal as (3, 5))."""
    spec = load_spec(MODELS / "mana_nav.roar")
    run = spec.run("locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0")
    assert run.ok
    assert any(re.fullmatch(r"planner::traj = <opaque \d+>", e.text) for e in run.events)
    trace = run.save_trace(tmp_path / "nav.jsonl")
    rep = replay(trace, MODELS / "mana_nav.roar")
    assert rep.confirmed is True and rep.steps == run.clf_steps
    note = " ".join(rep.notes)
    assert "(vrec (vcons (vnum 0.6) (vcons (vnum 0.8) vnil))) as (vrec (vcons (vnum 0) (vcons (vnum 0) vnil)))" in note
    assert "(vnum 4) as (vnum 5)" in note


def test_answered_values_are_read_occurrence_by_occurrence():
    from roar_formal.explore.replay import reads_as
    four = {"(vnum 4)": "(vnum 5)"}
    assert reads_as("ctl (vnum 4) (vrec (vnum 3) (vnum 4))", "ctl (vnum 5) (vrec (vnum 3) (vnum 4))", four)
    assert reads_as("ctl (vnum 4) (vnum 4)", "ctl (vnum 4) (vnum 4)", four)
    assert not reads_as("ctl (vnum 4) (vnum 4)", "ctl (vnum 5) (vnum 6)", four)
    assert not reads_as("ctl (vnum 3)", "ctl (vnum 5)", four)
    # a struct answered is one occurrence: its parts are not read apart
    pt = {"(vrec (vnum 4) (vnum 4))": "(vrec (vnum 0) (vnum 0))", **four}
    assert reads_as("p (vrec (vnum 4) (vnum 4)) (vnum 4)", "p (vrec (vnum 0) (vnum 0)) (vnum 5)", pt)
    assert not reads_as("p (vrec (vnum 4) (vnum 4))", "p (vrec (vnum 5) (vnum 4))", pt)


def test_a_trace_whose_events_were_edited_is_refused_at_that_line(roar_cli, tmp_path):
    """Replay re-derives each step's ROAR events: a recorded event that says something else
    (``tca-check`` and the reports read these fields) is refused at its line; an unedited
    trace replays. Lines are counted in the file, blank lines included."""
    trace, header, records, _out = _cli_run_and_replay(roar_cli, tmp_path, MUTUAL)
    k = next(i for i, r in enumerate(records) if r["event"] and r["event"].get("kind") == "write")
    ev = records[k]["event"]
    forged = [dict(r) for r in records]
    forged[k] = {**records[k], "event": {**ev, "text": ev["text"] + "0"}}
    out = tmp_path / "forged.jsonl"
    out.write_text(json.dumps(header) + "\n\n" + "\n".join(json.dumps(x) for x in forged) + "\n")
    with pytest.raises(RoarError) as e:
        replay_trace(out, MUTUAL[0])
    assert e.value.pos.line == k + 3 and f"step {records[k]['step']}: the trace records" in e.value.message
    # a step whose event was dropped, and a step that gained one
    for edit in ({"event": None}, ):
        forged[k] = {**records[k], **edit}
        _write(out, header, forged)
        with pytest.raises(RoarError, match="the trace's events do not describe its steps"):
            replay_trace(out, MUTUAL[0])
    quiet = next(i for i, r in enumerate(records) if r["event"] is None)
    forged = [dict(r) for r in records]
    forged[quiet] = {**records[quiet], "event": ev}
    _write(out, header, forged)
    with pytest.raises(RoarError) as e:
        replay_trace(out, MUTUAL[0])
    assert e.value.pos.line == quiet + 2 and "makes no event" in e.value.message


def test_a_step_missing_from_a_trace_is_named_where_the_replay_stops(roar_cli, tmp_path):
    trace, header, records, _out = _cli_run_and_replay(roar_cli, tmp_path, MUTUAL)
    out = tmp_path / "dropped.jsonl"
    for k in range(1, len(records) - 1):   # the first record whose loss the next step notices
        _write(out, header, records[:k] + records[k + 1:])
        try:
            replay_trace(out, MUTUAL[0])
        except RoarError as e:
            assert e.pos.line == k + 2   # the record after the gap (header on line 1)
            assert f"the trace has no step {records[k]['step']}: a step missing" in e.format()
            return
    raise AssertionError("no dropped step was noticed")


def test_a_timed_run_the_step_bound_stops_before_a_tick_is_not_quiescent():
    # the run to its end takes the clock's ticks when nothing else can happen; bounded to the
    # step before each tick, the run stopped with the clock still able to advance: not quiescent
    # (it said quiescent, as a deadlock would, when the bound fell just there)
    from roar_formal.roar.run import TICK_RULE
    spec = load_spec(ROOT / "tests" / "roar" / "data" / "wait_timeout.roar")
    whole = spec.run("door::open == true", time="timed", wait_timeout=100)
    assert whole.outcome == "failure" and whole.quiescent
    ticks = [i + 1 for i, s in enumerate(whole.result.steps) if s[0] == TICK_RULE]
    assert ticks
    for k in ticks:
        cut = spec.run("door::open == true", time="timed", wait_timeout=100, max_steps=k - 1)
        assert cut.clf_steps == k - 1 and cut.outcome == "running"
        assert not cut.quiescent
    # and bounded past the end, the run is the whole one
    assert spec.run("door::open == true", time="timed", wait_timeout=100,
                    max_steps=whole.clf_steps + 1).quiescent
