"""What the command line prints survives the terminal printer: ``file:100:col`` and
``file:1234:col`` stay locations (rich would turn ``:100:`` into an emoji), text read from
input is never taken for markup or sent as control characters. Through the real CLI."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from repo import ROOT


def cli(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "roar_formal.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=300, cwd=cwd, env={"COLUMNS": "300", "PATH": "/usr/bin:/bin"})


def one_line(text: str) -> str:
    return text.replace("\n", " ")


@pytest.mark.parametrize("line", [100, 1234])
def test_clf_type_error_location(tmp_path, line):
    src = ["nat : type."] + ["% filler"] * (line - 2) + ["    x : nosuch."]
    path = tmp_path / "p.clf"
    path.write_text("\n".join(src) + "\n")
    r = cli("clf", path)
    assert r.returncode == 2
    assert f"error: {path}:{line}:9: unknown type family 'nosuch'" in one_line(r.stderr), r.stderr
    assert "\U0001f4af" not in r.stderr and "\U0001f522" not in r.stderr  # 💯 and 🔢


@pytest.mark.parametrize("line", [100, 1234])
def test_job_file_error_location(tmp_path, line):
    job = tmp_path / "j.toml"
    job.write_text("\n".join(['model = "m.clf"'] + ["# filler"] * (line - 2) + ["colour = 3"]) + "\n")
    r = cli("check", job, "--no-traces")
    assert r.returncode == 2
    assert f"{job}:{line}:1: unknown key 'colour' in a job file" in one_line(r.stderr), r.stderr


@pytest.mark.parametrize("line", [100, 1234])
def test_trace_error_locations(tmp_path, line):
    ok = json.dumps({"event": "constraint_sent", "time": 0, "msg": "m", "kind": "goal"})
    path = tmp_path / "t.jsonl"
    path.write_text("\n".join([ok] * (line - 1) + ['{"event": "started", "time": 1, "msg": 7}']) + "\n")
    r = cli("tca-check", path)
    assert r.returncode == 2
    assert f"{path}:{line}:" in r.stderr and ":100:" in f"{path}:{line}:" or str(line) == "1234"
    assert re.search(rf"{re.escape(str(path))}:{line}:\d+: expected field 'msg'", one_line(r.stderr)), r.stderr
    # the engine trace reader of replay
    bad = tmp_path / "r.jsonl"
    bad.write_text("\n".join([json.dumps({"trace": "roar-formal", "version": 1})]
                             + [json.dumps({"step": i, "rule": "x"}) for i in range(1, line - 1)] + ["{oops"]) + "\n")
    r = cli("replay", bad, "--model", ROOT / "models" / "philosophers" / "dl.clf")
    assert r.returncode == 2
    assert f"{bad}:{line}:2: not a JSON object" in one_line(r.stderr), r.stderr


@pytest.mark.parametrize("line", [100, 1234])
def test_spec_error_location(tmp_path, line):
    spec = tmp_path / "s.roar"
    spec.write_text("\n".join(["// filler"] * (line - 1) + ["agent a {"]) + "\n")
    r = cli("run", spec, "--request", "a::x == 1")
    assert r.returncode == 2
    assert re.search(rf"{re.escape(str(spec))}:{line}:\d+:", r.stderr), r.stderr
    assert "Traceback" not in r.stderr


def test_input_text_is_not_markup_or_emoji_or_control(tmp_path):
    """Message ids from a trace print verbatim in tca-check's table and explanations."""
    ids = ["[bold]m1[/]", ":smile:m2", "m3\x1b[2J"]
    recs = [{"event": "constraint_sent", "time": 0, "msg": ids[0], "kind": "query"},  # a query with a child
            {"event": "started", "time": 1, "msg": ids[0]},
            {"event": "constraint_sent", "time": 2, "msg": ids[1], "kind": "command", "parent": ids[0]},
            {"event": "constraint_sent", "time": 0, "msg": ids[2], "kind": "query", "parent": ids[1]}]
    path = tmp_path / ":100:.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in recs))
    r = cli("tca-check", path)
    assert r.returncode == 1
    out = r.stdout
    assert f"{path}:" in out  # the file name itself, ':100:' and all
    assert "[bold]m1[/]" in out and ":smile:m2" in out
    assert "\x1b" not in out and "m3\\x1b[2J" in out
    assert "\U0001f604" not in out  # 😄


def test_a_missing_file_named_like_an_emoji_code(tmp_path):
    r = cli("replay", tmp_path / ":100:.jsonl", "--model", ROOT / "models" / "philosophers" / "dl.clf")
    assert r.returncode == 2
    assert f"cannot read {tmp_path}/:100:.jsonl: no such file" in one_line(r.stderr)


def test_every_console_of_the_package_comes_from_make_console():
    """rich's Console(...) directly would bring emoji and markup back."""
    package = ROOT / "roar_formal"
    found = []
    for f in package.rglob("*.py"):
        if f.name == "console.py" and f.parent == package / "cli":
            continue
        for n, text in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"\bConsole\(", text):
                found.append(f"{f.relative_to(ROOT)}:{n}: {text.strip()}")
    assert not found, "construct consoles with roar_formal.cli.console.make_console:\n" + "\n".join(found)


def test_shell_completion_names_commands_and_options():
    """`roar-verify --show-completion` (in bash) prints a script for `roar-verify`; the script's
    protocol completes command names and a command's options."""
    import os
    # (the shell named: detecting it walks up the process tree, which under a test runner may hold none)
    script = subprocess.run([sys.executable, "-m", "roar_formal", "--show-completion", "bash"], capture_output=True,
                            text=True, timeout=60, env={**os.environ, "SHELL": "/bin/bash"})
    assert script.returncode == 0 and "_roar_verify_completion()" in script.stdout
    env = {**os.environ, "_ROAR_VERIFY_COMPLETE": "complete_bash", "COMP_WORDS": "roar-verify ch", "COMP_CWORD": "1"}
    r = subprocess.run([sys.executable, "-m", "roar_formal"], capture_output=True, text=True, env=env, timeout=60)
    assert r.stdout.split() == ["check"]
    env.update(COMP_WORDS="roar-verify check --max", COMP_CWORD="2")
    r = subprocess.run([sys.executable, "-m", "roar_formal"], capture_output=True, text=True, env=env, timeout=60)
    assert set(r.stdout.split()) == {"--max-states", "--max-seconds", "--max-memory"}


def test_check_cut_short_by_its_reader_is_not_a_differing_verdict(tmp_path):
    """`check ... | head -1`: the reader leaves; the status is a pipeline's 141, not the 1 of a
    verdict that differs from its expectation (rich's default), and no traceback."""
    code = ("import sys\nfrom roar_formal.cli import main\nmain(['check', sys.argv[1], '--no-traces'])\n")
    many = [str(ROOT / "checker" / n) for n in ("philosophers_dl5.toml",) * 1]
    p = subprocess.Popen([sys.executable, "-c", code, *many], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         env={"COLUMNS": "300", "PATH": "/usr/bin:/bin"}, cwd=tmp_path)
    p.stdout.close()  # the reader leaves before the first line (as `| head -0` would)
    err = p.stderr.read().decode()
    p.wait(timeout=300)
    assert p.returncode == 141 and "Traceback" not in err and "internal error" not in err, (p.returncode, err)
