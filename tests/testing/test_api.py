"""The public API: loading, running, exploring; results print as the command line prints them."""

import inspect
import re
from pathlib import Path

import pytest

import roar_formal
import roar_formal.testing
from roar_formal import AgentSpec, ClfModel, RoarError, load, load_clf, load_spec

REQUEST = "cell::lifted == true"


@pytest.fixture(scope="module")
def pick(examples) -> AgentSpec:
    return load_spec(examples / "pick" / "pick.roar")


def _line() -> int:
    return inspect.currentframe().f_back.f_lineno


# ------------------------------------------------------------------ the package


def test_public_names_load_on_first_use_and_the_package_is_typed():
    from roar_formal.testing import api
    assert roar_formal.load_spec is api.load_spec and roar_formal.AgentSpec is api.AgentSpec
    assert roar_formal.testing.assert_no_deadlock.__module__ == "roar_formal.testing.assertions"
    assert {"load", "load_spec", "load_clf", "Exploration", "RunReport"} <= set(dir(roar_formal))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        roar_formal.nope
    with pytest.raises(AttributeError):
        roar_formal.testing.nope
    assert (Path(roar_formal.__file__).parent / "py.typed").is_file()


# ------------------------------------------------------------------ runs


def test_a_run_prints_exactly_as_roar_verify_run(pick, run_cli):
    spec = str(pick.path)
    run = pick.run(REQUEST, faults=["close_jaws:1"], seed=3)
    code, out, _err = run_cli("run", spec, "-r", REQUEST, "--fault", "close_jaws:1", "--seed", "3")
    assert code == 1 and not run.ok
    assert run.format() == out.rstrip("\n")
    code, out, _err = run_cli("run", spec, "-r", REQUEST, "-v")
    assert code == 0 and pick.run(REQUEST).format(verbose=True) == out.rstrip("\n")


def test_a_run_reads_outcome_events_and_final_values(pick):
    bad = pick.run(REQUEST, faults=["close_jaws:1"])
    assert (bad.outcome, bad.ok, bad.quiescent) == ("failure", False, True)
    assert bad.value("gripper::busy") is True and bad.final["cell::lifted"] is False
    assert "local failure: gripper.grasp.squeeze at 45:13: assert(close_jaws())" in bad.error_context
    kinds = [e.kind for e in bad.events]
    assert kinds[0] == "state" and "primitive-end" in kinds
    good = pick.run(REQUEST)
    assert good.ok and good.value("gripper::holding") is True and good.error_context == []
    assert repr(good) == "<run of 'cell::lifted == true': success after 41 CLF steps>"
    with pytest.raises(RoarError, match="no variable 'nope'"):
        good.value("nope")


def test_a_fault_that_matched_no_call_is_listed_when_not_strict(pick, tmp_path):
    run = pick.run(REQUEST, faults=["close_jaws:5", "close_jaws:1"], strict_faults=False)
    assert run.outcome == "failure"          # the same run as with close_jaws:1 alone
    assert run.unused_faults == ("close_jaws:5",)
    assert run.format().endswith("faults that matched no call: close_jaws:5")
    assert [e.text for e in run.events] == [e.text for e in pick.run(REQUEST, faults=["close_jaws:1"]).events]
    with pytest.raises(RoarError, match="close_jaws:5: no such call happened"):
        pick.run(REQUEST, faults=["close_jaws:5"])   # by default, as on the command line
    with pytest.raises(RoarError, match="expected NAME, NAME:K"):
        pick.run(REQUEST, faults=["close jaws"])
    trace = run.save_trace(tmp_path / "run.jsonl")
    from roar_formal.trace.format import read_trace
    header, steps = read_trace(trace)
    assert header["kind"] == "roar-run" and len(steps) == run.clf_steps


def test_compiled_models_are_cached_per_request_and_mode(pick):
    assert pick.compile(REQUEST) is pick.compile(REQUEST)
    assert pick.compile(REQUEST, "abstract") is not pick.compile(REQUEST)
    with pytest.raises(RoarError, match="compile mode"):
        pick.compile(REQUEST, "fast")


def test_a_spec_given_as_text_runs_and_prints_as_code_that_rebuilds_it(examples):
    text = (examples / "pick" / "pick.roar").read_text(encoding="utf-8")
    spec = AgentSpec.from_text(text, name="pick")
    assert spec.run(REQUEST).ok and spec.agents == ["cell", "gripper"]
    rebuilt = eval(repr(spec), {"AgentSpec": AgentSpec})
    assert rebuilt.text == text and rebuilt.ast == spec.ast


# ------------------------------------------------------------------ exploration


