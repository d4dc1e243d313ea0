"""Tests for the ROAR spec parser and loader (roar_formal.roar.parser), the AST helpers and the printer."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roar_formal.errors import RoarError, SyntaxError_
from roar_formal.roar import ast as a
from roar_formal.roar.parser import hyper_compat_warnings, parse_constraint, parse_expr, parse_recipes, parse_roar, parse_task
from roar_formal.roar.spec import load_spec
from roar_formal.roar.pretty import format_constraint, format_expr, format_spec, format_stmt, hyper_files

from repo import ROOT
MODELS = ROOT / "models"
DATA = Path(__file__).parent / "data"
ROAR_MODELS = ["spa_loop.roar", "mana_nav.roar", "conflict.roar"]


def full(e: a.Expr) -> str:
    """Fully parenthesised rendering, to read off how an expression was grouped."""
    if isinstance(e, a.Binary):
        return f"({full(e.left)} {e.op} {full(e.right)})"
    if isinstance(e, a.Unary):
        return f"({e.op}{full(e.operand)})"
    if isinstance(e, a.Field):
        return f"{full(e.base)}.{e.name}"
    if isinstance(e, a.Call):
        return f"{e.qualified}({', '.join(full(x) for x in e.args)})"
    if isinstance(e, a.LastError):
        return f"last_error?({full(e.constraint)})"
    return format_expr(e)


def recipe_of(body: str, extra: str = "") -> a.Recipe:
    spec = parse_roar("a = ability { tasks = { t = task { recipes = { r = recipe { "
                      + extra + " body = { " + body + " } } } } } }")
    return spec.agents[0].tasks[0].recipes[0]


# -- expressions ---------------------------------------------------------------

PRECEDENCE = [
    ("a || b && c", "(a || (b && c))"),
    ("a && b || c", "((a && b) || c)"),
    ("a < b && c < d", "((a < b) && (c < d))"),
    ("a == b || c != d", "((a == b) || (c != d))"),
    ("a + b * c", "(a + (b * c))"),
    ("a - b - c", "((a - b) - c)"),
    ("a / b * c", "((a / b) * c)"),
    ("a + b < c * d", "((a + b) < (c * d))"),
    ("!a == b", "((!a) == b)"),
    ("!(a == b)", "(!(a == b))"),
    ("-x * y", "((-x) * y)"),
    ("- -x", "(-(-x))"),
    ("p.x + q.y", "(p.x + q.y)"),
    ("f(x).y.z", "f(x).y.z"),
    ("planner::ready == true", "(planner::ready == true)"),
    ("planner::distance(a, b) <= 1.5", "(planner::distance(a, b) <= 1.5)"),
    ("last_error?(m::ready == true) && x", "(last_error?((m::ready == true)) && x)"),
    ("f()", "f()"),
    ("a >= b", "(a >= b)"),
    ("a && b && c", "((a && b) && c)"),
]


@pytest.mark.parametrize("text,expected", PRECEDENCE)
def test_precedence(text, expected):
    assert full(parse_expr(text)) == expected


def test_literals():
    assert parse_expr("42") == a.IntLit(42)
    assert parse_expr("1.0") == a.DoubleLit(1.0)
    assert parse_expr("2.5e3") == a.DoubleLit(2500.0)
    assert parse_expr("true") == a.BoolLit(True)
    assert parse_expr("false") == a.BoolLit(False)
    assert parse_expr(r'"a \"b\" \\ c\n"') == a.StringLit('a "b" \\ c\n')
    assert parse_expr("-3") == a.Unary("-", a.IntLit(3))


def test_positions_are_recorded_and_not_compared():
    e = parse_expr("x +\n  foo::bar", file="f.roar")
    assert e.pos == a.Pos("f.roar", 1, 1)
    assert e.op_pos == a.Pos("f.roar", 1, 3)
    assert e.right.pos == a.Pos("f.roar", 2, 3)
    assert e == parse_expr("x + foo::bar", file="other")
    assert parse_expr("(a)", file="f").parens and parse_expr("(a)", file="f").pos.col == 1


def test_comments():
    e = parse_expr("a /* block\n comment */ + // line\n b")
    assert full(e) == "(a + b)"


def test_keywords_are_contextual():
    # `init`, `end`, `pre`, `task` are plain names where no keyword can stand
    spec = parse_roar("a = ability { context = { { } { } { bool init = false; int end = 1; int pre; } } }")
    assert [v.name for v in spec.agents[0].private] == ["init", "end", "pre"]
    assert parse_expr("task + recipe") == a.Binary("+", a.Name("task"), a.Name("recipe"))


# -- constraints and statements ----------------------------------------------------

def test_constraint_with_where():
    c = parse_constraint("demo_loco::pos == demo_loco::goal where demo_loco::goal == 5")
    assert c.expr == a.Binary("==", a.Remote("demo_loco", "pos"), a.Remote("demo_loco", "goal"))
    assert c.where == (a.WherePair(a.Remote("demo_loco", "goal"), a.IntLit(5)),)
    assert c.target() == "demo_loco"
    assert c.writes() == {"goal": a.IntLit(5)}


def test_where_pairs_split_on_and():
    c = parse_constraint("p::ok == true where p::x == 1 && 2.0 == p::y && (p::z == q)")
    assert [(format_expr(w.left), format_expr(w.right)) for w in c.where] == [
        ("p::x", "1"), ("2.0", "p::y"), ("p::z", "q")]
    assert c.writes() == {"x": a.IntLit(1), "y": a.DoubleLit(2.0), "z": a.Name("q")}


def test_every_statement():
    r = recipe_of("""
        let start now();
        ensure(localization::localized == true);
        make(planner::ready == true where planner::target == goal);
        let h ensure(control::tracking == true, 100);
        wait(pos == goal, 50);
        wait(ready);
        assert(ok, 10);
        assert(ok);
        abort h;
        set simu_pos pos;
        set me::x 1;
        log("done");
    """, extra="pre = { {distance(pos, goal) < 10.0} } post = { } prefer = 2")
    kinds = [type(s).__name__ for s in r.body]
    assert kinds == ["Let", "Ensure", "Make", "Ensure", "Wait", "Wait", "Assert", "Assert", "Abort",
                     "Set", "Set", "ExprStmt"]
    b = r.body
    assert b[0] == a.Let("start", a.Call("now"))
    assert b[1] == a.Ensure(a.Constraint(parse_expr("localization::localized == true")))
    assert b[2].constraint.where == (a.WherePair(a.Remote("planner", "target"), a.Name("goal")),)
    assert b[3].handle == "h" and b[3].period == a.IntLit(100)
    assert (b[3].pos.line, b[3].pos.col) == (5, 9)  # a bound ensure is located at its `let`
    assert b[4] == a.Wait(parse_expr("pos == goal"), a.IntLit(50))
    assert b[5].period is None
    assert b[8] == a.Abort("h")
    assert b[9] == a.Set(a.Name("simu_pos"), a.Name("pos"))
    assert b[10] == a.Set(a.Remote("me", "x"), a.IntLit(1))
    assert b[11] == a.ExprStmt(a.Call("log", (a.StringLit("done"),)))
    assert r.pre == (parse_expr("distance(pos, goal) < 10.0"),) and r.post == ()
    assert r.prefer == a.IntLit(2) and r.preference() == 2


def test_recipe_end_block_and_field_order():
    spec = parse_roar("""a = ability { tasks = { t = task { post = { {x} } pre = { {y} {z} }
        recipes = { r = recipe { end = { set moving false; } body = { } pre = { {last_error?(b::ok == true)} } } } } } }""")
    t = spec.agents[0].tasks[0]
    assert t.pre == (a.Name("y"), a.Name("z")) and t.post == (a.Name("x"),)
    r = t.recipes[0]
    assert r.end == (a.Set(a.Name("moving"), a.BoolLit(False)),)
    assert r.pre == (a.LastError(parse_expr("b::ok == true")),)


# -- agents ------------------------------------------------------------------------

AGENT = """
import "other.roar"
// an agent with everything
geo = ability {
  context = {
    { point target; int speed = 2; }
    { int pos = get_pos(); double d = distance(target, target); }
    { bool init = false; }
  }
  export = {
    { point = struct { double x; double y; }; meters = newtype double; handle = opaquetype; }
    { double distance(point a, point); int get_count(); }
    { symmetry = distance(A, B) == X |- distance(B, A) == X;
      axiom = |- distance(A, A) == 0.0;
      two = P == Q, Q == R |- P == R, R == P; }
  }
  tasks = {
    get_pos = task { recipes = { r = recipe { body = { set pos 1; } } } }
  }
}
"""


def test_agent_declarations():
    spec = parse_roar(AGENT, "geo.roar")
    ag = spec.agents[0]
    assert ag.name == "geo" and ag.imports == (a.Import("other.roar"),)
    assert [(v.name, v.access) for v in ag.vars] == [
        ("target", "controllable"), ("speed", "controllable"), ("pos", "readable"), ("d", "readable"),
        ("init", "private")]
    assert ag.var("speed").init == a.IntLit(2) and ag.var("target").type == a.TypeRef("point")
    assert ag.types == (
        a.StructType("point", (a.StructField("x", a.TypeRef("double")), a.StructField("y", a.TypeRef("double")))),
        a.NewType("meters", a.TypeRef("double")), a.OpaqueType("handle"))
    assert ag.functions[0] == a.Function("distance", a.TypeRef("double"),
                                         (a.Param(a.TypeRef("point"), "a"), a.Param(a.TypeRef("point"))))
    assert ag.functions[1].params == ()
    assert [r.name for r in ag.rules] == ["symmetry", "axiom", "two"]
    assert ag.rules[1].premises == () and len(ag.rules[2].premises) == 2 and len(ag.rules[2].conclusions) == 2
    assert ag.reading_task("pos") == "get_pos" and ag.reading_task("d") is None
    assert ag.task_initialised() == {"pos": "get_pos"}


def test_empty_context_and_export():
    ag = parse_roar("a = ability { context = { } export = { } }").agents[0]
    assert ag.vars == () and ag.functions == ()
    assert parse_roar("a = ability { }").agents[0] == a.Agent("a")


def test_qualified_types():
    ag = parse_roar("a = ability { context = { { planner::point p; } { } { } } }").agents[0]
    assert ag.controllable[0].type == a.TypeRef("point", "planner")
    assert str(ag.controllable[0].type) == "planner::point"


def test_task_and_recipe_files():
    t = parse_task("task { pre = { {a} } post = { {b} } }", name="move")
    assert t == a.Task("move", (a.Name("a"),), (a.Name("b"),))
    assert parse_task("go = task { }", name="file_stem").name == "go"
    rs = parse_recipes("x = recipe { } y = recipe { prefer = 1 }")
    assert [r.name for r in rs] == ["x", "y"]
    assert parse_recipes("recipe { body = { wait(a); } }", name="stem")[0].name == "stem"


# -- the two layouts ------------------------------------------------------------------

def test_both_layouts_give_equal_asts():
    hyper = load_spec(MODELS / "demo_loco")
    single = load_spec(DATA / "demo_loco.roar")
    assert hyper == single
    assert hyper.agents[0].layout == "hyper" and single.agents[0].layout == "roar"
    # positions differ (different files), equality ignores them
    assert hyper.agents[0].pos.file != single.agents[0].pos.file
    # and the .ability file alone loads the same agent
    assert load_spec(MODELS / "demo_loco" / "demo_loco.ability") == hyper


def test_demo_loco_shape():
    ag = load_spec(MODELS / "demo_loco").agent("demo_loco")
    assert [v.name for v in ag.controllable] == ["goal"]
    assert [v.name for v in ag.readable] == ["pos"]
    assert [v.name for v in ag.private] == ["init", "simu_pos"]
    assert [t.name for t in ag.tasks] == ["get_pos", "init", "move"]
    move = ag.task("move")
    assert move.pre == (parse_expr("init == true"),) and move.post == (parse_expr("goal == pos"),)
    assert move.post_vars() == {"goal", "pos"}
    assert ag.task_initialised() == {"pos": "get_pos"}
    assert ag.task("move").recipes[0].pos.file.endswith("direct.recipe")


@pytest.mark.parametrize("model", ROAR_MODELS)
def test_hyper_files_round_trip(model, tmp_path):
    """Write every agent of a .roar model in hyper's layout, load the folder, get the same agents."""
    spec = load_spec(MODELS / model)
    names = [ag.name for ag in spec.agents]
    for ag in spec.agents:
        imports = tuple(a.Import(f"{o}.ability") for o in names if o != ag.name)
        for rel, text in hyper_files(dataclasses.replace(ag, imports=imports)).items():
            (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp_path / rel).write_text(text)
    back = load_spec(tmp_path)  # checks pass: every agent imports the others
    for ag in spec.agents:
        got = back.agent(ag.name)
        assert got.layout == "hyper"
        assert set(got.imported()) == set(names) - {ag.name}
        want = dataclasses.replace(ag, tasks=tuple(sorted(ag.tasks, key=lambda t: t.name)))
        assert dataclasses.replace(got, imports=()) == want


