"""The hypothesis strategies: what they generate is valid, varied, and shrinks to small examples."""

from collections import Counter

import pytest
from hypothesis import HealthCheck, find, given, settings, strategies as st
from hypothesis.errors import InvalidArgument

from roar_formal.errors import RoarError
from roar_formal import ClfModel, load, load_spec
from roar_formal.clf.program import Program
from roar_formal.clf.state import canonical_key
from roar_formal.roar.checks import check_request, spec_errors
from roar_formal.roar.run import parse_fault
from roar_formal.testing import (STATEMENT_KINDS, clf_programs, clf_terms, fault_schedules, paths, requests, specs,
                                 statement_kinds)

QUICK = settings(max_examples=25, deadline=None, database=None, derandomize=True,
                 suppress_health_check=[HealthCheck.too_slow])
FIND = settings(database=None, max_examples=2000, derandomize=True)

BARE_MAKE = """\
arm = ability {
  context = {
    { }
    { bool done = false; }
    { }
  }
  tasks = {
    work = task {
      post = { {done == true} }
      recipes = {
        direct = recipe {
          body = {
            make(arm::done == true);
          }
        }
      }
    }
  }
}
"""

SIG = ("nat : type. z : nat. s : nat -> nat.\n"
       "exp : type. num : nat -> exp. plus : exp -> exp -> exp.\n"
       "lab : type. mk : number -> string -> lab.\n"
       "vec : nat -> type. vnil : vec z.\n")            # a dependent family: left out of the terms


# ------------------------------------------------------------------ generated specs


