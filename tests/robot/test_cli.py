"""``roar-verify simulate``, ``conform`` and ``replay`` on robot traces, through the CLI entry point.

Exit codes (0 success / sound / realised, 1 not, 2 bad input with a location, never a
traceback), the printed run against the library's result, the trace and picture files.
"""

from __future__ import annotations

import json
import re

import pytest

from roar_formal.robot.setup import prepare
from roar_formal.robot.sim import simulate
from roar_formal.trace.format import read_trace

from repo import ROOT
MODELS = ROOT / "models"
SCEN = MODELS / "scenarios"
DOOR = MODELS / "door_nav.roar"
DOOR_REQ = "base::arrived == true where base::gx == 9.0 && base::gy == 3.0"
REQ_RETRY = "hand::holding == true"
LINE = re.compile(r"^ *(\d+) +(\d+\.\d\d)s (\S+) +(.*?)(   @ \(.*\))?$")


@pytest.fixture
def cli(roar_cli):
    """The shared in-process command line (tests/conftest.py), called as ``cli(capsys, *argv)``."""
    return lambda _capsys, *argv: roar_cli(*argv)


def test_simulate_prints_the_run_writes_its_trace_and_picture(cli, capsys, tmp_path):
    trace, png = tmp_path / "door.jsonl", tmp_path / "door.png"
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ,
                         "--fault", "door_closes", "--trace", trace, "--png", png)
    assert code == 0, err
    assert "Traceback" not in out + err
    assert re.search(r"^request success at t = 23\.\d\d s after \d+ CLF steps \(quiescent\)", out, re.M)
    # the printed events are the library's, with their simulated times
    spec_ast, model, binding, sc = prepare(DOOR, DOOR_REQ, SCEN / "door.toml")
    res = simulate(model, binding.robot, sc, seed=0, faults=["door_closes"])
    printed = [(int(m.group(1)), float(m.group(2)), m.group(3), m.group(4)) for m in map(LINE.match, out.splitlines())
               if m]
    # (repeated blocks folded, as the step table folds them: their expansion is the library's events)
    from roar_formal.trace.render import Repeat, event_rows, folded
    shown = [r for r in folded(event_rows(res.events, res.times)) if not isinstance(r, Repeat)]
    assert len(shown) < len(res.events) and "repeat" in out
    assert printed == [(r.step, round(r.time, 2), r.agent, r.text) for r in shown]
    header, steps = read_trace(trace)
    assert header["kind"] == "roar-robot-run" and header["faults"] == ["door_closes"]
    assert header["outcome"] == "success" and len(steps) == len(res.run.steps)
    assert all("time" in s and "pose" in s for s in steps)
    calls = [s["call"] for s in steps if s["rule"] == "functional_layer"]
    assert len(calls) == len(res.calls) and all(c["outcome"] for c in calls)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_simulate_exits_1_when_the_request_does_not_finish(cli, capsys):
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ,
                         "--fault", "door_stays_closed")
    assert code == 1
    assert "request running at t = 90.00 s" in out and "horizon of 90 s reached" in out


