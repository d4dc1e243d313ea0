"""``roar-verify run`` and ``roar-verify compile`` through the CLI entry point (``roar_formal.cli.main``).

Exit codes (0 success, 1 failure or unfinished, 2 bad input, never a traceback), the
``--json`` result against ``run_model`` called directly (an independent path through the
library), the ``--trace`` file against the printed run, and the compiled program.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from fractions import Fraction
from pathlib import Path

import pytest

from roar_formal.cli import main
from roar_formal.clf.program import Program
from roar_formal.roar.functional import functional_module, load_registry
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.spec import load_spec
from roar_formal.roar.run import parse_fault, run_model
from roar_formal.trace.format import read_trace

HERE = Path(__file__).resolve().parent
MODELS = HERE.parents[1] / "models"

DEMO = (MODELS / "demo_loco", "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5")
DEMO_ROAR = HERE / "data" / "demo_loco.roar"   # the same agent, single-file layout (copied to tmp_path)
SPA = (MODELS / "spa_loop.roar", "exec::arrived == true where exec::goal == 7")
NAV = (MODELS / "mana_nav.roar", "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0")

EVENT_LINE = re.compile(r"^ *(\d+) (\S+) +(.*?)$")
VERBOSE_LINE = re.compile(r"^ *(\d+) (\S+) +(.*)  \(([A-Za-z0-9_]+)\)$")
RESULT_LINE = re.compile(r"^request (\S+) after (\d+) CLF steps \((.*)\)$", re.M)


@pytest.fixture(autouse=True)
def _plain_console(monkeypatch):
    """No colours, and lines wide enough that rich never wraps the header."""
    for var in ("FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE", "ROAR_DEBUG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("COLUMNS", "400")
    monkeypatch.setenv("NO_COLOR", "1")


def cli(capsys, *argv) -> tuple[int, str, str]:
    """Run ``roar-verify ARGV``; (exit code, stdout, stderr)."""
    code = 0
    try:
        main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capsys.readouterr()
    return code, out, err


def run_cli(capsys, case, *extra):
    path, request = case
    return cli(capsys, "run", path, "--request", request, *extra)


def printed_events(out: str, verbose: bool = False) -> list[tuple]:
    """(step, agent, text[, rule]) of every event line of a printed run."""
    rx = VERBOSE_LINE if verbose else EVENT_LINE
    rows = []
    for line in out.splitlines():
        m = rx.match(line)
        if m:
            rows.append((int(m[1]), m[2], m[3]) + ((m[4],) if verbose else ()))
    return rows


def assert_user_error(code: int, err: str, *fragments: str) -> None:
    assert code == 2, err
    assert err.startswith("error: "), err
    assert "Traceback" not in err and "internal error" not in err, err
    for f in fragments:
        assert f in err, err


def direct_run(case, seed=0, faults=()):
    """The same run through the library: load, compile (python functional layer), run_model."""
    path, request = case
    model = compile_spec(load_spec(path), request, registry=load_registry(functional_module(path, None)),
                         functional="python")
    return run_model(model, seed=seed, registry=load_registry(functional_module(path, None)),
                     faults=[parse_fault(f) for f in faults])


# ------------------------------------------------------------------ exit codes


def test_success_exits_0(capsys):
    code, out, err = run_cli(capsys, DEMO)
    assert code == 0, err
    assert err == ""
    m = RESULT_LINE.search(out)
    assert m and m[1] == "success" and m[3] == "quiescent"
    assert "demo_loco::pos = 5" in [e[2] for e in printed_events(out)]


def test_failure_exits_1_with_the_error_context(capsys):
    code, out, err = run_cli(capsys, NAV, "--fault", "lidar_ok", "--fault", "sonar_ok")
    assert code == 1, err
    assert RESULT_LINE.search(out)[1] == "failure"
    assert "  error context: task failed: locomotion::goto" in out.splitlines()
    assert "  error context: task failed: perception::acquire" in out.splitlines()


def test_a_run_that_does_not_finish_exits_1(capsys):
    code, out, err = run_cli(capsys, DEMO, "--max-steps", "5")
    assert code == 1, err
    m = RESULT_LINE.search(out)
    assert m[1] != "success" and m[2] == "5"
    assert m[3] == "stopped at the bound of 5 steps, the functional layer's answers included"
    assert "one run cannot tell whether this goes on forever: `roar-verify check`" in " ".join(out.split())
    code, out, err = run_cli(capsys, DEMO)   # a run that ends says nothing of the kind
    assert code == 0 and "one run cannot tell" not in out


def test_unknown_variable_in_the_request_exits_2_located(capsys):
    request = "demo_loco::pos == demo_loco::nope"
    code, out, err = cli(capsys, "run", DEMO[0], "--request", request)
    col = request.index("demo_loco::nope") + 1
    assert_user_error(code, err, f"--request:1:{col}:", "nope")
    assert out == ""   # nothing ran


@pytest.mark.parametrize("fault", ["compute_plan:0", "compute_plan:x", "two words", "compute_plan=", ""])
def test_bad_fault_syntax_exits_2(capsys, fault):
    code, out, err = run_cli(capsys, SPA, "--fault", fault)
    assert_user_error(code, err, "--fault", "expected NAME, NAME:K")


@pytest.mark.parametrize("case,fault,fragment", [
    (SPA, "compute_plan:50", "no such call happened"),
    (DEMO, "no_such_primitive", "the spec has no function"),
    (SPA, "compute_plan=bogus", "has no outcome 'bogus'"),
], ids=["spa-call-50", "demo-unknown-primitive", "spa-unknown-outcome"])
def test_fault_on_a_call_that_never_happens_exits_2(capsys, case, fault, fragment):
    code, out, err = run_cli(capsys, case, "--fault", fault)
    assert_user_error(code, err, fragment, fault)


@pytest.mark.parametrize("faults,fragment", [
    (["compute_plan", "compute_plan=failure"], "--fault compute_plan=failure: conflicts with --fault compute_plan"),
    (["compute_plan:2", "compute_plan:2"], "--fault compute_plan:2: is given twice"),
    (["compute_plan:2=failure", "compute_plan:2"], "--fault compute_plan:2: conflicts with --fault compute_plan:2=failure"),
])
def test_two_faults_of_one_call_are_refused_before_the_run(capsys, faults, fragment):
    # the run took one and then said the other matched no call
    args = [a for f in faults for a in ("--fault", f)]
    code, out, err = run_cli(capsys, SPA, *args)
    assert_user_error(code, err, fragment, faults[0].split(":")[0].split("=")[0])
    assert out == ""   # nothing ran
    # faults of two calls of one function are two faults
    code, out, err = run_cli(capsys, SPA, "--fault", "compute_plan:1", "--fault", "compute_plan:2")
    assert code in (0, 1) and "request " in out, err


def test_missing_spec_exits_2(capsys, tmp_path):
    code, out, err = cli(capsys, "run", tmp_path / "nowhere.roar", "--request", DEMO[1])
    assert_user_error(code, err, "nowhere.roar", "no such file")
    code, out, err = cli(capsys, "compile", tmp_path / "nowhere.roar", "--request", DEMO[1])
    assert_user_error(code, err, "nowhere.roar", "no such file")


def _spec_with_module(tmp_path: Path, source: str) -> Path:
    """A copy of demo_loco (single file) with a functional-layer module next to it."""
    spec = tmp_path / "loco.roar"
    shutil.copy(DEMO_ROAR, spec)
    (tmp_path / "loco.py").write_text(source, encoding="utf-8")
    return spec


@pytest.mark.parametrize("command", ["run", "compile"])
def test_functional_module_that_raises_on_import_exits_2(capsys, tmp_path, command):
    spec = _spec_with_module(tmp_path, "import math\nraise RuntimeError('no simulator here')\n")
    code, out, err = cli(capsys, command, spec, "--request", DEMO[1])
    assert_user_error(code, err, "loco.py", "importing the functional-layer module failed",
                      "RuntimeError: no simulator here")
    # the same module named with --functional, next to another spec
    code, out, err = cli(capsys, command, DEMO_ROAR, "--request", DEMO[1], "--functional", tmp_path / "loco.py")
    assert_user_error(code, err, "loco.py", "RuntimeError: no simulator here")


def test_functional_module_with_a_syntax_error_exits_2(capsys, tmp_path):
    spec = _spec_with_module(tmp_path, "def registry(:\n")
    code, out, err = cli(capsys, "run", spec, "--request", DEMO[1])
    assert_user_error(code, err, "loco.py:1:14: the functional-layer module is not valid Python: invalid syntax")


def test_functional_module_that_fails_on_import_is_located_at_its_line(capsys, tmp_path):
    spec = _spec_with_module(tmp_path, "import math\nX = 1\nY = no_such_name + 1\n")
    code, out, err = cli(capsys, "run", spec, "--request", DEMO[1])
    assert_user_error(code, err, "loco.py:3:1: importing the functional-layer module failed: NameError")


@pytest.mark.parametrize("source,fragment", [
    ("X = 1\n", "defines registry() returning a Registry"),
    ("def registry():\n    return {}\n", "defines registry() returning a Registry"),
    ("registry = 3\n", "defines registry() returning a Registry"),
    ("def registry():\n    raise KeyError('lidar')\n", "registry() failed: KeyError"),
])
def test_functional_module_without_a_registry_exits_2(capsys, tmp_path, source, fragment):
    spec = _spec_with_module(tmp_path, source)
    code, out, err = cli(capsys, "run", spec, "--request", DEMO[1])
    assert_user_error(code, err, "loco.py", fragment)


def test_missing_functional_module_exits_2(capsys, tmp_path):
    code, out, err = cli(capsys, "run", DEMO_ROAR, "--request", DEMO[1], "--functional", tmp_path / "gone.py")
    assert_user_error(code, err, "gone.py", "no such functional-layer module")


# ------------------------------------------------------------------ --json against run_model


@pytest.mark.parametrize("case,seed,faults", [
    (NAV, 7, ("lidar_ok", "sonar_ok")),   # a failure, with its error context
    (SPA, 2, ("compute_plan:1",)),        # a temporary failure: pause and resume
], ids=["mana_nav-both-faults", "spa_loop-compute_plan-1"])
def test_json_agrees_with_run_model(capsys, case, seed, faults):
    extra = ["--seed", seed, "--json"] + [x for f in faults for x in ("--fault", f)]
    code, out, err = run_cli(capsys, case, *extra)
    got = json.loads(out)   # the whole of stdout is the JSON document
    res = direct_run(case, seed, faults)
    assert code == (0 if res.ok else 1), err
    assert got["outcome"] == res.outcome
    assert got["error_context"] == res.error_context
    assert got["events"] == json.loads(json.dumps([dict(step=e.step, **e.as_json()) for e in res.events]))
    assert got["clf_steps"] == len(res.steps) and got["quiescent"] == res.quiescent
    assert (got["spec"], got["request"], got["seed"], got["faults"]) == (str(case[0]), case[1], seed, list(faults))
    assert got["final"].keys() == res.final.keys()
    for k, v in res.final.items():
        if isinstance(v, Fraction):
            assert got["final"][k] == pytest.approx(float(v))
    if faults == ("lidar_ok", "sonar_ok"):
        assert got["outcome"] == "failure" and got["error_context"][0] == "task failed: locomotion::goto"


# ------------------------------------------------------------------ --trace and --verbose


def _trace_events(steps: list[dict]) -> list[tuple]:
    rows = []
    for s in steps:
        ev = s["event"]
        if ev is None:
            continue
        for e in (ev["events"] if ev["kind"] == "several" else [ev]):
            rows.append((s["step"], e["agent"], e["text"]))
    return rows


@pytest.mark.parametrize("case,faults", [(DEMO, ()), (SPA, ("compute_plan:1",))])
def test_trace_file_matches_the_printed_run(capsys, tmp_path, case, faults):
    path = tmp_path / "not" / "yet" / "there" / "run.jsonl"   # the folder does not exist
    extra = [x for f in faults for x in ("--fault", f)]
    code, out, err = run_cli(capsys, case, "--seed", 3, "--trace", path, *extra)
    assert code == 0, err
    header, steps = read_trace(path)
    assert header["kind"] == "roar-run" and header["outcome"] == "success"
    assert (header["request"], header["seed"], header["faults"]) == (case[1], 3, list(faults))
    n = int(RESULT_LINE.search(out)[2])
    assert [s["step"] for s in steps] == list(range(1, n + 1))   # one line per CLF step
    assert all(isinstance(s["rule"], str) and s["rule"] for s in steps)
    printed = printed_events(out)
    assert printed and _trace_events(steps) == printed
    assert f"trace written to {path}" in out
    if faults:
        assert any(s["rule"] == "functional_layer" for s in steps)


def test_trace_replaces_an_existing_file_atomically(capsys, tmp_path):
    folder = tmp_path / "traces"
    folder.mkdir()
    path = folder / "run.jsonl"
    path.write_text("an earlier trace\n", encoding="utf-8")
    before = os.stat(path).st_ino
    code, out, err = run_cli(capsys, DEMO, "--trace", path)
    assert code == 0, err
    header, steps = read_trace(path)
    assert header["kind"] == "roar-run" and steps
    assert os.stat(path).st_ino != before          # a new file renamed over the old one
    assert sorted(os.listdir(folder)) == ["run.jsonl"]   # no temporary file left behind


def test_a_failed_trace_write_keeps_the_earlier_trace(capsys, tmp_path, monkeypatch):
    path = tmp_path / "run.jsonl"
    path.write_text("an earlier trace\n", encoding="utf-8")

    def disk_full(_fd):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(os, "fsync", disk_full)
    code, out, err = run_cli(capsys, DEMO, "--trace", path)
    assert_user_error(code, err, "run.jsonl", "No space left on device")
    assert path.read_text(encoding="utf-8") == "an earlier trace\n"
    assert sorted(os.listdir(tmp_path)) == ["run.jsonl"]


def test_trace_onto_a_folder_is_a_user_error(capsys, tmp_path):
    code, out, err = run_cli(capsys, DEMO, "--trace", tmp_path)
    assert_user_error(code, err, str(tmp_path), "cannot write")
    assert os.listdir(tmp_path) == []


def test_verbose_shows_the_rule_of_each_event(capsys, tmp_path):
    path = tmp_path / "t.jsonl"
    code, out, err = run_cli(capsys, DEMO, "--verbose", "--trace", path)
    assert code == 0, err
    rows = printed_events(out, verbose=True)
    _header, steps = read_trace(path)
    assert rows and len(rows) == len(_trace_events(steps))
    for step, _agent, _text, rule in rows:
        assert rule == steps[step - 1]["rule"]
    rules = {r[3] for r in rows}
    assert "recipe_chosen" in rules and any(re.fullmatch(r"st\d+_set", r) for r in rules)
    # without --verbose, no rule names
    code, plain, err = run_cli(capsys, DEMO)
    assert "(recipe_chosen)" not in plain and "(recipe_chosen)" in out


def test_json_and_trace_together(capsys, tmp_path):
    path = tmp_path / "t.jsonl"
    code, out, err = run_cli(capsys, DEMO, "--json", "--trace", path)
    assert code == 0, err
    got = json.loads(out)   # the trace is written, and nothing but the JSON printed
    _header, steps = read_trace(path)
    assert got["clf_steps"] == len(steps)
    assert [(e["step"], e["agent"], e["text"]) for e in got["events"]] == _trace_events(steps)


# ------------------------------------------------------------------ compile


@pytest.mark.parametrize("case", [DEMO, SPA], ids=["demo_loco", "spa_loop"])
def test_compile_to_stdout_loads_as_a_clf_program(capsys, case):
    path, request = case
    code, out, err = cli(capsys, "compile", path, "--request", request)
    assert code == 0, err
    prog = Program.from_text(out, "<stdout>")
    direct = compile_spec(load_spec(path), request, registry=load_registry(functional_module(path, None)),
                          functional="abstract")
    assert out == direct.text
    assert any(re.fullmatch(r"st\d+_set", r) for r in prog.rule_names)
    assert any(hasattr(d, "start") for d in prog.sig.directives)   # the #exec of the initial context
    if path == SPA[0]:   # primitives as their declared outcome rules
        assert {"outcome_f_plan_compute_plan_planned", "outcome_f_plan_compute_plan_no_path"} <= set(prog.rule_names)


def test_compile_to_a_file_writes_the_same_text(capsys, tmp_path):
    code, printed, err = cli(capsys, "compile", SPA[0], "--request", SPA[1])
    assert code == 0, err
    target = tmp_path / "out" / "spa.clf"
    code, out, err = cli(capsys, "compile", SPA[0], "--request", SPA[1], "-o", target)
    assert code == 0, err
    assert out == ""
    assert target.read_text(encoding="utf-8") == printed
    assert os.listdir(target.parent) == ["spa.clf"]
    target.write_text("old\n", encoding="utf-8")   # an existing file is replaced
    code, out, err = cli(capsys, "compile", SPA[0], "--request", SPA[1], "--output", target)
    assert code == 0 and target.read_text(encoding="utf-8") == printed
    assert os.listdir(target.parent) == ["spa.clf"]


def test_compile_refuses_to_overwrite_the_spec(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("models_copy").mkdir()
    shutil.copy(DEMO_ROAR, "models_copy/x.roar")
    original = Path("models_copy/x.roar").read_text(encoding="utf-8")
    for out_path in ("models_copy/x.roar", "models_copy/../models_copy/x.roar", tmp_path / "models_copy" / "x.roar"):
        code, out, err = cli(capsys, "compile", "models_copy/x.roar", "--request", DEMO[1], "-o", out_path)
        assert_user_error(code, err, "refusing to overwrite")
        assert Path("models_copy/x.roar").read_text(encoding="utf-8") == original
    assert os.listdir("models_copy") == ["x.roar"]


def test_compile_refuses_to_overwrite_a_file_of_a_hyper_folder(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    shutil.copytree(DEMO[0], "loco")
    files = sorted(p for p in Path("loco").rglob("*") if p.is_file())
    before = {p: p.read_bytes() for p in files}
    for spec, victim in [("loco", "loco/demo_loco.ability"), ("loco", "loco/demo_loco/move/direct.recipe"),
                         ("loco/demo_loco.ability", "loco/demo_loco/move.task")]:
        code, out, err = cli(capsys, "compile", spec, "--request", DEMO[1], "-o", victim)
        assert_user_error(code, err, "refusing to overwrite", victim)
    assert {p: p.read_bytes() for p in files} == before
    # a new file inside the folder is fine
    code, out, err = cli(capsys, "compile", "loco", "--request", DEMO[1], "-o", "loco/compiled.clf")
    assert code == 0, err
    assert Path("loco/compiled.clf").read_text(encoding="utf-8").startswith("%")
    assert {p: p.read_bytes() for p in files} == before


def test_compile_errors_are_located(capsys, tmp_path):
    # (a constant expression such as 1 + 1 is a where value since issue 14 item 5; a variable is not)
    request = "demo_loco::pos == demo_loco::goal where demo_loco::goal == demo_loco::pos + 1"
    code, out, err = cli(capsys, "compile", DEMO[0], "--request", request)
    col = request.index("demo_loco::pos + 1") + 1
    assert_user_error(code, err, f"--request:1:{col}:", "must be a constant expression")
    assert out == ""
    code, out, err = cli(capsys, "compile", DEMO[0], "--request", DEMO[1], "-o", tmp_path)
    assert_user_error(code, err, "cannot write")


def test_a_request_no_task_can_handle_says_so(capsys):
    """Its error context is empty (the logic layer tried nothing): the run says why, in the words
    the explorer's verdicts use."""
    code, out, err = run_cli(capsys, (MODELS / "faulty" / "aim.roar", "arm::pos == 5"))
    assert code == 1, err
    assert "  error context: empty: no task of the target agent can handle it (nothing was tried)" in out.splitlines()


