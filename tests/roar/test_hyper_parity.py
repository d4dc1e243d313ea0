"""hyper parity (issue 14, item 5): constructs of hyper's language the compiler used to refuse,
now compiled with their hyper meaning (docs/semantics.md, "Initial values" and "The logic layer";
docs/spec-language.md, "hyper compatibility"). The specs are in tests/roar/parity/, each with
its meaning in its header; what is still refused is tests/roar/unsupported/ (test_compile.py).

* Initial values that are constant expressions, or read the agent's earlier variables, are
  evaluated at compile time: the value is checked against Python's own arithmetic (int division
  truncated toward zero) and against the run-time evaluation of the same expression by a ``set``
  (the framework's ``peval``), on random expressions.
* An initial value that calls the functional layer is computed when the agents start, before the
  request is sent: in a run the callable is called once; in exploration the start branches on
  the declared outcomes, which a plain enumeration through ``Program.steps`` confirms.
* Calls in task pre-conditions are made by the logic layer, through the functional layer, before
  each decision: in a run the callables answer (with the where values as arguments), in
  exploration each outcome is a branch; the enumeration checks, on every complete path, that the
  request succeeds exactly when the outcomes taken make the pre-conditions true, and the
  explorer's verdicts agree with it.
"""

from __future__ import annotations

import re

from collections import deque
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError, UnsupportedError
from roar_formal.roar.compile import Crashes, compile_spec
from roar_formal.roar.functional import load_registry
from roar_formal.roar.parser import parse_roar
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from roar_formal.testing.api import load_spec as api_load

from .test_run import replay_on_enumerator
from .printed import args_of

PARITY = Path(__file__).resolve().parent / "parity"


# ------------------------------------------------------------------ the independent enumeration


class Paths:
    """Every complete path of a compiled model, by a plain search through the engine's
    ``Program.steps`` / ``Program.successor``: for each final state (no step enabled), the set of
    functional-layer outcome rules taken on the way to it, and the state's printed facts."""

    def __init__(self, model, limit: int = 5000):
        p = self.program = model.program()
        start = p.start_context(next(d for d in p.sig.directives if hasattr(d, "start")).start)
        self.states = {canonical_key(start): start}
        succ: dict = {}
        queue = deque([canonical_key(start)])
        while queue:
            k = queue.popleft()
            ctx = self.states[k]
            out = []
            for c in p.steps(ctx):
                nxt, _step = p.successor(ctx, c)
                nk = canonical_key(nxt)
                if nk not in self.states:
                    assert len(self.states) < limit
                    self.states[nk] = nxt
                    queue.append(nk)
                out.append((c.rule, nk))
            succ[k] = out
        self.succ = succ
        memo: dict = {}

        def ends(k) -> set:   # (outcome rules taken from k on, final state key)
            if k in memo:
                return memo[k]
            memo[k] = set()   # (a cycle would end here: none in these specs, checked below)
            got = set()
            if not succ[k]:
                got.add((frozenset(), k))
            for rule, nk in succ[k]:
                for outs, fin in ends(nk):
                    got.add((outs | {rule} if rule.startswith("outcome_") else outs, fin))
            memo[k] = got
            return got
        self.ends = ends(canonical_key(start))
        self.start = canonical_key(start)

    def facts(self, k) -> list[str]:
        return [self.program.show(f) for _m, f, _n in self.states[k].facts()]

    def family(self, k, fam: str) -> list[list[str]]:
        return [args_of(f) for f in self.facts(k) if f.split(" ", 1)[0] == fam]

    def r0_state(self, k) -> str:
        """The state of the request from outside (its ``rq`` names the emitter ``itop``)."""
        (r0,) = [q[0] for q in self.family(k, "rq") if q[3] == "itop"]
        (s,) = [x[1] for x in self.family(k, "rs") if x[0] == r0]
        return s

    def cell(self, k, cell: str) -> str:
        (v,) = [x[1] for x in self.family(k, "contains") if x[0] == cell]
        return v

    def acyclic(self) -> bool:
        seen, done = set(), set()

        def visit(k) -> bool:
            if k in done:
                return True
            if k in seen:
                return False
            seen.add(k)
            ok = all(visit(nk) for _r, nk in self.succ[k] if nk != k)
            done.add(k)
            return ok
        return visit(self.start)


def registry_of(path: Path):
    return load_registry(path.with_suffix(".py"))


# ------------------------------------------------------------------ constant initial values


