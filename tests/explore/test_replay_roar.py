"""Replay at the model's level: ROAR events by default, the trace's claim confirmed on the model,
an interactive mode (roar-verify replay, verify/replay.py)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from roar_formal.clf.query import with_big_stack
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.verify.replay import replay_trace
from roar_formal.verify.report import counterexample_report

from repo import ROOT
CHECKER = ROOT / "checker"
FAULTY = ROOT / "models" / "faulty"

CASES = {   # job -> (property, spec, functional module)
    "mutual_make.toml": ("deadlock", FAULTY / "mutual_make.roar", None),
    "retry_forever.toml": ("livelock", FAULTY / "retry_forever.roar", None),
    "ordered_pick.toml": ("sequential-achievement", FAULTY / "ordered_pick.roar", FAULTY / "reliable_tools.py"),
}
_results: dict = {}


def counterexample(name: str, folder: Path):
    """(job result, saved trace) of a bundled seeded fault's counterexample."""
    if name not in _results:
        _results[name] = with_big_stack(lambda: run_job(load_job(CHECKER / name)))
    res = _results[name]
    return res, save_counterexample(res, CASES[name][0], folder)


def truncated(trace: Path, keep: int, out: Path) -> Path:
    """The trace with only its first ``keep`` steps (same header, so the same fingerprint)."""
    lines = trace.read_text(encoding="utf-8").splitlines()
    out.write_text("\n".join(lines[: 1 + keep]) + "\n", encoding="utf-8")
    return out


@pytest.mark.parametrize("name", sorted(CASES))
def test_replay_reads_the_counterexample_as_the_checker_reported_it(tmp_path, name):
    """Two readings of one path agree: the ROAR events and variable changes replay narrates from
    the engine's steps are those the checker's report gave for the explored path."""
    res, trace = counterexample(name, tmp_path)
    prop, spec, fn = CASES[name]
    rep = with_big_stack(lambda: replay_trace(trace, spec, functional=fn))
    report = counterexample_report(res, prop)
    assert [[e["text"] for e in s["events"]] for s in rep.steps] == \
           [[e["text"] for e in s["events"]] for s in report["steps"]]
    assert [s["changes"] for s in rep.steps] == [s["changes"] for s in report["steps"]]
    assert rep.state_table(len(rep.steps)) == report["final"]
    assert rep.confirmed is True, rep.confirmation


def test_the_command_prints_roar_events_and_confirms_the_deadlock(tmp_path, roar_cli):
    _res, trace = counterexample("mutual_make.toml", tmp_path)
    code, out, _err = roar_cli("replay", trace, "--model", FAULTY / "mutual_make.roar")
    assert code == 0
    assert "make R1 to door: door::open == true" in out        # a ROAR event, not CLF facts
    assert "contains v_" not in out
    assert "wait-for cycle: arm -> door -> arm" in out
    assert "confirmed: the final state is a deadlock" in out
    code, verbose, _err = roar_cli("replay", trace, "--model", FAULTY / "mutual_make.roar", "-v")
    assert code == 0 and "contains v_door_open (vbool ff)" in verbose   # -v adds the CLF step


@pytest.mark.parametrize("name,keep,why", [
    ("mutual_make.toml", -3, "not a deadlock: "),
    ("ordered_pick.toml", 20, "breaks no sequential-achievement pair"),
])
def test_a_trace_cut_short_is_not_confirmed(tmp_path, roar_cli, name, keep, why):
    """Every step still replays, but the end no longer shows the violation: exit 1."""
    _res, trace = counterexample(name, tmp_path)
    n = len(trace.read_text(encoding="utf-8").splitlines()) - 1
    cut = truncated(trace, keep if keep > 0 else n + keep, tmp_path / "cut.jsonl")
    _prop, spec, fn = CASES[name]
    argv = ["replay", cut, "--model", spec] + (["--functional", fn] if fn else [])
    code, out, _err = roar_cli(*argv)
    assert code == 1
    assert "NOT CONFIRMED" in out and why in out


