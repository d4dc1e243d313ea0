"""A search that runs out of budget on a spec names the number variables that kept growing as it
went deeper (roar/report.py ``growing_variables``): an unbounded counter is the usual reason a
state space never ends. The same worker with its count bounded, cut by the same budget, names
nothing: its counter's values all appear early."""

from __future__ import annotations

from pathlib import Path

from roar_formal.clf.query import with_big_stack
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job

DATA = Path(__file__).parent / "data" / "growing"


def _run(tmp_path: Path, spec_text: str, max_states: int):
    (tmp_path / "w.roar").write_text(spec_text, encoding="utf-8")
    (tmp_path / "w.toml").write_text(f'name = "w"\nspec = "w.roar"\nrequest = "w::done == true"\n'
                                     f'[bounds]\nmax_states = {max_states}\n', encoding="utf-8")
    return with_big_stack(run_job, load_job(tmp_path / "w.toml"))


def test_an_unbounded_counter_is_named_when_the_budget_runs_out(tmp_path):
    res = _run(tmp_path, (DATA / "unbounded.roar").read_text(encoding="utf-8"), 400)
    v = res.verdicts["deadlock"]
    assert v.status == "incomplete" and not res.graph.complete
    assert "w::tries kept growing as the search went deeper" in v.message
    assert "if nothing bounds it, the state space is infinite" in v.message
    assert all(x.details.get("growing") for x in res.verdicts.values() if x.status == "incomplete")
    # the depths quoted are those of the graph: each value first produced deeper than the one before
    grown = v.details["growing"][0]
    depths = [int(x.split(" at depth ")[1]) for x in grown.split("(")[1].split(", of")[0].split(", ")]
    assert depths == sorted(depths) and depths[-1] <= max(res.graph.depth)


def test_a_bounded_counter_cut_by_the_same_budget_is_not_named(tmp_path):
    text = (DATA / "unbounded.roar").read_text(encoding="utf-8")
    bounded = text.replace("        r = recipe {\n", "        r = recipe {\n          pre = { {tries < 3} }\n")
    assert bounded != text
    # 81 states in all, 47 levels deep; its counter's last value (3) first appears at depth 34:
    # cut near the end, the search saw the counter stop well before its deepest level
    res = _run(tmp_path, bounded, 78)
    assert not res.graph.complete and max(res.graph.depth) >= 44
    assert not any("kept growing" in v.message for v in res.verdicts.values())
    assert not any(v.details.get("growing") for v in res.verdicts.values())


def test_a_counter_that_only_decreases_is_named_as_shrinking(tmp_path):
    text = (DATA / "unbounded.roar").read_text(encoding="utf-8")
    down = text.replace("set tries tries + 1;", "set tries tries - 1;")
    assert down != text
    res = _run(tmp_path, down, 400)
    v = res.verdicts["deadlock"]
    assert "w::tries kept shrinking as the search went deeper" in v.message and "kept growing" not in v.message