def test_constant_initial_values_are_evaluated_at_compile_time():
    spec = load_spec(PARITY / "init_expression.roar")
    m = compile_spec(spec, "a::x == 1")
    init = m.init
    for cell, value in [("v_a_y", "(vnum 3)"), ("v_a_q", "(vnum -3)"), ("v_a_d", "(vnum 0.25)"),
                        ("v_a_big", "(vbool tt)")]:
        assert f"contains {cell} {value}" in init, (cell, init)
    # the same model as with the literals written out: nothing runs at start
    lit = (PARITY / "init_expression.roar").read_text(encoding="utf-8").replace(
        'int y = 1 + 2; int q = -7 / 2; double d = 1.0 / 4.0; bool big = y * 2 > 5 && q < 0;',
        'int y = 3; int q = -3; double d = 0.25; bool big = true;')
    assert compile_spec(parse_roar(lit, "lit.roar"), "a::x == 1").init == init
    # a run: big holds, so the task runs and sets x to y - 2
    rep = api_load(PARITY / "init_expression.roar").run("a::x == 1")
    assert rep.result.outcome == "success" and rep.result.final["a::x"] == 1
    assert rep.result.final["a::q"] == -3 and rep.result.final["a::d"] == 0.25
    # exploration: one start, every path succeeds
    ex = api_load(PARITY / "init_expression.roar").explore("a::x == 1", ["deadlock", "mission-completion"])
    assert ex.status("deadlock") == "holds" and ex.status("mission-completion") == "holds"
    paths = Paths(m)
    assert {paths.r0_state(k) for _o, k in paths.ends} == {"s_success"}


def test_initial_values_read_earlier_variables():
    m = compile_spec(load_spec(PARITY / "init_variable.roar"), "a::x == 1")
    assert "contains v_a_y (vnum 0) * contains v_a_w (vnum 4)" in m.init
    rep = api_load(PARITY / "init_variable.roar").run("a::x == 1")
    assert rep.result.outcome == "success" and rep.result.final == {"a::x": 1, "a::y": 0, "a::w": 4}


def _int_expr(depth: int = 3):
    leaf = st.integers(-9, 9).map(lambda n: str(n) if n >= 0 else f"(-{-n})")
    if depth == 0:
        return leaf
    sub = _int_expr(depth - 1)
    return st.one_of(leaf, st.tuples(sub, st.sampled_from("+-*/"), sub).map(lambda t: f"({t[0]} {t[1]} {t[2]})"))


def _python_value(text: str) -> int:
    """Python's own value of an int expression of the spec language: C division, truncating."""
    class T(int):
        def _w(self, v):
            return T(v)

        def __add__(self, o):
            return T(int(self) + int(o))

        def __sub__(self, o):
            return T(int(self) - int(o))

        def __mul__(self, o):
            return T(int(self) * int(o))

        def __truediv__(self, o):
            if int(o) == 0:
                raise ZeroDivisionError
            return T(int(Fraction(int(self), int(o))))   # int() of a Fraction truncates toward zero

        def __neg__(self):
            return T(-int(self))
    import re
    return int(eval(re.sub(r"\d+", lambda m: f"T({m.group(0)})", text)))


SPEC_INT = """a = ability {{
  context = {{ {{ int x; }} {{ int y = {e}; int r; }} {{ }} }}
  tasks = {{ t = task {{ post = {{ {{x == 1}} }} recipes = {{ r = recipe {{ body = {{ set r {e}; set x 1; }} }} }} }} }}
}}
"""


@settings(max_examples=30, deadline=None)
@given(_int_expr())
def test_constant_initial_values_agree_with_python_and_with_the_run_time(e):
    """The compile-time value of an initialiser is Python's value of the expression (division
    truncating toward zero) and the value the engine computes for the same expression in a ``set``
    at run time; a division by zero is a located error."""
    spec = parse_roar(SPEC_INT.format(e=e), "gen.roar")
    try:
        want = _python_value(e)
    except ZeroDivisionError:
        with pytest.raises(RoarError, match="divides by zero") as info:
            compile_spec(spec, "a::x == 1")
        assert info.value.pos is not None and info.value.pos.line == 2
        return
    m = compile_spec(spec, "a::x == 1", functional="python")
    res = run_model(m)
    assert res.outcome == "success"
    assert res.final["a::y"] == want == res.final["a::r"], (e, res.final)


