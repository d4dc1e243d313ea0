"""Fairness, budgets, job files and the check command."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings, strategies as st

from roar_formal.cli import main
from roar_formal.clf.program import Program
from roar_formal.verify.check import run_job
from roar_formal.explore.ground import GroundExplorer, GroundModel
from roar_formal.verify.jobs import load_job
from roar_formal.explore.properties import check_deadlock, check_livelock
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import ClfSystem, Options

from repo import ROOT


def graph(src: str, options: Options, budget: Budget = Budget()):
    p = Program.from_text(src)
    ex = Explorer(ClfSystem(p, p.start_context(p.sig.directives[0].start), options))
    return ex.run(budget)


UNFAIR_ONLY = """
proc : type. a : proc. b : proc.
spin : proc -> type. spun : proc -> type. beat : proc -> type.
loop1 : spin P -o {spun P}.
loop2 : spun P -o {spin P}.
heartbeat : beat P -o {beat P}.
#exec * spin a * beat b.
"""


def test_an_unfair_cycle_is_not_a_livelock():
    # a spins forever without progress, but b (whose only step is progress) is enabled all
    # along and never moves: every progress-free cycle starves b.
    g = graph(UNFAIR_ONLY, Options(progress_rules=("heartbeat",)))
    v = check_livelock(g)
    assert v.status == "holds" and v.details["unfair_cycles"]


def test_the_same_cycle_is_a_livelock_when_b_can_stop():
    src = UNFAIR_ONLY.replace("heartbeat : beat P -o {beat P}.", "heartbeat : beat P -o {1}.")
    g = graph(src, Options(progress_rules=("heartbeat",)))
    v = check_livelock(g)
    assert v.violated
    rules = [g.labels.names[g.label[e]] for e in v.counterexample.prefix + v.counterexample.cycle]
    assert rules[: len(v.counterexample.prefix)] == ["heartbeat"]  # b stops first, then a loops alone
    assert set(rules[len(v.counterexample.prefix):]) == {"loop1", "loop2"}


def test_without_fairness_the_unfair_cycle_is_reported():
    g = graph(UNFAIR_ONLY, Options(progress_rules=("heartbeat",), fairness="none"))
    assert check_livelock(g).violated


COUNTER = """
nat : type. z : nat. s : nat -> nat.
c : nat -> type.
up : c N -o {c (s N)}.
#exec * c z.
"""


def test_an_exhausted_budget_is_an_incomplete_verdict_never_holds():
    g = graph(COUNTER, Options(), Budget(max_states=50))
    assert not g.complete
    for v in (check_deadlock(g), check_livelock(g)):
        assert v.status == "incomplete"
        assert "incomplete" in v.message and "50" in v.message
    # worded as the complete verdict is: no *fair* livelock (an unfair cycle is none either)
    assert check_livelock(g).message.startswith("no fair livelock in")
    assert check_livelock(g, strong=True).message.startswith("no strongly fair livelock in")


def test_a_violation_in_a_partial_graph_is_reported():
    src = COUNTER.replace("up : c N -o {c (s N)}.", "up : c N -o {c (s N)}.\nstop : c (s (s z)) -o {1}.")
    g = graph(src, Options(), Budget(max_states=20))
    assert not g.complete
    v = check_deadlock(g)
    assert v.violated and len(v.counterexample.prefix) == 3


# ------------------------------------------------------------ random programs: both backends agree

@st.composite
def programs(draw):
    consts = ["k0", "k1"]
    fams = ["p", "q", "r"]
    rules = []
    for i in range(draw(st.integers(1, 4))):
        prem = draw(st.lists(st.tuples(st.sampled_from(fams), st.sampled_from(consts + ["X"])), min_size=1, max_size=2))
        concl = draw(st.lists(st.tuples(st.sampled_from(fams), st.sampled_from(consts + ["X"])), max_size=2))
        if not any(a == "X" for _, a in prem):
            concl = [(f, a if a != "X" else "k0") for f, a in concl]
        lhs = " * ".join(f"{f} {a}" for f, a in prem)
        rhs = " * ".join(f"{f} {a}" for f, a in concl) or "1"
        rules.append(f"r{i} : {lhs} -o {{{rhs}}}.")
    start = draw(st.lists(st.tuples(st.sampled_from(fams), st.sampled_from(consts)), min_size=1, max_size=4))
    return ("k : type. k0 : k. k1 : k.\n" + "".join(f"{f} : k -> type.\n" for f in fams)
            + "\n".join(rules) + "\n#exec * " + " * ".join(f"{f} {a}" for f, a in start) + ".\n")


@settings(max_examples=40, deadline=None)
@given(programs())
def test_ground_and_general_backends_agree(src):
    p = Program.from_text(src)
    start = p.start_context(p.sig.directives[0].start)
    opts = Options(progress_rules=("r0",))
    g1 = Explorer(ClfSystem(p, start, opts)).run(Budget(max_states=3000))
    if not g1.complete:
        return  # unbounded multisets: compare only finite spaces
    try:
        g2 = GroundExplorer(GroundModel(p, start, opts)).run()
    except Exception as exc:  # the ground backend may refuse (counts too large): never disagree
        assert "exceeds" in str(exc) or "too large" in str(exc)
        return
    assert (g1.n_states, g1.n_edges) == (g2.n_states, g2.n_edges)
    assert sorted(g1.depth) == sorted(g2.depth)
    for check in (check_deadlock, check_livelock):
        a, b = check(g1), check(g2)
        assert a.status == b.status
        if a.counterexample:
            assert a.counterexample.length() == b.counterexample.length() or check is check_livelock


# ------------------------------------------------------------ job files and the command

def write(tmp: Path, name: str, text: str) -> Path:
    f = tmp / name
    f.write_text(text, encoding="utf-8")
    return f


def test_checker_folder_jobs_all_pass():
    for f in sorted((ROOT / "checker").glob("philosophers_*5.toml")):
        res = run_job(load_job(f))
        assert res.ok, (f, res.mismatches)


def test_unexpected_verdict_exits_1(tmp_path, capsys):
    job = write(tmp_path, "j.toml", f'''
name = "wrong expectation"
model = "{ROOT / 'models/philosophers/dl.clf'}"
properties = "{ROOT / 'properties/philosophers.toml'}"
[expect]
deadlock = "holds"
''')
    with pytest.raises(SystemExit) as e:
        main(["check", str(job), "--traces", str(tmp_path / "t")])
    assert e.value.code == 1
    out = capsys.readouterr().out
    assert "expected holds, got violated" in out
    assert (tmp_path / "t" / "wrong_expectation.deadlock.jsonl").exists()


@pytest.mark.parametrize("text,where,msg", [
    ('name = "x"\nmodel = 3\n', ":2:1", "'model' in a job file must be a string"),
    ('model = "m.clf"\n[bounds]\nmax_sates = 3\n', ":3:1", "unknown key 'max_sates'"),
    ('model = "m.clf"\n[expect]\ndeadlock = "fine"\n', ":3:1", "must be 'holds' or 'violated'"),
    ('model = "m.clf"\nbackend = "fast"\n[expect]\ndeadlock = "holds"\n', ":2:1", "'backend' must be one of"),
    ('model = "m.clf\n', ":1:", "invalid TOML"),
    ('model = "m.clf"\n', ":1:1", "the job checks nothing"),
    ('model = "nope.clf"\n', ":1:10", 'model = "nope.clf": no such model'),
    ('model = "m.clf"\n[invariant]\nnever = ["a"]\n', ":2:1", "'invariant' belongs in a property file"),
    ('check = ["deadlock"]\n', ":1:1", "this file looks like one: a folder of jobs should not hold it"),
    ('spec = "nope.roar"\nrequest = "a::b == true"\n', ":1:9", 'spec = "nope.roar": no such spec'),
    ('model = "m.clf"\nproperties = ["none.toml"]\n', ":2:16", 'properties = "none.toml": no such property'),
    # found by fuzzing: a NUL in a path crashed the path library
    ('name = "x"\nspec = "a\\u0000b.roar"\nrequest = "a::b == true"\n', ":2:1", "holds a NUL character"),
])
def test_malformed_job_files_are_located_errors(tmp_path, capsys, text, where, msg):
    write(tmp_path, "m.clf", "a : type.\n")   # the model the jobs name exists: the error is the one tested
    job = write(tmp_path, "bad.toml", text)
    with pytest.raises(SystemExit) as e:
        main(["check", str(job)])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"{job}{where}" in err.replace("\n", "") and msg in err.replace("\n", "")
    assert "Traceback" not in err


def test_json_output(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["check", str(ROOT / "checker/philosophers_ll5.toml"), "--json", "--traces", str(tmp_path)])
    assert e.value.code == 0
    import json
    doc = json.loads(capsys.readouterr().out)
    assert doc[0]["verdicts"]["livelock"]["status"] == "violated"
    assert doc[0]["verdicts"]["livelock"]["counterexample"]["shape"] == "lasso"
    assert doc[0]["states"] == 572
    assert doc[0]["ok"] is True and doc[0]["mismatches"] == []


def test_json_names_what_failed_a_check_from_the_command_line(tmp_path, capsys):
    # no job file: a violation is unexpected, and --json lists it as the text does
    import json
    with pytest.raises(SystemExit) as e:
        main(["check", str(ROOT / "models/philosophers/dl.clf"), "--json", "--no-traces"])
    assert e.value.code == 1
    doc = json.loads(capsys.readouterr().out)[0]
    assert doc["ok"] is False and doc["verdicts"]["deadlock"]["status"] == "violated"
    assert [m.split(":")[0] for m in doc["mismatches"]] == ["deadlock"]
    assert "a check from the command line expects every property to hold" in doc["mismatches"][0]


def test_saved_counterexamples_replay_on_the_engine(tmp_path, capsys):
    for job in ("philosophers_dl5.toml", "philosophers_ll5.toml"):
        with pytest.raises(SystemExit):
            main(["check", str(ROOT / "checker" / job), "--traces", str(tmp_path)])
    capsys.readouterr()
    for trace in sorted(tmp_path.glob("*.jsonl")):
        model = ROOT / "models" / "philosophers" / ("dl.clf" if "-dl-" in trace.name else "ll.clf")
        with pytest.raises(SystemExit) as e:
            main(["replay", str(trace), "--model", str(model)])
        assert e.value.code == 0
        out = capsys.readouterr().out
        assert "replayed" in out
        if "livelock" in trace.name:
            assert "cycle closes" in out


def test_a_tampered_trace_does_not_replay(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["check", str(ROOT / "checker/philosophers_dl5.toml"), "--traces", str(tmp_path)])
    trace = tmp_path / "philosophers-dl-5.deadlock.jsonl"
    lines = trace.read_text().splitlines()
    lines[2] = lines[2].replace("take_first", "eat")
    trace.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["replay", str(trace), "--model", str(ROOT / "models/philosophers/dl.clf")])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "step 2 (eat) cannot be replayed" in err.replace("\n", " ") and "Traceback" not in err


def test_counterexamples_with_fresh_names_replay(tmp_path, capsys):
    # every step makes fresh names; the trace's names differ from the replay's, consistently
    model = write(tmp_path, "fresh.clf", """
