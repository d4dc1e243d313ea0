"""Tests for the functional-layer registry (roar_formal.roar.functional)."""

from __future__ import annotations


import pytest

from roar_formal.errors import RoarError
from roar_formal.roar.functional import (DEFAULT_OUTCOMES, Binding, BindingError, Outcome, Primitive, Registry)
from roar_formal.roar.spec import load_spec
from roar_formal.roar.parser import parse_roar
from repo import ROOT

MODELS = ROOT / "models"


def test_register_plain_and_decorator():
    reg = Registry(builtins=False)
    reg.register("double_it", lambda x: 2 * x)

    @reg.register("planner::cost", outcomes=[Outcome("cheap", True), Outcome("none", False)])
    def cost(x):
        return x + 1

    assert cost(1) == 2  # the decorator returns the function itself
    assert reg.call("double_it", 4) == 8
    assert reg.lookup("cost", owner="planner")(1) == 2
    assert reg.lookup("cost") is None and reg.lookup("double_it", owner="x").name == "double_it"
    assert reg["double_it"].outcomes == DEFAULT_OUTCOMES
    assert [o.name for o in reg["planner::cost"].outcomes] == ["cheap", "none"]
    assert reg.names() == ["double_it", "planner::cost"]
    assert "double_it" in reg and reg.get("zz") is None


def test_exploration_only_primitive():
    reg = Registry(builtins=False)
    reg.register("demo_loco::pos", outcomes=[Outcome("at_goal", True, {"pos": 5})])
    p = reg["demo_loco::pos"]
    assert p.fn is None and p.outcome("at_goal").writes == {"pos": 5}
    with pytest.raises(RoarError, match="registered for exploration only"):
        p()
    with pytest.raises(KeyError):
        p.outcome("nope")


