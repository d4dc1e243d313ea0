"""ROAR runs as TCA task trees: tca-check on the project's own traces.

* every bundled spec's ``run --trace`` is a task tree that conforms (and is not empty);
* the ``ordered_pick`` counterexample breaks SeqAch, naming the two subtrees;
* a trace with no task-tree message is an error, not a pass;
* the explorer's sequential-achievement monitor and the TCA check agree on random paths
  through the explored state spaces of the seeded faulty models (an independent oracle
  for each: a monitor kept in the states, the axioms and theorem in Z3 on the trace).
"""

from __future__ import annotations

import json


import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.roar.explore import path_events
from roar_formal.tca.check import check_events, check_trace
from roar_formal.tca.roar_runs import task_tree_events

from repo import ROOT
MODELS = ROOT / "models"

RUNS = [
    (MODELS / "demo_loco", "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5"),
    (MODELS / "spa_loop.roar", "exec::arrived == true where exec::goal == 7"),
    (MODELS / "mana_nav.roar", "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0"),
    (MODELS / "conflict.roar", "mission::done == true"),
    (MODELS / "door_nav.roar", "base::arrived == true where base::gx == 9.0 && base::gy == 3.0"),
    (MODELS / "pick_place.roar", "carrier::delivered == true"),
]


@pytest.fixture
def cli(roar_cli):
    """The shared in-process command line (tests/conftest.py), called as ``cli(capsys, *argv)``."""
    return lambda _capsys, *argv: roar_cli(*argv)


