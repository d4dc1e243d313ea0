"""Visited states kept compact (benchmark B8): exact keys as byte strings, expanded states frozen
without their matching indexes, and hash compaction as a bug-hunting mode. Each is checked
against the plain search it replaces: the same graph, edge for edge."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from roar_formal.clf.context import FrozenContext
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.signature import ExecDirective
from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import Options
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem
from roar_formal.roar.spec import load_spec
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job

from repo import ROOT

SPECS = [
    (ROOT / "models" / "faulty" / "mutual_make.roar", "arm::started == true"),
    (ROOT / "models" / "faulty" / "camera_retry.roar", "camera::taken == true"),
    (ROOT / "models" / "faulty" / "ensure_slammed.roar", "user::done == true"),
]


def _system(spec, request, frozen: bool = True):
    model = compile_spec(load_spec(spec), request)
    program = model.program()
    d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
    system = RoarSystem(model, program.start_context(d.start), Options(progress_rules=PROGRESS_RULES,
                                                                       fairness="agent"))
    if not frozen:
        system.freeze = system.thaw = system.frozen_type = None   # the plain store: contexts as they are
    return system


def _graph(ex):
    g = ex.graph
    return [list(a) for a in (g.src, g.dst, g.label, g.group, g.progress, g.parent, g.depth)]


@pytest.mark.parametrize("spec,request_", SPECS, ids=[s[0].stem for s in SPECS])
def test_frozen_states_explore_exactly_as_live_ones(spec, request_):
    def go():
        plain = Explorer(_system(spec, request_, frozen=False))
        plain.run(Budget(max_states=3000))
        frozen = Explorer(_system(spec, request_))
        frozen.run(Budget(max_states=3000))
        return plain, frozen
    plain, frozen = with_big_stack(go)
    assert _graph(plain) == _graph(frozen)
    assert plain.graph.n_states == frozen.graph.n_states > 20
    assert isinstance(frozen.states.items[0], FrozenContext) and not isinstance(plain.states.items[0], FrozenContext)
    system = frozen.system
    for sid in range(0, frozen.graph.n_states, 7):   # the two searches' states are one up to renaming
        assert canonical_key(plain.states[sid]) == canonical_key(frozen.states[sid])
    for sid in range(0, plain.graph.n_states, 5):    # frozen and thawed: the same facts and enabled steps
        a = plain.states[sid]
        b = FrozenContext(a).thaw()
        assert list(map(str, a.facts())) == list(map(str, b.facts()))
        assert canonical_key(a) == canonical_key(b)
        assert [(c.rule, c.consumed) for c in system.program.steps(a)] == \
               [(c.rule, c.consumed) for c in system.program.steps(b)]


def test_a_long_frontier_is_frozen_too_and_the_graph_does_not_change(monkeypatch):
    import roar_formal.explore.search as search
    spec, request_ = SPECS[2]
    plain = Explorer(with_big_stack(lambda: _system(spec, request_, frozen=False)))
    with_big_stack(lambda: plain.run(Budget(max_states=1500)))
    monkeypatch.setattr(search, "LIVE_FRONTIER", 3)
    short = Explorer(with_big_stack(lambda: _system(spec, request_)))
    with_big_stack(lambda: short.run(Budget(max_states=1500)))
    assert _graph(plain) == _graph(short)
    waiting = list(short.frontier)
    assert len(waiting) > 3 and sum(isinstance(short.states.items[i], FrozenContext) for i in waiting) >= len(waiting) - 3


FAN = """
planner = ability {
  context = { { } { bool done = false; } { } }
  export = { { } { } { } }
  tasks = { work = task { pre = { } post = { {done == true} } recipes = { r = recipe { pre = { } body = {
    let h1 ensure(w1::done == true, 100);
    let h2 ensure(w2::done == true, 100);
    let h3 ensure(w3::done == true, 100);
    wait(w1::done == true && w2::done == true && w3::done == true, 100);
    abort h1; abort h2; abort h3;
    set done true;
  } } } } }
}
""" + "".join(f"""
w{i} = ability {{
  context = {{ {{ }} {{ bool done = false; }} {{ int tries = 0; }} }}
  export = {{ {{ }} {{ bool op(); }} {{ }} }}
  tasks = {{ work = task {{ pre = {{ }} post = {{ {{done == true}} }} recipes = {{ r = recipe {{ pre = {{ {{tries < 2}} }}
    body = {{ set tries tries + 1; assert(op()); set done true; }} }} }} }} }}
}}
""" for i in (1, 2, 3))


def test_a_wide_frontier_enumerates_alike_live_or_thawed(monkeypatch, tmp_path):
    """Three workers interleaving: every state is built in the order thawing gives it
    (``Context.in_order``), so a search that freezes its frontier almost at once numbers its
    states and edges as one that keeps it live (before, removals reordered a live state's
    bags and the two graphs differed from a few thousand states on)."""
    import roar_formal.explore.search as search
    spec = tmp_path / "fan.roar"
    spec.write_text(FAN, encoding="utf-8")
    graphs = []
    for live in (10 ** 9, 2):
        monkeypatch.setattr(search, "LIVE_FRONTIER", live)
        ex = Explorer(with_big_stack(lambda: _system(spec, "planner::done == true")))
        with_big_stack(lambda: ex.run(Budget(max_states=2000)))
        graphs.append(_graph(ex))
        if live == 2:
            for sid in list(ex.frontier)[:40]:   # a frozen waiting state thaws to its live self's order
                a = ex.states[sid]
                b = FrozenContext(a).thaw()
                assert [(c.rule, c.consumed) for c in ex.system.program.steps(a)] == \
                       [(c.rule, c.consumed) for c in ex.system.program.steps(b)]
    assert graphs[0] == graphs[1]


def test_keys_are_exact_byte_strings():
    ex = with_big_stack(lambda: Explorer(_system(*SPECS[1])))
    with_big_stack(lambda: ex.run(Budget(max_states=500)))
    keys = list(ex.ids)
    assert all(isinstance(k, bytes) and len(k) % 8 == 0 for k in keys)
    assert len(set(keys)) == len(keys) == ex.graph.n_states


JOBS = ["mutual_make.toml", "retry_forever.toml", "camera_retry.toml", "philosophers_dl5.toml"]


@pytest.mark.parametrize("name", JOBS)
def test_hash_compaction_gives_the_exact_searchs_graph_and_says_what_a_verdict_is_worth(tmp_path, name):
    exact = with_big_stack(lambda: run_job(load_job(ROOT / "checker" / name)))
    text = (ROOT / "checker" / name).read_text(encoding="utf-8")
    text = text.replace('"../', f'"{ROOT}/')
    job = tmp_path / name
    job.write_text(text.replace("[bounds]", 'visited = "hash"\nbackend = "general"\n[bounds]', 1)
                   if "[bounds]" in text else text + '\nvisited = "hash"\nbackend = "general"\n', encoding="utf-8")
    hashed = with_big_stack(lambda: run_job(load_job(job)))
    assert hashed.backend == "general, hash compaction"
    from roar_formal.testing.api import Exploration
    doc = Exploration(hashed).as_json()
    assert doc["backend"] == "general, hash compaction"
    assert all(v["visited"] == "hash" and 0 <= v["omission_probability"] < 1e-9 for v in doc["verdicts"].values())
    assert (hashed.graph.n_states, hashed.graph.n_edges) == (exact.graph.n_states, exact.graph.n_edges)
    n = hashed.graph.n_states
    for p, v in hashed.verdicts.items():
        assert v.status == exact.verdicts[p].status
        assert v.details["omission_probability"] == pytest.approx(n * (n - 1) / 2 / 2 ** 64)
        if v.status == "holds":
            assert "[hash compaction: not verified; the probability that a state was missed is at most" in v.message
            assert "verified" not in exact.verdicts[p].message


def test_hash_compaction_really_forgets_colliding_states():
    """Two states with one hash are taken for one: with a key that collides for every state, the
    search sees the start state only, while the exact search of the same system sees them all."""
    system = with_big_stack(lambda: _system(*SPECS[0]))
    system.key = lambda state: 42
    ex = Explorer(system, visited="hash")
    with_big_stack(lambda: ex.run(Budget(max_states=1000)))
    assert ex.graph.n_states == 1 and ex.graph.n_edges >= 1 and ex.graph.complete
    assert ex.omission_probability() == 0.0   # (one state: no pair to collide; the bound is about n states)
    with pytest.raises(ValueError, match="visited must be"):
        Explorer(system, visited="bits")


def _job(tmp_path, name: str, extra: str) -> "Path":
    text = (ROOT / "checker" / name).read_text(encoding="utf-8").replace('"../', f'"{ROOT}/')
    head, _, tail = text.partition("[bounds]")
    job = tmp_path / name
    job.write_text(head + extra + ("[bounds]" + tail if tail else ""), encoding="utf-8")
    return job


def test_a_swarm_finds_the_seeded_deadlock_with_a_real_counterexample(tmp_path):
    """Eight philosophers (dl: each may take the left fork first): a few hundred states of a
    randomized depth-first search find the deadlock; replay confirms the path on the model."""
    res = with_big_stack(lambda: run_job(load_job(_job(tmp_path, "philosophers_dl8.toml",
                                                       'search = "swarm"\n[swarm]\nruns = 4\nmax_states = 300\n'))))
    v = res.verdicts["deadlock"]
    assert v.status == "violated" and "[swarm: found by randomized depth-first search" in v.message
    # the budget is checked before each expansion: the last one may add its successors past it
    assert res.graph.n_states <= 300 + max(res.graph.out_degree()) and not res.graph.complete
    from roar_formal.verify.check import save_counterexample
    from roar_formal.verify.replay import replay_trace
    trace = save_counterexample(res, "deadlock", tmp_path)
    rep = with_big_stack(lambda: replay_trace(trace, ROOT / "models" / "philosophers" / "dl8.clf"))
    assert rep.confirmed is True


def test_a_swarm_that_finds_nothing_never_says_holds(tmp_path):
    res = with_big_stack(lambda: run_job(load_job(_job(
        tmp_path, "conflict.toml", 'search = "swarm"\nvisited = "hash"\n[swarm]\nruns = 2\nmax_states = 60\n'))))
    assert res.verdicts["livelock"].status in ("violated", "incomplete")
    for p in ("deadlock", "exclusive-writes"):
        v = res.verdicts[p]
        assert v.status == "incomplete", v.message
        assert v.message.startswith("no violation found by 2 randomized depth-first searches (") and \
            "not verified" in v.message


def test_a_swarm_member_that_covers_everything_gives_the_complete_verdicts(tmp_path):
    exact = with_big_stack(lambda: run_job(load_job(ROOT / "checker" / "mutual_make_fixed.toml")))
    res = with_big_stack(lambda: run_job(load_job(_job(tmp_path, "mutual_make_fixed.toml",
                                                       'search = "swarm"\n[swarm]\nruns = 3\n'))))
    assert res.graph.complete and res.graph.n_states == exact.graph.n_states
    assert {p: v.status for p, v in res.verdicts.items()} == {p: v.status for p, v in exact.verdicts.items()}
    assert all("covered the whole state space" in v.message for v in res.verdicts.values())


@pytest.mark.parametrize("extra,message,line", [
    ('visited = "hashed"\n', "'visited' must be one of exact, hash, bitstate, not 'hashed'", 3),
    ('visited = "hash"\nbackend = "ground"\n', 'visited = "hash" is a mode of the general backend', 3),
    ('[swarm]\nruns = 3\n', 'a [swarm] table needs search = "swarm"', 3),
    ('search = "swarm"\n[swarm]\nruns = 0\n', "[swarm] runs must be a whole number, at least 1, not 0", 5),
    ('search = "swarm"\n[swarm]\nmax_state = 5\n', "max_state", None),
])
def test_bad_search_settings_are_located(tmp_path, extra, message, line):
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT}/models/philosophers/dl.clf"\nproperties = ["{ROOT}/properties/philosophers.toml"]\n'
                   + extra, encoding="utf-8")
    with pytest.raises(RoarError) as e:
        load_job(job)
    assert message in e.value.message and e.value.pos.file == str(job)
    if line is not None:
        assert e.value.pos.line == line, e.value.pos


def test_an_open_swarm_verdict_hints_at_more_or_longer_searches(tmp_path, capsys, monkeypatch):
    """The last line of check names what a swarm can be given (its members stop at their own
    bound, not the job's), not the job's bounds."""
    from roar_formal.cli import main
    monkeypatch.setenv("COLUMNS", "250")
    job = _job(tmp_path, "conflict.toml", 'search = "swarm"\nvisited = "hash"\n[swarm]\nruns = 2\nmax_states = 60\n')
    try:
        with_big_stack(lambda: main(["check", str(job), "--no-traces"]))
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr().out
    assert code in (1, 4)
    assert "more or longer ones may ([swarm] runs and max_states in the job file)" in out
    assert "--max-states" not in out.split("incomplete: ")[-1]


def test_the_jobs_state_bound_holds_for_a_swarm_as_a_whole(tmp_path, capsys, monkeypatch):
    """--max-states (like [bounds] max_states) bounds the swarm's searches together: the verdict
    says how many ran and which bound stopped them, and the hint names that bound."""
    from roar_formal.cli import main
    monkeypatch.setenv("COLUMNS", "250")
    job = _job(tmp_path, "conflict.toml", 'search = "swarm"\nvisited = "hash"\n[swarm]\nruns = 4\nmax_states = 60\n')
    loaded = load_job(job)
    loaded.budget.max_states = 100
    res = with_big_stack(lambda: run_job(loaded))
    v = res.verdicts["deadlock"]
    assert v.status == "incomplete" and v.message.startswith("no violation found by 2 of 4 randomized"), v.message
    assert "; 2 did not run: the state budget of 100 reached)" in v.message
    assert v.details["swarm_states"] <= 100 + 10
    try:
        with_big_stack(lambda: main(["check", str(job), "--no-traces", "--max-states", "100"]))
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr().out
    assert code in (1, 4)
    last = out.split("incomplete: ")[-1]
    assert "the job's budget ended the randomized searches early; raise it (--max-states" in last
    assert " states in the last search, " in out   # the header: the verdicts say the total
    # the summary table counts the swarm's states in all, not its last search's
    row = next(line for line in out.splitlines() if "conflict" in line and "│" in line)
    assert f"{v.details['swarm_states']:,} (swarm)" in row or f"{v.details['swarm_states']:,} (swar" in row, row


def test_a_swarm_that_covers_everything_is_exhaustive_in_json(tmp_path, roar_cli):
    job = _job(tmp_path, "mutual_make_fixed.toml", 'search = "swarm"\n[swarm]\nruns = 3\n')
    code, out, _ = roar_cli("check", job, "--json", "--no-traces")
    doc = json.loads(out)
    assert code == 0 and doc[0]["complete"] and doc[0]["exhaustive"] is True and doc[0]["result"] == "ok"


def test_json_ok_is_false_when_a_verdict_is_missing(tmp_path, roar_cli):
    """A job that expects nothing and runs out of budget is not "ok" in JSON either (exit 4)."""
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT}/models/philosophers/ok.clf"\nproperties = ["{ROOT}/properties/philosophers.toml"]\n'
                   '[bounds]\nmax_states = 5\n', encoding="utf-8")
    code, out, _ = roar_cli("check", job, "--json", "--no-traces")
    doc = json.loads(out)
    assert code == 4 and doc[0]["ok"] is False and doc[0]["result"] == "incomplete" and doc[0]["incomplete"]


def _short(reason: str, check=("deadlock",)):
    from types import SimpleNamespace
    from roar_formal.verify.jobs import PropertySpec
    props = PropertySpec()
    props.check = list(check)
    return SimpleNamespace(graph=SimpleNamespace(stop_reason=reason), job=SimpleNamespace(search="bfs", props=props))


@pytest.mark.parametrize("reason,check,has,lacks", [
    ("time budget of 5 s reached", ("deadlock",), ["--max-seconds", 'search = \"swarm\"'], ["hash", "bitstate"]),
    ("state budget of 9 reached", ("deadlock",), ["--max-states", "swarm"], ["hash", "bitstate"]),
    ("memory budget of 300 MiB reached", ("deadlock",), ["--max-memory", "--visited hash or bitstate"], []),
    ("memory budget of 300 MiB reached", ("deadlock", "livelock"), ["--visited hash", "--search swarm"],
     ["bitstate"]),
])
def test_the_budget_hint_offers_only_modes_that_help(reason, check, has, lacks):
    """Hash compaction and bitstate save memory, not time; bitstate decides no property read on
    cycles: the hint offers them only when memory ran out, and bitstate only when it can decide."""
    from roar_formal.cli.check import _budget_hint
    hint = _budget_hint([_short(reason, check)])
    assert all(h in hint for h in has) and not any(x in hint for x in lacks), hint


def test_search_and_visited_from_the_command_line(roar_cli):
    """--search and --visited override every job's, as a job file's keys would: same states and
    verdicts as the exact search when a swarm's search covers everything, labelled not verified."""
    exact = with_big_stack(lambda: run_job(load_job(ROOT / "checker" / "conflict.toml")))
    code, out, _ = roar_cli("check", ROOT / "checker" / "conflict.toml", "--search", "swarm", "--visited", "hash",
                            "--json", "--no-traces")
    doc = json.loads(out)[0]
    assert code == 0 and doc["visited"] == "hash" and doc["states"] == exact.graph.n_states
    assert {p: v["status"] for p, v in doc["verdicts"].items()} == {p: v.status for p, v in exact.verdicts.items()}
    assert doc["exhaustive"] is False and "covered the whole state space" in doc["verdicts"]["deadlock"]["message"]


@pytest.mark.parametrize("args,message", [
    (["--search", "bogus"], "--search bogus: expected bfs, dfs or swarm"),
    (["--visited", "bits"], "--visited bits: expected exact, hash or bitstate"),
    # a spec's default properties include mission completion, read on cycles
    (["--visited", "bitstate"], "--visited bitstate decides properties read on states; mission-completion needs "
                                "the cycles of the graph"),
    (["--visited", "bitstate", "--search", "swarm", "-p", "deadlock"],
     '--visited bitstate is not available with search = "swarm"'),
])
def test_bad_search_options_are_refused_before_anything_runs(roar_cli, args, message):
    code, out, err = roar_cli("check", ROOT / "models" / "conflict.roar", "-r", "mission::done == true", *args)
    assert code == 2 and message in err and "Traceback" not in err, err


def test_a_one_search_swarm_cut_by_the_jobs_state_bound_names_it(tmp_path):
    job = load_job(_job(tmp_path, "conflict.toml", 'search = "swarm"\nvisited = "hash"\n[swarm]\nruns = 1\nmax_states = 500\n'))
    job.budget.max_states = 50
    res = with_big_stack(lambda: run_job(job))
    v = res.verdicts["deadlock"]
    assert v.status == "incomplete" and "; the state budget of 50 reached)" in v.message, v.message
    assert res.graph.stop_reason == "state budget of 50 reached"