@pytest.mark.parametrize("name,kwargs,fragment", [
    ("bad name", {}, "a primitive is named 'f' or 'agent::f'"),
    ("f", {"outcomes": []}, "needs at least one outcome"),
    ("f", {"outcomes": [Outcome("x"), Outcome("x", False)]}, "two outcomes named 'x'"),
    ("f", {"outcomes": ["ok"]}, "is not an Outcome"),
    ("f", {"outcomes": [Outcome("x", True, {"a b": 1})]}, "a variable is named 'var' or 'agent::var'"),
    ("f", {"fn": 3}, "is not callable"),
])
def test_register_errors(name, kwargs, fragment):
    with pytest.raises(RoarError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        Registry(builtins=False).register(name, **kwargs)


def test_duplicate_registration():
    reg = Registry(builtins=False)
    reg.register("f", lambda: 1)
    with pytest.raises(RoarError, match="already registered"):
        reg.register("f", lambda: 2)
    reg.register("f", lambda: 3, replace=True)
    assert reg.call("f") == 3


def test_outcome_is_hashable_and_primitive_compares_without_fn():
    assert hash(Outcome("a", True, {"x": 1})) == hash(Outcome("a", True, {"x": 2}))
    assert Primitive("f", lambda: 1) == Primitive("f", lambda: 2)


SPEC = """
a = ability {
  context = { { } { int pos = read(); int n = count(); } { } }
  export = { { } { int count(); double dist(int, int); } { sym = dist(A, B) == X |- dist(B, A) == X; } }
  tasks = {
    read = task { recipes = { r = recipe { body = { set pos count(); } } } }
    go = task {
      post = { {dist(pos, 1) < 1.0} }
      recipes = { r = recipe { pre = { {helper(1)} } body = { let t now(); wait(dist(pos, 2) < 0.5); } } }
    }
  }
}
b = ability { export = { { } { bool helper(int); } { } } }
"""


def test_resolve_reports_every_unbound_use():
    spec = parse_roar(SPEC, "s.roar")
    with pytest.raises(BindingError) as info:
        Registry().resolve(spec)
    err = info.value
    where = [(e.pos.line, e.pos.col) for e in err.errors]
    assert where == [(3, 47), (6, 61), (8, 17), (9, 41), (9, 81)]
    assert "function 'count' (declared by agent 'a') has no binding" in err.errors[0].message
    assert "register it as 'count' or 'a::count'" in err.errors[0].message
    assert "function 'helper' (declared by agent 'b')" in err.errors[3].message
    assert err.message.endswith("(and 4 more errors)")
    # rules are not bound, `now` is a builtin, `pos = read()` runs a task


def test_resolve_binds_and_checks():
    spec = parse_roar(SPEC, "s.roar")
    reg = Registry()
    reg.register("count", lambda: 3)
    reg.register("a::dist", lambda p, q: abs(p - q) * 1.0,
                 outcomes=[Outcome("near", True, {"n": 1}), Outcome("far", True, {"b::zz": 0})])
    reg.register("helper", lambda x, y=0: True)
    reg.register("a::pos", outcomes=[Outcome("zero", True, {"pos": 0, "nothere": 1})])
    with pytest.raises(BindingError) as info:
        reg.resolve(spec)
    msgs = [e.message for e in info.value.errors]
    assert msgs == [  # sorted by position: the variable `pos` (line 3), then `dist` (line 4)
        "outcome 'zero' of primitive 'a::pos' writes 'nothere', which is not a variable of agent 'a'",
        "outcome 'far' of primitive 'a::dist' writes 'b::zz', which is not a variable of agent 'b'",
    ]
    reg.register("a::dist", lambda p, q: 0.0, outcomes=[Outcome("near", True, {"n": 1})], replace=True)
    reg.register("a::pos", outcomes=[Outcome("zero", True, {"pos": 0})], replace=True)
    binding = reg.resolve(spec)
    assert isinstance(binding, Binding)
    assert set(binding.functions) == {"a::count", "a::dist", "b::helper", "now"}
    assert binding.function("a", "count")() == 3 and binding.function(None, "now")() >= 0
    assert set(binding.variables) == {"a::pos"}


@pytest.mark.parametrize("outcomes, helper_outcomes, message", [
    ([Outcome("near", True, {"n": True})], None,
     "outcome 'near' of primitive 'a::dist' writes True to 'n', which is int: expected a whole number"),
    ([Outcome("near", True, {"n": 2.5})], None,
     "outcome 'near' of primitive 'a::dist' writes 2.5 to 'n', which is int"),
    ([Outcome("near", True, result="close")], None,
     "outcome 'near' of primitive 'a::dist' returns 'close', but 'dist' is declared to return double"),
    (None, [Outcome("yes", True, result=7)],
     "outcome 'yes' of primitive 'helper' returns 7, but 'helper' is declared to return bool: expected true or "
     "false"),
])
def test_resolve_checks_the_types_of_outcome_values(outcomes, helper_outcomes, message):
    """An outcome's result or writes of another type than the spec declares is an error at the
    declaration (it was read as it was, and the recipe reading it stopped: a false deadlock)."""
    spec = parse_roar(SPEC, "s.roar")
    reg = Registry()
    reg.register("count", lambda: 3)
    reg.register("a::dist", lambda p, q: 0.0, outcomes=outcomes or [Outcome("near", True, {"n": 1}, result=0.5)])
    reg.register("helper", lambda x: True, outcomes=helper_outcomes)
    with pytest.raises(BindingError) as info:
        reg.resolve(spec)
    assert [e.message for e in info.value.errors][0].startswith(message)


def test_a_callable_returning_another_type_stops_the_run_located(tmp_path):
    """run: a callable returning 7 for a bool function is a located error naming the call (it was
    read as a number, and the wait reading it never woke)."""
    from roar_formal import load_spec as api_load
    spec = tmp_path / "plug.roar"
    spec.write_text("""
base = ability {
  context = { { } { bool charging = false; } { } }
  export = { { } { bool plug(); } { } }
  tasks = { charge = task { post = { {charging == true} }
    recipes = { r = recipe { body = { assert(plug()); set charging true; } } } } }
}
""", encoding="utf-8")
    (tmp_path / "plug.py").write_text(
        "from roar_formal.roar.functional import Registry\n"
        "def registry():\n    reg = Registry()\n    reg.register('plug', lambda: 7)\n    return reg\n",
        encoding="utf-8")
    with pytest.raises(RoarError) as info:
        api_load(spec).run("base::charging == true")
    err = info.value
    assert err.message == ("primitive 'base::plug' returned 7, but it is declared to return bool: "
                           "expected true or false (a Python bool)")
    assert (err.pos.file, err.pos.line) == (str(spec), 6)


def test_resolve_checks_arity_of_callables():
    spec = parse_roar(SPEC, "s.roar")
    reg = Registry()
    reg.register("count", lambda: 3)
    reg.register("dist", lambda p: 0.0)
    reg.register("helper", lambda *xs: True)
    with pytest.raises(BindingError) as info:
        reg.resolve(spec)
    assert info.value.message == ("the callable bound to 'dist' takes 1 argument, but agent 'a' declares "
                                  "'dist' with 2")
    assert (info.value.pos.line, info.value.pos.col) == (4, 40)


def test_demo_loco_needs_no_binding_and_mana_nav_does():
    assert Registry().resolve(load_spec(MODELS / "demo_loco")).functions == {}
    spec = load_spec(MODELS / "mana_nav.roar")
    reg = Registry()
    for name, fn in {"grab": lambda: object(), "lidar_ok": lambda: True, "sonar_ok": lambda: True, "fuse": lambda c, v: v + 1,
                     "mk_point": lambda x, y: (x, y), "distance": lambda p, q: 0.0,
                     "astar": lambda v, g: [g], "straight": lambda g: [g], "odom": lambda: (0.0, 0.0),
                     "follow": lambda t: True}.items():
        reg.register(name, fn)
    binding = reg.resolve(spec)
    assert "planner::astar" in binding.functions and "locomotion::follow" in binding.functions


def test_a_registry_entry_abstracts_a_task_initialised_variable_in_exploration():
    """``loco::pos`` is task-initialised (reading it runs locate). Its registry entry abstracts the
    read for exploration: one step of the functional layer whose outcomes write pos or fail the
    read, and the task does not run. With Python callables (a run), the read runs the task."""
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.run import run_model
    from roar_formal.roar.spec import load_spec
    from pathlib import Path

    from roar_formal.roar.functional import load_registry
    data = Path(__file__).parent / "data"
    spec = load_spec(data / "abstract_read.roar")
    reg = load_registry(data / "abstract_read.py")
    abstract = compile_spec(spec, "loco::arrived == true", registry=reg, functional="abstract")
    assert "fv_loco_pos" in abstract.functions and "crun_loco_locate" not in abstract.csts
    seen = set()
    for seed in range(12):
        r = run_model(abstract, seed=seed, max_steps=400)
        texts = [e.text for e in r.events]
        assert not any("recipe odometry" in t for t in texts) and r.final["loco::tries"] == 0
        if r.outcome == "success":
            seen.add("at_goal")
            assert r.final["loco::pos"] == 5
        if any("local failure" in t and "assert(pos == 5)" in t for t in texts):
            seen.add("short")     # pos written 3: the recipe's assert fails
        if any("local failure" in t and "read loco::pos (abstracted)" in t for t in texts):
            seen.add("lost")      # the read itself failed
    assert seen == {"at_goal", "short", "lost"}
    ran = run_model(compile_spec(spec, "loco::arrived == true"), seed=0)   # (no registry: the task runs)
    assert ran.outcome == "success" and ran.final["loco::tries"] == 1
    assert "crun_loco_locate" in compile_spec(spec, "loco::arrived == true", registry=reg,
                                              functional="python").csts


def test_exploration_refuses_a_module_that_leaves_a_function_unbound(tmp_path):
    """A spec with a functional layer is explored with its module's bindings: a called function the
    module leaves out is refused at the call (as a run refuses it), not explored with made-up
    outcomes; so is a callable with the wrong number of arguments."""
    from roar_formal.roar.compile import compile_spec
    spec = tmp_path / "g.roar"
    spec.write_text("""
g = ability {
  context = { { } { bool held = false; } { } }
  export = { { } { int force(); bool close(int); } { } }
  tasks = {
    grasp = task {
      post = { {held == true} }
      recipes = { r = recipe { body = { let f force(); assert(close(f)); set held true; } } }
    }
  }
}
""", encoding="utf-8")
    reg = Registry()
    reg.register("close", lambda width: True)
    with pytest.raises(BindingError, match="function 'force' .* has no binding") as err:
        compile_spec(load_spec(spec), "g::held == true", registry=reg, functional="abstract")
    assert err.value.pos is not None and err.value.pos.line == 8
    reg.register("force", lambda a, b: 3)
    with pytest.raises(BindingError, match="takes 2 arguments"):
        compile_spec(load_spec(spec), "g::held == true", registry=reg, functional="abstract")