def test_a_counterexample_prints_exactly_as_roar_verify_check(models, root, run_cli, tmp_path):
    res = load_spec(models / "faulty" / "mutual_make.roar").explore("arm::started == true", ["deadlock", "livelock"])
    assert res.violated("deadlock") and res.holds("livelock") and res.complete
    cx = res.counterexample("deadlock")
    assert cx.kind == "path" and len(cx) == 27 and res.counterexample("livelock") is None
    code, out, _err = run_cli("check", root / "checker" / "mutual_make.toml", "--no-traces")
    assert code == 0
    lines = out.splitlines()
    start = lines.index(next(x for x in lines if x.startswith("  deadlock: violated")))
    end = next(i for i in range(start, len(lines)) if lines[i].startswith("  livelock:"))
    assert any(x.startswith("    wait-for cycle: arm -> door -> arm") for x in lines[start:end])
    assert cx.format() == "\n".join(lines[start:end])
    assert any(ev.text == "make R2 to arm: arm::parked == true" for evs in cx.events for ev in evs)
    # saved, it replays on the engine through the command line
    path = cx.save(tmp_path)
    assert cx.trace == path and f"trace: {path}" in cx.format()
    code, out, err = run_cli("replay", path, "--model", models / "faulty" / "mutual_make.roar")
    assert code == 0, err
    assert "replayed 27 steps" in out
    # and through the API, which the command is built on: the same text, the claim confirmed
    rep = roar_formal.replay(path, models / "faulty" / "mutual_make.roar")
    assert rep.steps == 27 and rep.confirmed is True and rep.claim == "deadlock"
    assert rep.format() == out.rstrip("\n")
    start, end = rep.state(0), rep.state(27)
    assert set(start) == set(end) == {"arm", "door"}
    assert start != end
    with pytest.raises(IndexError, match="this replay has states 0 .the start. to 27"):
        rep.state(28)
    with pytest.raises(RoarError, match=r"replay needs the model to replay on: name it: replay\(trace, model\)"):
        roar_formal.replay(path)


def test_exploration_statistics_and_its_printed_form(models):
    res = load_spec(models / "faulty" / "retry_forever.roar").explore("hand::holding == true", ["livelock"])
    assert res.status("livelock") == "violated" and res.counterexample("livelock").kind == "lasso"
    assert res.states > 0 and res.transitions >= res.states - 1 and res.backend == "general"
    text = str(res)
    assert text.splitlines()[0].startswith(f"retry_forever: request hand::holding == true  ({res.states:,} states")
    assert "-- cycle (repeats forever) --" in text
    with pytest.raises(RoarError, match="'deadlock' was not checked"):
        res.verdict("deadlock")


def test_bad_input_is_a_located_roar_error(pick, models):
    line = _line() + 2
    with pytest.raises(RoarError) as e:
        pick.explore(REQUEST, ["deadlok"])
    assert "unknown property 'deadlok'" in e.value.message
    assert (Path(e.value.pos.file).name, e.value.pos.line) == ("test_api.py", line)
    line = _line() + 2
    with pytest.raises(RoarError) as e:
        pick.explore(REQUEST, never=["nosuch X"])
    assert "unknown type family 'nosuch'" in e.value.message and e.value.pos.line == line
    with pytest.raises(RoarError, match="agent 'cell' has no variable 'nope'") as e:
        pick.run("cell::nope == true")
    assert e.value.pos is not None
    with pytest.raises(RoarError, match="no such file"):
        load(models / "nope.roar")
    with pytest.raises(RoarError, match="no such file"):
        load_clf(models / "nope.clf")
    with pytest.raises(RoarError, match="unknown budget key"):
        pick.explore(REQUEST, budget={"states": 5})


# ------------------------------------------------------------------ CLF models


def test_a_clf_model_runs_and_explores(models):
    m = load(models / "clf" / "arith.clf")
    assert isinstance(m, ClfModel) and m.starts == 2
    run = m.run()
    assert run.quiescent and run.steps == 26 and run.state == ["return (s (s (s (s (s (s (s (s (s (s (s (s z)))))))))))) "
                                                                + run.state[0].split(" ")[-1]]
    dead = m.explore(["deadlock"])
    assert dead.violated("deadlock") and len(dead.counterexample("deadlock")) == 26
    assert m.explore(["deadlock"], accept="return V D").holds("deadlock")
    with pytest.raises(RoarError, match="start 3 but the program has 2"):
        m.run(start=3)
    with pytest.raises(RoarError, match="fairness must be"):
        m.explore(["livelock"], fairness="strong")


# ------------------------------------------------------------------ the robot


def test_a_run_on_the_reference_robot(models):
    spec = load_spec(models / "door_nav.roar")
    run = spec.run("base::arrived == true where base::gx == 9.0 && base::gy == 3.0",
                   scenario=models / "scenarios" / "door.toml", max_steps=300)
    assert run.robot is not None and run.outcome == "running"     # stopped at the step bound
    text = run.format()
    assert text.splitlines()[0].endswith("on scenario door, seed 0")
    assert "compute_path(9, 3)" in text and "robot at (" in text


def test_mission_properties_from_the_api_agree_with_the_checker_job(models, root):
    """mission-completion and mission-failure (the spec defaults of a job) through the API:
    the verdicts and state count of checker/camera_retry.toml."""
    from roar_formal.verify.check import run_job
    from roar_formal.verify.jobs import load_job
    job = run_job(load_job(root / "checker" / "camera_retry.toml"))
    res = load_spec(models / "faulty" / "camera_retry.roar").explore(
        "camera::taken == true", ["deadlock", "mission-completion", "mission-failure"])
    for p in ("deadlock", "mission-completion", "mission-failure"):
        assert res.status(p) == job.verdicts[p].status, p
    assert res.violated("mission-completion") and res.counterexample("mission-completion").kind == "lasso"
    assert res.states == job.graph.n_states