dest : type.
tok : dest -> type. link : dest -> dest -> type. go : type. stuck : dest -> type.
mk : go -o {Exists a. Exists b. tok a * link a b}.
hop : tok A * link A B -o {stuck A * stuck B}.
#exec * go * go.
""")
    job = write(tmp_path, "j.toml", '''
name = "fresh"
model = "fresh.clf"
[expect]
deadlock = "violated"
''')
    with pytest.raises(SystemExit) as e:
        main(["check", str(job), "--traces", str(tmp_path / "t")])
    assert e.value.code == 0
    trace = tmp_path / "t" / "fresh.deadlock.jsonl"
    assert "#" in trace.read_text()  # fresh names are recorded as hint#id
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["replay", str(trace), "--model", str(model)])
    assert e.value.code == 0, capsys.readouterr()
    assert "replayed 4 steps" in capsys.readouterr().out


def test_a_progress_rule_name_that_names_no_rule_is_refused_where_it_is_written(tmp_path, roar_cli):
    """A misspelt progress rule would make no step progress, and livelock would report every
    cycle: refused at its place in the property file, with the rule meant."""
    props = tmp_path / "p.toml"
    props.write_text('check = ["livelock"]\n[livelock]\nprogress = ["eta"]\n', encoding="utf-8")
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT / "models" / "philosophers" / "ll.clf"}"\nproperties = ["p.toml"]\n',
                   encoding="utf-8")
    code, out, err = roar_cli("check", job)
    assert code == 2 and "Traceback" not in out + err
    assert f"{props}:3:14: livelock progress 'eta' is not the name of a rule" in err and "did you mean 'eat'" in err
    props.write_text('check = ["livelock"]\n[livelock]\nprogress = ["ea*"]\n', encoding="utf-8")   # a glob: fine
    code, out, err = roar_cli("check", job, "--no-traces")
    assert code == 1 and "livelock: violated" in out


def test_an_unknown_property_is_located_at_its_name(tmp_path, capsys):
    """A misspelt property in a property file is located at the word, not at the line's start."""
    write(tmp_path, "m.clf", "a : type.\n")
    props = write(tmp_path, "p.toml", 'check = ["deadlock",\n         "livelok"]\n')
    job = write(tmp_path, "j.toml", 'model = "m.clf"\nproperties = ["p.toml"]\n')
    with pytest.raises(SystemExit) as e:
        main(["check", str(job)])
    assert e.value.code == 2
    err = capsys.readouterr().err.replace("\n", "")
    assert f"{props}:2:11: unknown property 'livelok' (did you mean 'livelock'?)" in err


