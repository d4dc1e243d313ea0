"""A counterexample's trace carries its claim (property formula, progress, fairness), and replay
re-decides it on the model the user names (verify/claims.py): the explorer's counterexamples are
confirmed, and a trace whose claim the replayed run does not bear out (an unfair cycle, a cycle
that makes progress, a goal that is reached) is not."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from roar_formal.clf.query import with_big_stack
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.verify.replay import replay_trace

from checker_cache import checker_result
from repo import ROOT

FAULTY = ROOT / "models" / "faulty"

CONFIRMED = [   # (job, property, model replayed on)
    ("aim.toml", "mission-completion", FAULTY / "aim.roar"),
    ("aim.toml", "mission-failure", FAULTY / "aim.roar"),
    ("camera_retry.toml", "mission-completion", FAULTY / "camera_retry.roar"),
    ("retry_forever.toml", "livelock", FAULTY / "retry_forever.roar"),
    ("survey.toml", "mission-failure", FAULTY / "survey.roar"),              # (a crash: recompiled with it)
    ("track_switch.toml", "mission-failure", FAULTY / "track_switch.roar"),
    ("philosophers_ll5.toml", "livelock", ROOT / "models" / "philosophers" / "ll.clf"),
]


def _edit(trace: Path, out: Path, header=None, steps=None) -> Path:
    lines = trace.read_text(encoding="utf-8").splitlines()
    h = json.loads(lines[0])
    recs = [json.loads(x) for x in lines[1:]]
    if header:
        header(h)
    if steps:
        recs = steps(recs)
    out.write_text("\n".join(json.dumps(x) for x in [h] + recs) + "\n", encoding="utf-8")
    return out


@pytest.mark.parametrize("job,prop,model", CONFIRMED, ids=[f"{j}-{p}" for j, p, _m in CONFIRMED])
def test_the_explorers_counterexamples_carry_their_claim_and_are_confirmed(tmp_path, job, prop, model):
    res = checker_result(job)
    assert res.verdicts[prop].status == "violated"
    trace = save_counterexample(res, prop, tmp_path)
    header = json.loads(trace.read_text(encoding="utf-8").splitlines()[0])
    assert header["claim"], header
    if res.verdicts[prop].counterexample.kind == "lasso":
        assert header["claim"]["fairness"] == "weak"
    rep = with_big_stack(lambda: replay_trace(trace, model))
    assert rep.confirmed is True, rep.confirmation


def test_a_cycle_that_makes_the_claimed_progress_is_not_a_livelock(tmp_path):
    res = checker_result("retry_forever.toml")
    trace = save_counterexample(res, "livelock", tmp_path)
    cycle_rules = [json.loads(x)["rule"] for x in trace.read_text(encoding="utf-8").splitlines()[1:]
                   if json.loads(x)["loop"]]
    bad = _edit(trace, tmp_path / "bad.jsonl",
                header=lambda h: h["claim"].__setitem__("progress_rules", [cycle_rules[-1]]))
    rep = with_big_stack(lambda: replay_trace(bad, FAULTY / "retry_forever.roar"))
    assert rep.confirmed is False and "makes progress" in rep.confirmation and cycle_rules[-1] in rep.confirmation


def test_a_lasso_on_which_the_claimed_goal_holds_is_not_confirmed(tmp_path):
    res = checker_result("camera_retry.toml")
    trace = save_counterexample(res, "mission-completion", tmp_path)
    ok = with_big_stack(lambda: replay_trace(trace, FAULTY / "camera_retry.roar"))
    assert ok.confirmed is True
    # the same run read against a goal it does reach (R0 runs on the cycle)
    bad = _edit(trace, tmp_path / "bad.jsonl",
                header=lambda h: h["claim"].__setitem__("formula", "eventually request R0 running"))
    rep = with_big_stack(lambda: replay_trace(bad, FAULTY / "camera_retry.roar"))
    assert rep.confirmed is False and "'request R0 running' holds at state" in rep.confirmation


CLF = """a : type. b : type. c : type.
ra : a -o {a}.
rb : b -o {c}.
#exec * a * b.
"""


def test_an_unfair_cycle_is_not_confirmed(tmp_path):
    """ra loops forever while rb waits: fair only once rb has moved. The explorer's lasso moves rb
    first; the same cycle taken at the start (rb enabled all along, never moving) is not fair."""
    (tmp_path / "m.clf").write_text(CLF, encoding="utf-8")
    (tmp_path / "p.toml").write_text('check = ["livelock"]\n[livelock]\nprogress = ["rb"]\nfairness = "rule"\n',
                                     encoding="utf-8")
    (tmp_path / "j.toml").write_text('name = "j"\nmodel = "m.clf"\nproperties = ["p.toml"]\n'
                                     '[expect]\nlivelock = "violated"\n', encoding="utf-8")
    res = run_job(load_job(tmp_path / "j.toml"))
    v = res.verdicts["livelock"]
    assert v.status == "violated" and [res.graph.labels.names[res.graph.label[e]] for e in v.counterexample.prefix] == ["rb"]
    trace = save_counterexample(res, "livelock", tmp_path)
    header = json.loads(trace.read_text(encoding="utf-8").splitlines()[0])
    assert header["claim"] == {"fairness": "weak", "progress_rules": ["rb"], "groups": "rule"}
    assert replay_trace(trace, tmp_path / "m.clf").confirmed is True
    unfair = _edit(trace, tmp_path / "unfair.jsonl", steps=lambda recs: [r for r in recs if r["loop"]])
    rep = replay_trace(unfair, tmp_path / "m.clf")
    assert rep.confirmed is False
    assert rep.confirmation.startswith("the cycle is not fair: rb is enabled in every state of the cycle")
    # a claim replay cannot read is an error in the trace, located at its header
    broken = _edit(trace, tmp_path / "broken.jsonl", header=lambda h: h["claim"].__setitem__("groups", "agents"))
    from roar_formal.errors import RoarError
    with pytest.raises(RoarError, match='claim.groups') as e:
        replay_trace(broken, tmp_path / "m.clf")
    assert e.value.pos.line == 1


@pytest.mark.parametrize("spec", [False, True], ids=["clf", "spec"])
def test_an_invariant_of_clf_patterns_is_re_decided(tmp_path, spec):
    """A counterexample of an invariant written as CLF patterns carries them; replay matches the
    final state against them (confirmed), and against a pattern it does not match (not)."""
    props = tmp_path / "p.toml"
    if spec:   # a CLF pattern next to the spec's predicates: here the compiled model's own facts
        model = FAULTY / "mutual_make.roar"
        props.write_text('check = ["invariant"]\n[invariant]\nnever = ["rs R s_running"]\n', encoding="utf-8")
        body = f'spec = "{model}"\nrequest = "arm::started == true"\n'
    else:
        model = ROOT / "models" / "philosophers" / "dl.clf"
        props.write_text('check = ["invariant"]\n[invariant]\nnever = ["busy P * busy Q"]\n', encoding="utf-8")
        body = f'model = "{model}"\n'
    job = tmp_path / "j.toml"
    job.write_text(body + 'properties = ["p.toml"]\n', encoding="utf-8")
    res = with_big_stack(lambda: run_job(load_job(job)))
    assert res.verdicts["invariant"].status == "violated", res.verdicts["invariant"].message
    trace = save_counterexample(res, "invariant", tmp_path)
    header = json.loads(trace.read_text(encoding="utf-8").splitlines()[0])
    assert header["claim"]["never_patterns"] == [json.loads(props.read_text().split("never = ")[1])[0]]
    rep = with_big_stack(lambda: replay_trace(trace, model))
    assert rep.confirmed is True and "the final state matches the forbidden pattern" in rep.confirmation
    # a pattern the final state does not match: three busy philosophers where two were found; a
    # request failed where one runs
    other = "busy P * busy Q * busy R" if not spec else "rs R s_failure"
    bad = _edit(trace, tmp_path / "bad.jsonl", header=lambda h: h["claim"].__setitem__("never_patterns", [other]))
    rep = with_big_stack(lambda: replay_trace(bad, model))
    assert rep.confirmed is False, rep.confirmation
    assert ("matches none of the job's forbidden patterns" if not spec else "breaks none") in rep.confirmation


def test_a_lasso_whose_claim_was_removed_is_not_confirmed_as_breaking_its_property(tmp_path):
    """Without its claim a livelock trace can only show its cycle closes: replay says the
    property is not re-decided (it said "confirmed")."""
    res = checker_result("retry_forever.toml")
    trace = save_counterexample(res, "livelock", tmp_path)
    bare = _edit(trace, tmp_path / "bare.jsonl", header=lambda h: h.pop("claim"))
    rep = with_big_stack(lambda: replay_trace(bare, FAULTY / "retry_forever.roar"))
    assert rep.confirmed is None and "records no claim" in rep.confirmation and "'livelock'" in rep.confirmation
    assert with_big_stack(lambda: replay_trace(trace, FAULTY / "retry_forever.roar")).confirmed is True
