"""A function's declared outcomes and callables against the spec's types (structs, opaque types),
and the mistakes a user makes writing a spec or a request (from a new-user trial)."""

from __future__ import annotations

import importlib.util

import pytest

from roar_formal.errors import RoarError
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.functional import Outcome
from roar_formal.roar.parser import parse_constraint, read_spec
from roar_formal.roar.run import parse_fault, run_model
from roar_formal.roar.spec import load_spec
from roar_formal.roar import ast as a
from repo import ROOT

DATA = ROOT / "tests" / "roar" / "data" / "outcomes"
REQUEST = "base::arrived == true where base::station == 2"


def _layer():
    spec = importlib.util.spec_from_file_location("outcomes_base_layer", DATA / "base.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _run(mod, faults=()):
    reg = mod.registry()
    model = compile_spec(load_spec(DATA / "base.roar"), REQUEST, registry=reg, functional="python")
    return run_model(model, registry=reg, faults=[parse_fault(f) for f in faults], max_steps=2_000)


@pytest.mark.parametrize("result,why", [
    ({"x": 0.0, "z": 0.0}, "a struct base::pose has the fields x, y; missing: y; not a field: z"),
    (7, "expected a struct base::pose: a dict with the fields x, y"),
    ((1.0,), "a struct base::pose has 2 fields (x, y), not 1"),
    ({"x": 0.0, "y": "north"}, "field 'y': expected a number (a Python int or float)"),
])
def test_an_outcome_whose_result_is_not_the_declared_struct_is_located(result, why):
    """(A dict without a field crashed the compiler with a KeyError; a number for a struct was
    taken, and the model then read a field of a number: a false deadlock.)"""
    mod = _layer()
    mod.OUTCOMES["station_pose"] = [Outcome("bench", True, result=result)]
    with pytest.raises(RoarError) as err:
        mod.registry().resolve(load_spec(DATA / "base.roar"))
    text = err.value.format()
    assert "base.roar:11:12" in text and "outcome 'bench' of primitive 'station_pose' returns" in text and why in text


def test_a_callable_returning_another_struct_stops_the_run_at_the_call():
    mod = _layer()
    reg = mod.registry()
    reg.register("station_pose", lambda k: {"x": 1.0}, outcomes=mod.OUTCOMES["station_pose"], replace=True)
    model = compile_spec(load_spec(DATA / "base.roar"), REQUEST, registry=reg, functional="python")
    with pytest.raises(RoarError, match=r"primitive 'base::station_pose' returned \{'x': 1.0\}, but it is declared "
                                        r"to return base::pose: a struct base::pose has the fields x, y; missing: y"):
        run_model(model, registry=reg, max_steps=2_000)


def test_an_opaque_value_reaches_the_functions_as_the_object_or_as_none():
    """The callable's object is handed on; an outcome forced by a fault makes no object, and the
    function it is passed to gets None (it got the number 0)."""
    mod = _layer()
    res = _run(mod)
    assert res.outcome == "success" and isinstance(mod.SEEN[-1], mod.Costmap)
    mod.SEEN.clear()
    res = _run(mod, ["load_costmap=loaded"])
    assert res.outcome == "success" and mod.SEEN == [None]
    mod.OUTCOMES["load_costmap"] = [Outcome("loaded", True, result="a costmap")]   # any object stands for one
    mod.SEEN.clear()
    res = _run(mod, ["load_costmap=loaded"])
    assert res.outcome == "success" and mod.SEEN == ["a costmap"]


@pytest.mark.parametrize("word,keyword", [("prefered", "prefer"), ("bodys", "body"), ("ending", "end")])
def test_a_keyword_glued_to_more_letters_is_reported_as_the_word_written(tmp_path, word, keyword):
    text = (DATA / "base.roar").read_text(encoding="utf-8").replace("        planned = recipe {\n",
                                                                       f"        planned = recipe {{\n          {word} = 2\n")
    (tmp_path / "base.roar").write_text(text, encoding="utf-8")
    with pytest.raises(RoarError) as err:
        read_spec(tmp_path / "base.roar")
    assert err.value.format().startswith(f"{tmp_path / 'base.roar'}:20:11: unexpected name '{word}' "
                                         f"(did you mean '{keyword}'?)")


def test_a_bare_boolean_request_is_read_as_a_comparison():
    c = parse_constraint("base::arrived where base::station == 2")
    assert isinstance(c.expr, a.Binary) and c.expr.op == "==" and c.expr.right == a.BoolLit(True)
    c = parse_constraint("!base::arrived")
    assert c.expr.right == a.BoolLit(False)
    mod = _layer()
    reg = mod.registry()
    model = compile_spec(load_spec(DATA / "base.roar"), "base::arrived where base::station == 2", registry=reg,
                         functional="python")
    assert run_model(model, registry=reg, max_steps=2_000).outcome == "success"   # (it failed: no task for it)


def test_a_misspelt_statement_written_like_a_call_suggests_it(tmp_path):
    text = (DATA / "base.roar").read_text(encoding="utf-8").replace("assert(drive(cm, p));", "asert(drive(cm, p));")
    (tmp_path / "base.roar").write_text(text, encoding="utf-8")
    with pytest.raises(RoarError, match="unknown function 'asert'.*did you mean 'assert'"):
        load_spec(tmp_path / "base.roar")


def test_a_bare_boolean_constraint_in_a_make_is_a_comparison_too(tmp_path):
    """The same reading for what a recipe sends (one rule for every constraint): the task whose
    post-condition is ``arrived == true`` serves ``make(base::arrived)``."""
    text = (DATA / "base.roar").read_text(encoding="utf-8") + """
mission = ability {
  context = { { } { bool done = false; } { } }
  export = { { } { } { } }
  tasks = { go = task { post = { {done == true} }
    recipes = { r = recipe { body = { make(base::arrived where base::station == 3); set done true; } } } } }
}
"""
    (tmp_path / "two.roar").write_text(text, encoding="utf-8")
    (tmp_path / "two.py").write_text((DATA / "base.py").read_text(encoding="utf-8"), encoding="utf-8")
    spec = load_spec(tmp_path / "two.roar")
    made = [n for n in _walk(spec) if isinstance(n, a.Constraint) and "arrived" in str(n.expr)]
    assert made and all(isinstance(c.expr, a.Binary) and c.expr.right == a.BoolLit(True) for c in made)
    from roar_formal import load_spec as api_load
    assert api_load(tmp_path / "two.roar").run("mission::done").ok


def _walk(n):
    yield n
    for c in n.children():
        yield from _walk(c)