@pytest.mark.parametrize("model", ROAR_MODELS + ["demo_loco"])
def test_format_spec_round_trip(model):
    spec = load_spec(MODELS / model)
    text = format_spec(spec)
    assert parse_roar(text) == spec
    assert format_spec(parse_roar(text)) == text


# -- loading -------------------------------------------------------------------------

def write(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


def test_hyper_imports_and_cycles(tmp_path):
    write(tmp_path, {
        "a.ability": 'import "b.ability"\na = ability { context = { { } { int x = 0; } { } } }',
        "b.ability": 'import "a.ability"\nb = ability { context = { { } { int y = 0; } { } } }',
        "a/t.task": "task { post = { {b::y == x} } }",
        "a/t/r.recipe": "recipe { body = { set x b::y; } }",
    })
    spec = load_spec(tmp_path / "a.ability")
    assert [ag.name for ag in spec.agents] == ["a", "b"]
    assert spec.agent("a").imports == (a.Import("b.ability", ("b",)),)
    assert spec.agent("b").imported() == {"a"}
    t = spec.agent("a").task("t")
    assert t.name == "t" and t.recipes[0].name == "r"
    assert spec.visible("a") == {"a", "b"}
    # the folder loads both files once
    assert load_spec(tmp_path) == spec


def test_roar_imports(tmp_path):
    write(tmp_path, {
        "main.roar": 'import "lib.roar"\nm = ability { context = { { } { int v = lib::w; } { } } }',
        "lib.roar": "lib = ability { context = { { } { int w = 1; } { } } }",
    })
    spec = load_spec(tmp_path / "main.roar")
    assert [ag.name for ag in spec.agents] == ["m", "lib"]
    assert spec.agent("m").imports == (a.Import("lib.roar", ("lib",)),)


def test_folder_of_roar_files(tmp_path):
    write(tmp_path, {"x.roar": "x = ability { }", "y.roar": "y = ability { }", "notes.txt": "hello"})
    assert [ag.name for ag in load_spec(tmp_path).agents] == ["x", "y"]


def test_recipes_of_several_files_in_file_name_order(tmp_path):
    write(tmp_path, {
        "r.ability": "r = ability { context = { { } { } { int x; } } }",
        "r/t.task": "t = task { }",
        "r/t/b.recipe": "second = recipe { body = { set x 2; } } third = recipe { body = { set x 3; } }",
        "r/t/a.recipe": "recipe { body = { set x 1; } }",
        "r/t/.hidden": "garbage",
        "r/t/a.recipe~": "garbage",
    })
    t = load_spec(tmp_path / "r.ability").agent("r").task("t")
    assert [r.name for r in t.recipes] == ["a", "second", "third"]


def test_ability_name_differs_from_file(tmp_path):
    write(tmp_path, {"file.ability": "agent = ability { }"})
    spec = load_spec(tmp_path / "file.ability")
    assert spec.agents[0].name == "agent"
    assert any("hyper expects the file to be named agent.ability" in w.message for w in spec.warnings)


LOAD_ERRORS = [
    ({}, "missing.roar", "cannot read", None),
    ({"x.txt": "x"}, ".", "holds no .ability or .roar file", None),
    ({"x.spec": "x"}, "x.spec", "a spec file ends in .ability", None),
    ({"a.ability": 'import "zz.ability"\na = ability { }'}, "a.ability", 'cannot import "zz.ability"', (1, 1)),
    ({"a.ability": "a = ability { }", "a/t.task": "task { }", "a/u/r.recipe": "recipe { }"}, "a.ability",
     "recipe folder", (1, 1)),
    ({"a.ability": ""}, "a.ability", "holds exactly one agent", (1, 1)),
    ({"a.ability": "a = ability { }", "a/t.task": "task { pre = { {x} }"}, "a.ability",
     "unexpected end of file", (1, 21)),
]


@pytest.mark.parametrize("files,path,fragment,where", LOAD_ERRORS)
def test_load_errors(tmp_path, files, path, fragment, where):
    write(tmp_path, files)
    with pytest.raises(RoarError) as info:
        load_spec(tmp_path / path)
    assert fragment in info.value.message, info.value.format()
    if where is not None:
        assert (info.value.pos.line, info.value.pos.col) == where, info.value.format()
    if fragment == "unexpected end of file":
        assert info.value.pos.file.endswith("t.task")


def test_bad_utf8(tmp_path):
    (tmp_path / "x.roar").write_bytes(b"a = ability { } \xff")
    with pytest.raises(RoarError, match="not valid UTF-8"):
        load_spec(tmp_path / "x.roar")


# -- AST helpers ---------------------------------------------------------------------

def test_constraint_domain_and_sequential_pairs():
    r = recipe_of("""
        make(mapper::map_ready == true);
        let v 1;
        make(planner::ok == true where planner::target == v);
        ensure(perception::on == true);
        make(done == true);
        wait(x);
    """)
    assert r.constraint_domain() == {"mapper", "planner", "perception"}
    assert r.constraint_domain("me") == {"mapper", "planner", "perception", "me"}
    pairs = r.sequential_pairs()
    assert [(format_stmt(x), format_stmt(y)) for x, y in pairs] == [
        ("make(mapper::map_ready == true)", "make(planner::ok == true where planner::target == v)"),
        ("make(planner::ok == true where planner::target == v)", "make(done == true)"),
    ]
    assert r.sequential_pairs(strict=True) == []
    r2 = recipe_of("make(a::x == 1); make(b::y == 2); make(c::z == 3);")
    assert len(r2.sequential_pairs(strict=True)) == 2


def test_domain_counts_reads():
    r = recipe_of("wait(sensor::fresh == true); set x planner::f(1);", extra="pre = { {last_error?(m::ok == true)} }")
    assert r.domain("me") == {"sensor", "planner", "m"}
    assert r.constraint_domain("me") == frozenset()


def test_post_vars_and_handles():
    t = parse_roar("a = ability { tasks = { t = task { post = { {x == a::y} {b::z < w} } } } }").agents[0].tasks[0]
    assert t.post_vars("a") == {"x", "y", "b::z", "w"}
    assert t.post_vars() == {"x", "a::y", "b::z", "w"}
    r = recipe_of("let h ensure(p::q == 1); let k 2; ensure(p::r == 3);")
    assert set(r.handles()) == {"h"}


def test_walk_and_conjuncts():
    e = parse_expr("a && (b && c) && f(d)")
    assert [format_expr(x) for x in a.conjuncts(e)] == ["a", "b", "c", "f(d)"]
    assert {n.name for n in a.walk(e) if isinstance(n, a.Name)} == {"a", "b", "c", "d"}


# -- hyper compatibility ----------------------------------------------------------------

COMPAT = [
    ("a < b && c < d", "(a < (b && c)) < d"),
    ("x == 1 || y", "x == (1 || y)"),
    ("ok && n > 3", "(ok && n) > 3"),
    ("a == b && c", "a == (b && c)"),
    ("p < q + r || s", "p < ((q + r) || s)"),
]


@pytest.mark.parametrize("text,hyper_reading", COMPAT)
def test_hyper_compat_warns(text, hyper_reading):
    ws = hyper_compat_warnings(parse_expr(text, file="f"))
    assert len(ws) == 1
    assert f"hyper reads this as '{hyper_reading}'" in ws[0].message
    assert ws[0].pos == a.Pos("f", 1, 1)


@pytest.mark.parametrize("text", [
    "(a < b) && (c < d)", "a && b || c", "a + b * c < d", "a < b", "!(a == b)", "f(x) == g(y)",
    "(a == b) || c",
])
def test_hyper_compat_silent(text):
    assert hyper_compat_warnings(parse_expr(text)) == []


def test_hyper_compat_nested_and_located():
    ws = hyper_compat_warnings(parse_expr("f(1, a < b && c) || (x == y && z)", file="f"))
    assert [(w.pos.line, w.pos.col) for w in ws] == [(1, 6), (1, 21)]


def test_hyper_compat_in_specs():
    text = """a = ability { context = { { } { bool ok = n > 1 && m; } { int n = 0; int m = 0; } }
      tasks = { t = task { pre = { {n < 3 && m < 3} }
        recipes = { r = recipe { body = { make(b::ok == true where b::x == 1 && b::y == 2); wait((n < 1) && (m < 1)); } } } } } }"""
    spec = parse_roar(text, "s.roar", hyper_compat=True)
    assert [(w.pos.line, w.pos.col) for w in spec.warnings] == [(1, 43), (2, 37)]
    assert all(w.format().startswith("s.roar:") and "warning:" in w.format() for w in spec.warnings)
    assert parse_roar(text, "s.roar").warnings == ()
    # where clauses are pair lists in both grammars: no warning for `b::x == 1 && b::y == 2`


def test_load_spec_hyper_compat(tmp_path):
    write(tmp_path, {"a.ability": "a = ability { context = { { } { bool ok = x < 1 || x > 9; } { int x = 0; } } }"})
    spec = load_spec(tmp_path / "a.ability", hyper_compat=True, check=False)
    assert len(spec.warnings) == 1 and spec.warnings[0].pos.line == 1
    assert load_spec(tmp_path / "a.ability", check=False).warnings == ()


def test_models_are_hyper_clean():
    for m in ROAR_MODELS + ["demo_loco"]:
        assert load_spec(MODELS / m, hyper_compat=True).warnings == (), m


# -- printer round trip (hypothesis) ------------------------------------------------------

NAMES = st.sampled_from(["a", "b", "goal", "pos", "x1", "init", "end"])
AGENTS = st.sampled_from(["p", "planner", "loco"])
ATOMS = st.one_of(
    st.integers(min_value=0, max_value=10**6).map(a.IntLit),
    st.floats(min_value=0, max_value=1e9, allow_nan=False, allow_infinity=False).map(a.DoubleLit),
    st.text(alphabet='ab "\\\n\tz', max_size=5).map(a.StringLit),
    st.booleans().map(a.BoolLit),
    NAMES.map(a.Name),
    st.builds(a.Remote, AGENTS, NAMES),
)
OPS = st.sampled_from(list(a.LOGIC_OPS + a.COMPARISONS + a.ARITH_OPS))


def _extend(children):
    return st.one_of(
        st.builds(a.Binary, OPS, children, children),
        st.builds(a.Unary, st.sampled_from(["!", "-"]), children),
        st.builds(a.Field, children, NAMES),
        st.builds(a.Call, NAMES, st.lists(children, max_size=3).map(tuple), st.none() | AGENTS),
        st.builds(a.LastError, children),
    )


EXPRS = st.recursive(ATOMS, _extend, max_leaves=12)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(EXPRS)
def test_expression_round_trip(e):
    text = format_expr(e)
    assert parse_expr(text) == e, text


def _as_read(e: a.Expr) -> a.Expr:
    """A constraint's predicate as the language reads it (docs/spec-language.md): a boolean
    variable alone is ``x == true``, ``!x`` is ``x == false``; anything else as written."""
    if isinstance(e, a.Unary) and e.op == "!" and isinstance(e.operand, (a.Name, a.Remote)):
        return a.Binary("==", e.operand, a.BoolLit(False))
    if isinstance(e, (a.Name, a.Remote)):
        return a.Binary("==", e, a.BoolLit(True))
    return e


PREDICATES = EXPRS.map(_as_read)


@pytest.mark.parametrize("text, read", [("a", "a == true"), ("!a", "a == false"), ("b::x", "b::x == true"),
                                        ("!b::x", "b::x == false")])
def test_a_variable_alone_is_read_as_a_comparison_and_printed_as_written(text, read):
    c = parse_constraint(text)
    assert c.expr == parse_constraint(read).expr   # the same constraint as the comparison
    assert c.expr.implied and not parse_constraint(read).expr.implied
    assert format_constraint(c) == text            # messages and printed specs say what was written
    assert format_constraint(parse_constraint(read)) == read

STMTS = st.one_of(
    st.builds(a.Let, NAMES, EXPRS),
    st.builds(a.Set, NAMES.map(a.Name) | st.builds(a.Remote, AGENTS, NAMES), EXPRS),
    st.builds(a.Make, st.builds(a.Constraint, PREDICATES)),
    st.builds(a.Ensure, st.builds(a.Constraint, PREDICATES, st.lists(st.builds(a.WherePair, EXPRS, EXPRS),
                                                                  max_size=2).map(tuple)),
              st.none() | EXPRS, st.none() | NAMES),
    st.builds(a.Wait, EXPRS, st.none() | EXPRS),
    st.builds(a.Assert, EXPRS, st.none() | EXPRS),
    st.builds(a.Abort, NAMES),
    st.builds(a.ExprStmt, EXPRS),
)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(STMTS, max_size=5).map(tuple), st.lists(EXPRS, max_size=2).map(tuple), st.none() | EXPRS)
def test_recipe_round_trip(body, pre, prefer):
    r = a.Recipe("r", pre=pre, prefer=prefer, body=body, end=body[:1])
    spec = a.Spec((a.Agent("ag", tasks=(a.Task("t", pre=pre, recipes=(r,)),)),))
    assert parse_roar(format_spec(spec)) == spec


