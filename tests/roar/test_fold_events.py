"""Repeated blocks of events are folded in the step table (a recipe retried for ever reads as
one attempt and a count); ``--verbose`` shows every event."""

from __future__ import annotations

from hypothesis import given, settings, strategies as st

from roar_formal.cli import main
from roar_formal.trace.render import MIN_REPEATS, Repeat, Row, event_lines, folded
from repo import ROOT


def rows_of(texts):
    return [Row(i + 1, "state", "a", t) for i, t in enumerate(texts)]


def unfold(items) -> list[str]:
    """The independent reading: each Repeat stands for its block, written out again."""
    out: list[str] = []
    for x in items:
        if isinstance(x, Repeat):
            block = out[-x.period:]
            out.extend(block * x.times)
        else:
            out.append(x.text)
    return out


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from("abc"), max_size=40))
def test_folding_loses_nothing(texts):
    items = folded(rows_of(texts))
    assert unfold(items) == texts
    for i, x in enumerate(items):
        if isinstance(x, Repeat):
            assert x.times >= MIN_REPEATS - 1 and not isinstance(items[i - 1], Repeat)


def test_a_retry_loop_reads_as_one_attempt_and_a_count():
    texts = ["sent"] + ["try", "fail", "again"] * 5 + ["done"]
    items = folded(rows_of(texts))
    assert [x.text if isinstance(x, Row) else ("repeat", x.period, x.times) for x in items] == [
        "sent", "try", "fail", "again", ("repeat", 3, 4), "done"]
    assert items[4].first == 5 and items[4].last == 16
    assert folded(rows_of(["x", "y", "x", "y", "z"])) == rows_of(["x", "y", "x", "y", "z"])   # twice: kept
    assert "repeat 4 more times (steps 5 to 16" in event_lines(rows_of(texts)).text()
    assert event_lines(rows_of(texts), verbose=True).text().count("fail") == 5


def test_run_prints_a_failing_retry_once_with_its_count(capsys):
    spec = str(ROOT / "models" / "faulty" / "retry_forever.roar")

    def run(*extra) -> str:
        try:
            main(["run", spec, "-r", "hand::holding == true", "--max-steps", "300", "--fault", "grip", *extra])
        except SystemExit:
            pass
        return capsys.readouterr().out
    short, full = run(), run("--verbose")
    calls = full.count("grip() = false")
    assert calls > 10 and short.count("grip() = false") == 1
    assert f"the 6 events above repeat {calls - 1} more times" in short


def test_replay_folds_the_same_repeats(capsys, tmp_path):
    spec = str(ROOT / "models" / "faulty" / "retry_forever.roar")
    trace = tmp_path / "rf.jsonl"

    def cli(*argv) -> str:
        try:
            main(list(argv))
        except SystemExit:
            pass
        return capsys.readouterr().out
    cli("run", spec, "-r", "hand::holding == true", "--max-steps", "300", "--fault", "grip", "--trace", str(trace))
    short = cli("replay", str(trace), "--model", spec)
    full = cli("replay", str(trace), "--model", spec, "--verbose")
    assert "steps above repeat" in short and "replayed 300 steps" in short
    assert short.count("grip() = false") == 1 and full.count("grip() = false") > 10
