"""Reading trace events: tolerant of what is not ours, strict about what is."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from roar_formal.errors import RoarError
from roar_formal.tca.trace_events import Declared, Mark, Sent, dumps, parse_events, read_events

TRACES = Path(__file__).parent / "traces"


def test_reads_the_three_record_shapes():
    events = parse_events([
        '{"step": 12, "time": 3.5, "event": "constraint_sent", "msg": "m7", "kind": "goal", "parent": "m3",'
        ' "agent": "loco", "constraint": "at(x)"}',
        '{"time": 4, "event": "started", "msg": "m7"}',
        '{"event": "seq_ach", "m1": "m7", "m2": "m8"}',
    ], "t.jsonl")
    sent, mark, decl = events
    assert isinstance(sent, Sent) and sent.time == Fraction(7, 2) and sent.parent == "m3"
    assert sent.agent == "loco" and sent.constraint == "at(x)" and sent.pos.line == 1
    assert isinstance(mark, Mark) and mark.what == "started" and mark.time == 4
    assert isinstance(decl, Declared) and (decl.m1, decl.m2, decl.time) == ("m7", "m8", None)


def test_times_are_exact_decimals():
    (e,) = parse_events(['{"time": 0.1, "event": "started", "msg": "a"}'])
    assert e.time == Fraction(1, 10)


def test_step_stands_in_for_a_missing_time():
    (e,) = parse_events(['{"step": 9, "event": "ended", "msg": "a"}'])
    assert e.time == 9


def test_skips_what_is_not_a_tca_event():
    events = parse_events([
        '{"trace": "roar-formal", "version": 1}',
        "",
        '{"step": 1, "rule": "r", "consumed": [], "event": null}',
        '{"step": 2, "event": {"kind": "recipe_selected"}}',
        '{"step": 3, "event": "recipe_selected", "agent": "loco"}',
        '{"step": 4, "event": "started", "msg": "a", "extra": [1, 2]}',
    ])
    assert [type(e).__name__ for e in events] == ["Mark"]


@pytest.mark.parametrize("name,where,words", [
    ("malformed_json.jsonl", (3, 30), "malformed JSON"),
    ("missing_field.jsonl", (2, 1), "'kind'"),
    ("bad_kind.jsonl", (1, 54), "one of query, goal, command, monitor"),
    ("bad_time.jsonl", (3, 2), "'time' to be a number"),
])
def test_bad_input_is_located(name, where, words):
    with pytest.raises(RoarError) as info:
        read_events(TRACES / name)
    err = info.value
    assert (err.pos.file, err.pos.line, err.pos.col) == (str(TRACES / name), *where)
    assert words in err.message


@pytest.mark.parametrize("line,words", [
    ('[1, 2]', "a JSON object"),
    ('{"time": NaN, "event": "started", "msg": "a"}', "NaN"),
    ('{"time": true, "event": "started", "msg": "a"}', "number"),
    ('{"step": 1.5, "event": "started", "msg": "a"}', "integer"),
    ('{"event": "started", "msg": "a"}', "'time' (or 'step')"),
    ('{"time": 1, "event": "started", "msg": ""}', "non-empty string"),
    ('{"event": "precedes", "m1": "a"}', "'m2'"),
])
def test_each_kind_of_bad_record(line, words):
    with pytest.raises(RoarError) as info:
        parse_events([line], "x.jsonl")
    assert words in info.value.message and info.value.pos.line == 1


def test_missing_file_is_a_user_error(tmp_path):
    with pytest.raises(RoarError, match="cannot read trace"):
        read_events(tmp_path / "nope.jsonl")


def test_dumps_reads_back():
    events = parse_events((TRACES / "seq_ach_ok.jsonl").read_text().splitlines())
    again = parse_events(dumps(events).splitlines())
    assert [(type(e), getattr(e, "msg", None), getattr(e, "time", None)) for e in events] == \
           [(type(e), getattr(e, "msg", None), getattr(e, "time", None)) for e in again]