def test_a_constant_without_a_decimal_form_is_computed_at_start():
    src = """a = ability {
  context = { { int x; } { double d = 1.0 / 3.0; double e = d * 3.0; } { } }
  tasks = { t = task { post = { {x == 1} } recipes = { r = recipe { body = { set x 1; } } } } }
}
"""
    m = compile_spec(parse_roar(src, "third.roar"), "a::x == 1")
    assert "sgate r0" in m.init   # the request waits for the start
    res = run_model(compile_spec(parse_roar(src, "third.roar"), "a::x == 1", functional="python"))
    assert res.outcome == "success" and res.final["a::e"] == 1
    assert abs(res.final["a::d"] - 1 / 3) < 1e-12


@pytest.mark.parametrize("init,fragment,at", [
    ("int y = b::v;", "a variable of another agent", "b::v"),
    ("int y = w; int w;", "declared after it", "w;"),
    ("int y = y + 1;", "declared at the same place", "y + 1"),
    ("int y = p + 1;", "whose value is made by running task 'get_p'", "p + 1"),
])
def test_initial_values_that_stay_refused(init, fragment, at):
    src = f"""b = ability {{ context = {{ {{ }} {{ int v; }} {{ }} }} }}
a = ability {{
  context = {{ {{ int x; }} {{ int p = get_p(); {init} }} {{ }} }}
  tasks = {{
    get_p = task {{ recipes = {{ r = recipe {{ body = {{ set p 2; }} }} }} }}
    t = task {{ post = {{ {{x == 1}} }} recipes = {{ r = recipe {{ body = {{ set x 1; }} }} }} }}
  }}
}}
"""
    spec = parse_roar(src, "refused.roar")
    with pytest.raises(UnsupportedError, match=fragment) as info:
        compile_spec(spec, "a::x == 1")
    pos = info.value.pos
    line = src.splitlines()[pos.line - 1]
    assert line[pos.col - 1:].startswith(at), (line, pos)


# ------------------------------------------------------------------ initial values from the functional layer


def test_an_initial_call_is_made_once_when_the_agent_starts():
    path = PARITY / "init_call.roar"
    spec = load_spec(path)
    reg = registry_of(path)
    m = compile_spec(spec, "a::x == 1", registry=reg, functional="python")
    calls = reg.lookup("level", "a").fn.__globals__["CALLS"]   # (the module's own list of calls)
    calls.clear()
    res = run_model(m, registry=reg)
    assert calls == ["level"]
    assert res.outcome == "success" and res.final["a::y"] == 3 and res.final["a::z"] == 30
    texts = [e.text for e in res.events]
    assert texts.index("level() = 3") < texts.index("a::y = 3") < texts.index("a::z = 30") \
        < texts.index("R0 sent -> pending  (a::x == 1)")
    assert replay_on_enumerator(res) == len(res.steps)
    # a fault: the declared outcome, or a failed call, which leaves the default
    rep = api_load(path).run("a::x == 1", faults=["level=low"])
    assert rep.result.outcome == "failure" and rep.result.final["a::y"] == 1 and rep.result.final["a::z"] == 10
    rep = api_load(path).run("a::x == 1", faults=["level"])
    assert rep.result.outcome == "failure" and rep.result.final["a::y"] == 0 and rep.result.final["a::z"] == 0


def test_an_initial_call_branches_the_start_in_exploration():
    path = PARITY / "init_call.roar"
    m = compile_spec(load_spec(path), "a::x == 1", registry=registry_of(path))
    paths = Paths(m)
    assert paths.acyclic()
    # before the start is done, the request is not sent and no variable but y and z changes
    start_facts = paths.facts(paths.start)
    assert any(f.startswith("sgate ") for f in start_facts) and not any(f.startswith("rs ") for f in start_facts)
    finals = {}
    for outs, k in paths.ends:
        y = paths.cell(k, "v_a_y")
        finals.setdefault(y, set()).add(paths.r0_state(k))
        assert paths.cell(k, "v_a_z") == {"(vnum 1)": "(vnum 10)", "(vnum 3)": "(vnum 30)",
                                          "(vnum 0)": "(vnum 0)"}[y]
        (taken,) = outs   # one outcome per path: the start's
        assert y == {"outcome_f_a_level_low": "(vnum 1)", "outcome_f_a_level_high": "(vnum 3)",
                     "outcome_f_a_level_broken": "(vnum 0)"}[taken]
    # hyper's meaning: the task needs y > 2, so only level's 3 leads to success
    assert finals == {"(vnum 1)": {"s_failure"}, "(vnum 3)": {"s_success"}, "(vnum 0)": {"s_failure"}}
    ex = api_load(path).explore("a::x == 1", ["deadlock", "mission-completion", "mission-failure"])
    assert ex.status("deadlock") == "holds"
    assert ex.status("mission-completion") == "violated" and ex.status("mission-failure") == "violated"


