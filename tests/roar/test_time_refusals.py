"""Never a silent pass (issue 14): a ``wait_timeout`` that would change nothing is refused.

``wait_timeout`` applies to the waits with a period alone (docs/semantics.md, "Time"). Given for
a spec whose periods are all on asserts and ensures (or whose waits have none), the timed model
is the one without the timeout: the job (located at its ``wait_timeout``), the command line (one
line, exit 2) and the API (RoarError) refuse it, as they refuse the timed mode on a spec that
writes no period at all. A ``wait_timeout`` without the timed mode is refused everywhere too.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from roar_formal.errors import RoarError
from roar_formal.roar.compile import Timing, compile_spec, nothing_timed, timeout_unused
from roar_formal.roar.spec import load_spec
from roar_formal.testing.api import load

DATA = Path(__file__).resolve().parent / "data"
TIMEOUT_SPEC = DATA / "wait_timeout.roar"    # a wait with a period (100 ms)
OPEN = "door::open == true"
WHY = "wait_timeout applies to the waits with a period"

#: periods on an assert and an ensure, a wait without one: timed, but nothing a timeout applies to
NO_TIMED_WAIT = """\
door = ability {
  context = {
    { }
    { bool open = false; bool latched = true; }
    { }
  }
  tasks = {
    open_door = task {
      pre = { }
      post = { {open == true} }
      recipes = {
        r = recipe {
          body = {
            wait(latched == true);
            assert(open == false, 100);
            ensure(latched == true, 50);
            set open true;
          }
        }
      }
    }
  }
}
"""


@pytest.fixture
def spec(tmp_path) -> Path:
    path = tmp_path / "no_timed_wait.roar"
    path.write_text(NO_TIMED_WAIT, encoding="utf-8")
    return path


def write_job(tmp_path: Path, spec: Path, extra: str, name: str = "job") -> Path:
    job = tmp_path / f"{name}.toml"
    job.write_text(f'spec = "{spec}"\nrequest = "{OPEN}"\n{extra}', encoding="utf-8")
    return job


def one_line_error(code: int, out: str, err: str) -> str:
    assert code == 2, (code, out, err)
    assert "Traceback" not in out + err, err
    assert err.startswith("error: ") and err.count("\n") == 1, err   # one line
    return err


# ------------------------------------------------------------------ the library: the reason, no refusal


def test_the_library_says_why_and_compiles():
    ast = load_spec(TIMEOUT_SPEC)
    assert timeout_unused(compile_spec(ast, OPEN, time=Timing("timed", 250))) is None
    assert timeout_unused(compile_spec(ast, OPEN, time="timed")) is None       # no timeout given
    assert timeout_unused(compile_spec(ast, OPEN)) is None                     # untimed


def test_a_spec_without_a_timed_wait_has_a_reason(spec):
    ast = load_spec(spec)
    model = compile_spec(ast, OPEN, time=Timing("timed", 250))   # the library compiles it ...
    assert nothing_timed(model) is None and model.tick_ms == 50   # ... timed: its assert and ensure are
    why = timeout_unused(model)
    assert why and WHY in why and "250 ms would change nothing" in why
    # the timeout changes nothing: the model is the timed one without it, to the byte
    assert model.text == compile_spec(ast, OPEN, time="timed").text


# ------------------------------------------------------------------ a job file: located at wait_timeout


@pytest.mark.parametrize("extra,line", [
    ('[time]\nmode = "timed"\nwait_timeout = 250\n', 5),
    ('[time]\nwait_timeout = 250\n', 4),                   # a [time] table is timed by default
])
def test_a_job_s_unused_wait_timeout_is_located(tmp_path, roar_cli, spec, extra, line):
    job = write_job(tmp_path, spec, extra)
    err = one_line_error(*roar_cli("check", job, "--no-traces"))
    assert f"{job}:{line}:16: {WHY}" in err, err


def test_the_same_job_without_the_timeout_runs(tmp_path, roar_cli, spec, monkeypatch):
    monkeypatch.chdir(tmp_path)
    job = write_job(tmp_path, spec, 'time = "timed"\n')
    code, out, err = roar_cli("check", job, "--no-traces")
    assert code in (0, 1) and "Traceback" not in err and WHY not in out + err, (out, err)
    assert "deadlock: holds" in out, out


def test_a_job_with_a_timed_wait_keeps_its_timeout(tmp_path, roar_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    job = write_job(tmp_path, TIMEOUT_SPEC, '[time]\nmode = "timed"\nwait_timeout = 250\n')
    code, out, err = roar_cli("check", job, "--no-traces")
    assert code == 1 and "mission-failure: violated" in out and "timeout: wait(" in out, (out, err)


def test_a_spec_without_periods_is_still_refused_at_its_mode(tmp_path, roar_cli):
    """No period at all: the refusal of the timed mode comes first, at the mode's line."""
    from repo import ROOT
    spec = ROOT / "models" / "faulty" / "retry_forever.roar"
    job = tmp_path / "job.toml"
    job.write_text(f'spec = "{spec}"\nrequest = "hand::holding == true"\n[time]\nmode = "timed"\n'
                   f'wait_timeout = 250\n', encoding="utf-8")
    err = one_line_error(*roar_cli("check", job))
    assert f"{job}:4:8: the timed mode models the periods" in err, err