def test_a_clf_deadlock_is_confirmed_and_a_cut_one_is_not(tmp_path, roar_cli):
    res = run_job(load_job(CHECKER / "philosophers_dl5.toml"))
    trace = save_counterexample(res, "deadlock", tmp_path)
    model = ROOT / "models" / "philosophers" / "dl.clf"
    code, out, _err = roar_cli("replay", trace, "--model", model)
    assert code == 0 and "confirmed: the final state is a deadlock: no step is enabled" in out
    assert "[p1] take_first" in out                    # a .clf model's steps stay CLF steps (as check prints them)
    cut = truncated(trace, res.verdicts["deadlock"].counterexample.length() - 1, tmp_path / "cut.jsonl")
    code, out, _err = roar_cli("replay", cut, "--model", model)
    # with p0..p3 holding their first fork, p4 can take its first, and p3 its second (p4's, still free)
    assert code == 1 and "not a deadlock: 2 step(s) are enabled where the replayed path ends (take_first, take_second)" in out


def test_interactive_replay_steps_back_and_shows_agents(tmp_path, roar_cli, monkeypatch):
    _res, trace = counterexample("mutual_make.toml", tmp_path)
    n = len(trace.read_text(encoding="utf-8").splitlines()) - 1
    monkeypatch.setattr("sys.stdin", io.StringIO("n\nn\nb\ns\na door\na nobody\nj 99\ne\ns\nq\n"))
    code, out, _err = roar_cli("replay", trace, "--model", FAULTY / "mutual_make.roar", "-i")
    assert code == 0
    assert f"{n} steps; commands:" in out
    assert "R0 sent -> pending  (arm::started == true)" in out        # step 1
    assert "back to the state after step 1" in out
    assert "state after step 1:" in out and "request R0 arm::started == true: pending" in out
    assert "no agent 'nobody'; the agents are: arm, door" in out
    assert f"j N: N from 0 to {n}" in out
    assert "wait-for cycle: arm -> door -> arm" in out                 # `s` at the end
    assert f"[{n}/{n}]>" in out


def test_replay_json_of_the_check_and_the_replay_name_the_same_requests(tmp_path, roar_cli):
    """The requests the replay labels (R0, R1, ...) are the checker's labels."""
    res, trace = counterexample("ordered_pick.toml", tmp_path)
    rep = with_big_stack(lambda: replay_trace(trace, FAULTY / "ordered_pick.roar",
                                              functional=FAULTY / "reliable_tools.py"))
    assert rep.requests == counterexample_report(res, "sequential-achievement")["requests"]
    assert json.dumps(rep.steps)   # plain data