# ------------------------------------------------------------------ calls in task pre-conditions

PRE = PARITY / "pre_call.roar"
GO5 = "a::x == a::goal where a::goal == 5"


def test_pre_condition_calls_in_a_run_use_the_where_values():
    reg = registry_of(PRE)
    calls = reg.lookup("ready", "a").fn.__globals__["CALLS"]
    for goal, outcome in [(5, "success"), (50, "failure")]:
        calls.clear()
        m = compile_spec(load_spec(PRE), f"a::x == a::goal where a::goal == {goal}", registry=reg,
                         functional="python")
        res = run_model(m, registry=reg)
        assert res.outcome == outcome, res.error_context
        # the logic layer calls before it decides, with the goal the where clause gives
        assert calls == ["battery", "ready", f"in_range({goal})"]
        texts = [e.text for e in res.events]
        assert texts.index(f"in_range({goal}) = {'true' if goal < 10 else 'false'}") < len(texts)
        if outcome == "success":
            assert texts.index("R0: tasks prep then go") > texts.index(f"in_range({goal}) = true")
            assert res.final["a::armed"] is True and res.final["a::x"] == goal
        else:
            assert res.final["a::goal"] == 0 and res.final["a::armed"] is False   # rejected: nothing written
        assert replay_on_enumerator(res) == len(res.steps)


@pytest.mark.parametrize("faults,outcome", [(["battery=low"], "failure"), (["battery"], "failure"),
                                            (["ready=no"], "failure"), ([], "success")])
def test_pre_condition_calls_with_faults(faults, outcome):
    rep = api_load(PRE).run(GO5, faults=faults, strict_faults=True)
    assert rep.result.outcome == outcome


def test_pre_condition_calls_branch_in_exploration():
    """On every complete path, the request succeeds exactly when the outcomes taken make the
    pre-conditions true (ready: yes; battery: full, i.e. 80 > 20); the explorer agrees."""
    m = compile_spec(load_spec(PRE), GO5, registry=registry_of(PRE))
    paths = Paths(m)
    assert paths.acyclic()
    seen = set()
    for outs, k in paths.ends:
        taken = {o[len("outcome_f_"):] for o in outs}   # outcome_f_a_ready_yes -> a_ready_yes
        expect = {"a_ready_yes", "a_battery_full"} <= taken
        assert (paths.r0_state(k) == "s_success") == expect, (taken, paths.r0_state(k))
        seen.add(frozenset(taken))
        # a decision's calls are made once each: one outcome per function on a path
        assert len([t for t in taken if t.startswith("a_ready")]) == 1
    assert len(seen) == 2 * 3   # every combination of ready's and battery's outcomes (in_range: one)
    ex = api_load(PRE).explore(GO5, ["deadlock", "mission-completion", "mission-failure"])
    assert ex.status("deadlock") == "holds"
    assert ex.status("mission-completion") == "violated" and ex.status("mission-failure") == "violated"
    assert any(paths.r0_state(k) == "s_success" for _o, k in paths.ends)


def test_a_failed_call_makes_its_conjunct_false_and_the_others_are_subgoaled():
    m = compile_spec(load_spec(PRE), GO5, registry=registry_of(PRE))
    # go's second pre-condition is split: the call is the logic layer's, armed == true is sub-goaled
    tpre = next(line for line in m.spec_text.splitlines() if line.startswith("tpre_t_a_go "))
    assert "(pc lp_a_2)" in tpre and "(pc lp_a_3)" in tpre and "(pbin o_eq (pc v_a_armed) (pl (vbool tt)))" in tpre
    assert m.candidates  # the constraint's candidates are unchanged by the calls
    assert ("a", "go") in m.candidates[m.request_cst]


def test_pre_condition_calls_and_crashes_combine():
    """(They used to be refused.) With the agent that may crash, the logic activation's rules are
    guarded by the epoch of the request it decides on; tests/roar/test_time_crashes.py checks a
    crash during such a decision against a plain search."""
    m = compile_spec(load_spec(PRE), GO5, crashes=Crashes(("a",)))
    names = m.program().rule_names
    assert "unavailable_lq" in names and "unavailable_lq_call" in names
    lpre = [x.group(0) for x in re.finditer(r"^st\d+_lpre : .*?\}\.", m.spec_text, re.S | re.M)]
    assert lpre and all("hs Rg (h_lq I)" in x and "ep_cur" in x for x in lpre)


# ------------------------------------------------------------------ request where values