# -- robustness: only located SyntaxErrors, never a lark exception ----------------------------

_TOKENS = ["a", "b", "x", " ", "\n", "=", "==", "{", "}", "(", ")", ";", ",", "::", "ability", "task", "recipe",
           "context", "export", "tasks", "recipes", "pre", "post", "body", "end", "prefer", "let", "set",
           "make", "ensure", "wait", "assert", "abort", "where", "&&", "||", "<", "!", "-", "+", ".", "1",
           "1.5", '"s"', '"', "|-", "last_error?", "/*", "*/", "//", "import", "?", "&", "|", ":", "$", "struct"]
_INTERNAL = ["$END", "_SEMI", "_RBRACE", "_EQ", "LBRACE", "LPAR", "__ANON", "Token(", "Unexpected", "CMPOP"]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(_TOKENS), max_size=30).map(" ".join))
def test_garbage_only_raises_syntax_errors(text):
    for parse in (parse_roar, parse_expr, parse_constraint, parse_task, parse_recipes):
        try:
            parse(text)
        except SyntaxError_ as e:
            assert e.pos is not None and e.pos.line >= 1 and e.pos.col >= 1
            assert not any(w in e.message for w in _INTERNAL), e.message


def test_garbage_wrapped_in_an_agent():
    texts = ["a = ability { tasks = { t = task { recipes = { r = recipe { body = { " + t + " } } } } } }"
             for t in ["let", "set x", "make()", "ensure(a,)", "wait(,1)", "abort 1", "let h ensure(a) 3",
                       "x::", "f(1 2)", "(a", "a)", "a b", "last_error?", "!", "1 2"]]
    for text in texts:
        with pytest.raises(SyntaxError_) as info:
            parse_roar(text)
        assert re.match(r"unexpected|'", info.value.message), info.value.message


def test_a_number_too_long_to_read_is_a_located_error(tmp_path):
    """Found by fuzzing: a 5,000-digit literal crashed the int conversion."""
    from roar_formal.roar.parser import parse_roar
    src = (ROOT / "models" / "faulty" / "ordered_pick.roar").read_text()
    i = src.index("set done true")
    bad = src[:i] + "set done " + "9" * 5000 + src[i + len("set done true"):]
    line = src[:i].count("\n") + 1
    with pytest.raises(SyntaxError_) as info:
        parse_roar(bad, "p.roar")
    assert info.value.pos.line == line and "a number of 5,000 characters" in info.value.message