@pytest.mark.parametrize("spec,request_", RUNS, ids=[p.name.split(".")[0] for p, _r in RUNS])
def test_every_bundled_run_is_a_conforming_task_tree(cli, capsys, tmp_path, spec, request_):
    trace = tmp_path / "run.jsonl"
    assert cli(capsys, "run", spec, "-r", request_, "--trace", trace)[0] == 0
    report = check_trace(trace)
    kinds = {m.kind for m in report.tree.messages.values()}
    assert report.ok, [v.explanation for v in report.violations]
    assert "goal" in kinds and len(report.tree.messages) >= 2
    if spec.name != "demo_loco":
        assert "command" in kinds          # primitive calls are commands
    code, out, err = cli(capsys, "tca-check", trace)
    assert code == 0 and f"{len(report.tree.messages)} messages" in out and "no violations" in out
    code, out, err = cli(capsys, "tca-check", trace, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["ok"] is True and doc["violations"] == []
    assert doc["messages"] == len(report.tree.messages) and doc["declared"] == len(report.tree.declared)


def test_a_robot_run_is_a_task_tree_with_its_simulated_times(cli, capsys, tmp_path):
    trace = tmp_path / "robot.jsonl"
    code, _out, err = cli(capsys, "simulate", MODELS / "pick_place.roar", "-s", MODELS / "scenarios" / "gripper.toml",
                          "-r", "carrier::delivered == true", "--trace", trace)
    assert code == 0, err
    report = check_trace(trace)
    assert report.ok and report.tree.declared        # make; make declares SeqAch
    ends = [m.end for m in report.tree.messages.values() if m.end is not None]
    assert max(ends) > 10                            # seconds of simulated time, not step numbers


def test_the_ordered_pick_counterexample_breaks_sequential_achievement(cli, capsys, tmp_path):
    res = run_job(load_job(ROOT / "checker" / "ordered_pick.toml"))
    trace = save_counterexample(res, "sequential-achievement", tmp_path)
    code, out, err = cli(capsys, "tca-check", trace)
    assert code == 1
    report = check_trace(trace)
    seq = [v for v in report.violations if v.rule == "seq_ach"]
    assert len(seq) == 1 and not [v for v in report.violations if v.rule != "seq_ach"]
    a, b = seq[0].messages[:2]
    assert report.tree.messages[a].kind == report.tree.messages[b].kind == "goal"
    assert f"SeqAch({a}, {b})" in out
    # the pair said with its constraints, as the spec wrote them (not by request numbers alone)
    said = f"({a}: {report.tree.messages[a].constraint}; {b}: {report.tree.messages[b].constraint})"
    assert report.tree.messages[a].constraint and said in " ".join(out.split())
    assert "declared at line 1 (the trace's header)" in " ".join(out.split())
    # --json: the same violations as the library's report, and the same exit status
    code, out, err = cli(capsys, "tca-check", trace, "--json")
    assert code == 1, err
    doc = json.loads(out)
    assert doc["ok"] is False and doc["messages"] == len(report.tree.messages)
    assert [(v["rule"], v["messages"]) for v in doc["violations"]] == \
        [(v.rule, list(dict.fromkeys(v.messages))) for v in report.violations]
    assert all(v["explanation"] and v["trace_lines"] for v in doc["violations"])


def test_a_trace_without_task_tree_messages_is_an_error(cli, capsys, tmp_path):
    trace = tmp_path / "empty.jsonl"
    trace.write_text('{"trace": "roar-formal", "version": 1, "kind": "roar-run"}\n'
                     '{"step": 1, "rule": "r", "consumed": [], "produced": [], "event": null}\n')
    code, out, err = cli(capsys, "tca-check", trace)
    assert code == 2 and "no task-tree message" in err and f"{trace}:1:1" in err


# ---------------------------------------------------------------- the two checks agree


_JOBS: dict = {}


def explored(name: str):
    if name not in _JOBS:
        res = run_job(load_job(ROOT / "checker" / f"{name}.toml"))
        model, start, explorer = res.roar
        out: dict = {}
        for e in range(res.graph.n_edges):
            out.setdefault(res.graph.src[e], []).append(e)
        pairs = [[p.a, p.b] for p in explorer.system.pairs]
        _JOBS[name] = (res, model, start, explorer, out, pairs)
    return _JOBS[name]


@pytest.mark.parametrize("name", ["ordered_pick", "ordered_pick_fixed"])
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_the_monitor_and_tca_check_agree_on_every_path(name, data):
    res, model, start, explorer, out, pairs = explored(name)
    graph, system = res.graph, explorer.system
    # walk the graph, re-taking each edge from the concrete state reached so far: the graph's
    # stored states are representatives (up to renaming), and a path's steps must share names
    s, state, states, steps = 0, system.initial(), [system.initial()], []
    for _ in range(data.draw(st.integers(1, 80), label="length")):
        choices = out.get(s)
        if not choices:
            break
        e = data.draw(st.sampled_from(sorted(choices)), label="edge")
        want = system.key(explorer.states[graph.dst[e]])
        succ = next(x for x in system.successors(state) if x.label == graph.labels.names[graph.label[e]]
                    and system.key(x.state) == want)
        s, state = graph.dst[e], succ.state
        states.append(state)
        steps.append(succ.step)
    monitor = any(system.violates_sequence(x) is not None for x in states)
    events = path_events(model, start, steps)
    per: list = [[] for _ in steps]
    for ev in events:
        per[ev.step - 1].append(ev.as_json())
    records = []
    for i, (step, evs) in enumerate(zip(steps, per), 1):
        rec = dict(system.describe_step(step), step=i)
        rec["event"] = (evs[0] if len(evs) == 1 else {"kind": "several", "events": evs}) if evs else None
        records.append(rec)
    report = check_events(task_tree_events({"trace": "roar-formal", "seq_pairs": pairs}, records))
    # the theorem over commands (rule seq_ach) is the monitor's property: they agree exactly
    seq = [v for v in report.violations if v.rule == "seq_ach"]
    assert bool(seq) == monitor, (monitor, [v.explanation for v in report.violations])
    # TCA is stricter on a prefix: a goal of A's subtree still being handled (a held ensure)
    # when B starts breaks SeqAch through the goals' achievement intervals, before any of its
    # commands runs late. Every other violation must be of that kind: nothing else breaks.
    for v in report.violations:
        if v.rule != "seq_ach":
            assert "d_seq_ach" in v.rule and name == "ordered_pick", v.explanation


def test_run_writes_its_task_tree_as_tca_check_reads_it(cli, capsys, tmp_path):
    """`run --dot` draws the task tree tca-check checks: the same messages, kinds and parents,
    and the sequential-achievement constraint of `make A; make B` as a dashed edge."""
    import re
    spec = ROOT / "models" / "faulty" / "ordered_pick_fixed.roar"
    fn = ROOT / "models" / "faulty" / "reliable_tools.py"
    code = cli(capsys, "run", spec, "-r", "cell::done == true", "--functional", fn,
               "--trace", tmp_path / "t.jsonl", "--dot", tmp_path / "tree.dot")[0]
    assert code == 0
    dot = (tmp_path / "tree.dot").read_text()
    nodes = dict(re.findall(r'^  "(\w+)" \[shape=(\w+),', dot, re.M))
    edges = set(re.findall(r'^  "(\w+)" -> "(\w+)";$', dot, re.M))
    tree = check_trace(tmp_path / "t.jsonl").tree
    assert set(nodes) == set(tree.messages)
    assert {m: {"box": "goal", "ellipse": "command"}[s] for m, s in nodes.items()} == \
           {m: msg.kind for m, msg in tree.messages.items()}
    assert edges == {(m.parent, m.id) for m in tree.messages.values() if m.parent is not None}
    assert re.search(r'^  "R1" -> "R3" \[style=dashed.*label="SeqAch"\];$', dot, re.M)


@pytest.mark.parametrize("change,message", [
    (('"kind": "primitive-start"', '"kind": "primitive-strat"'), "an event of unknown kind 'primitive-strat'"),
    (('"step": 3}', '"step": "3"}'), "the step number is '3': a whole number is expected"),
])
def test_a_corrupted_run_trace_is_an_error_not_a_pass(cli, capsys, tmp_path, change, message):
    """A hand-edited event kind used to make its command vanish from the task tree, and a
    violated trace then passed; a step number written as a string was read as its position."""
    trace = tmp_path / "run.jsonl"
    spec = ROOT / "models" / "faulty" / "ordered_pick.roar"
    cli(capsys, "run", spec, "--request", "cell::done == true", "--trace", trace)
    text = trace.read_text(encoding="utf-8")
    assert change[0] in text
    bad = tmp_path / "bad.jsonl"
    bad.write_text(text.replace(change[0], change[1], 1), encoding="utf-8")
    code, out, err = cli(capsys, "tca-check", bad)
    assert code == 2 and message in err and f"{bad}:" in err, (code, out, err)


def test_a_sequencing_violation_names_the_commands_as_the_trace_does(cli, capsys, tmp_path):
    """The violation's commands are named as the spec calls them, not only C1 and C2."""
    job = load_job(ROOT / "checker" / "ordered_pick.toml")
    trace = save_counterexample(run_job(job), "sequential-achievement", tmp_path)
    report = check_trace(trace)
    (v,) = [v for v in report.violations if v.rule == "seq_ach"]
    assert "'press()' by jaw" in v.explanation and "'spin()' by drill" in v.explanation



def _call_events(records: list, call: str) -> tuple[int, int]:
    """The indices of the records holding the start and the end of a call."""
    def has(i, kind):
        ev = records[i].get("event")
        evs = ev.get("events", []) if isinstance(ev, dict) and ev.get("kind") == "several" else [ev]
        return any(isinstance(e, dict) and e.get("kind") == kind and e.get("call") == call for e in evs)
    start = next(i for i in range(len(records)) if has(i, "primitive-start"))
    end = next(i for i in range(len(records)) if has(i, "primitive-end"))
    return start, end


@pytest.mark.parametrize("edit", ["end before start", "no start"])
def test_a_call_ending_before_it_starts_or_never_started_is_a_violation(cli, capsys, tmp_path, edit):
    """A run trace edited so that a call ends before it starts (its end's step moved earlier), or
    so that it never starts (the start event removed), used to pass: the end was moved to just
    after the start, or dropped. Now the task tree reports it."""
    trace = tmp_path / "run.jsonl"
    spec = ROOT / "models" / "faulty" / "ordered_pick_fixed.roar"
    fn = ROOT / "models" / "faulty" / "reliable_tools.py"
    assert cli(capsys, "run", spec, "-r", "cell::done == true", "--functional", fn, "--trace", trace)[0] == 0
    lines = trace.read_text(encoding="utf-8").splitlines()
    header, records = json.loads(lines[0]), [json.loads(x) for x in lines[1:]]
    assert check_trace(trace).ok
    start, end = _call_events(records, "C1")
    assert start < end
    if edit == "end before start":
        records[end]["step"], records[start]["step"] = records[start]["step"], records[end]["step"]
        records[start], records[end] = records[end], records[start]
    else:
        ev = records[start]["event"]
        records[start]["event"] = None if ev.get("kind") != "several" else \
            {**ev, "events": [e for e in ev["events"] if e.get("kind") != "primitive-start"]}
    bad = tmp_path / "bad.jsonl"
    bad.write_text("\n".join(json.dumps(x) for x in [header, *records]) + "\n", encoding="utf-8")
    report = check_trace(bad)
    assert not report.ok
    text = " ".join(v.explanation for v in report.violations)
    if edit == "end before start":
        assert "start(C1) < end(C1) is false" in text, text
    else:
        assert "'ended' for message C1, which was never sent" in text, text
    code, _out, _err = cli(capsys, "tca-check", bad)
    assert code == 1