# ------------------------------------------------------------------ the command line: one line, exit 2


@pytest.mark.parametrize("command", ["check", "run", "compile"])
def test_the_command_line_refuses_an_unused_wait_timeout(roar_cli, spec, command, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = one_line_error(*roar_cli(command, spec, "-r", OPEN, "--time", "timed", "--wait-timeout", "250"))
    assert str(spec) in err and WHY in err, err
    # the same command without the timeout is not refused
    code, out, err = roar_cli(command, spec, "-r", OPEN, "--time", "timed", *(["--no-traces"] if command == "check"
                                                                             else []))
    assert code in (0, 1) and WHY not in out + err and "Traceback" not in err, (out, err)


@pytest.mark.parametrize("command", ["check", "run", "compile"])
def test_the_command_line_refuses_a_wait_timeout_without_the_timed_mode(roar_cli, command, tmp_path,
                                                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    for extra in ([], ["--time", "untimed"]):
        err = one_line_error(*roar_cli(command, TIMEOUT_SPEC, "-r", OPEN, "--wait-timeout", "250", *extra))
        assert "wait_timeout needs the timed mode" in err, err


def test_check_refuses_a_wait_timeout_on_job_files(roar_cli):
    from repo import ROOT
    err = one_line_error(*roar_cli("check", ROOT / "checker" / "door_sensor.toml", "--wait-timeout", "100"))
    assert "--wait-timeout is for a spec named on the command line" in err, err


# ------------------------------------------------------------------ the API: RoarError


def test_the_api_refuses_an_unused_wait_timeout(spec):
    s = load(spec)
    with pytest.raises(RoarError, match=WHY):
        s.run(OPEN, time="timed", wait_timeout=250)
    with pytest.raises(RoarError, match=WHY):
        s.compile(OPEN, "abstract", time="timed", wait_timeout=250)
    with pytest.raises(RoarError, match=WHY):
        s.compile(OPEN, time=Timing("timed", 250))
    with pytest.raises(RoarError, match=WHY):
        s.explore(OPEN, properties=["deadlock"], time="timed", wait_timeout=250)
    # without the timeout, the timed mode is used (the assert and the ensure have periods)
    assert s.run(OPEN, time="timed").ok
    assert s.explore(OPEN, properties=["deadlock"], time="timed").verdicts["deadlock"].status == "holds"


@pytest.mark.parametrize("time,wait_timeout,message", [
    (None, 250, "wait_timeout needs the timed mode"),                   # untimed is the default
    ("untimed", 250, "wait_timeout needs the timed mode"),
    (Timing("untimed"), 250, "wait_timeout needs the timed mode"),       # was silently dropped
    (Timing("timed", 100), 250, "wait_timeout given twice"),             # was silently dropped
])
def test_the_api_refuses_a_wait_timeout_without_the_timed_mode(time, wait_timeout, message):
    s = load(TIMEOUT_SPEC)
    with pytest.raises(RoarError, match=message):
        s.run(OPEN, time=time, wait_timeout=wait_timeout)
    with pytest.raises(RoarError, match=message):
        s.explore(OPEN, properties=["deadlock"], time=time, wait_timeout=wait_timeout)


def test_the_api_takes_the_timeout_in_the_timing_or_beside_it():
    s = load(TIMEOUT_SPEC)
    for kw in ({"time": Timing("timed", 250)}, {"time": Timing("timed"), "wait_timeout": 250},
               {"time": Timing("timed", 250), "wait_timeout": 250}, {"time": "timed", "wait_timeout": 250}):
        report = s.run(OPEN, **kw)
        assert not report.ok and "did not hold within 250 ms" in str(report), kw