def test_simulate_refuses_bad_input_with_a_location(cli, capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nbounds = [0.0, 0.0, 5.0]\n')
    code, out, err = cli(capsys, "simulate", DOOR, "-s", bad, "-r", DOOR_REQ)
    assert code == 2 and f"{bad}:2:" in err and "Traceback" not in err
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--fault", "door_open")
    assert code == 2 and "not a fault point of scenario 'door'" in err and "door_closes" in err
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--fault", "door_close")
    assert code == 2 and "--fault 'door_close' (did you mean 'door_closes'?)" in err
    # a spec without a functional-layer module, and one whose module has no robot binding
    code, out, err = cli(capsys, "simulate", MODELS / "faulty" / "mutual_make.roar", "-s", SCEN / "clear.toml",
                         "-r", "a::x == true")
    assert code == 2 and "no functional-layer module found" in err and "Traceback" not in err
    code, out, err = cli(capsys, "simulate", MODELS / "faulty" / "retry_forever.roar", "-s", SCEN / "clear.toml",
                         "-r", REQ_RETRY, "--functional", MODELS / "faulty" / "reliable_tools.py")
    assert code == 2 and "defines no robot_registry()" in err and "Traceback" not in err
    # an output that would overwrite an input
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--trace", DOOR)
    assert code == 2 and "refusing to overwrite" in err


def test_conform_reports_outcomes_per_primitive_and_exits_0_when_sound(cli, capsys):
    code, out, err = cli(capsys, "conform", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--runs", "2",
                         "--fault", "door_closes", "--json")
    assert code == 0, err
    rep = json.loads(out)
    assert rep["sound"] and len(rep["runs"]) == 2
    assert rep["outcomes"]["planner::compute_path"]["no_path"] > 0      # the door was closed
    assert rep["outcomes"]["planner::path_blocked"]["blocked"] > 0
    assert "not_driving" in rep["never"]["base::drive"]                 # a warning, not an error


def test_replay_of_a_robot_trace_needs_the_spec_and_refuses_a_stale_one(cli, capsys, tmp_path):
    trace = tmp_path / "door.jsonl"
    assert cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--trace", trace)[0] == 0
    code, out, err = cli(capsys, "replay", trace)
    assert code == 2 and "--model SPEC" in err
    code, out, err = cli(capsys, "replay", trace, "--model", DOOR)
    assert code == 0 and "every step is a step of the model" in out
    # the same spec with an edit: stale
    other = tmp_path / "door_nav.roar"
    other.write_text(DOOR.read_text().replace("wait(at_goal(gx, gy), 100);", "wait(at_goal(gx, gy), 50);"))
    (tmp_path / "door_nav.py").write_text((MODELS / "door_nav.py").read_text())
    code, out, err = cli(capsys, "replay", trace, "--model", other)
    assert code == 2 and "stale" in err
    code, out, err = cli(capsys, "replay", trace, "--model", other, "--force")
    assert code == 0
    # another spec altogether: the message names the spec the trace was made from
    code, out, err = cli(capsys, "replay", trace, "--model", MODELS / "pick_place.roar")
    assert code == 2 and f"the trace was made from {DOOR}, not " in " ".join(err.split())


def test_replay_of_an_edited_robot_trace_names_the_step(cli, capsys, tmp_path):
    trace = tmp_path / "door.jsonl"
    assert cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--trace", trace)[0] == 0
    lines = trace.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if '"function": "base::drive"' in line)
    rec = json.loads(lines[k])
    rec["call"]["result"]["value"] = 42
    lines[k] = json.dumps(rec)
    trace.write_text("\n".join(lines) + "\n")
    code, out, err = cli(capsys, "replay", trace, "--model", DOOR)
    assert code == 1
    assert f"step {rec['step']} (functional_layer): the robot's result of base::drive is covered by no declared " \
           f"outcome" in out
    assert "declared outcomes of base::drive: driving, not_driving" in out


def test_the_door_excerpt_in_the_docs_is_what_simulate_prints(cli, capsys):
    doc = (ROOT / "docs" / "robot.md").read_text()
    block = doc.split("An excerpt:\n\n```\n", 1)[1].split("```", 1)[0]
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--fault", "door_closes")
    assert code == 0
    printed = set(out.splitlines())
    shown = [line for line in block.splitlines() if line.strip() and line.strip() != "..."]
    assert len(shown) > 10
    assert [line for line in shown if line not in printed] == []


def test_conform_with_no_primitive_call_checked_nothing_and_says_so(cli, capsys):
    # `written_holds`: the request already holds, so no recipe runs and nothing calls the robot
    code, out, err = cli(capsys, "conform", MODELS / "pick_place.roar", "-s", SCEN / "gripper.toml",
                         "-r", "gripper::holding == false", "--runs", "1", "--no-random-faults")
    assert code == 1 and "nothing checked: no run called a primitive" in out


