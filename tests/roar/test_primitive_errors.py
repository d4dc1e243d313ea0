"""A functional layer's bugs are located errors, never failures the recipe retries forever."""

from __future__ import annotations

from pathlib import Path

import pytest

from roar_formal.errors import RoarError
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.functional import Registry, load_registry
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec

DATA = Path(__file__).parent / "data" / "raising"
SPEC = DATA / "poke.roar"
CALL = f"{SPEC}:15:20"   # assert(poke(3)) in the recipe


def test_a_raising_primitive_is_a_located_error_naming_it(roar_cli):
    code, out, err = roar_cli("run", SPEC, "-r", "a::done == true")
    assert code == 2
    assert f"error: {CALL}: primitive 'a::poke' raised ValueError: sensor unplugged" in err
    assert "called as poke(3)" in err and "Traceback" not in err
    assert "temporary failure" not in out          # no failure, no retry


def test_the_library_raises_it_too():
    reg = load_registry(DATA / "poke.py")
    model = compile_spec(load_spec(SPEC), "a::done == true", registry=reg, functional="python")
    with pytest.raises(RoarError) as info:
        run_model(model, seed=0, registry=reg)
    assert str(info.value.pos) == CALL and "ValueError" in info.value.message


def test_a_callable_with_the_wrong_number_of_parameters_is_refused_before_running():
    reg = Registry()
    reg.register("poke", lambda: True)
    with pytest.raises(RoarError) as info:
        compile_spec(load_spec(SPEC), "a::done == true", registry=reg, functional="python")
    assert "takes 0 arguments, but agent 'a' declares 'poke' with 1" in info.value.format()


def test_a_primitive_that_returns_false_is_still_an_ordinary_failure():
    reg = Registry()
    reg.register("poke", lambda n: False)
    model = compile_spec(load_spec(SPEC), "a::done == true", registry=reg, functional="python")
    res = run_model(model, seed=0, registry=reg, max_steps=400)
    assert not res.ok and any("temporary failure" in e.text for e in res.events)