# ------------------------------------------------------------------ what the command line is built on


def test_job_files_run_through_the_api_as_check_runs_them(root, run_cli):
    """`roar-verify check` is load_jobs, Job.run and Exploration.lines/as_json: the same verdicts,
    block and JSON (timings aside); a job's budget can be changed before it runs."""
    import json
    import re

    from roar_formal import load_jobs
    path = root / "checker" / "mutual_make.toml"
    [job] = load_jobs([path])
    assert job.path == path and job.expect["deadlock"] == "violated" and "deadlock" in job.properties
    res = job.run()
    assert res.ok and res.violated("deadlock") and not res.unexpected and res.expected("deadlock") == "violated"
    code, out, _err = run_cli("check", path, "--no-traces")
    assert code == 0

    def timeless(text):
        return re.sub(r"\d+\.\d+ s", "T s", text)

    block = timeless(res.lines().text())
    assert block.startswith(f"ok {job.name}  (") and block in timeless(out)
    code, out, _err = run_cli("check", path, "--no-traces", "--json")
    [printed] = json.loads(out)
    mine = res.as_json()
    for doc in (printed, mine):
        doc.pop("seconds"), doc.pop("memory_mb")
    fresh = re.compile(r"#\d+")   # fresh names are numbered per process, not per exploration
    assert fresh.sub("#", json.dumps(mine)) == fresh.sub("#", json.dumps(printed))
    with pytest.raises(RoarError, match="no such job file or folder"):
        load_jobs([root / "checker" / "nope.toml"])
    [small] = load_jobs([path])
    small.budget.max_states = 5
    assert small.run().status("deadlock") in ("incomplete", "violated") and small.budget.max_states == 5


def test_a_run_report_is_what_run_json_prints_and_saves_what_run_writes(pick, run_cli, tmp_path):
    import json
    import re

    from roar_formal.trace.format import read_trace
    run = pick.run(REQUEST, seed=2, faults=["close_jaws:1"])
    code, out, _err = run_cli("run", pick.path, "-r", REQUEST, "--seed", "2", "--fault", "close_jaws:1", "--json",
                              "--trace", tmp_path / "cli.jsonl")
    assert code == 1 and json.loads(out) == run.as_json()
    header, steps = read_trace(run.save_trace(tmp_path / "api.jsonl"))
    cli_header, cli_steps = read_trace(tmp_path / "cli.jsonl")
    assert header == cli_header, {k: (header.get(k), cli_header.get(k)) for k in set(header) | set(cli_header) if header.get(k) != cli_header.get(k)}
    fresh = re.compile(r"#\d+")   # fresh names are numbered per process, not per run
    assert json.loads(fresh.sub("#", json.dumps(steps))) == json.loads(fresh.sub("#", json.dumps(cli_steps)))
    assert header["faults"] == ["close_jaws:1"] and header["fingerprint"]
    dot = run.save_task_tree(tmp_path / "tree.dot").read_text(encoding="utf-8")
    assert dot.startswith("digraph") and "close_jaws" in dot


@pytest.mark.parametrize("progress", [["request R0 finished"], ["gripper::busy == true"], ["*"]])
def test_livelock_progress_is_read_as_a_job_file_reads_it(examples, tmp_path, progress):
    """``explore(progress=...)`` takes predicates in the spec's terms and rule names, as a job's
    ``[livelock] progress`` does (they were all taken as rule names, so a predicate made nothing
    progress); the job file's verdict on the same progress is the oracle."""
    spec_path = examples / "pick_fixed" / "pick.roar"
    got = load_spec(spec_path).explore("cell::lifted == true", ["livelock"], progress=progress)
    props = tmp_path / "p.toml"
    props.write_text('check = ["livelock"]\n[livelock]\nprogress = [' + ", ".join(f'"{p}"' for p in progress)
                     + "]\n", encoding="utf-8")
    job = tmp_path / "j.toml"
    job.write_text(f'spec = "{spec_path}"\nrequest = "cell::lifted == true"\nproperties = ["{props}"]\n',
                   encoding="utf-8")
    from roar_formal.verify.check import run_job
    from roar_formal.verify.jobs import load_job
    assert got.verdicts["livelock"].status == run_job(load_job(job)).verdicts["livelock"].status


@pytest.mark.parametrize("progress,message", [
    (["gripper::bussy == true"], "has no variable 'bussy' (did you mean 'busy'?)"),
    (["no_such_rule"], "is neither a predicate in the spec's terms"),
])
def test_a_progress_that_names_nothing_is_an_error(examples, progress, message):
    with pytest.raises(RoarError, match=re.escape(message)):
        load_spec(examples / "pick_fixed" / "pick.roar").explore("cell::lifted == true", ["livelock"],
                                                                 progress=progress)