def test_replay_draws_the_chart_the_checker_draws(tmp_path, roar_cli):
    """The chart of a replayed deadlock has the arrows and wait-for cycle of the checker's chart."""
    from roar_formal.verify.pictures import chart_of_report, sequence_chart
    from roar_formal.verify.report import replay_report
    res, trace = counterexample("mutual_make.toml", tmp_path)
    code, out, _err = roar_cli("replay", trace, "--model", FAULTY / "mutual_make.roar",
                               "--png", tmp_path / "r.png", "--svg", tmp_path / "r.svg")
    assert code == 0 and f"chart written to {tmp_path / 'r.png'}" in out
    assert (tmp_path / "r.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "r.svg").read_text().lstrip().startswith("<?xml")
    rep = with_big_stack(lambda: replay_trace(trace, FAULTY / "mutual_make.roar"))
    _f, _a, mine = chart_of_report(replay_report(rep), "t", "t")
    _f, _a, theirs = sequence_chart(res, "deadlock")
    assert [(a, b, label) for a, b, label, _x in mine["arrows"]] == \
           [(a, b, label) for a, b, label, _x in theirs["arrows"]]
    assert [(a, b) for a, b, _x in mine["cycle"]] == [(a, b) for a, b, _x in theirs["cycle"]] == \
           [("arm", "door"), ("door", "arm")]


def test_run_draws_its_chart_and_never_overwrites_an_input(tmp_path, roar_cli):
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.run import run_model
    from roar_formal.roar.spec import load_spec
    from roar_formal.verify.pictures import chart_of_report
    from roar_formal.verify.report import run_report
    spec = FAULTY / "mutual_make_fixed.roar"
    code, out, _err = roar_cli("run", spec, "-r", "arm::started == true", "--svg", tmp_path / "run.svg")
    assert code == 0 and "chart written to" in out and (tmp_path / "run.svg").stat().st_size > 1000
    model = compile_spec(load_spec(spec), "arm::started == true", functional="python")
    _f, _a, art = chart_of_report(run_report(run_model(model, seed=0)), "t", "t")
    assert set(art["lifelines"]) == {"arm", "door"}
    assert [(a, b, label) for a, b, label, _x in art["arrows"]] == [
        ("arm", "door", "9. make R1: door::open == true"), ("door", "arm", "18. make R2: arm::parked == true")]
    before = spec.read_bytes()
    code, _out, err = roar_cli("run", spec, "-r", "arm::started == true", "--png", spec)
    assert code == 2 and "is an input of this command; refusing to overwrite it" in err
    assert spec.read_bytes() == before


def test_replay_writes_the_task_tree_of_a_counterexample(tmp_path, roar_cli):
    """replay --dot: the counterexample's task tree, with the SeqAch edge it breaks; a trace with
    no task-tree message (a .clf model's) is refused before the replay."""
    import re
    _res, trace = counterexample("ordered_pick.toml", tmp_path)
    code, out, _err = roar_cli("replay", trace, "--model", FAULTY / "ordered_pick.roar",
                               "--functional", FAULTY / "reliable_tools.py", "--dot", tmp_path / "t.dot")
    assert code == 0 and f"task tree written to {tmp_path / 't.dot'}" in out
    dot = (tmp_path / "t.dot").read_text()
    assert re.search(r'^  "R1" -> "R3" \[style=dashed.*label="SeqAch"\];$', dot, re.M)
    assert set(re.findall(r'^  "(\w+)" \[shape=', dot, re.M)) == {"R0", "R1", "R2", "R3", "C1", "C2"}
    res = run_job(load_job(CHECKER / "philosophers_dl5.toml"))
    clf_trace = save_counterexample(res, "deadlock", tmp_path)
    code, out, err = roar_cli("replay", clf_trace, "--model", ROOT / "models" / "philosophers" / "dl.clf",
                              "--dot", tmp_path / "c.dot")
    assert code == 2 and "holds no task-tree message" in err and "replayed" not in out
    assert not (tmp_path / "c.dot").exists()


def test_no_output_is_written_inside_a_hyper_spec_folder(tmp_path, roar_cli):
    # a file written into a hyper spec's agent folder (or a new .ability file) would be read as part
    # of the spec next time (a trace there was read as a task): every command refuses it before any
    # work, as an input; a file at the folder's top is not read (test_run_cli: compile -o loco/x.clf)
    import shutil
    spec = tmp_path / "demo_loco"
    shutil.copytree(ROOT / "models" / "demo_loco", spec)
    before = sorted(p.relative_to(spec) for p in spec.rglob("*"))
    req = "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5"
    for argv, opt in [(("run", spec, "-r", req, "--trace", spec / "demo_loco" / "run.jsonl"), "--trace"),
                      (("run", spec, "-r", req, "--png", spec / "demo_loco" / "move" / "run.png"), "--png"),
                      (("compile", spec, "-r", req, "-o", spec / "demo_loco" / "m.clf"), "--output"),
                      (("compile", spec, "-r", req, "-o", spec / "extra.ability"), "--output"),
                      (("check", spec, "-r", req, "--png", spec / "demo_loco"), "--png"),
                      (("check", spec, "-r", req, "--html", spec / "demo_loco" / "report"), "--html")]:
        code, out, err = roar_cli(*argv)
        assert code == 2 and f"{opt} " in err and "a folder this command reads as its input" in err, (argv, err)
        assert "states" not in out
    assert sorted(p.relative_to(spec) for p in spec.rglob("*")) == before
    # outside it, the run writes its trace, and the spec still loads and replays it
    code, out, _err = roar_cli("run", spec, "-r", req, "--trace", tmp_path / "run.jsonl")
    assert code == 0 and (tmp_path / "run.jsonl").is_file()
    code, _out, err = roar_cli("replay", tmp_path / "run.jsonl", "--model", spec)
    assert code == 0, err
