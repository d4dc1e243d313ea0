"""The new sequential sub-goals as TCA reads them (docs/tca.md, "ROAR runs as task trees").

* every ordered pair of sending statements of one block declares SeqAch (not only consecutive
  ones), an ensure let go before the next statement too;
* a plan of sub-goal tasks is a sequence of task goals under the request, with SeqAch between
  consecutive tasks;
* the explorer's monitor and tca-check agree on every random path through the explored state
  spaces of the seeded faults of ``tests/roar/data/seq_*.roar`` and their fixed twins: the
  theorem over commands (rule ``seq_ach``) exactly; TCA may be stricter only through the goals'
  handling intervals (``d_seq_ach``: an ensure aborted before the next statement is still being
  handled, asynchronously, when the next statement's commands start).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from roar_formal.clf.query import with_big_stack
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import Options
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem, path_events, sequential_pairs
from roar_formal.roar.functional import load_registry
from roar_formal.roar.spec import load_spec
from roar_formal.tca.check import check_events, check_trace
from roar_formal.tca.roar_runs import task_tree_events
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job

from repo import ROOT

DATA = ROOT / "tests" / "roar" / "data"
TOOLS = DATA / "seq_tools.py"
SPECS = {"seq_later_pair.roar": "cell::done == true", "seq_later_pair_fixed.roar": "cell::done == true",
         "seq_aborted_ensure.roar": "cell::done == true", "seq_aborted_ensure_fixed.roar": "cell::done == true",
         "seq_plan.roar": "arm::holding == true", "seq_plan_fixed.roar": "arm::holding == true"}

_SPACES: dict = {}


def space(spec: str):
    if spec not in _SPACES:
        def go():
            model = compile_spec(load_spec(DATA / spec), SPECS[spec], registry=load_registry(TOOLS),
                                 functional="abstract")
            program = model.program()
            start = program.start_context(next(d for d in program.sig.directives
                                               if type(d).__name__ == "ExecDirective").start)
            pairs = sequential_pairs(model)
            system = RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent"), pairs)
            ex = Explorer(system)
            g = ex.run(Budget(max_states=20_000))
            assert g.complete
            out: dict = {}
            for e in range(g.n_edges):
                out.setdefault(int(g.src[e]), []).append(e)
            header = {"trace": "roar-formal", "seq_pairs": [[p.a, p.b, p.where, p.a_text, p.b_text] for p in pairs]}
            return model, start, ex, g, out, header
        _SPACES[spec] = with_big_stack(go)
    return _SPACES[spec]


def _walk(spec: str, data=None, edges=None):
    """Along random edges (``data``) or given ones: does the monitor see a violation on the path,
    and tca-check's report on the path's trace."""
    model, start, ex, g, out, header = space(spec)
    system = ex.system
    s, state, states, steps = 0, system.initial(), [system.initial()], []
    todo = list(edges) if edges is not None else None
    for _ in range(len(todo) if todo is not None else data.draw(st.integers(1, 90), label="length")):
        choices = out.get(s)
        if not choices:
            break
        e = todo.pop(0) if todo is not None else data.draw(st.sampled_from(sorted(choices)), label="edge")
        # re-take each edge from the concrete state reached so far: the graph's stored states are
        # representatives (up to renaming), and a path's steps must share names
        want = system.key(ex.states[int(g.dst[e])])
        succ = next(x for x in system.successors(state) if x.label == g.labels.names[g.label[e]]
                    and system.key(x.state) == want)
        s, state = int(g.dst[e]), succ.state
        states.append(state)
        steps.append(succ.step)
    events = path_events(model, start, steps)
    per: list = [[] for _ in steps]
    for ev in events:
        per[ev.step - 1].append(ev.as_json())
    records = []
    for i, (step, evs) in enumerate(zip(steps, per), 1):
        rec = dict(system.describe_step(step), step=i)
        rec["event"] = (evs[0] if len(evs) == 1 else {"kind": "several", "events": evs}) if evs else None
        records.append(rec)
    report = check_events(task_tree_events(header, records))
    return any(system.violates_sequence(x) is not None for x in states), report


@pytest.mark.parametrize("spec", sorted(SPECS))
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(data=st.data())
def test_the_monitor_and_tca_check_agree_on_every_path(spec, data):
    monitor, report = _walk(spec, data)
    seq = [v for v in report.violations if v.rule == "seq_ach"]
    assert bool(seq) == monitor, (monitor, [v.explanation for v in report.violations])
    for v in report.violations:
        if v.rule != "seq_ach":
            assert "d_seq_ach" in v.rule, v.explanation
            assert "aborted_ensure" in spec or "fixed" not in spec, v.explanation


@pytest.mark.parametrize("spec", [s for s in sorted(SPECS) if "fixed" not in s])
def test_on_the_shortest_violation_both_see_it(spec):
    from roar_formal.explore.properties import check_states
    _m, _s, ex, g, _out, _h = space(spec)
    v = check_states(g, "sequential-achievement", lambda x: ex.system.sequence_reason(ex.states[x]))
    assert v.status == "violated"
    monitor, report = _walk(spec, edges=v.counterexample.prefix)
    assert monitor and [x for x in report.violations if x.rule == "seq_ach"]


def test_every_ordered_pair_and_every_plan_step_is_declared():
    _m, _s, _ex, _g, _out, header = space("seq_later_pair_fixed.roar")
    assert len(header["seq_pairs"]) == 3
    _m, _s, _ex, _g, _out, header = space("seq_plan_fixed.roar")
    assert header["seq_pairs"] == [["plan:arm", "plan:arm", "arm (planned tasks)", "a planned sub-goal task",
                                    "the next planned task"]]


def _trace(tmp_path: Path, spec: str) -> Path:
    (tmp_path / "p.toml").write_text('check = ["sequential-achievement"]\n', encoding="utf-8")
    job = tmp_path / "j.toml"
    job.write_text(f'spec = "{DATA / spec}"\nrequest = "{SPECS[spec]}"\nfunctional = "{TOOLS}"\n'
                   f'properties = ["p.toml"]\n', encoding="utf-8")
    res = run_job(load_job(job))
    return save_counterexample(res, "sequential-achievement", tmp_path)


def test_the_plan_counterexample_breaks_seq_ach_between_the_planned_tasks(tmp_path, roar_cli):
    trace = _trace(tmp_path, "seq_plan.roar")
    report = check_trace(trace)
    tree = report.tree.messages
    assert tree["R0.approach"].kind == tree["R0.grasp"].kind == "goal"
    assert tree["R0.approach"].parent == tree["R0.grasp"].parent == "R0"
    seq = [v for v in report.violations if v.rule == "seq_ach"]
    assert len(seq) == 1 and seq[0].messages[:2] == ("R0.approach", "R0.grasp")
    code, out, _err = roar_cli("tca-check", trace)
    assert code == 1 and "SeqAch(R0.approach, R0.grasp)" in out


def test_a_run_of_the_fixed_plan_is_a_conforming_task_tree_with_its_tasks(tmp_path, roar_cli):
    trace, dot = tmp_path / "run.jsonl", tmp_path / "tree.dot"
    code, _out, err = roar_cli("run", DATA / "seq_plan_fixed.roar", "-r", SPECS["seq_plan_fixed.roar"],
                               "--functional", TOOLS, "--trace", trace, "--dot", dot)
    assert code == 0, err
    report = check_trace(trace)
    assert report.ok, [v.explanation for v in report.violations]
    tree = report.tree.messages
    # the base's request is sent by approach's activation: its parent is the task goal
    assert [m.parent for m in tree.values() if "base::parked" in (m.constraint or "")] == ["R0.approach"]
    assert [m.parent for m in tree.values() if m.kind == "command"] == ["R1", "R0.grasp"]   # park(), close()
    assert [(d.m1, d.m2) for d in report.tree.declared] == [("R0.approach", "R0.grasp")]
    assert '"R0.approach" -> "R0.grasp" [style=dashed' in dot.read_text()


def test_tca_check_with_the_model_reads_the_task_tree_from_the_spec_not_the_file(tmp_path, roar_cli):
    """A counterexample whose header pairs were emptied checks clean as recorded (and says it
    read the file as recorded, naming no pairs); replayed on the spec (--model) its pairs are the
    model's and the violation is back. Garbled pairs and time going back are refused."""
    import json
    trace = _trace(tmp_path, "seq_plan.roar")
    lines = trace.read_text(encoding="utf-8").splitlines()
    header = json.loads(lines[0])
    emptied = tmp_path / "emptied.jsonl"
    emptied.write_text("\n".join([json.dumps({**header, "seq_pairs": []})] + lines[1:]) + "\n", encoding="utf-8")
    code, out, _err = roar_cli("tca-check", emptied)
    assert code == 0 and "as recorded" in out and "names no sequential-achievement pairs" in out
    code, out, err = roar_cli("tca-check", emptied, "--model", DATA / "seq_plan.roar", "--functional", TOOLS)
    assert code == 1 and "SeqAch(R0.approach, R0.grasp)" in out and "as recorded" not in out, err
    # the unedited trace: the same verdict either way
    assert roar_cli("tca-check", trace, "--model", DATA / "seq_plan.roar", "--functional", TOOLS)[0] == 1
    garbled = tmp_path / "garbled.jsonl"
    garbled.write_text("\n".join([json.dumps({**header, "seq_pairs": "all"})] + lines[1:]) + "\n", encoding="utf-8")
    code, _out, err = roar_cli("tca-check", garbled)
    assert code == 2 and f"{garbled}:1:1: expected \"seq_pairs\"" in err
    recs = [json.loads(x) for x in lines[1:]]
    recs[3]["time"], recs[4]["time"] = 5.0, 1.0
    back = tmp_path / "back.jsonl"
    back.write_text("\n".join(json.dumps(x) for x in [header] + recs) + "\n", encoding="utf-8")
    code, _out, err = roar_cli("tca-check", back)
    assert code == 2 and f"{back}:6:1: step {recs[4]['step']}'s time 1.0 is before the step before it" in err
