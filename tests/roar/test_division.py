"""A division by zero is a local failure at its location, not a recipe blocked forever (which
the explorer would report as a deadlock)."""

from __future__ import annotations

from pathlib import Path

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from roar_formal.testing import load

SPEC = Path(__file__).parent / "data" / "divide_by_zero.roar"   # set x 10 / d; with d = 0


def test_the_run_fails_the_recipe_at_the_division():
    model = compile_spec(load_spec(SPEC), "a::done == true", functional="python")
    res = run_model(model, seed=0, max_steps=60)
    failures = [e.text for e in res.events if "local failure" in e.text]
    assert failures and failures[0].endswith("local failure at 15:24 (division by zero: d is 0 in set x 10 / d)")
    assert res.final["a::x"] == 0                    # nothing was written


def test_the_explorer_finds_no_deadlock_and_a_nonzero_divisor_succeeds(tmp_path):
    spec = load(SPEC)
    ex = spec.explore("a::done == true", properties=["deadlock"])
    assert ex.verdicts["deadlock"].status == "holds"  # it was "violated": the recipe blocked
    fixed = tmp_path / "fixed.roar"
    fixed.write_text(SPEC.read_text().replace("int d = 0;", "int d = 2;"))
    run = load(fixed).run("a::done == true")
    assert run.outcome == "success" and run.value("a::x") == 5
