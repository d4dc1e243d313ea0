"""The fuzzing harness (roar_formal/fuzz): a bounded campaign, and each failure it found, kept as a regression.

Every case runs ``roar-verify`` in-process in a forked child with a time bound and must end
with exit status 0, 1, 2 or 4 (never 3, "internal error"), within the bound, and with a
``file:line:col`` location whenever Python's own TOML or JSON reader can locate the input
error. ``python bench/fuzz.py --cases 10000`` runs the long campaign (docs/checking.md).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings

from roar_formal.fuzz import Case, cases, run_case
from roar_formal.fuzz.mutate import REQUESTS, ROOT, counterexample_trace
from roar_formal.fuzz.runner import warm_up

TIMEOUT = 20.0
MM = str(ROOT / "models/faulty/mutual_make.roar")


@pytest.fixture(scope="module", autouse=True)
def _warm():
    counterexample_trace()
    warm_up()


def _ok(o) -> None:
    assert not o.hang, f"hang past {TIMEOUT} s: {o.case.describe()}"
    assert not o.internal_error, f"internal error (exit {o.status}, signal {o.signal}): {o.stderr[-800:]}\n" \
                                 f"case: {o.case.describe()}"
    assert not o.unlocated, f"error without a location: {o.stderr[-400:]}\ncase: {o.case.describe()}"


@settings(max_examples=24, derandomize=True, database=None, deadline=None, phases=[Phase.explicit, Phase.generate],
          suppress_health_check=list(HealthCheck))
@given(case=cases())
def test_mutated_inputs_of_every_kind_end_in_a_user_facing_exit_status(case):
    _ok(run_case(case, timeout=TIMEOUT))


def test_the_harness_sees_an_internal_error_a_hang_and_an_unlocated_error():
    """The oracles themselves: a crash is an internal error, a sleep is a hang, a TOML error
    without its location is unlocated."""
    import roar_formal.fuzz.runner as runner
    o = run_case(Case("x", "x", ["tca-check", "/nonexistent.jsonl"]), timeout=TIMEOUT)
    assert o.status == 2 and not o.internal_error
    o = runner.Outcome(Case("x", "x", []), 3, "", "internal error: ValueError: x", 0.1)
    assert o.internal_error and o.verdict == "internal-error"
    o = runner.Outcome(Case("job", "x", [], expect_location=True, target="input.toml"), 2, "",
                       "error: invalid TOML: Invalid value", 0.1)
    assert o.unlocated
    o = runner.Outcome(Case("job", "x", [], expect_location=True, target="input.toml"), 2, "",
                       "error: input.toml:3:7: invalid TOML: Invalid value", 0.1)
    assert not o.unlocated


def test_a_hang_is_killed_at_the_bound(monkeypatch):
    import os
    import time

    import roar_formal.cli
    monkeypatch.setattr(roar_formal.cli, "main", lambda argv: time.sleep(60))   # the forked child inherits it
    pid = os.getpid()
    began = time.monotonic()
    o = run_case(Case("x", "x", ["check", "job.toml"]), timeout=2.0)
    assert os.getpid() == pid   # the parent, not a child, goes on
    assert 2.0 <= time.monotonic() - began < 10.0
    assert o.hang and o.status is None and o.verdict == "hang"


# ---------------------------------------------------------------- what the campaigns found, one case each

def _run(argv, files=None, special=None):
    return run_case(Case("regression", "x", argv, files=files or {}, special=special or {},
                         target=next(iter(files or {"input": b""}))), timeout=TIMEOUT)


@pytest.mark.parametrize("argv", [
    ["check", "in.toml"], ["check", "in.clf"], ["compile", "in.roar", "-r", "arm::started == true"],
    ["tca-check", "in.jsonl"], ["tca-simulate", "in.toml", "--out", "o.jsonl"], ["replay", "in.jsonl", "--model", MM],
    ["simulate", str(ROOT / "models/door_nav.roar"), "-s", "in.toml", "-r", REQUESTS["door_nav.roar"]],
])
def test_a_fifo_or_a_device_given_as_input_is_refused(argv):
    name = argv[1] if argv[0] != "simulate" else "in.toml"
    o = run_case(Case("x", "x", argv, special={name: "fifo"}), timeout=TIMEOUT)
    _ok(o)
    assert o.status == 2 and "it is a FIFO, not a regular file" in o.stderr
    o = run_case(Case("x", "x", [a if a != name else "/dev/zero" for a in argv]), timeout=TIMEOUT)
    _ok(o)
    assert o.status == 2
    assert ("/dev/zero: it is a character device, not a regular file" in o.stderr
            or "a spec file ends in .ability (hyper layout) or .roar" in o.stderr), o.stderr


def test_deeply_nested_toml_is_a_located_error():
    deep = "[" * 3000 + "1" + "]" * 3000
    o = _run(["check", "job.toml", "--no-traces"], {
        "p.toml": f'check = ["deadlock"]\nnever = {deep}\n'.encode(),
        "job.toml": f'name = "a"\nspec = "{MM}"\nrequest = "arm::started == true"\nproperties = ["p.toml"]\n'.encode()})
    _ok(o)
    assert "p.toml:2:109: invalid TOML: arrays or tables nested too deeply" in o.stderr
    o = _run(["tca-simulate", "m.toml", "--out", "o.jsonl"], {"m.toml": f"[model]\nname = {deep}\n".encode()})
    _ok(o)
    assert "m.toml:2:108: malformed TOML: arrays or tables nested too deeply" in o.stderr


def test_a_number_past_the_int_string_limit_is_a_located_error():
    text = (ROOT / "models/scenarios/clear.toml").read_text()
    text = text.replace("dt = 0.01", "dt = " + "9" * 5000)
    assert "9" * 5000 in text
    o = _run(["simulate", str(ROOT / "models/door_nav.roar"), "-s", "sc.toml", "-r", REQUESTS["door_nav.roar"]],
             {"sc.toml": text.encode()})
    _ok(o)
    assert "sc.toml:" in o.stderr and "a number with more than 4000 digits" in o.stderr
    job = (ROOT / "checker/mutual_make.toml").read_text().replace('"../', f'"{ROOT}/')
    o = _run(["check", "job.toml"], {"job.toml": job.replace("200_000", "9" * 5000).encode()})
    _ok(o)
    assert "job.toml:8:14: invalid TOML: a number with more than 4000 digits" in o.stderr


@pytest.mark.parametrize("command", ["tca-check", "replay"])
def test_deeply_nested_json_in_a_trace_is_a_located_error(command):
    lines = counterexample_trace().splitlines()
    lines[2] = '{"step": ' + "[" * 100000 + "]" * 100000 + "}"
    argv = ["tca-check", "t.jsonl"] if command == "tca-check" else ["replay", "t.jsonl", "--model", MM]
    o = _run(argv, {"t.jsonl": ("\n".join(lines) + "\n").encode()})
    _ok(o)
    assert "t.jsonl:3:1:" in o.stderr and "nested too deeply" in o.stderr


def test_a_traces_folder_under_a_file_is_refused_before_any_work():
    o = _run(["check", str(ROOT / "checker/mutual_make.toml"), "--traces", "afile/sub"], {"afile": b"x"})
    _ok(o)
    assert o.status == 2 and "--traces afile/sub: afile is not a folder" in o.stderr
    assert "states" not in o.stdout


def test_bench_fuzz_prints_its_tallies(tmp_path):
    import subprocess
    import sys
    r = subprocess.run([sys.executable, str(ROOT / "bench/fuzz.py"), "--cases", "3", "--jobs", "1", "--seed", "5",
                        "--timeout", str(TIMEOUT), "--keep", str(tmp_path)], capture_output=True, text=True,
                       timeout=180, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith("3 cases in ")
    assert "internal errors: 0, hangs: 0, unlocated errors: 0" in r.stdout
    assert len(Path(tmp_path / "shard0.jsonl").read_text().splitlines()) == 3


def test_a_tca_model_field_of_the_wrong_type_or_bytes_that_are_not_utf8_are_located_errors():
    text = (ROOT / "models/ambler/ambler.toml").read_text()
    line = next(n for n, x in enumerate(text.splitlines(), 1) if x.startswith("children = "))
    lines = text.splitlines()
    lines[line - 1] = "children = 1979-05-27"
    o = _run(["tca-simulate", "m.toml", "--out", "o.jsonl"], {"m.toml": "\n".join(lines).encode()})
    _ok(o)
    assert f"m.toml:{line}:1: expected classes.Walk.children to be an array" in o.stderr
    data = text.encode()
    at = data.index(b"\n[model]") + 3
    o = _run(["tca-simulate", "m.toml", "--out", "o.jsonl"], {"m.toml": data[:at] + b"\xff\xfe" + data[at:]})
    _ok(o)
    row = data[:at].count(b"\n") + 1
    assert f"m.toml:{row}:3: model is not UTF-8 text: invalid start byte" in o.stderr


def test_a_job_whose_properties_hold_a_non_path_is_a_located_error():
    job = (ROOT / "checker/philosophers_dl5.toml").read_text().replace('"../', f'"{ROOT}/')
    job = job.replace(f'properties = ["{ROOT}/properties/philosophers.toml"]', "properties = [[[1]]]")
    assert "properties = [[[1]]]" in job
    o = _run(["check", "job.toml", "--no-traces"], {"job.toml": job.encode()})
    _ok(o)
    line = next(n for n, x in enumerate(job.splitlines(), 1) if x.startswith("properties"))
    assert f"job.toml:{line}:1: 'properties' must be a path or a list of paths" in o.stderr


def test_a_tca_trace_field_holding_a_number_where_a_name_goes_is_a_located_error():
    lines = (ROOT / "models/ambler/traces/walk.jsonl").read_text().splitlines()
    lines[0] = lines[0].replace('"agent": "gait_planner"', '"agent": 1.5')
    assert '"agent": 1.5' in lines[0]
    o = _run(["tca-check", "t.jsonl"], {"t.jsonl": ("\n".join(lines) + "\n").encode()})
    _ok(o)
    assert "t.jsonl:1:" in o.stderr and "expected field 'agent' to be a non-empty string, got 1.5" in o.stderr


@pytest.mark.parametrize("argv", [["check", "X.roar", "-r", "a::b == 1"], ["compile", "X.roar", "-r", "a::b == 1"],
                                  ["check", "X.clf"], ["check", "job.toml", "--no-traces"]])
def test_a_file_name_the_system_refuses_is_an_input_error(argv):
    long = "x" * 300
    job = (ROOT / "checker/mutual_make.toml").read_text().replace('"../', f'"{ROOT}/')
    job = job.replace(f'"{ROOT}/models/faulty/mutual_make.roar"', f'"{long}.roar"')
    o = _run([a.replace("X", long) for a in argv], {"job.toml": job.encode()})
    _ok(o)
    assert o.status == 2, o.stderr
    assert f"{long}.roar: File name too long" in o.stderr or f"{long}.clf: File name too long" in o.stderr


def test_a_tca_duration_that_is_not_finite_is_a_located_error():
    text = (ROOT / "models/ambler/ambler.toml").read_text()
    line = next(n for n, x in enumerate(text.splitlines(), 1) if x.startswith("plan = ["))
    lines = text.splitlines()
    lines[line - 1] = "plan = [-1e999999999, 4.0]"
    o = _run(["tca-simulate", "m.toml", "--out", "o.jsonl"], {"m.toml": "\n".join(lines).encode()})
    _ok(o)
    # (the located line is the first one holding "plan =": walk_plan's, a known imprecision of tca/model.py)
    assert re.search(r"m\.toml:\d+:\d+: expected durations\.plan = \[lo, hi\] \(two finite numbers\)", o.stderr)