def test_a_constant_where_value_is_its_literal():
    spec = load_spec(PARITY / "request_where_not_literal.roar")
    folded = compile_spec(spec, "a::x == a::goal where a::goal == 2 + 3")
    literal = compile_spec(spec, "a::x == a::goal where a::goal == 5")
    assert folded.spec_text == literal.spec_text
    rep = api_load(PARITY / "request_where_not_literal.roar").run("a::x == a::goal where a::goal == 2 * 4 - 10 / 3")
    assert rep.result.outcome == "success" and rep.result.final["a::x"] == 5
    with pytest.raises(UnsupportedError, match="reads 'a::x'") as info:
        compile_spec(spec, "a::x == a::goal where a::goal == a::x + 1")
    assert (info.value.pos.file, info.value.pos.col) == ("<request>", 34)
    with pytest.raises(RoarError, match="divides by zero"):
        compile_spec(spec, "a::x == a::goal where a::goal == 1 / (2 - 2)")


# ------------------------------------------------------------------ untouched specs: the same model


def test_specs_without_these_constructs_compile_as_before():
    """A spec with only literal initial values and call-free task pre-conditions has no start
    activation and no logic activation: not one rule more."""
    root = Path(__file__).resolve().parents[2]
    m = compile_spec(load_spec(root / "models" / "demo_loco"),
                     "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5")
    for word in ("i_start", "sgate", "lsnap", "h_lq", "lselect_", "lp_"):
        assert word not in m.spec_text


# ------------------------------------------------------------------ one constraint, several where clauses


def test_a_request_with_its_own_where_clause():
    path = PARITY / "request_where_differs.roar"
    req = "b::y == 1 where b::h == 4"
    m = compile_spec(load_spec(path), req)
    assert m.request_cst != "c1_b" and m.request_cst.startswith("c1_b_w")   # a variant of the recipes' constraint
    assert f"id_{m.request_cst} : cst_id {m.request_cst} 1." in m.spec_text and "id_c1_b : cst_id c1_b 1." in m.spec_text
    assert m.where_cells[m.request_cst] == ["v_b_h"] and m.where_cells["c1_b"] == ["v_b_g"]
    rep = api_load(path).run(req)
    assert rep.result.outcome == "success" and rep.result.final["b::h"] == 4 and rep.result.final["b::g"] == 0
    paths = Paths(m)
    for _o, k in paths.ends:
        assert paths.r0_state(k) == "s_success"
        assert (paths.cell(k, "v_b_h"), paths.cell(k, "v_b_g"), paths.cell(k, "v_b_y")) == \
            ("(vnum 4)", "(vnum 0)", "(vnum 1)")
    ex = api_load(path).explore(req, ["deadlock", "mission-completion"])
    assert ex.status("deadlock") == "holds" and ex.status("mission-completion") == "holds"


def test_one_constraint_sent_with_two_where_clauses():
    path = PARITY / "where_two_clauses.roar"
    m = compile_spec(load_spec(path), "a::done == true")
    rep = api_load(path).run("a::done == true")
    texts = [e.text for e in rep.result.events]
    assert rep.result.outcome == "success"
    assert texts.index("b::g = 2") < texts.index("b::h = 2")   # each send writes its own clause
    assert replay_on_enumerator(rep.result) == len(rep.result.steps)
    paths = Paths(m)
    for _o, k in paths.ends:
        assert paths.r0_state(k) == "s_success"
        assert (paths.cell(k, "v_b_g"), paths.cell(k, "v_b_h")) == ("(vnum 2)", "(vnum 2)")
    ex = api_load(path).explore("a::done == true", ["deadlock", "mission-completion"])
    assert ex.status("deadlock") == "holds" and ex.status("mission-completion") == "holds"


def test_the_clauses_of_one_constraint_share_its_failures():
    """The first recipe's constraint fails; the second sends the same constraint with another
    where clause, so it is invalid too (5.2), and last_error? names the constraint whatever its
    clause: on every path the third recipe ends the task, and the second never runs."""
    path = PARITY / "where_variant_error.roar"
    m = compile_spec(load_spec(path), "a::done == true")
    rep = api_load(path).run("a::done == true")
    assert rep.result.outcome == "success" and rep.result.final["a::via"] == 3
    paths = Paths(m)
    assert paths.ends
    for _o, k in paths.ends:
        assert paths.r0_state(k) == "s_success" and paths.cell(k, "v_a_via") == "(vnum 3)"
    assert not any(q[3] == "r_a_t_second" for k in paths.states for q in paths.family(k, "act"))