@pytest.mark.parametrize("bound", [30, 61, 300])
def test_the_step_bound_is_the_number_of_steps_the_run_takes(capsys, bound):
    """--max-steps N stops a run that does not end after exactly N steps, the functional layer's
    answers among them (it stopped at about 0.57 N: the bound was given to the engine as steps
    left, which the engine reads as its own steps in all)."""
    spec = str(MODELS / "faulty" / "retry_forever.roar")
    code, out, err = cli(capsys, "run", spec, "--request", "hand::holding == true", "--fault", "grip",
                         "--max-steps", str(bound), "--json")
    assert code == 1, err
    got = json.loads(out)
    assert got["clf_steps"] == bound and not got["quiescent"]
    assert max(e["step"] for e in got["events"]) <= bound


def test_a_compiled_spec_checked_as_a_program_says_to_check_the_spec(capsys, tmp_path):
    """A compiled spec's runs all end quiescent, success included: checked as a plain .clf program
    its success is a deadlock, and the verdict says why and what to check instead."""
    spec = MODELS / "faulty" / "mutual_make_fixed.roar"
    target = tmp_path / "compiled.clf"
    code, _out, err = cli(capsys, "compile", spec, "--request", "arm::started == true", "-o", target)
    assert code == 0, err
    code, out, _err = cli(capsys, "check", target)
    text = " ".join(out.split())
    assert code == 1 and "deadlock: violated" in text
    assert "this program is a compiled ROAR spec, whose every run ends in a quiescent state" in text


