"""Tests for the Celf parser (roar_formal.clf.parser) and the surface printer."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roar_formal.clf import surface as s
from roar_formal.clf.parser import parse_expr, parse_file, parse_program
from roar_formal.clf.pretty_surface import format_expr, format_program
from roar_formal.errors import Pos, RoarError, SyntaxError_

P = Pos("<test>", 0, 0)  # positions are not compared, any will do


# -- tree builders (positions excluded from equality) ------------------------

def I(name):
    return s.Id(P, name)


def app(fn, *args):
    """``app(f, a, ('!', b))``: left-nested application, optionally marked."""
    for a in args:
        mark, a = a if isinstance(a, tuple) else (None, a)
        fn = s.App(P, fn, a, mark)
    return fn


def arr(op, left, right, rev=False):
    return s.Arrow(P, op, left, right, rev)


def lolli(a, b):
    return arr("-o", a, b)


def ten(a, b):
    return s.Tensor(P, a, b)


def wth(a, b):
    return s.With(P, a, b)


def pi(x, body, ty=None):
    return s.Pi(P, x, ty, body)


def ex(x, body, ty=None):
    return s.Exists(P, x, ty, body)


def lam(x, body, mode="linear", ty=None):
    return s.Lam(P, x, body, mode, ty)


def bang(a):
    return s.Bang(P, a)


def aff(a):
    return s.Affine(P, a)


def monad(a):
    return s.Monad(P, a)


A, B, C, D = I("A"), I("B"), I("C"), I("D")


# -- precedence and associativity ------------------------------------------

PRECEDENCE = [
    # arrows
    ("A -o B -o C", lolli(A, lolli(B, C))),
    ("A -> B -@ C", arr("->", A, arr("-@", B, C))),
    ("C o- A", arr("-o", A, C, rev=True)),
    ("C o- A o- B", arr("-o", B, arr("-o", A, C, rev=True), rev=True)),
    ("C <- A @- B", arr("-@", B, arr("->", A, C, rev=True), rev=True)),
    ("C o- A -o B", arr("-o", lolli(A, B), C, rev=True)),
    ("A -o B o- C", arr("-o", C, lolli(A, B), rev=True)),
    # * and &: one level, right associative, tighter than arrows
    ("A * B * C", ten(A, ten(B, C))),
    ("A * B & C", ten(A, wth(B, C))),
    ("A & B * C", wth(A, ten(B, C))),
    ("A * B -o C", lolli(ten(A, B), C)),
    ("A -o B & C", lolli(A, wth(B, C))),
    ("(A * B) * C", ten(ten(A, B), C)),
    # application and prefixes
    ("f x y", app(I("f"), I("x"), I("y"))),
    ("f (x y)", app(I("f"), app(I("x"), I("y")))),
    ("f !x y", app(I("f"), ("!", I("x")), I("y"))),
    ("f @x", app(I("f"), ("@", I("x")))),
    ("!foo x", bang(app(I("foo"), I("x")))),
    ("@foo x", aff(app(I("foo"), I("x")))),
    ("!!A", bang(bang(A))),
    ("!@A", bang(aff(A))),
    ("!A * @B", ten(bang(A), aff(B))),
    ("f (!x)", app(I("f"), bang(I("x")))),
    ("a b * c d -o e", lolli(ten(app(I("a"), I("b")), app(I("c"), I("d"))), I("e"))),
    # projections bind tighter than application
    ("f x #1", app(I("f"), s.Proj(P, I("x"), 1))),
    ("(f x) #2", s.Proj(P, app(I("f"), I("x")), 2)),
    ("M #1 #2", s.Proj(P, s.Proj(P, I("M"), 1), 2)),
    ("f !x #1", app(I("f"), ("!", s.Proj(P, I("x"), 1)))),
    # binders extend as far right as possible
    ("Pi x. A -o B", pi("x", lolli(A, B))),
    ("Pi x:A. B x", pi("x", app(B, I("x")), A)),
    ("Exists x. A * B", ex("x", ten(A, B))),
    ("Exists x:nat. A", ex("x", A, I("nat"))),
    ("\\x. f x", lam("x", app(I("f"), I("x")))),
    ("\\@x. x", lam("x", I("x"), "affine")),
    ("\\!x. x", lam("x", I("x"), "persistent")),
    ("\\x:A. x", lam("x", I("x"), ty=A)),
    ("Pi x. Pi y. A", pi("x", pi("y", A))),
    ("Pi x:Pi y. A. B", pi("x", B, pi("y", A))),
    # a binder may end an application or be a right operand, unparenthesised
    ("llet E \\x. F x", app(I("llet"), I("E"), lam("x", app(I("F"), I("x"))))),
    ("llet E (\\x. F x)", app(I("llet"), I("E"), lam("x", app(I("F"), I("x"))))),
    ("f !\\x. x", app(I("f"), ("!", lam("x", I("x"))))),
    ("A -o Pi x. B -o C", lolli(A, pi("x", lolli(B, C)))),
    ("A * Exists x. B * C", ten(A, ex("x", ten(B, C)))),
    ("C o- Pi x. B o- A", arr("-o", pi("x", arr("-o", A, B, rev=True)), C, rev=True)),
    ("!Pi x. A", bang(pi("x", A))),
    ("(Pi x. A) -o B", lolli(pi("x", A), B)),
    ("(\\x. x) y", app(lam("x", I("x")), I("y"))),
    # atoms
    ("type", s.TypeKw(P)),
    ("1", s.One(P)),
    ("_", s.Underscore(P)),
    ("T", I("T")),
    ("{A}", monad(A)),
    ("(M : A -o B)", s.Annot(P, I("M"), lolli(A, B))),
    ("< M, N >", s.Pair(P, I("M"), I("N"))),
    ("< M, N > #1", s.Proj(P, s.Pair(P, I("M"), I("N")), 1)),
    ("f < a, b >", app(I("f"), s.Pair(P, I("a"), I("b")))),
    ("< \\x. x, Pi y. A >", s.Pair(P, lam("x", I("x")), pi("y", A))),
    ("x' _y a_1'", app(I("x'"), I("_y"), I("a_1'"))),
    ("o o- o", arr("-o", I("o"), I("o"), rev=True)),
    ("types Pis", app(I("types"), I("Pis"))),
]


@pytest.mark.parametrize("text,tree", PRECEDENCE, ids=[t for t, _ in PRECEDENCE])
def test_precedence(text, tree):
    assert parse_expr(text) == tree


# -- positions ---------------------------------------------------------------

def _at(node):
    return (node.pos.line, node.pos.col)


def test_positions_are_first_tokens():
    e = parse_expr("f x -o\n  {Exists y. !g y}", file="f.clf")
    assert e.pos == Pos("f.clf", 1, 1)
    assert isinstance(e, s.Arrow) and _at(e.left) == (1, 1) and _at(e.left.arg) == (1, 3)
    m = e.right
    assert _at(m) == (2, 3) and _at(m.body) == (2, 4)
    assert _at(m.body.body) == (2, 14) and _at(m.body.body.body) == (2, 15)


def test_positions_reversed_arrow_and_parens():
    e = parse_expr("(a b) c o- d")
    assert _at(e) == (1, 1)                    # the reversed arrow: its conclusion's first token
    assert _at(e.right) == (1, 1)              # (a b) c starts at '('
    assert _at(e.right.fn) == (1, 1)           # (a b) too
    assert _at(e.right.fn.fn) == (1, 2)        # a
    assert _at(e.left) == (1, 12)


def test_positions_of_items():
    prog = parse_program("% c\n  nat : type.\n#query * 1 * 1 nat.\n #exec 3 a.\n#mode p + -.")
    assert [_at(i) for i in prog.items] == [(2, 3), (3, 1), (4, 2), (5, 1)]
    assert all(i.pos.file == "<input>" for i in prog.items)


def test_positions_block_comment_and_tabs():
    prog = parse_program("%{ one\ntwo }% a\t: b.")
    d = prog.items[0]
    assert _at(d) == (2, 8) and _at(d.classifier) == (2, 12)


# -- items and directives ----------------------------------------------------

def test_declarations():
    prog = parse_program("nat : type.\nz : nat.\nev : exp -> dest -> type.\n"
                         "c : A = M.\nt : type = A -o B.", file="x.clf")
    assert prog.file == "x.clf"
    assert prog.items == (
        s.Decl(P, "nat", s.TypeKw(P)),
        s.Decl(P, "z", I("nat")),
        s.Decl(P, "ev", arr("->", I("exp"), arr("->", I("dest"), s.TypeKw(P)))),
        s.Decl(P, "c", A, I("M")),
        s.Decl(P, "t", s.TypeKw(P), lolli(A, B)),
    )


def test_directives():
    prog = parse_program("#query * 1 * 1 Pi d. p d.\n#query 10 0 * 2 p.\n"
                         "#exec * {a}.\n#exec 12 a * b.\n#trace 0 1.\n#trace * a.\n"
                         "#mode plus + + -.\n#mode q *.")
    assert prog.items == (
        s.Query(P, "*", 1, "*", 1, pi("d", app(I("p"), I("d")))),
        s.Query(P, 10, 0, "*", 2, I("p")),
        s.Exec(P, "*", monad(I("a"))),
        s.Exec(P, 12, ten(I("a"), I("b"))),
        s.Exec(P, 0, s.One(P), trace=True),
        s.Exec(P, "*", I("a"), trace=True),
        s.Mode(P, "plus", ("+", "+", "-")),
        s.Mode(P, "q", ("*",)),
    )


def test_query_goal_may_start_with_one():
    # the fifth slot is the goal: `1` there is the unit type, not a bound
    assert parse_program("#query 1 1 1 1 1.").items == (s.Query(P, 1, 1, 1, 1, s.One(P)),)



@pytest.mark.parametrize("goal", ["(1 type)", "(1) type", "(1 a) b", "(2 a)"])
def test_a_parenthesised_goal_headed_by_a_number_is_no_fifth_bound(goal):
    # bare, `#query * * * 0 1 type.` is refused as a fifth bound; in parentheses it is the goal,
    # and the printer writes such a goal in parentheses (found by the round-trip property)
    q = parse_program(f"#query * * * 0 {goal}.").items[0]
    assert q.attempts == 0 and isinstance(q.goal, s.App)
    assert parse_program(format_program(s.Program("<input>", (q,)))).items == (q,)
    with pytest.raises(SyntaxError_, match="fifth bound"):
        parse_program(f"#query * * * 0 {goal.replace('(', '').replace(')', '')}.")


def test_comments_and_whitespace():
    text = ("% a line comment\n"
            "%{ a block\n comment with % and . inside }%\n"
            "a : b. % trailing\r\n"
            "%{}% c %{ inline }% : d.\n"
            "%")
    assert parse_program(text).items == (s.Decl(P, "a", I("b")), s.Decl(P, "c", I("d")))


@pytest.mark.parametrize("text", ["", "   \n\t\n", "% nothing\n", "%{ }%"])
def test_empty_programs(text):
    assert parse_program(text).items == ()


def test_parse_expr_rejects_trailing_dot_and_empty():
    with pytest.raises(SyntaxError_):
        parse_expr("a b.")
    with pytest.raises(SyntaxError_, match="end of file"):
        parse_expr("")


# -- real-looking programs ----------------------------------------------------

EV_PLUS = r"""
ev_plus : eval (plus E1 E2) D -o {Exists d1. Exists d2. eval E1 d1 * eval E2 d2 *
            (Pi V1. Pi V2. return V1 d1 -o return V2 d2 -o {addv V1 V2 D})}.
