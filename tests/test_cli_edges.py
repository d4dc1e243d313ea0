"""Edges of the command line a reviewer found: interrupts, bounds, located job errors, default
markers, what ``--json`` says of a search that ran out of budget, what ``T`` is in CLF."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from repo import ROOT

LOOP = "a : type. r : a -o {a}. #exec * a.\n"   # runs forever


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_endless_run_stops_on_an_interrupt_without_a_traceback(tmp_path, sig):
    """The search runs in a thread with a big stack; the process must not wait for it once the
    main thread is interrupted (it did for SIGTERM), and Ctrl-C prints no traceback (it did for
    ``clf``, which bypasses the command framework)."""
    (tmp_path / "loop.clf").write_text(LOOP, encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NO_COLOR": "1"}
    # (the child gets the default handling of SIGINT: a test worker may run with it ignored, which
    # a child inherits, and Python then installs no Ctrl-C handler)
    p = subprocess.Popen([sys.executable, "-m", "roar_formal.cli", "clf", "loop.clf"], cwd=tmp_path, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        time.sleep(3)
        assert p.poll() is None   # still running: the loop does not end by itself
        p.send_signal(sig)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert "Traceback" not in err and "Traceback" not in out
    assert p.returncode == (130 if sig == signal.SIGINT else 128 + signal.SIGTERM)
    if sig == signal.SIGINT:
        assert "interrupted" in err


@pytest.mark.parametrize("command", ["run", "simulate"])
@pytest.mark.parametrize("bound", ["0", "-5"])
def test_a_step_bound_must_be_positive(roar_cli, command, bound):
    code, out, err = roar_cli(command, ROOT / "models" / "spa_loop.roar", "-r", "exec::arrived == true",
                              "--max-steps", bound)
    assert code == 2 and "--max-steps" in out + err and "success" not in out


def test_a_start_past_the_models_exec_directives_is_located(roar_cli, tmp_path):
    (tmp_path / "m.clf").write_text("a : type.\n#exec * a.\n", encoding="utf-8")
    (tmp_path / "j.toml").write_text('model = "m.clf"\nstart = 5\n[expect]\ndeadlock = "violated"\n',
                                     encoding="utf-8")
    code, out, err = roar_cli("check", tmp_path / "j.toml")
    assert code == 2
    assert f"{tmp_path / 'j.toml'}:2:1: 'start = 5' but m.clf has only 1 #exec or #trace directive(s)" in out + err


def test_the_default_property_of_a_program_is_marked(roar_cli, tmp_path):
    code, out, _err = roar_cli("check", ROOT / "models" / "philosophers" / "dl.clf", "--traces", tmp_path)
    assert code == 1
    assert "deadlock: violated" in out and "(a default property)" in out
    code, out, _err = roar_cli("check", ROOT / "models" / "philosophers" / "dl.clf", "--property", "deadlock",
                               "--traces", tmp_path)
    assert code == 1 and "(a default property)" not in out


def test_json_names_the_properties_a_budget_left_without_a_verdict(roar_cli, tmp_path):
    code, out, _err = roar_cli("check", ROOT / "models" / "philosophers" / "ok.clf", "--max-states", "50", "--json",
                               "--traces", tmp_path)
    assert code == 4
    (job,) = json.loads(out)
    assert job["complete"] is False and job["incomplete"] == ["deadlock"]
    code, out, _err = roar_cli("check", ROOT / "models" / "philosophers" / "ok.clf", "--max-states", "50",
                               "--traces", tmp_path)
    assert code == 4 and "--max-states" in out


def test_a_mismatch_with_top_says_what_T_is(roar_cli, tmp_path):
    (tmp_path / "t.clf").write_text("q : type. a : q.\nf : T -> type.\ng : f a -> type.\n", encoding="utf-8")
    code, out, err = roar_cli("clf", tmp_path / "t.clf")
    assert code == 2
    assert "t.clf:3:7: type mismatch in the argument 'a'" in out + err
    assert "'T' is CLF's top type" in out + err
    (tmp_path / "u.clf").write_text("q : type. a : q.\nf : U -> type.\n", encoding="utf-8")
    code, out, err = roar_cli("clf", tmp_path / "u.clf")
    assert code == 2 and "'U' is a variable, not a type family (CLF has no type variables)" in out + err


def test_check_a_spec_with_a_functional_layer_named_on_the_command_line(roar_cli, tmp_path, checker_job):
    """`check SPEC --functional MODULE`: the spec's outcomes come from MODULE, not from a SPEC.py
    next to it; the same graph as the checker job that names the module in its file."""
    import shutil
    spec = tmp_path / "pick.roar"
    shutil.copy(ROOT / "models" / "faulty" / "ordered_pick.roar", spec)
    code, out, _ = roar_cli("check", spec, "-r", "cell::done == true", "--functional",
                            ROOT / "models" / "faulty" / "reliable_tools.py", "--no-traces", "--json")
    ref = checker_job("ordered_pick.toml")
    job = json.loads(out)[0]
    assert job["states"] == ref.graph.n_states and job["transitions"] == ref.graph.n_edges
    code, _out, err = roar_cli("check", spec, "-r", "cell::done == true", "--functional", tmp_path / "nope.py")
    assert code == 2 and "--functional" in err and "no such file" in err
    code, _out, err = roar_cli("check", ROOT / "checker" / "ordered_pick.toml", "--functional",
                               ROOT / "models" / "faulty" / "reliable_tools.py")
    assert code == 2 and "a job file says its own" in err


def test_trial_messages_say_what_was_meant(roar_cli, tmp_path):
    """Found by a trial: a misspelt [robot] key gets a did-you-mean; a bound written at the top of a
    job file says it belongs in [bounds]; a truncated trace line does not leave "starting at"
    dangling; a spec given to prove --model says what a TCA model is."""
    job = tmp_path / "k.toml"
    job.write_text(f'name = "x"\nmodel = "{ROOT / "models" / "philosophers" / "ok.clf"}"\nmax_state = 3\n')
    code, _out, err = roar_cli("check", job)
    assert code == 2 and "(did you mean 'max_states'?; the bounds go in a [bounds] table)" in err
    job.write_text(f'name = "x"\nmodel = "{ROOT / "models" / "philosophers" / "ok.clf"}"\nmax_states = 3\n'
                   '[expect]\ndeadlock = true\n')
    code, _out, err = roar_cli("check", job)
    assert code == 2 and "('max_states' is a bound: it goes in a [bounds] table)" in err and "did you mean" not in err
    assert "must be 'holds' or 'violated', not true" in err   # the value as TOML writes it, not Python's True
    job.write_text(f'name = "x"\nspec = "{ROOT / "models" / "conflict.roar"}"\nrequest = "mission::done == true"\n'
                   f'[robot]\nscenario = "{ROOT / "models" / "scenarios" / "gripper.toml"}"\nquantize = "exact"\n')
    code, _out, err = roar_cli("check", job)
    assert code == 2 and "unknown key 'quantize' in [robot] (did you mean 'quantise'?)" in err
    trace = tmp_path / "t.jsonl"
    trace.write_text('{"kind": "roar-run", "spec": "unfinished\n')
    code, _out, err = roar_cli("tca-check", trace)
    assert code == 2 and "Unterminated string starting here" in err and "starting at" not in err
    code, _out, err = roar_cli("prove", "--model", ROOT / "models" / "conflict.roar")
    assert code == 2 and "is a ROAR spec; a TCA model is a task-tree TOML file" in err


def test_replay_on_robot_of_a_counterexample_of_another_spec_says_so(roar_cli, tmp_path):
    """replay --on-robot checks the trace's spec before compiling the trace's request on the spec
    given (which failed on a variable the other spec has: "agent 'mission' has no variable")."""
    code, _out, err = roar_cli("check", ROOT / "checker" / "conflict.toml", "--traces", tmp_path / "tr")
    assert code == 0, err
    trace = tmp_path / "tr" / "conflict.livelock.jsonl"
    code, _out, err = roar_cli("replay", trace, "--model", ROOT / "models" / "faulty" / "camera_retry.roar",
                               "--on-robot", ROOT / "models" / "scenarios" / "ptu_cable.toml")
    assert code == 2 and "was recorded on another spec than" in err and "conflict.roar" in err
    assert "has no variable" not in err


def test_a_job_file_reports_every_independent_error_at_once(roar_cli, tmp_path):
    """Unknown keys, bad bounds and bad expected verdicts in different tables are all reported in
    one run, in the order of the file's lines; a key whose value was refused does not bring a
    second error about what reads it (a [swarm] table after a refused 'search')."""
    job = tmp_path / "j.toml"
    job.write_text(f'spec = "{ROOT / "models" / "conflict.roar"}"\nrequest = "x"\nvisted = "hash"\n'
                   'search = "breadth"\n[swarm]\nruns = 2\n'
                   '[bounds]\nmax_states = -5\nmax_secs = 3\n[expect]\nlivelok = "holds"\ndeadlock = "maybe"\n',
                   encoding="utf-8")
    code, out, err = roar_cli("check", job)
    assert code == 2 and "Traceback" not in out + err
    text = out + err
    found = [(int(m.group(1)), m.group(2)) for m in re.finditer(rf"{re.escape(str(job))}:(\d+):\d+: ([^\n]*)", text)]
    lines = [n for n, _ in found]
    assert lines == [3, 4, 8, 9, 11, 12], text
    assert "unknown key 'visted'" in found[0][1] and "(and 5 more errors)" in found[0][1]
    assert "'search' must be one of" in found[1][1]
    assert "max_states must be" in found[2][1] and "unknown key 'max_secs'" in found[3][1]
    assert "unknown key 'livelok'" in found[4][1] and 'not "maybe"' in found[5][1]
    assert "needs search" not in text   # the [swarm] table is not blamed for the refused search
    # one error alone reads as before: no count, no notes
    job.write_text(f'spec = "{ROOT / "models" / "conflict.roar"}"\nrequest = "x"\nvisted = "hash"\n', encoding="utf-8")
    code, out, err = roar_cli("check", job)
    assert code == 2 and "more error" not in out + err and f"{job}:3:1: unknown key 'visted'" in out + err


def test_a_property_file_on_the_command_line_checks_as_the_job_naming_it(roar_cli, tmp_path, checker_job):
    """`check MODEL --properties FILE` checks what FILE names, the way it says (livelock progress
    rules on a .clf program): the same verdicts and graph as the bundled job naming that file."""
    code, out, _ = roar_cli("check", ROOT / "models" / "philosophers" / "ll.clf", "--properties",
                            ROOT / "properties" / "philosophers.toml", "--no-traces", "--json")
    ref = checker_job("philosophers_ll5.toml")
    job = json.loads(out)[0]
    assert code == 1   # a violation the command line did not expect
    assert job["states"] == ref.graph.n_states and job["transitions"] == ref.graph.n_edges
    assert {k: v["status"] for k, v in job["verdicts"].items()} == {k: v.status for k, v in ref.verdicts.items()}
    # --property narrows what the file names; the file still says how (its progress rules)
    code, out, _ = roar_cli("check", ROOT / "models" / "philosophers" / "ll.clf", "--properties",
                            ROOT / "properties" / "philosophers.toml", "-p", "livelock", "--no-traces", "--json")
    assert list(json.loads(out)[0]["verdicts"]) == ["livelock"]
    assert json.loads(out)[0]["verdicts"]["livelock"]["status"] == "violated"


def test_a_spec_checked_with_a_property_file_names_progress_in_its_terms(roar_cli, tmp_path):
    """The endless camera retry: livelock holds by the default progress (and says what it counted),
    is violated with the property file's progress (the job's request finishes), as a job file
    naming the same file finds it."""
    spec = ROOT / "models" / "faulty" / "camera_retry.roar"
    req = "camera::taken == true"
    code, out, _ = roar_cli("check", spec, "-r", req, "-p", "livelock", "--no-traces", "--json")
    v = json.loads(out)[0]["verdicts"]["livelock"]
    assert code == 0 and v["status"] == "holds" and "progress: any request of any agent" in v["message"]
    code, out, _ = roar_cli("check", spec, "-r", req, "--properties", ROOT / "properties" / "roar.toml",
                            "--no-traces", "--json")
    direct = json.loads(out)[0]
    job = tmp_path / "j.toml"
    job.write_text(f'spec = "{spec}"\nrequest = "{req}"\nproperties = ["{ROOT / "properties" / "roar.toml"}"]\n',
                   encoding="utf-8")
    _code, out, _ = roar_cli("check", job, "--no-traces", "--json")
    viajob = json.loads(out)[0]
    assert code == 1 and direct["verdicts"]["livelock"]["status"] == "violated"
    assert {k: v["status"] for k, v in direct["verdicts"].items()} == \
        {k: v["status"] for k, v in viajob["verdicts"].items()}
    assert direct["states"] == viajob["states"]


def test_property_files_on_the_command_line_are_checked_before_anything_runs(roar_cli, tmp_path):
    clf = ROOT / "models" / "philosophers" / "ll.clf"
    code, _, err = roar_cli("check", clf, "--properties", tmp_path / "none.toml")
    assert code == 2 and "--properties" in err and "no such file" in err
    terms = tmp_path / "terms.toml"
    terms.write_text('[invariant]\nnever = ["arm::x == 1"]\n', encoding="utf-8")
    code, _, err = roar_cli("check", clf, "--properties", terms)
    assert code == 2 and "written in the spec's terms" in err and f"{terms}:2:" in err
    code, _, err = roar_cli("check", clf, "-p", "livelock")
    assert code == 2 and "--properties FILE" in err
    code, _, err = roar_cli("check", ROOT / "checker" / "conflict.toml", "--properties", terms)
    assert code == 2 and "--properties" in err and "a job file" in err
    (tmp_path / "empty").mkdir()
    code, _, err = roar_cli("check", tmp_path / "empty", "-r", "a::x == 1")
    assert code == 2 and "no model, spec or job file" in err


@pytest.mark.parametrize("backend", ["auto", "ground", "general"])
def test_a_rule_with_a_head_only_variable_is_refused_at_the_rule(roar_cli, tmp_path, backend):
    """``Q`` is bound by no premise: firing ``r`` puts a logic variable in the state. The auto
    backend used to ground it forever; the general one refused with no location."""
    (tmp_path / "m.clf").write_text("proc : type. p1 : proc.\nidle : proc -> type.\n"
                                    "r : idle P -o {idle Q}.\n#exec * idle p1.\n", encoding="utf-8")
    (tmp_path / "j.toml").write_text(f'model = "m.clf"\nbackend = "{backend}"\n[expect]\ndeadlock = "holds"\n',
                                     encoding="utf-8")
    code, out, err = roar_cli("check", tmp_path / "j.toml", "--max-seconds", "60")
    assert code == 2
    assert f"{tmp_path / 'm.clf'}:3:1: rule 'r' uses variable Q only in its head" in out + err


def test_backend_ground_on_a_model_it_cannot_run_points_at_the_line(roar_cli, tmp_path):
    (tmp_path / "m.clf").write_text("a : type. n : type. b : n -> type.\nr : a -o {Exists x. b x}.\n#exec * a.\n",
                                    encoding="utf-8")
    (tmp_path / "j.toml").write_text('model = "m.clf"\n\nbackend = "ground"\n[expect]\ndeadlock = "violated"\n',
                                     encoding="utf-8")
    code, out, err = roar_cli("check", tmp_path / "j.toml")
    assert code == 2
    assert (f"{tmp_path / 'j.toml'}:3:11: backend 'ground' cannot run this model: rule 'r' makes fresh names"
            in out + err)


def test_a_livelock_job_on_a_clf_model_needs_progress_rules_as_the_command_line_does(roar_cli, tmp_path):
    """Without progress rules every cycle is a livelock: the command line refused; a job ran."""
    (tmp_path / "m.clf").write_text("a : type. b : type.\nab : a -o {b}.\nba : b -o {a}.\n#exec * a.\n",
                                    encoding="utf-8")
    (tmp_path / "j.toml").write_text('model = "m.clf"\n[expect]\nlivelock = "holds"\n', encoding="utf-8")
    code, out, err = roar_cli("check", tmp_path / "j.toml")
    assert code == 2 and f"{tmp_path / 'j.toml'}:3:1: " in err and "needs its progress rules" in err
    code, out, err = roar_cli("check", tmp_path / "m.clf", "--property", "livelock")
    assert code == 2 and "needs its progress rules" in err