def test_run_outputs_never_overwrite_the_functional_module_or_each_other(capsys, tmp_path, monkeypatch):
    """``--trace spa_loop.py`` used to replace the functional-layer module with the trace, and two
    outputs on one path left only the last one written."""
    monkeypatch.chdir(tmp_path)
    shutil.copy(SPA[0], "spa.roar")
    shutil.copy(SPA[0].with_suffix(".py"), "spa.py")
    before = {p: Path(p).read_bytes() for p in ("spa.roar", "spa.py")}
    for argv, option in ((["--trace", "spa.py"], "--trace"), (["--dot", "spa.roar"], "--dot"),
                         (["--trace", "out.jsonl", "--dot", "out.jsonl"], "--dot"),
                         (["--trace", "spa.py/out.jsonl"], "--trace")):
        code, out, err = cli(capsys, "run", "spa.roar", "-r", SPA[1], *argv)
        assert_user_error(code, err, option)
        assert out == ""   # refused before the run
    assert {p: Path(p).read_bytes() for p in before} == before
    assert sorted(os.listdir(".")) == ["spa.py", "spa.roar"]
    code, out, err = cli(capsys, "compile", "spa.roar", "-r", SPA[1], "-o", "spa.py")
    assert_user_error(code, err, "refusing to overwrite")
    assert Path("spa.py").read_bytes() == before["spa.py"]
