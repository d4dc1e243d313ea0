"""Tests for the static checks (roar_formal.roar.checks) and the malformed-spec suite."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roar_formal.errors import RoarError, SyntaxError_, TypeError_
from roar_formal.roar.checks import (CheckError, SpecCheckError, check_request, check_spec, request_errors,
                                     spec_errors)
from roar_formal.roar import ast as a
from roar_formal.roar.spec import load_spec
from roar_formal.roar.parser import parse_constraint, parse_roar
from roar_formal.roar.pretty import format_expr, format_spec

from repo import ROOT
MODELS = ROOT / "models"
HERE = Path(__file__).parent


def errors(text: str) -> list[CheckError]:
    return spec_errors(parse_roar(text, "t.roar"))


def codes(text: str) -> list[str]:
    return [e.code for e in errors(text)]


def agent(context: str = "{ } { } { }", export: str = "", body: str = "", pre: str = "", post: str = "",
          extra: str = "", recipe_extra: str = "") -> str:
    """One agent `a` with one task `t` and one recipe `r` (plus `extra` agents)."""
    exp = f"export = {{ {export} }}" if export else ""
    return (f"a = ability {{ context = {{ {context} }} {exp} tasks = {{ t = task {{ pre = {{ {pre} }} "
            f"post = {{ {post} }} recipes = {{ r = recipe {{ {recipe_extra} body = {{ {body} }} }} }} }} }} }}\n"
            + extra)


# -- the models pass -------------------------------------------------------------------

@pytest.mark.parametrize("model", ["demo_loco", "spa_loop.roar", "mana_nav.roar", "conflict.roar"])
def test_models_pass_the_checks(model):
    spec = load_spec(MODELS / model)
    assert spec_errors(spec) == []
    checked = check_spec(spec)
    assert checked.spec is spec
    # what the compiler consumes: every variable typed, and every expression of a recipe
    assert set(checked.var_types) == {(ag.name, v.name) for ag in spec.agents for v in ag.vars}
    # (the compiler asks the types of operators' operands and of a field's base)
    operands = [x for n in a.walk(spec) if isinstance(n, (a.Binary, a.Field))
                for x in ((n.left, n.right) if isinstance(n, a.Binary) else (n.base,))]
    assert operands and [format_expr(e) for e in operands if id(e) not in checked.typed] == []
    assert all(checked.type_of(e) == "bool" for ag in spec.agents for t in ag.tasks for e in t.post)


def test_demo_loco_single_file_passes():
    load_spec(HERE / "data" / "demo_loco.roar")


REQUESTS = [
    ("demo_loco", "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5"),
    ("spa_loop.roar", "exec::arrived == true where exec::goal == 7"),
    ("mana_nav.roar", "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0"),
    ("conflict.roar", "mission::done == true"),
]


@pytest.mark.parametrize("model,request_text", REQUESTS)
def test_model_requests(model, request_text):
    spec = load_spec(MODELS / model)
    c = check_request(spec, request_text)
    assert c == parse_constraint(request_text)


def test_bad_requests():
    spec = load_spec(MODELS / "demo_loco")
    got = request_errors(spec, parse_constraint(
        "demo_loco::pos == 1.0 where demo_loco::pos == 5 && goal == 1 && demo_loco::init == true"))
    msgs = [e.message for e in got]
    assert any("cannot compare int with double" in m for m in msgs)
    assert any("'demo_loco::pos' is readable, not controllable" in m for m in msgs)
    assert any("a request names its variables with their agent" in m for m in msgs)
    assert any("'demo_loco::init' is private to agent 'demo_loco'" in m for m in msgs)
    with pytest.raises(SpecCheckError, match="a request names the agent"):
        check_request(spec, "1 == 1")


# -- all errors, one exception -------------------------------------------------------------

def test_all_errors_are_collected_sorted_and_listed():
    text = agent(context="{ int g; } { } { }", body="set g 1.0; abort h; set zz 1;",
                 post="{g}", extra="a = ability { }")
    with pytest.raises(SpecCheckError) as info:
        check_spec(parse_roar(text, "t.roar"))
    err = info.value
    assert isinstance(err, TypeError_) and isinstance(err, RoarError)
    assert [e.code for e in err.errors] == ["not-bool", "int-double", "abort", "unknown-variable", "duplicate"]
    lines = [(e.pos.line, e.pos.col) for e in err.errors]
    assert lines == sorted(lines)
    assert err.pos == err.errors[0].pos
    assert err.message.endswith("(and 4 more errors)")
    text_out = err.format()
    assert text_out.count("t.roar:") == 5 and "Traceback" not in text_out


def test_one_error_has_no_suffix():
    with pytest.raises(SpecCheckError) as info:
        check_spec(parse_roar(agent(body="set nope 1;"), "t.roar"))
    assert info.value.message == "unknown variable 'nope' in agent 'a'"
    assert info.value.notes == []


def test_load_spec_can_skip_checks(tmp_path):
    p = tmp_path / "x.roar"
    p.write_text(agent(body="set nope 1;"))
    assert load_spec(p, check=False).agents[0].name == "a"
    with pytest.raises(SpecCheckError):
        load_spec(p)


# -- each check -------------------------------------------------------------------------------

CASES = [
    # names and visibility
    (agent(body="make(zz::x == 1);"), "unknown-agent", "unknown agent 'zz'"),
    (agent(body="make(bb::x == 1);", extra="bbb = ability { }"), "unknown-agent", "did you mean 'bbb'?"),
    (agent(context="{ int speed; } { } { }", body="set speed sped;"), "unknown-variable",
     "unknown variable 'sped' in agent 'a'; did you mean 'speed'?"),
    (agent(body="let x distanse(1);", export="{ } { int distance(int); } { }"), "unknown-function",
     "did you mean 'distance'?"),
    (agent(body="wait(b::nope == 1);", extra="b = ability { }"), "unknown-variable", "agent 'b' has no variable 'nope'"),
    (agent(body="wait(b::s == 1);", extra="b = ability { context = { { } { } { int s; } } }"),
     "private", "'b::s' is private to agent 'b'"),
    (agent(context="{ } { } { int s; }", body="wait(a::s == 1);"), None, None),  # own private: fine
    (agent(context="{ a::t x; } { } { }"), "unknown-type", "agent 'a' declares no type 't'"),
    (agent(context="{ zz::t x; } { } { }"), "unknown-agent", "unknown agent 'zz' in type 'zz::t'"),
    (agent(context="{ } { } { int x; int x; }"), "duplicate", "duplicate variable 'x'"),
    (agent(export="{ p = opaquetype; p = opaquetype; } { } { }"), "duplicate", "duplicate type 'p'"),
    (agent(export="{ } { int f(); int f(); } { }"), "duplicate", "duplicate function 'f'"),
    (agent(export="{ } { } { r = |- true; r = |- true; }"), "duplicate", "duplicate rule 'r'"),
    (agent(export="{ } { int t(); } { }"), "duplicate", "'t' is both a function and a task"),
    (agent(export="{ p = struct { int x; int x; }; } { } { }"), "duplicate", "duplicate field 'x'"),
    # functions
    (agent(body="f(1);"), "unknown-function", "unknown function 'f'"),
    (agent(body="b::f(1);", extra="b = ability { }"), "unknown-function", "agent 'b' exports no function 'f'"),
    (agent(body="t();"), "task-call", "'t' is a task of agent 'a', not a function"),
    (agent(body="let x f(1, 2);", export="{ } { int f(int); } { }"), "arity", "takes 1 argument, not 2"),
    (agent(body="let x f(true);", export="{ } { int f(int); } { }"), "type", "argument 1 of 'f' must be int"),
    (agent(body="let x f(1);", extra="b = ability { export = { { } { int f(int); } { } } }"
                                     "c = ability { export = { { } { int f(int); } { } } }"),
     "ambiguous", "function 'f' is exported by agents b, c"),
    (agent(body="let x f(1);", extra="b = ability { export = { { } { int f(int); } { } } }"), None, None),
    (agent(body="let start now(); wait(now() > start + 10);"), None, None),
    (agent(context="{ } { int p = t(1); } { }"), "arity", "a task takes no arguments"),
    # where clauses
    (agent(body="make(b::ok == true where b::g == 1);",
           extra="b = ability { context = { { int g; } { bool ok = false; } { } } }"), None, None),
    (agent(body="make(b::ok == true where 1 == b::g);",
           extra="b = ability { context = { { int g; } { bool ok = false; } { } } }"), None, None),
    (agent(context="{ int g; } { bool ok = false; } { }", body="make(ok == true where g == 1);"), None, None),
    (agent(body="make(b::ok == true where b::g == true);",
           extra="b = ability { context = { { int g; } { bool ok = false; } { } } }"),
     "type", "the where pair 'b::g == true' sets int to bool"),
    (agent(body="make(b::ok == true where 1 == 2);",
           extra="b = ability { context = { { int g; } { bool ok = false; } { } } }"),
     "where", "writes no controllable variable of agent 'b'"),
    (agent(body="make(b::x == c::y);", extra="b = ability { context = { { } { int x = 0; } { } } }"
                                           "c = ability { context = { { } { int y = 0; } { } } }"),
     "constraint-agents", "names b, c"),
    (agent(body="make(1);"), "not-bool", "a constraint must be a bool condition"),
    # a variable alone reads 'x == true': said as written, for a variable that is not a bool
    (agent(body="make(b::g);", extra="b = ability { context = { { int g; } { } { } } }"),
     "type", "'b::g' is int, not bool: a variable alone in a constraint means 'b::g == true'"),
    (agent(body="make(!b::g);", extra="b = ability { context = { { int g; } { } { } } }"),
     "type", "'b::g' is int, not bool"),
    # statements
    (agent(body="set b::g 1;", extra="b = ability { context = { { int g; } { } { } } }"), "set-remote",
     "set changes only this agent's own variables"),
    (agent(context="{ int g; } { } { }", body="set a::g 1;"), None, None),
    (agent(body="let h ensure(true == true); set h 1;"), "set-handle", "'h' is an ensure handle"),
    (agent(body="let h ensure(true == true); let y h;"), "handle-value", "'h' is an ensure handle"),
    (agent(body="let x 1; set x 2;"), None, None),
    (agent(body="let x 1; set x 2.0;"), "int-double", "cannot set 'x' (int) to '2.0' (double)"),
    (agent(body="let x 1; let x 2;"), "duplicate", "'x' is already bound by let at 1:"),
    (agent(context="{ int g; } { } { }", body="let g 2;"), "shadow", "let 'g' would hide the context variable"),
    (agent(body="abort h;"), "abort", "abort h: no 'let h ensure(...)'"),
    (agent(body="let h ensure(true == true); abort h;"), None, None),
    (agent(body="ensure(true == true, 1.5);"), "int-double", "a period is an int number of milliseconds"),
    (agent(body="wait(true, \"x\");"), "type", "a period is an int number of milliseconds"),
    (agent(body="assert(1);"), "not-bool", "the condition of assert must be a bool condition"),
    # types
    (agent(post="{1 + 1.0 == 2.0}"), "int-double", "'+' mixes int and double"),
    (agent(post="{\"a\" < \"b\"}"), "type", "'<' needs two ints or two doubles, not string and string"),
    (agent(post="{!1}"), "type", "'!' needs a bool"),
    (agent(post="{-true}"), "type", "'-' needs an int or a double"),
    (agent(post="{1 && true}"), "type", "'&&' needs bool operands; '1' is int"),
    (agent(context="{ } { } { string s = \"x\"; identifier i = \"y\"; }", post="{s == \"z\"} {i == \"w\"}"),
     None, None),
    (agent(context="{ } { } { string s = \"x\"; identifier i = \"y\"; }", post="{s == i}"),
     "type", "cannot compare string with identifier"),
    (agent(context="{ } { } { m d; }", export="{ m = newtype double; } { } { }", post="{d < 1.0}"),
     "type", "'<' needs two ints or two doubles, not a::m and double"),
    (agent(context="{ } { } { p q; }", export="{ p = struct { double x; }; } { } { }", post="{q.x < 1.0}"),
     None, None),
    (agent(context="{ } { } { p q; }", export="{ p = struct { double x; }; } { } { }", post="{q.y < 1.0}"),
     "field", "struct a::p has no field 'y' (its fields: x)"),
    (agent(context="{ } { } { int q; }", post="{q.y < 1.0}"), "field", "'q' is int, which has no fields"),
    (agent(context="{ } { } { b::p q; }", post="{q.x == 1}",
           extra="b = ability { export = { { p = struct { int x; }; } { } { } } }"), None, None),
    (agent(context="{ } { } { p q; }", post="{true}",
           extra="b = ability { export = { { p = opaquetype; } { } { } } }"), None, None),
    (agent(context="{ } { } { int x = 1.0; }"), "int-double", "'x' is int but its initial value '1.0' is double"),
    (agent(export="{ } { double dist(int, int); } { sym = dist(A, B) == X |- dist(B, A) == X; }"), None, None),
    (agent(export="{ } { double dist(int, int); } { bad = dist(A) == X |- true; }"), "arity", "takes 2"),
    (agent(export="{ } { } { bad = lower == 1 |- true; }"), "unknown-variable", "unknown variable 'lower'"),
    # pre, post, last_error?, prefer, recipes
    (agent(recipe_extra="pre = { {last_error?(b::ok == true)} }", extra="b = ability { context = { { } { bool ok = false; } { } } }"),
     None, None),
    (agent(pre="{last_error?(true)}"), "last-error", "only be used in the pre-conditions of a recipe"),
    (agent(recipe_extra="prefer = -1"), None, None),
    (agent(recipe_extra="prefer = 1 + 1"), "prefer", "prefer must be an integer literal such as 2"),
    (agent(recipe_extra="prefer = true"), "prefer", "'true' is bool"),
    ("a = ability { tasks = { t = task { } } }", "no-recipe", "task 't' of agent 'a' has no recipe"),
    ("a = ability { tasks = { t = task { recipes = { r = recipe { } r = recipe { } } } } }", "duplicate",
     "duplicate recipe 'r' in task 't'"),
    ("a = ability { } b = ability { } a = ability { }", "duplicate", "duplicate agent 'a'"),
]


@pytest.mark.parametrize("text,code,fragment", CASES)
def test_check(text, code, fragment):
    got = errors(text)
    if code is None:
        assert got == [], [e.format() for e in got]
        return
    assert [e.code for e in got] == [code], [e.format() for e in got]
    assert fragment in got[0].message, got[0].message
    assert got[0].pos is not None and got[0].pos.file == "t.roar" and got[0].pos.line >= 1


# -- hyper layout: imports ------------------------------------------------------------------

def write(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


HYPER = {
    "loco.ability": "loco = ability { context = { { } { bool moving = false; } { } } }",
    "planner.ability": "planner = ability { context = { { int target; } { bool ready = false; } { } } "
                       "export = { { point = struct { int x; }; } { int cost(int); } { } } }",
    "loco/go.task": "task { post = { {moving == true} } }",
    "loco/go/r.recipe": "recipe { body = { make(planner::ready == true where planner::target == planner::cost(1)); "
                        "set moving true; } }",
}


def test_hyper_agent_must_import(tmp_path):
    write(tmp_path, HYPER)
    with pytest.raises(SpecCheckError) as info:
        load_spec(tmp_path)
    errs = info.value.errors
    assert {e.code for e in errs} == {"not-imported"}
    assert all("add 'import \"planner.ability\"' at the top of loco.ability" in e.message for e in errs)
    assert [(Path(e.pos.file).name, e.pos.line, e.pos.col) for e in errs] == [
        ("r.recipe", 1, 24), ("r.recipe", 1, 53), ("r.recipe", 1, 72)]


def test_hyper_import_makes_it_visible(tmp_path):
    files = dict(HYPER)
    files["loco.ability"] = 'import "planner.ability"\n' + files["loco.ability"]
    write(tmp_path, files)
    spec = load_spec(tmp_path / "loco.ability")
    assert spec.visible("loco") == {"loco", "planner"}
    assert spec.visible("planner") == {"planner"}  # imports are not symmetric


def test_hyper_unimported_types_and_calls(tmp_path):
    write(tmp_path, {
        "a.ability": "a = ability { context = { { } { } { b::point p; int c = cost(1); } } }",
        "b.ability": "b = ability { export = { { point = struct { int x; }; } { int cost(int); } { } } }",
    })
    with pytest.raises(SpecCheckError) as info:
        load_spec(tmp_path)
    msgs = [e.message for e in info.value.errors]
    assert msgs[0].startswith("agent 'b' is not imported by agent 'a'")
    assert msgs[1].startswith("unknown function 'cost'")


def test_single_file_agents_see_each_other_but_not_other_files(tmp_path):
    write(tmp_path, {
        "one.roar": "x = ability { context = { { } { int v = y::w + z::u; } { } } }\n"
                    "y = ability { context = { { } { int w = 0; } { } } }",
        "two.roar": "z = ability { context = { { } { int u = 0; } { } } }",
    })
    with pytest.raises(SpecCheckError) as info:
        load_spec(tmp_path)
    assert [e.code for e in info.value.errors] == ["not-imported"]
    assert "'z'" in info.value.message and "import the file that declares it" in info.value.message


# -- the malformed suite ------------------------------------------------------------------------

MALFORMED = sorted((HERE / "malformed").iterdir())
EXPECT = re.compile(r"//\s*expect:\s*(\d+):(\d+)\s+(.*\S)")
_INTERNAL = ["Traceback", "$END", "_SEMI", "_RBRACE", "LBRACE", "__ANON", "Token(", "Unexpected", "CMPOP"]


def _expectation(entry: Path) -> tuple[Path, int, int, str]:
    files = [entry] if entry.is_file() else sorted(f for f in entry.rglob("*") if f.is_file())
    for f in files:
        m = EXPECT.match(f.read_text(encoding="utf-8").splitlines()[0])
        if m:
            return f, int(m[1]), int(m[2]), m[3]
    raise AssertionError(f"{entry.name}: no file starts with '// expect: LINE:COL message'")


def test_malformed_suite_is_large_enough():
    assert len(MALFORMED) >= 20
    assert sum(1 for p in MALFORMED if p.name.startswith("syn_")) >= 10
    assert sum(1 for p in MALFORMED if p.name.startswith("chk_")) >= 20


@pytest.mark.parametrize("entry", MALFORMED, ids=[p.name for p in MALFORMED])
def test_malformed(entry):
    file, line, col, fragment = _expectation(entry)
    try:
        load_spec(entry)
    except RoarError as e:
        err = e
    else:
        pytest.fail(f"{entry.name} loaded without an error")
    assert (Path(err.pos.file).name, err.pos.line, err.pos.col) == (file.name, line, col), err.format()
    assert fragment in err.message, err.format()
    if entry.name.startswith("syn_"):
        assert isinstance(err, SyntaxError_)
    if entry.name.startswith("chk_"):
        assert isinstance(err, SpecCheckError) and len(err.errors) == 1, err.format()
    assert not any(w in err.format() for w in _INTERNAL), err.format()


# -- robustness: any well-formed spec gets located CheckErrors, never a crash -------------------

try:  # the expression and statement strategies of the parser tests
    from .test_spec_parser import EXPRS, STMTS
except ImportError:  # pragma: no cover - tests run as top-level modules
    from test_spec_parser import EXPRS, STMTS

_BASE = parse_roar("""
p = ability {
  context = { { int goal; double x1; } { bool a = false; int pos = 0; } { string b = "s"; } }
  export = { { pt = struct { double x1; }; } { int end(int, int); bool init(); } { } }
}
loco = ability { context = { { int goal; } { bool a = false; } { int init = 0; } } }
""").agents


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(STMTS, max_size=4).map(tuple), st.lists(EXPRS, max_size=2).map(tuple), st.none() | EXPRS)
def test_checks_never_crash(body, conds, prefer):
    r = a.Recipe("r", pre=conds, prefer=prefer, body=body, end=body[-1:])
    p = _BASE[0]
    spec = a.Spec((a.Agent(p.name, p.controllable, p.readable, p.private, p.types, p.functions,
                           tasks=(a.Task("t", pre=conds, post=conds, recipes=(r,)),)), _BASE[1]))
    spec = parse_roar(format_spec(spec), "gen.roar")  # real positions
    for e in spec_errors(spec):
        assert isinstance(e, CheckError) and e.pos is not None and e.pos.file == "gen.roar"
        assert e.code and e.message


def test_setting_a_misspelt_variable_suggests_the_name(tmp_path):
    from roar_formal.errors import RoarError as _E
    from roar_formal.roar.spec import load_spec as _load
    src = (ROOT / "models" / "faulty" / "survey.roar").read_text(encoding="utf-8").replace(
        "set done true;", "set dnoe true;", 1)
    path = tmp_path / "survey.roar"
    path.write_text(src, encoding="utf-8")
    with pytest.raises(_E) as err:
        _load(path)
    assert "unknown variable 'dnoe' in agent 'mission'; did you mean 'done'?" in err.value.format()


NEWTYPE = """
base = ability {
  context = { { meters goal; } { bool arrived = false; } { } }
  export = { { meters = newtype double; } { } { } }
  tasks = { go = task { post = { {arrived == true} } recipes = { r = recipe { body = { set arrived true; } } } } }
}
"""


@pytest.mark.parametrize("where, ok", [("3.0", True), ("-2.5", True), ("3", False), ("base::arrived", False)])
def test_a_request_gives_a_newtype_variable_a_literal_of_its_representation(where, ok):
    """There is no other way to write a newtype's value in a request: a literal of the
    representation (a double for meters) is accepted; another type still is not."""
    spec = parse_roar(NEWTYPE, "n.roar")
    check_spec(spec)
    errs = request_errors(spec, parse_constraint(f"base::arrived == true where base::goal == {where}", "<request>"))
    assert (errs == []) == ok, [e.message for e in errs]
    if not ok and where == "3":
        assert "sets base::meters to int" in errs[0].message