def test_generated_specs_use_every_statement_kind_and_pass_the_static_checks():
    """1,000 generated specs (derandomized): each passes the static checks, and every statement
    kind is in at least 2% of them. About 11 s here: hypothesis' draws about half, parsing a third."""
    with_kind: Counter = Counter()
    agents: Counter = Counter()
    seen = []

    @settings(max_examples=1000, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(specs())
    def draw(spec):
        assert spec_errors(spec.ast) == []   # from_text checked it already; the test does not rely on that
        with_kind.update(set(statement_kinds(spec)))
        agents[len(spec.agents)] += 1
        seen.append(spec.text)

    draw()
    assert len(seen) == 1000 and len(set(seen)) > 900
    assert set(with_kind) == set(STATEMENT_KINDS)
    assert all(with_kind[k] >= 20 for k in STATEMENT_KINDS), with_kind   # abort, the rarest, needs a handle
    assert agents[1] > 100 and agents[2] > 100


def _bare(spec) -> bool:
    """One task and one recipe an agent, no pre-condition, preference or end block."""
    n = len(spec.agents)
    return (spec.text.count("task {") == n and spec.text.count("recipe {") == n
            and not any(x in spec.text for x in ("pre =", "prefer =", "end =", "export")))


def test_generated_specs_shrink_to_a_bare_recipe():
    spec = find(specs(max_agents=1), lambda s: statement_kinds(s)["make"] >= 1, settings=FIND)
    assert statement_kinds(spec) == Counter({"make": 1}) and _bare(spec)
    assert spec.text == BARE_MAKE


@QUICK
@given(st.data())
def test_requests_are_accepted_by_their_spec(data):
    spec = data.draw(specs(max_agents=3))
    request = data.draw(requests(spec))
    check_request(spec.ast, request)
    assert request.split("::")[0] in spec.agents


def test_requests_shrink_to_the_first_post_condition(examples):
    pick = load_spec(examples / "pick" / "pick.roar")
    assert find(requests(pick), lambda r: True, settings=FIND) == "cell::lifted == true"
    assert "where" not in find(requests(pick), lambda r: "gripper" in r, settings=FIND)


# A generated spec compiles, runs, and its runs are paths of the explored model: test_dogfood.py.


# ------------------------------------------------------------------ fault schedules


def test_fault_schedules_name_the_functions_and_their_declared_outcomes(models):
    spa = load_spec(models / "spa_loop.roar")
    fns = {f for _a, f in spa.functions()}
    reg = spa.registry()

    @QUICK
    @given(fault_schedules(spa, permanent=True, max_faults=4))
    def check(faults):
        assert len(faults) == len(set(faults)) <= 4
        for text in faults:
            f = parse_fault(text)
            assert f.name in fns and (f.call is None or 1 <= f.call <= 3)
            if f.outcome is not None:
                assert f.outcome in [o.name for o in reg.lookup(f.name).outcomes]

    check()
    assert find(fault_schedules(spa), lambda f: len(f) > 0, settings=FIND) == ["new_scan:1"]
    assert find(fault_schedules(spa), lambda f: any("=" in x for x in f), settings=FIND) == ["new_scan:1=scan"]
    permanent = find(fault_schedules(spa, permanent=True), lambda f: any(":" not in x for x in f), settings=FIND)
    assert len(permanent) == 1 and permanent[0] in fns
    assert find(fault_schedules(spa, outcomes=False), lambda f: True, settings=FIND) == []
    assert not find(fault_schedules(spa, outcomes=False, max_faults=3), lambda f: len(f) == 3,
                    settings=FIND)[0].count("=")


# ------------------------------------------------------------------ paths


def _explored_keys(system_start_program):
    from roar_formal.explore.search import Budget, Explorer
    system = system_start_program
    ex = Explorer(system, "bfs")
    graph = ex.run(Budget())
    assert graph.complete
    return {canonical_key(s) for s in ex.states}, graph


def test_paths_of_a_clf_model_are_paths_of_the_explorers_graph(models):
    from roar_formal.explore.system import ClfSystem, Options
    dl = load(models / "philosophers" / "dl.clf")
    keys, _graph = _explored_keys(ClfSystem(dl.program, dl.start_context(), Options()))
    assert len(keys) == 572

    @QUICK
    @given(paths(dl, max_length=30))
    def check(path):
        assert len(path.states) == len(path) + 1
        assert all(canonical_key(s) in keys for s in path.states)
        assert path.quiescent == (not dl.program.steps(path.states[-1]))

    check()
    assert find(paths(dl), lambda p: len(p) >= 3, settings=FIND).rules == ["take_first"] * 3


def test_paths_of_a_spec_carry_its_roar_events_and_reach_its_deadlock(models):
    from roar_formal.explore.system import Options
    from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem, roar_final
    spec = load_spec(models / "faulty" / "mutual_make.roar")
    req = "arm::started == true"
    model = spec.compile(req, "abstract")
    program = model.program()
    start = program.start_context(next(d for d in program.sig.directives if hasattr(d, "start")).start)
    keys, _graph = _explored_keys(RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent")))
    path = find(paths(spec, req, max_length=60), lambda p: p.quiescent, settings=FIND)
    assert len(path) == 27 and not roar_final(path.states[-1])      # the explorer's deadlock
    assert all(canonical_key(s) in keys for s in path.states)
    texts = [e.text for e in path.events]
    assert texts[0] == "R0 sent -> pending  (arm::started == true)" and "make R2 to arm: arm::parked == true" in texts
    # as hypothesis prints a falsifying path: in the spec's terms, not the engine's rule names
    shown = repr(path)
    assert shown.startswith("<path of 27 steps, its ROAR events: 1. arm: R0 sent -> pending  (arm::started == true);")
    assert shown.endswith(", then quiescent>") and "select_" not in shown
    # hypothesis' pretty printer (a falsifying example): one event a line, as many as the events
    from hypothesis.vendor.pretty import pretty
    pretty_lines = pretty(path).splitlines()
    assert pretty_lines[0] == "<path of 27 steps, its ROAR events:"
    assert pretty_lines[1:-1] == [f"    {e.step}. {e.agent}: {e.text}" for e in path.events]
    assert pretty_lines[-1] == "    then quiescent>"
    with pytest.raises(InvalidArgument, match="need a request"):
        find(paths(spec), lambda p: True, settings=FIND)
    # a path's states read in the spec's terms: each variable's value as the events wrote it
    assert path.value("arm::started", 0) is False and path.value("door::open", 0) is False
    written = {}
    for e in path.events:
        if e.kind == "write":
            written[e.as_json()["var"]] = e.as_json()["value"]
    for var, v in written.items():
        assert path.value(var) == v, var
    assert any(f.startswith("contains v_arm_started") for f in path.facts())
    with pytest.raises(RoarError, match="no variable 'arm::nope'"):
        path.value("arm::nope")


# ------------------------------------------------------------------ CLF terms and programs


@QUICK
@given(st.data())
def test_clf_terms_are_well_typed_and_bounded(data):
    ty = data.draw(st.sampled_from(["nat", "exp", "lab"]))
    term = data.draw(clf_terms(SIG, ty, max_depth=3))
    Program.from_text(SIG + f"holds : {ty} -> type.\n#exec * holds ({term}).\n")   # type reconstruction agrees
    nesting, deepest = 0, 0
    for ch in term:
        nesting += {"(": 1, ")": -1}.get(ch, 0)
        deepest = max(deepest, nesting)
    assert deepest <= 2   # max_depth 3: a constant applied to terms of depth 2, nested in two parentheses


def test_clf_terms_shrink_to_the_first_constant_and_refuse_what_they_cannot_build():
    assert find(clf_terms(SIG, "nat"), lambda t: True, settings=FIND) == "z"
    assert find(clf_terms(SIG, "exp"), lambda t: "plus" in t, settings=FIND) == "plus (num z) (num z)"
    assert find(clf_terms(SIG, "lab"), lambda t: True, settings=FIND) == 'mk 0 ""'
    with pytest.raises(InvalidArgument, match="'vec' is not a base type"):
        clf_terms(SIG, "vec")
    with pytest.raises(InvalidArgument, match="no closed term of depth at most 0"):
        clf_terms(SIG, "exp", max_depth=0)


@QUICK
@given(clf_programs(SIG + "p : exp -> type.\nq : nat -> lab -> type.\n"))
def test_clf_programs_type_check_run_and_explore(model):
    assert isinstance(model, ClfModel) and model.start == 1
    run = model.run(max_steps=50)
    assert run.steps <= 50
    res = model.explore(["deadlock"], budget={"max_states": 200})
    assert res.status("deadlock") in ("holds", "violated", "incomplete")


def test_clf_programs_shrink_to_one_rule_and_one_fact():
    m = find(clf_programs(SIG + "p : exp -> type.\n"), lambda m: True, settings=FIND)
    assert m.text.endswith("r0 : p (num z) -o {1}.\n#exec * p (num z).\n")
    with pytest.raises(InvalidArgument, match="declares no predicate"):
        clf_programs("nat : type. z : nat.")


@pytest.mark.parametrize("given_as", ["model from text", "program"])
def test_a_signature_given_as_a_model_from_text_or_a_program_draws_programs_that_type_check(given_as):
    """A ClfModel made from text has no file yet (it read the missing scratch file), and a
    Program keeps no text (its programs were drawn without their declarations)."""
    src = SIG + "p : exp -> type.\n"
    sig = ClfModel.from_text(src + "#exec * p (num z).\n") if given_as == "model from text" else Program.from_text(src)
    m = find(clf_programs(sig), lambda m: "plus" in m.text, settings=FIND)
    assert m.program is not None and m.start == m.starts   # (the drawn #exec, after any the signature has)
    assert find(clf_terms(sig, "exp"), lambda t: "plus" in t, settings=FIND) == "plus (num z) (num z)"