#query * 1 * 1 Pi d. eval (plus (num z) (num z)) d -o {return V d}.
"""


def test_destination_passing_example():
    ev, q = parse_program(EV_PLUS).items
    E1, E2, d1, d2, V1, V2, d = (I(n) for n in ("E1", "E2", "d1", "d2", "V1", "V2", "d"))
    cont = pi("V1", pi("V2", lolli(app(I("return"), V1, d1),
                                   lolli(app(I("return"), V2, d2),
                                         monad(app(I("addv"), V1, V2, D))))))
    assert ev == s.Decl(P, "ev_plus", lolli(
        app(I("eval"), app(I("plus"), E1, E2), D),
        monad(ex("d1", ex("d2", ten(app(I("eval"), E1, d1), ten(app(I("eval"), E2, d2), cont)))))))
    nz = app(I("num"), I("z"))
    assert q == s.Query(P, "*", 1, "*", 1, pi("d", lolli(
        app(I("eval"), app(I("plus"), nz, nz), d), monad(app(I("return"), I("V"), d)))))


def test_eval_llet_rule():
    text = (r"eval_llet : eval (llet E1 (\x. E2 x)) D -o {Exists d1. eval E1 d1 * "
            r"(Pi V1. return V1 d1 -o {eval (E2 V1) D})}.")
    (decl,) = parse_program(text).items
    E1, E2, d1, V1 = I("E1"), I("E2"), I("d1"), I("V1")
    assert decl == s.Decl(P, "eval_llet", lolli(
        app(I("eval"), app(I("llet"), E1, lam("x", app(E2, I("x")))), D),
        monad(ex("d1", ten(app(I("eval"), E1, d1),
                           pi("V1", lolli(app(I("return"), V1, d1),
                                          monad(app(I("eval"), app(E2, V1), D)))))))))


def test_backward_chaining_program():
    text = """
    nat : type.   z : nat.   s : nat -> nat.
    plus : nat -> nat -> nat -> type.
    #mode plus + + -.
    plus_z : plus z N N.
    plus_s : plus (s M) N (s P) <- plus M N P.
    #query * 1 * 1 plus (s z) (s z) X.
    """
    items = parse_program(text).items
    assert [type(i).__name__ for i in items] == ["Decl"] * 4 + ["Mode", "Decl", "Decl", "Query"]
    assert items[6].name == "plus_s"
    rule = items[6].classifier
    assert rule == arr("->", app(I("plus"), I("M"), I("N"), I("P")),
                       app(I("plus"), app(I("s"), I("M")), I("N"), app(I("s"), I("P"))), rev=True)


# -- parse_file ----------------------------------------------------------------

def test_parse_file(tmp_path):
    f = tmp_path / "prog.clf"
    f.write_text("a : type.\n", encoding="utf-8")
    prog = parse_file(f)
    assert prog.file == str(f) and prog.items == (s.Decl(P, "a", s.TypeKw(P)),)
    assert prog.items[0].pos.file == str(f)


def test_parse_file_errors(tmp_path):
    with pytest.raises(RoarError, match="no such file"):
        parse_file(tmp_path / "missing.clf")
    with pytest.raises(RoarError, match="directory"):
        parse_file(tmp_path)
    bad = tmp_path / "bad.clf"
    bad.write_bytes(b"a : \xff.")
    with pytest.raises(RoarError, match="UTF-8"):
        parse_file(bad)
    err = tmp_path / "err.clf"
    err.write_text("a : (b.", encoding="utf-8")
    with pytest.raises(SyntaxError_) as info:
        parse_file(err)
    assert info.value.pos == Pos(str(err), 1, 7)
    assert info.value.format().startswith(f"{err}:1:7: unexpected '.'")


# -- the malformed suite ------------------------------------------------------

MALFORMED = sorted((Path(__file__).parent / "malformed").glob("*.clf"))
EXPECT = re.compile(r"%\s*expect:\s*(\d+):(\d+)\s+(.*\S)")


def test_malformed_suite_is_large_enough():
    assert len(MALFORMED) >= 12


@pytest.mark.parametrize("path", MALFORMED, ids=[p.stem for p in MALFORMED])
def test_malformed(path):
    text = path.read_text(encoding="utf-8")
    m = EXPECT.match(text.splitlines()[0])
    assert m, f"{path.name}: first line must be '% expect: LINE:COL message'"
    line, col, fragment = int(m[1]), int(m[2]), m[3]
    with pytest.raises(SyntaxError_) as info:
        parse_program(text, file=path.name)
    err = info.value
    assert (err.pos.file, err.pos.line, err.pos.col) == (path.name, line, col), err.format()
    assert fragment in err.message, err.format()


# -- robustness: no lark exception ever escapes ---------------------------------

_TOKENS = ["a", "B", "x", " ", "\n", ".", ":", "=", "(", ")", "{", "}", "<", ">", ",", "!", "@",
           "\\", "*", "&", "-o", "->", "-@", "o-", "<-", "@-", "Pi", "Exists", "type", "1", "_",
           "#1", "#2", "#query", "#exec", "#trace", "#mode", "#foo", "3", "%", "%{", "}%", "$", "-", "+"]


# lark's names for things, which must never reach a user (none occurs in _TOKENS)
_INTERNAL = ["$END", "_DOT", "_COLON", "_RPAR", "ANON", "LPAR", "LBRACE", "NUMBER", "LAMBDA",
             "LOLLI", "Token(", "UnexpectedToken"]


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(_TOKENS), max_size=25).map(" ".join))
def test_garbage_only_raises_syntax_errors(text):
    for parse in (parse_program, parse_expr):
        try:
            parse(text)
        except SyntaxError_ as e:
            assert e.pos is not None and e.pos.line >= 1 and e.pos.col >= 1
            leaked = [n for n in _INTERNAL if n in e.message]
            assert not leaked, e.message


# -- printer round trip --------------------------------------------------------

_NAMES = st.sampled_from(["a", "b", "x", "F", "T", "o", "x'", "_y", "nat1", "Pis", "types"])


def _trees(leaves):
    def extend(c):
        return st.one_of(
            st.builds(s.App, st.just(P), c, c, st.sampled_from([None, "!", "@"])),
            st.builds(s.Lam, st.just(P), _NAMES, c,
                      st.sampled_from(["linear", "affine", "persistent"]), st.none() | c),
            st.builds(s.Pi, st.just(P), _NAMES, st.none() | c, c),
            st.builds(s.Exists, st.just(P), _NAMES, st.none() | c, c),
            st.builds(s.Arrow, st.just(P), st.sampled_from(["->", "-o", "-@"]), c, c, st.booleans()),
            st.builds(s.Tensor, st.just(P), c, c),
            st.builds(s.With, st.just(P), c, c),
            st.builds(s.Bang, st.just(P), c),
            st.builds(s.Affine, st.just(P), c),
            st.builds(s.Monad, st.just(P), c),
            st.builds(s.Pair, st.just(P), c, c),
            st.builds(s.Proj, st.just(P), c, st.sampled_from([1, 2])),
            st.builds(s.Annot, st.just(P), c, c),
        )
    return st.recursive(leaves, extend, max_leaves=14)


EXPRS = _trees(st.one_of(st.builds(s.Id, st.just(P), _NAMES), st.just(s.TypeKw(P)),
                         st.just(s.One(P)), st.just(s.Underscore(P))))


@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
@given(EXPRS)
def test_round_trip_expr(e):
    text = format_expr(e)
    assert parse_expr(text) == e, text


_BOUNDS = st.sampled_from(["*", 0, 1, 7])
ITEMS = st.one_of(
    st.builds(s.Decl, st.just(P), _NAMES, EXPRS, st.none() | EXPRS),
    # the number of attempts is a number in Celf's grammar, never '*'
    # and Celf refuses e > l and more than one attempt with l not '*'
    st.builds(s.Query, st.just(P), _BOUNDS, _BOUNDS, _BOUNDS, st.sampled_from([0, 1, 7]), EXPRS).filter(
        lambda q: not (q.expected != "*" and q.look != "*" and q.expected > q.look)
        and not (q.attempts > 1 and q.look != "*")),
    st.builds(s.Exec, st.just(P), _BOUNDS, EXPRS, st.booleans()),
    st.builds(s.Mode, st.just(P), _NAMES,
              st.lists(st.sampled_from(["+", "-", "*"]), min_size=1, max_size=4).map(tuple)),
)


@settings(max_examples=100, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(ITEMS, max_size=5))
def test_round_trip_program(items):
    prog = s.Program("<input>", tuple(items))
    assert parse_program(format_program(prog)) == prog


def test_printer_uses_few_parentheses():
    for text in ["llet E \\x. F x", "A -o Pi x. B -o C", "C o- B o- A", "A * B & C -o D",
                 "f !x (g y) #1", "!foo x", "(Pi x. A) -o B", "< a, \\x. x > #1"]:
        assert format_expr(parse_expr(text)) == text


# -- a large file (its speed is measured in bench/, never asserted here) ----

def test_large_file_parses_every_item():
    lines = []
    for i in range(1250):
        lines.append(f"r{i} : eval (llet E1 (\\x. E2 x)) D -o {{Exists d1. eval E1 d1 *")
        lines.append(f"    (Pi V1. return V1 d1 -o {{eval (E2 V1) D}})}}.  % rule {i}")
        lines.append(f"c{i} : a{i} o- b * !c @- d & < e, f > #1.")
        lines.append(f"#query * 1 * 1 Pi d. eval (plus (num z) (num z)) d -o {{return V d}}.")
    text = "\n".join(lines)
    prog = parse_program(text)
    assert len(prog.items) == 3750
    assert [type(i).__name__ for i in prog.items[:3]] == ["Decl", "Decl", "Query"]


def test_a_number_too_long_to_read_is_a_located_parse_error():
    """Python converts at most 4,300 digits; a longer number was an internal error (found by fuzzing)."""
    import pytest as _pytest
    from roar_formal.clf.parser import parse_program
    from roar_formal.errors import RoarError as _RoarError
    with _pytest.raises(_RoarError) as e:
        parse_program("nat : type.\nn : nat = " + "9" * 5000 + ".\n", "big.clf")
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == ("big.clf", 2, 11)
    assert "5,000 digits" in e.value.message
    assert parse_program("nat : type.\n#query * 1 * 1 nat.\n", "ok.clf") is not None