def _door_with_compute_path(tmp_path, body: str):
    """door_nav.roar next to a binding whose robot ``compute_path(gx, gy)`` runs ``body``."""
    import shutil
    spec = tmp_path / "door_nav.roar"
    shutil.copy(DOOR, spec)
    (tmp_path / "door_nav.py").write_text(
        "import importlib.util\n"
        f"_s = importlib.util.spec_from_file_location('door_nav_base', {str(MODELS / 'door_nav.py')!r})\n"
        "_m = importlib.util.module_from_spec(_s)\n_s.loader.exec_module(_m)\n"
        "registry = _m.registry\n"
        "def robot_registry():\n"
        "    reg = _m.robot_registry()\n"
        "    def replaced(gx, gy):\n"
        f"        {body}\n"
        "    reg.register('compute_path', replaced, outcomes=_m.OUTCOMES['compute_path'], replace=True)\n"
        "    return reg\n")
    return spec


def test_a_binding_that_raises_is_a_located_error_on_the_robot(cli, capsys, tmp_path):
    """As in `run`: an exception in a robot primitive is a bug of the binding, reported at the
    call with the primitive's name, never a failure the recipe retries."""
    spec = _door_with_compute_path(tmp_path, "raise RuntimeError('planner crashed')")
    code, out, err = cli(capsys, "simulate", spec, "-s", SCEN / "door.toml", "-r", DOOR_REQ)
    assert code == 2, out
    # door_nav.roar:33:20 is the call `compute_path(gx, gy)` in the planner's recipe
    assert f"error: {spec}:33:20: primitive 'planner::compute_path' raised RuntimeError: planner crashed" in err
    assert "called as compute_path(9, 3)" in err and "Traceback" not in err


def test_a_binding_that_returns_another_type_is_a_located_error_on_the_robot(cli, capsys, tmp_path):
    """As in `run`: a robot primitive answering a value of another type than its declaration's
    (a string where a bool is declared) is a bug of the binding, located at the call; read as it
    was, the recipe reading it stopped silently until the horizon."""
    spec = _door_with_compute_path(tmp_path, "return 'yes'")
    code, out, err = cli(capsys, "simulate", spec, "-s", SCEN / "door.toml", "-r", DOOR_REQ)
    assert code == 2, out
    assert f"error: {spec}:33:20: primitive 'planner::compute_path' returned 'yes', but it is declared to return" \
        in err and "Traceback" not in err


def test_a_misspelt_fault_on_the_command_line_is_not_located_in_the_cli_code(cli, capsys):
    code, out, err = cli(capsys, "simulate", DOOR, "-s", SCEN / "door.toml", "-r", DOOR_REQ, "--fault", "door_clses")
    assert code == 2 and err.startswith("error: --fault 'door_clses'") and ".py:" not in err


def test_the_scenarios_seed_is_the_default_seed(cli, capsys, tmp_path):
    """A scenario's `seed` key is its runs' seed unless --seed says otherwise (it was ignored: the
    command line's default 0 overrode it)."""
    text = (SCEN / "door.toml").read_text()
    assert "\nseed = 0\n" in text
    seeded = tmp_path / "door7.toml"
    seeded.write_text(text.replace("\nseed = 0\n", "\nseed = 7\n", 1))
    traces = {}
    for name, argv in (("scenario", ["-s", seeded]), ("flag", ["-s", SCEN / "door.toml", "--seed", "7"]),
                       ("zero", ["-s", SCEN / "door.toml"]), ("override", ["-s", seeded, "--seed", "0"])):
        traces[name] = tmp_path / f"{name}.jsonl"
        code, out, err = cli(capsys, "simulate", DOOR, *argv, "-r", DOOR_REQ, "--trace", traces[name])
        assert code == 0, err
    runs = {n: read_trace(p) for n, p in traces.items()}
    assert runs["scenario"][0]["seed"] == runs["flag"][0]["seed"] == 7
    assert runs["zero"][0]["seed"] == runs["override"][0]["seed"] == 0
    poses = {n: [s["pose"] for s in steps] for n, (_h, steps) in runs.items()}
    assert poses["scenario"] == poses["flag"] and poses["zero"] == poses["override"]
    assert poses["scenario"] != poses["zero"]   # the noise differs: the seed was used
    # conform's first run takes it too
    code, out, err = cli(capsys, "conform", DOOR, "-s", seeded, "-r", DOOR_REQ, "--runs", "1", "--no-random-faults")
    assert code == 0, err
    assert "run 1/1: seed 7," in out
