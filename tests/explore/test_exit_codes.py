"""Exit codes of ``roar-verify check`` as SPIN and TLC give them: a violation is an error unless expected.

0: every verdict as expected; 1: a verdict differs from its expectation, or a property the job
expects nothing of is violated; 4: no violation, but a search ran out of budget (no verdict).
"""

from __future__ import annotations


from roar_formal.cli import main

from repo import ROOT


def check(capsys, tmp_path, text: str, *more: str) -> tuple[int, str, str]:
    job = tmp_path / "job.toml"
    job.write_text(text)
    code = 0
    try:
        main(["check", str(job), "--no-traces", *more])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return code, out, err


def job(model: str, extra: str = "") -> str:
    return (f'name = "j"\nmodel = "{ROOT / "models" / "philosophers" / model}"\n'
            f'properties = ["{ROOT / "properties" / "philosophers.toml"}"]\n{extra}')


def test_a_violation_without_an_expectation_is_an_error(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    code, out, err = check(capsys, tmp_path, job("dl.clf"))
    assert code == 1
    assert "deadlock: violated, and the job expects nothing of it: a violation is an error" in out
    assert "as expected" not in out


def test_the_same_violation_expected_passes(capsys, tmp_path):
    code, out, err = check(capsys, tmp_path, job("dl.clf", '[expect]\ndeadlock = "violated"\nlivelock = "holds"\n'))
    assert code == 0 and "as expected" in out


def test_no_violation_but_no_verdict_has_its_own_exit_code(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    code, out, err = check(capsys, tmp_path, job("ok.clf", "[bounds]\nmax_states = 5\n"))
    assert code == 4
    assert "incomplete" in out and "a budget ran out before a verdict" in out
    # the hint names the bound that ran out, and the modes for a model too large to exhaust
    # (a state or time bound: hash compaction and bitstate save memory, not time, so not them)
    assert "raise it (--max-states, or a job's [bounds])" in out and 'search = "swarm"' in out
    assert 'visited = "hash"' not in out


def test_a_budget_hint_is_given_when_an_expected_verdict_is_left_open(capsys, tmp_path, monkeypatch):
    """A property expected to hold whose search ran out makes the job fail (exit 1): the hint
    says which budget, as for exit 4."""
    monkeypatch.setenv("COLUMNS", "200")
    code, out, err = check(capsys, tmp_path, job("ok.clf", '[bounds]\nmax_states = 5\n[expect]\ndeadlock = "holds"\n'))
    assert code == 1
    assert "incomplete: " in out and "raise it (--max-states" in out and "exit status 4" not in out


def test_max_memory_overrides_the_jobs_bound(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    code, out, err = check(capsys, tmp_path, job("ok.clf", ""), "--max-memory", "5")
    assert code == 2 and "--max-memory 5: expected a whole number of MiB, at least 16" in err


def test_version_and_module_entry_point(capsys):
    import subprocess
    import sys
    code = 0
    try:
        main(["--version"])
    except SystemExit as exc:
        code = exc.code or 0
    out, _err = capsys.readouterr()
    assert code == 0 and out.startswith("roar-verify (roar-formal) ")
    run = subprocess.run([sys.executable, "-m", "roar_formal", "--version"], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0 and run.stdout == out


def run_check(capsys, *argv) -> tuple[int, str, str]:
    code = 0
    try:
        main(["check", *map(str, argv), "--no-traces"])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return code, out, err


def test_a_spec_or_a_program_is_checked_without_a_job_file(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    code, out, err = run_check(capsys, ROOT / "models" / "faulty" / "mutual_make.roar",
                               "-r", "arm::started == true", "--max-states", "10000")
    assert code == 1 and "deadlock: violated: a check from the command line expects every property to hold" in out
    code, out, err = run_check(capsys, ROOT / "models" / "faulty" / "mutual_make_fixed.roar",
                               "-r", "arm::started == true")
    assert code == 0 and "deadlock: holds" in out and "mission-completion: holds" in out   # the spec defaults
    assert "mission-failure: holds" in out and "(a default property)" in out and "livelock" not in out
    code, out, err = run_check(capsys, ROOT / "models" / "philosophers" / "dl.clf", "--property", "deadlock")
    assert code == 1 and "deadlock: violated" in out
    code, out, err = run_check(capsys, ROOT / "models" / "philosophers" / "ok.clf", "--max-states", "5")
    assert code == 4 and "incomplete" in out


def test_checking_without_a_job_file_refuses_what_it_cannot_mean(capsys):
    code, out, err = run_check(capsys, ROOT / "models" / "conflict.roar")
    assert code == 2 and "needs the request to enforce" in err
    code, out, err = run_check(capsys, ROOT / "models" / "philosophers" / "ok.clf", "-p", "livelock")
    assert code == 2 and "needs its progress rules" in err
    code, out, err = run_check(capsys, ROOT / "checker" / "conflict.toml", "-r", "x::y == 1")
    assert code == 2 and "a job file says its own" in err
    code, out, err = run_check(capsys, ROOT / "models" / "philosophers" / "ok.clf", "--max-seconds", "nan")
    assert code == 2 and "--max-seconds" in err


def test_the_readme_deadlock_excerpt_is_what_check_prints(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## What a finding looks like", 1)[1]
    block = section.split("(excerpt):\n\n```\n", 1)[1].split("```", 1)[0]
    code, out, err = run_check(capsys, ROOT / "models" / "faulty" / "mutual_make.roar", "-r", "arm::started == true")
    assert code == 1
    printed = [line.rstrip() for line in out.splitlines()]
    shown = [line.rstrip() for line in block.splitlines() if line.strip()]
    assert len(shown) >= 5 and [line for line in shown if line not in printed] == []


def test_a_spec_named_on_the_command_line_has_a_default_time_bound():
    """No job file gives a bound: a check of a spec or model named directly stops after
    COMMAND_LINE_SECONDS (incomplete, exit 4) instead of running for hours; --max-seconds and
    --max-states override it."""
    from roar_formal.verify.jobs import COMMAND_LINE_SECONDS, job_for_model
    job = job_for_model(ROOT / "models" / "conflict.roar", "mission::done == true")
    assert job.budget.max_seconds == COMMAND_LINE_SECONDS == 600.0 and job.budget.max_states is None
    assert job_for_model(ROOT / "models" / "philosophers" / "dl.clf").budget.max_seconds == COMMAND_LINE_SECONDS


def test_an_incomplete_job_is_not_headed_ok(roar_cli):
    """A job with no violation whose search ran out of budget has no verdict: its header says
    "incomplete", not "ok", and the exit status is 4."""
    code, out, err = roar_cli("check", ROOT / "models" / "conflict.roar", "-r", "mission::done == true",
                              "--max-states", "200", "--no-traces")
    assert code == 4, (out, err)
    first = next(line for line in out.splitlines() if "conflict" in line and "states" in line)
    assert first.startswith("incomplete conflict"), out


def test_a_misspelt_property_on_the_command_line_gets_a_suggestion(capsys):
    code, out, err = run_check(capsys, ROOT / "models" / "faulty" / "mutual_make.roar", "-r", "arm::started == true",
                               "-p", "deadlok")
    assert code == 2 and "--property deadlok (did you mean 'deadlock'?)" in err