def test_two_jobs_of_one_name_keep_both_traces(tmp_path, capsys):
    # jobs in two folders, one name (the dl and ll philosophers): the later one's trace is
    # <name>-2, not written over the first; each replays on its own model
    jobs = []
    for variant in ("dl5", "ll5"):
        folder = tmp_path / variant
        folder.mkdir()
        text = (ROOT / "checker" / f"philosophers_{variant}.toml").read_text(encoding="utf-8")
        text = re.sub(r'^name = ".*"$', 'name = "phil"', text, flags=re.M)
        text = text.replace('"../', f'"{ROOT.as_posix()}/')
        assert 'name = "phil"' in text
        (folder / "job.toml").write_text(text, encoding="utf-8")
        jobs.append(str(folder / "job.toml"))
    traces = tmp_path / "traces"
    with pytest.raises(SystemExit):
        main(["check", *jobs, "--traces", str(traces)])
    out = capsys.readouterr().out
    first, second = sorted(traces.glob("phil.*.jsonl")), sorted(traces.glob("phil-2.*.jsonl"))
    assert first and second, sorted(traces.iterdir())
    assert f"phil-2.{second[0].name.split('.')[1]}.jsonl" in re.sub(r"\s+", "", out)   # (wrapped or not)
    for trace, model in [(first[0], "dl.clf"), (second[-1], "ll.clf")]:
        with pytest.raises(SystemExit) as e:
            main(["replay", str(trace), "--model", str(ROOT / "models" / "philosophers" / model)])
        assert e.value.code == 0, capsys.readouterr().out
        capsys.readouterr()
