"""The trace checker against plain-Python oracles on random task trees."""

from __future__ import annotations

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roar_formal.tca.check import check_events
from roar_formal.tca.trace_events import parse_events

import tca_oracle

KINDS = ("goal", "goal", "command", "command", "monitor", "query")
INNER_KINDS = ("goal",) * 8 + ("command", "query")  # inner nodes: mostly goals, sometimes not (axiom 8, q_leaf)


@st.composite
def task_trees(draw) -> list[dict]:
    """Well-formed traces: a forest scheduled top-down with small integer times
    (so ties happen), then declarations between random messages, some ends
    cut off (a prefix) and some times nudged (to break axioms now and then)."""
    n = draw(st.integers(1, 8))
    msgs = []
    for i in range(n):
        parent = draw(st.one_of(st.none(), st.integers(0, i - 1))) if i else None
        kind = draw(st.sampled_from(KINDS))
        if parent is not None and msgs[parent]["kind"] != "goal" and draw(st.integers(0, 3)):
            msgs[parent]["kind"] = draw(st.sampled_from(INNER_KINDS))
        if parent is None:
            sent = draw(st.integers(0, 3))
        else:
            p = msgs[parent]
            sent = draw(st.integers(p["start"], p["end"]))
        start = sent + draw(st.integers(0, 3))
        end = start + draw(st.integers(1, 4))
        msgs.append({"id": f"m{i}", "parent": parent, "kind": kind, "sent": sent, "start": start, "end": end})
    for m in msgs:
        for key in ("sent", "start", "end"):
            if draw(st.integers(0, 9)) == 0:
                m[key] += draw(st.sampled_from([-2, -1, 1, 2]))
        if m["start"] < 0 or m["sent"] < 0:
            m["start"], m["sent"] = max(m["start"], 0), max(m["sent"], 0)
    records = []
    for m in msgs:
        parent = msgs[m["parent"]]["id"] if m["parent"] is not None else None
        records.append({"time": m["sent"], "event": "constraint_sent", "msg": m["id"], "kind": m["kind"],
                        "parent": parent})
        cut = draw(st.integers(0, 9))
        if cut > 0:
            records.append({"time": m["start"], "event": "started", "msg": m["id"]})
            if cut > 1:
                records.append({"time": m["end"], "event": "ended", "msg": m["id"]})
        if cut > 1 and draw(st.integers(0, 7)) == 0:
            a = m["start"] + draw(st.integers(-1, 1))
            b = max(m["end"] + draw(st.integers(-1, 3)), a)
            records.append({"time": a, "event": "achieving_started", "msg": m["id"]})
            records.append({"time": b, "event": "achieving_ended", "msg": m["id"]})
    siblings = [(a["id"], b["id"]) for a in msgs for b in msgs if a is not b and a["parent"] == b["parent"]]
    if siblings:
        for first, second in draw(st.lists(st.sampled_from(siblings), max_size=2)):
            records.append({"event": "seq_ach", "m1": first, "m2": second})
    if n > 1:
        pairs = st.tuples(st.sampled_from(["seq_ach", "precedes", "delay_planning"]),
                          st.integers(0, n - 1), st.integers(0, n - 1)).filter(lambda t: t[1] != t[2])
        for relation, i, j in draw(st.lists(pairs, max_size=2)):
            records.append({"event": relation, "m1": f"m{i}", "m2": f"m{j}"})
    return records


def _check(records: list[dict]):
    lines = [json.dumps(r) for r in records]
    return check_events(parse_events(lines, "random"))


@settings(max_examples=90, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(task_trees())
def test_sequencing_verdict_matches_pairwise_oracle(records):
    report = _check(records)
    found = {(v.messages[0], v.messages[1]) for v in report.violations if v.rule == "seq_ach"}
    assert found == tca_oracle.sequencing_violations(records)


@settings(max_examples=90, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(task_trees())
def test_overall_verdict_matches_difference_constraint_oracle(records):
    report = _check(records)
    assert not [v for v in report.violations if v.rule == "well_formed"]
    assert report.ok == tca_oracle.consistent(records)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(task_trees())
def test_a_sequencing_failure_is_never_consistent(records):
    """The theorem on instances: a broken SeqAch property means the axioms cannot hold."""
    if tca_oracle.sequencing_violations(records):
        assert not tca_oracle.consistent(records)
        assert not _check(records).ok


def test_oracles_see_the_hand_written_cases():
    from pathlib import Path

    here = Path(__file__).parent / "traces"
    for name, seq_ok, ok in (("seq_ach_ok", True, True), ("seq_ach_violated", False, False),
                             ("goal_planning_late", True, False), ("delay_planning_violated", True, False),
                             ("delay_planning_ok", True, True), ("truncated_violated", False, False)):
        records = [json.loads(line) for line in (here / f"{name}.jsonl").read_text().splitlines() if line.strip()]
        assert (not tca_oracle.sequencing_violations(records)) == seq_ok, name
        assert tca_oracle.consistent(records) == ok, name
