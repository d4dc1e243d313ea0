"""The built-in domain of ground numbers and strings (docs/clf.md, "Built-in
numbers and strings"): literals, their printing and hash-consing, every
built-in family against Python's own arithmetic as an independent oracle
(through ``#query`` goals and through forward rules), and the errors."""

from __future__ import annotations

import math
from decimal import Decimal
from fractions import Fraction

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roar_formal.clf import surface as S
from roar_formal.clf.backward import Backward, show_proof
from roar_formal.clf.builtins import (BUILTIN_FAMILIES, BUILTINS, BuiltinError, builtin_names, is_builtin, num_term,
                                      num_value, string_term, string_value)
from roar_formal.clf.parser import parse_expr, parse_program
from roar_formal.clf.pretty_surface import format_expr
from roar_formal.clf.printer import show
from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, show_context, with_big_stack
from roar_formal.clf.signature import QueryDirective
from roar_formal.clf.state import canonical_key, same_state
from roar_formal.clf.terms import Const, Lit, Root, const, zonk
from roar_formal.errors import QueryError, SyntaxError_, TypeError_, UnsupportedError

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])


def run(text: str, seed: int = 0):
    prog = Program.from_text(text)
    lines: list[str] = []
    res = with_big_stack(run_directives, prog, seed=seed, emit=lines.append)
    return prog, res, lines


def solutions(text: str, limit: int = 3) -> list[list[dict]]:
    """For each #query of ``text``: its solutions (at most ``limit``), each the values of
    the query's logic variables as terms."""
    prog = Program.from_text(text)
    out = []
    for d in prog.sig.directives:
        assert isinstance(d, QueryDirective)
        bw = Backward(prog)
        sols = []
        for _ in bw.solve(d.goal):
            sols.append({n: zonk(x) for n, x in d.logic_vars})
            if len(sols) >= limit:
                break
        out.append(sols)
    return out


# -- independent renderings and references ---------------------------------------

def decimal_text(n: int, k: int) -> str:
    """The text of n / 10**k with k digits after the point (k = 0: an integer)."""
    if k == 0:
        return str(n)
    sign = "-" if n < 0 else ""
    return f"{sign}{abs(n) // 10 ** k}.{abs(n) % 10 ** k:0{k}d}"


def shortest_decimal(q: Fraction) -> str:
    """Printing oracle for finite decimals, through the decimal module."""
    d = (Decimal(q.numerator) / Decimal(q.denominator)).normalize()
    return format(d, "f")


def trunc_div(a: int, b: int) -> int:
    """Division truncating toward zero, by repeated subtraction on the magnitudes."""
    n, d, q = abs(a), abs(b), 0
    while n >= d:
        n -= d
        q += 1
    return q if (a < 0) == (b < 0) else -q


def trunc_mod(a: int, b: int) -> int:
    return a - b * trunc_div(a, b)


# numbers as (text, exact value): integers and decimals with up to 4 places
NUMBERS = st.builds(lambda n, k: (decimal_text(n, k), Fraction(n, 10 ** k)),
                    st.integers(-10 ** 6, 10 ** 6), st.integers(0, 4))
SMALL_INTS = st.integers(-300, 300).map(lambda n: (str(n), Fraction(n)))
STRINGS = st.text(alphabet=st.sampled_from(list('ab Z09%{}"\\\n\t.é')), max_size=8)


def quote(s: str) -> str:
    """A string literal, escaped independently of the printer."""
    out = []
    for c in s:
        out.append({"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t"}.get(c, c))
    return '"' + "".join(out) + '"'


# -- literals: lexing, parsing, printing ----------------------------------------

@pytest.mark.parametrize("text,value", [
    ("5", Fraction(5)), ("0", Fraction(0)), ("-1", Fraction(-1)), ("3.0", Fraction(3)), ("0.1", Fraction(1, 10)),
    ("-2.5", Fraction(-5, 2)), ("007", Fraction(7)), ("10", Fraction(10)),
])
def test_number_literals_parse(text, value):
    e = parse_expr(f"f {text}")
    assert isinstance(e.arg, S.Num) and e.arg.value == value and e.arg.text == text


def test_one_is_the_unit_and_the_number_one():
    assert isinstance(parse_expr("1"), S.One)
    assert isinstance(parse_expr("f 1").arg, S.One)
    assert parse_expr("f 1.5").arg.value == Fraction(3, 2)
    # as a term, `1` is the number one
    _, res, _ = run("#query * 1 * 1 num_add 1 1.0 2.")
    assert res[0].solutions == 1
    # and still the unit in a positive type
    _, res, _ = run("p : type. #query * 1 * 1 p -o {p * 1}.")
    assert res[0].solutions == 1


@pytest.mark.parametrize("text,value", [
    ('"abc"', "abc"), ('""', ""), (r'"a\"b"', 'a"b'), (r'"back\\slash"', "back\\slash"),
    (r'"tab\tnl\n"', "tab\tnl\n"), ('"50% {not a comment}"', "50% {not a comment}"),
])
def test_string_literals_parse(text, value):
    e = parse_expr(f"f {text}")
    assert e.arg == S.Str(None, value)


def test_operators_and_directive_bounds_still_lex():
    prog = parse_program("#query 1 2 * 3 p -o q.\n#exec 10 count 10.\n#trace * f -1 -o g 2.5 -@ h.\n"
                         "#query 1 1 1 1 1.\nr : a -> b -o c.\n#mode p + - .\n")
    q, e, t, one, r, m = prog.items
    assert (q.depth, q.expected, q.look, q.attempts) == (1, 2, "*", 3)
    assert isinstance(q.goal, S.Arrow) and q.goal.op == "-o"
    assert e.steps == 10 and e.start.arg.value == 10
    assert t.start.op == "-o" and t.start.left.arg.value == -1
    assert t.start.right.op == "-@" and t.start.right.left.arg.value == Fraction(5, 2)
    assert isinstance(one.goal, S.One) and one.attempts == 1
    assert r.classifier.op == "->" and r.classifier.right.op == "-o"
    assert m.modes == ("+", "-")


@pytest.mark.parametrize("text,fragment,col", [
    # `1.2` is a number, then the '.' ends the declaration and `3` cannot start another
    ("a : f 1.2.3.", "unexpected number 3", 11),
    ('a : f "abc.', "unterminated string literal", 7),
    ('a : f "a\\qb".', "invalid escape '\\q'", 7),
])
def test_malformed_literals(text, fragment, col):
    with pytest.raises(SyntaxError_) as info:
        parse_program(text)
    assert fragment in info.value.message
    assert (info.value.pos.line, info.value.pos.col) == (1, col)


def test_identifiers_that_start_with_digits():
    # Celf's lexer: a run of identifier characters is one identifier (`a->b-o`, `12ab`, `1x`),
    # digits alone are a number and `-` then digits a (negative) number literal
    (d,) = parse_program("r : a->b-o c 12ab 1x 1+ -1.").items
    args = []
    e = d.classifier
    while isinstance(e, S.App):
        args.append(e.arg)
        e = e.fn
    assert e == S.Id(None, "a->b-o")
    assert [a.name for a in reversed(args[1:])] == ["c", "12ab", "1x", "1+"]
    assert isinstance(args[0], S.Num) and args[0].value == -1


def test_number_printing():
    cases = {Fraction(5): "5", Fraction(-1): "-1", Fraction(0): "0", Fraction(1, 10): "0.1",
             Fraction(5, 2): "2.5", Fraction(-5, 2): "-2.5", Fraction(-1, 20): "-0.05", Fraction(1, 3): "1/3",
             Fraction(-2, 3): "-2/3", Fraction(1, 1024): "0.0009765625", Fraction(123456, 100): "1234.56"}
    for q, text in cases.items():
        assert show(num_term(q)) == text
    assert show(string_term('a"b\\c\nd\te')) == r'"a\"b\\c\nd\te"'


@settings(max_examples=200, **SETTINGS)
@given(NUMBERS)
def test_decimal_round_trip(num):
    text, value = num
    t = num_term(value)
    assert show(t) == shortest_decimal(value)
    assert num_term(text) is t
    printed = parse_expr(f"f {show(t)}").arg
    got = Fraction(1) if isinstance(printed, S.One) else printed.value
    assert got == value


@settings(max_examples=200, **SETTINGS)
@given(STRINGS)
def test_string_round_trip(s):
    t = string_term(s)
    assert show(t) == quote(s)
    assert parse_expr(f"f {show(t)}").arg.value == s
    assert format_expr(S.Str(None, s)) == quote(s)


@settings(max_examples=100, **SETTINGS)
@given(NUMBERS)
def test_surface_printer_round_trip(num):
    _, value = num
    e = S.App(None, S.Id(None, "f"), S.Num(None, value))
    assert parse_expr(format_expr(e)) == e
    assert parse_expr(format_expr(S.Num(None, Fraction(1)))) == S.Num(None, Fraction(1))


# -- values and hash-consing --------------------------------------------------------

def test_python_api():
    assert num_term(3) is num_term("3.0") is num_term(Fraction(6, 2)) is num_term(Decimal("3.00"))
    assert num_value(num_term("0.1")) == Fraction(1, 10)
    assert num_value(string_term("3")) is None and string_value(num_term(3)) is None
    assert string_value(string_term("x")) == "x"
    assert num_term(3) is not string_term("3")
    assert num_value(const("foo")) is None
    t = num_term(-7)
    assert type(t) is Root and type(t.head) is Lit and t.args == () and not t.evars and not t.maxb
    with pytest.raises(TypeError):
        num_term(1.5)  # floats are not exact
    with pytest.raises(ValueError):
        num_term("abc")
    names = builtin_names()
    assert names[:2] == ["number", "string"]
    assert {"num_lt", "num_le", "num_eq", "num_ne", "string_eq", "string_ne", "num_add", "num_sub", "num_mul",
            "num_div", "num_idiv", "num_mod", "num_neg", "num_abs", "num_floor", "num_min", "num_max",
            "string_concat", "num_to_string"} == set(names[2:])
    assert all(is_builtin(n) for n in names) and not is_builtin("nat")
    assert {c.name for c in BUILTIN_FAMILIES} == set(names)


def test_three_point_zero_is_three():
    text = """
same : number -> number -> type.
refl : same X X.
cell : number -> type.
got : number -> type.
r : cell 3 -o {got 3.0}.
#query * 1 * 1 same 3.0 3.
#query * 1 * 1 same 3 X.
#query * 0 * 1 same 3 3.5.
#query * 1 * 1 num_eq 3.0 3.
#exec 1 cell 3.00.
"""
    _, res, _ = run(text)
    assert [r.solutions for r in res[:4]] == [1, 1, 0, 1]
    assert res[1].answers == [{"X": "3"}]
    assert show_context(res[4].final) == ["got 3"]


def test_state_keys_with_literals():
    prog = Program.from_text("""
cell : number -> type.
name : string -> type.
dest : type.
at : dest -> number -> type.
""")
    a = prog.start_context(parse_start(prog, 'cell 3 * name "x" * Exists d:dest. at d 2.5'))
    b = prog.start_context(parse_start(prog, 'Exists e:dest. at e 2.50 * name "x" * cell 3.0'))
    c = prog.start_context(parse_start(prog, 'cell 3 * name "y" * Exists d:dest. at d 2.5'))
    assert same_state(a, b) and canonical_key(a) == canonical_key(b)
    assert not same_state(a, c)
    # the argument index finds literal arguments
    assert len(a.candidates(Const("cell"), 0, num_term(3))) == 1


def parse_start(prog, text):
    from roar_formal.clf.signature import Elaborator
    from roar_formal.clf.surface import Exec

    el = Elaborator(prog.sig)
    return el.exec_(Exec(None, "*", parse_expr(text))).start


# -- every built-in against Python ---------------------------------------------------

TESTS = {
    "num_lt": lambda a, b: a < b, "num_le": lambda a, b: a <= b,
    "num_eq": lambda a, b: a == b, "num_ne": lambda a, b: a != b,
}
BINARY = {
    "num_add": lambda a, b: a + b, "num_sub": lambda a, b: a - b, "num_mul": lambda a, b: a * b,
    "num_div": lambda a, b: a / b if b else None,
    "num_min": lambda a, b: a if a <= b else b, "num_max": lambda a, b: b if a <= b else a,
    "num_idiv": lambda a, b: (Fraction(trunc_div(int(a), int(b)))
                              if a.denominator == b.denominator == 1 and b else None),
    "num_mod": lambda a, b: (Fraction(trunc_mod(int(a), int(b)))
                             if a.denominator == b.denominator == 1 and b else None),
}
UNARY = {
    "num_neg": lambda a: -a, "num_abs": lambda a: a if a >= 0 else -a,
    "num_floor": lambda a: Fraction(math.floor(a)),
}


def check_numbers(a_text, a, b_text, b):
    text = "\n".join(
        [f"#query * * * 1 {n} {a_text} {b_text}." for n in TESTS]
        + [f"#query * * * 1 {n} {a_text} {b_text} X." for n in BINARY]
        + [f"#query * * * 1 {n} {a_text} X." for n in UNARY]
        + [f"#query * * * 1 num_to_string {a_text} S."])
    sols = solutions(text)
    k = 0
    for name, ref in TESTS.items():
        assert len(sols[k]) == (1 if ref(a, b) else 0), (name, a, b)
        k += 1
    for name, ref in BINARY.items():
        want = ref(a, b)
        got = [num_value(s["X"]) for s in sols[k]]
        assert got == ([] if want is None else [want]), (name, a, b)
        k += 1
    for name, ref in UNARY.items():
        assert [num_value(s["X"]) for s in sols[k]] == [ref(a)], (name, a)
        k += 1
    assert [string_value(s["S"]) for s in sols[k]] == [shortest_decimal(a)]


@settings(max_examples=150, **SETTINGS)
@given(NUMBERS, NUMBERS)
def test_number_builtins_match_python(x, y):
    check_numbers(*x, *y)


@settings(max_examples=150, **SETTINGS)
@given(SMALL_INTS, SMALL_INTS)
def test_integer_builtins_match_python(x, y):
    check_numbers(*x, *y)


def test_outputs_are_checked_when_given():
    text = """
#query * 1 * 1 num_add 2 3 5.
#query * 0 * 1 num_add 2 3 6.
#query * 1 * 1 num_mul 0.5 4 2.0.
#query * 1 * 1 num_div 1 3 X.
#query * 1 * 1 num_sub 0.3 0.1 0.2.
"""
    _, res, _ = run(text)
    assert [r.solutions for r in res] == [1, 0, 1, 1, 1]
    assert res[3].answers == [{"X": "1/3"}]


@pytest.mark.parametrize("a,b,q,r", [(7, 2, 3, 1), (-7, 2, -3, -1), (7, -2, -3, 1), (-7, -2, 3, -1),
                                     (6, 3, 2, 0), (-6, 3, -2, 0), (0, 5, 0, 0), (1, 2, 0, 1), (-1, 2, 0, -1)])
def test_idiv_and_mod_truncate_toward_zero(a, b, q, r):
    assert (trunc_div(a, b), trunc_mod(a, b)) == (q, r)  # the reference itself, by hand
    sols = solutions(f"#query * * * 1 num_idiv {a} {b} Q.\n#query * * * 1 num_mod {a} {b} R.")
    assert [num_value(s["Q"]) for s in sols[0]] == [q]
    assert [num_value(s["R"]) for s in sols[1]] == [r]


def test_division_by_zero_and_non_integers_fail():
    text = """
#query * 0 * 1 num_div 1 0 X.
#query * 0 * 1 num_div 0 0.0 X.
#query * 0 * 1 num_idiv 7 0 X.
#query * 0 * 1 num_mod 7 0 X.
#query * 0 * 1 num_idiv 7.5 2 X.
#query * 0 * 1 num_mod 7 2.5 X.
#query * 1 * 1 num_idiv 7.0 2 3.
"""
    _, res, _ = run(text)
    assert [r.solutions for r in res] == [0, 0, 0, 0, 0, 0, 1]


@settings(max_examples=100, **SETTINGS)
@given(STRINGS, STRINGS)
def test_string_builtins_match_python(s, t):
    text = (f"#query * * * 1 string_eq {quote(s)} {quote(t)}.\n"
            f"#query * * * 1 string_ne {quote(s)} {quote(t)}.\n"
            f"#query * * * 1 string_concat {quote(s)} {quote(t)} U.\n"
            f"#query * * * 1 string_eq {quote(s)} {quote(s)}.\n")
    sols = solutions(text)
    assert len(sols[0]) == (1 if s == t else 0)
    assert len(sols[1]) == (1 if s != t else 0)
    assert [string_value(x["U"]) for x in sols[2]] == [s + t]
    assert len(sols[3]) == 1


ALL = list(TESTS) + list(BINARY) + list(UNARY)
FORWARD_RULES = """
inp : number -> number -> type.  % `in` is a keyword of Celf's
yes : string -> type.
out : string -> number -> type.
""" + "\n".join(
    [f"tok_{n} : type." for n in ALL]
    + [f"t_{n} : tok_{n} -o !inp A B -o !{n} A B -o {{!yes \"{n}\"}}." for n in TESTS]
    + [f"f_{n} : tok_{n} -o !inp A B -o !{n} A B C -o {{!out \"{n}\" C}}." for n in BINARY]
    + [f"u_{n} : tok_{n} -o !inp A B -o !{n} A C -o {{!out \"{n}\" C}}." for n in UNARY])


@settings(max_examples=40, **SETTINGS)
@given(NUMBERS, NUMBERS)
def test_number_builtins_in_forward_rules(x, y):
    (a_text, a), (b_text, b) = x, y
    # each rule consumes its own token, so it fires at most once; a rule whose built-in
    # fails leaves its token behind
    start = " * ".join([f"!inp {a_text} {b_text}"] + [f"tok_{n}" for n in ALL])
    _, res, _ = run(FORWARD_RULES + f"\n#exec * {start}.\n")
    ctx = res[0].final
    yes = {string_value(t.args[0]) for t in ctx.pers if t.head is Const("yes")}
    outs: dict = {}
    for t in ctx.pers:
        if t.head is Const("out"):
            outs.setdefault(string_value(t.args[0]), set()).add(num_value(t.args[1]))
    left = {t.head.name[len("tok_"):] for t in ctx.lin}
    assert yes == {n for n, ref in TESTS.items() if ref(a, b)}
    want = {n: {ref(a, b)} for n, ref in BINARY.items() if ref(a, b) is not None}
    want.update({n: {ref(a)} for n, ref in UNARY.items()})
    assert outs == want
    assert left == set(ALL) - yes - set(outs)
    assert res[0].steps == len(ALL) - len(left)


def test_countdown():
    text = """
count : number -> type.
tick : count N -o !num_lt 0 N -o !num_sub N 1 M -o {count M}.
#exec 10 count 10.
#exec * count 10.
#exec 0 count 0.
#exec * count 2.5.
"""
    _, res, lines = run(text)
    assert res[0].steps == 10 and show_context(res[0].final) == ["count 0"]
    assert res[1].steps == 10 and show_context(res[1].final) == ["count 0"]
    assert res[2].steps == 0
    assert res[3].steps == 3 and show_context(res[3].final) == ["count -0.5"]
    with pytest.raises(QueryError, match="expected exactly 11 steps, but the program quiesced after 10"):
        run(text.replace("#exec 10 count 10.", "#exec 11 count 10."))


def test_linear_premise_of_a_builtin_is_evaluated_too():
    _, res, _ = run("""
count : number -> type.
tick : count N -o num_lt 0 N -o num_sub N 1 M -o {count M}.
#exec 3 count 3.
""")
    assert show_context(res[0].final) == ["count 0"]


def test_output_determines_a_rule_variable():
    prog = Program.from_text("""
foo : number -> type.
r : foo X -o !num_add X 1 Y -o {foo Y}.
""")
    ctx = prog.start_context(const("foo", num_term(1)))
    steps, quiescent = prog.run(ctx, 4)
    assert steps == 4 and show_context(ctx) == ["foo 5"]
    # the explorer sees the one step with its computed output
    (choice,) = prog.steps(ctx)
    nxt, _ = prog.successor(ctx, choice)
    assert show_context(nxt) == ["foo 6"]


def test_builtin_output_already_bound_is_compared():
    _, res, _ = run("""
pair : number -> number -> type.
ok : number -> type.
r : pair A B -o !num_mul A 2 B -o {ok A}.
#exec * pair 3 6 * pair 3 7 * pair 1.5 3.
""")
    assert show_context(res[0].final) == ["ok 1.5", "ok 3", "pair 3 7"]


def test_builtins_in_backward_clauses():
    text = """
fact : number -> number -> type.
fact0 : fact 0 1.
factn : fact N F <- num_lt 0 N <- num_sub N 1 M <- fact M G <- num_mul N G F.
#query * 1 * 1 fact 10 X.
#query * 1 * 1 fact 0 X.
#query * 0 * 1 fact 3 7.
"""
    _, res, _ = run(text)
    assert res[0].answers == [{"X": str(math.factorial(10))}]
    assert res[1].answers == [{"X": "1"}]


def test_persistent_backward_premise_reaching_a_builtin():
    _, res, _ = run("""
small : number -> type.
small_def : small N <- num_lt N 10.
item : number -> type.
kept : number -> type.
keep : item N -o small N -> {kept N}.
#exec * item 3 * item 12 * item 9.99.
""")
    assert show_context(res[0].final) == ["item 12", "kept 3", "kept 9.99"]


def test_proof_terms_name_the_builtin():
    prog = Program.from_text("p : number -> type. pz : p X <- num_add 1 2 X.\n#query * 1 * 1 p X.")
    lines: list[str] = []
    with_big_stack(run_directives, prog, emit=lines.append, proofs=True)
    assert "Solution: pz !num_add" in lines and " #X = 3" in lines
    bw = Backward(prog)
    (pf,) = list(bw.solve(const("p", num_term(3))))
    assert show_proof(pf) == "pz !num_add"


# -- errors ----------------------------------------------------------------------------

def test_non_ground_input_in_a_query():
    with pytest.raises(BuiltinError) as info:
        run("c : type.\n#query * 1 * 1 num_add X 1 Y.")
    err = info.value
    assert "built-in 'num_add': its inputs must be ground" in err.message
    assert "argument 1 is an unbound logic variable" in err.message
    assert (err.pos.line, err.pos.col) == (2, 1)


def test_non_literal_input_in_a_forward_rule():
    text = """
c : number -> type.
d : number -> type.
e : type.
r : c X -o {Exists y:number. d y}.
s : d Y -o !num_lt Y 3 -o {e}.
#exec * c 1.
"""
    with pytest.raises(BuiltinError) as info:
        run(text)
    msg = info.value.message
    assert "built-in 'num_lt': its inputs must be ground" in msg and "not a number literal" in msg
    assert "rule 's'" in msg
    assert info.value.pos.line == 7


def test_undetermined_builtin_input_is_refused_when_compiled():
    with pytest.raises(UnsupportedError, match="argument 1 of the built-in 'num_add' \\(Z\\) is not determined"):
        Program.from_text("foo : number -> type.\nr : foo X -o !num_add Z 1 Y -o {foo Y}.")
    # an input determined by an earlier built-in's output is fine
    Program.from_text("foo : number -> type.\nr : foo X -o !num_add X 1 Y -o !num_mul Y 2 Z -o {foo Z}.")
    # but not by a later one: built-in premises are evaluated in order
    with pytest.raises(UnsupportedError, match="num_mul"):
        Program.from_text("foo : number -> type.\nr : foo X -o !num_mul Y 2 Z -o !num_add X 1 Y -o {foo Z}.")


@pytest.mark.parametrize("name", builtin_names())
def test_builtin_names_are_reserved(name):
    with pytest.raises(TypeError_, match=f"'{name}' is reserved by the built-in domain") as info:
        Program.from_text(f"nat : type.\n{name} : type.")
    assert (info.value.pos.line, info.value.pos.col) == (2, 1)


@pytest.mark.parametrize("text,line,col", [
    ("c : type.\nr : c -o {num_lt 1 2}.", 2, 11),
    ("c : type.\nr : c -o {c * !num_add 1 2 3}.", 2, 16),
    ("c : type.\nr : c -o {@num_eq 1 1}.", 2, 12),
    ("c : type.\nr : c -o {!(c -> num_lt 1 2)}.", 2, 12),
    ("#exec * num_lt 1 2.", 1, 9),
    ("#query * 1 * 1 {num_lt 1 2}.", 1, 17),
])
def test_builtin_cannot_be_a_fact(text, line, col):
    with pytest.raises(TypeError_, match="the built-in family '[a-z_]+' cannot be a fact") as info:
        Program.from_text(text)
    assert (info.value.pos.line, info.value.pos.col) == (line, col)


@pytest.mark.parametrize("text,fragment", [
    ("pi : number.", "'pi' cannot be declared of type number"),
    ("c : type.\nf : c -> string.", "'f' cannot be declared of type string"),
    ("lt : num_lt 1 2.", "'lt' would be a clause of the built-in family 'num_lt'"),
    ("ax : num_add A 0 A.", "'ax' would be a clause of the built-in family 'num_add'"),
])
def test_no_declaration_concludes_in_a_builtin(text, fragment):
    with pytest.raises(TypeError_, match=fragment):
        Program.from_text(text)


def test_literal_types_are_checked():
    with pytest.raises(TypeError_, match="type mismatch"):
        Program.from_text('#query * 1 * 1 num_add 1 "two" X.')
    with pytest.raises(TypeError_, match="type mismatch"):
        Program.from_text("nat : type. c : nat -> type. #exec * c 3.")
    with pytest.raises(TypeError_, match="expected a type, found the number literal '5'"):
        Program.from_text("c : 5.")
    with pytest.raises(TypeError_, match="takes 3 arguments, given 2"):
        Program.from_text("#query * 1 * 1 num_add 1 2.")


def test_builtin_families_are_backward_families():
    prog = Program.from_text("c : type.")
    assert BUILTIN_FAMILIES <= prog.backward_families
    assert set(BUILTINS) <= BUILTIN_FAMILIES
    assert prog.sig.lookup("num_add").builtin and "num_add" not in prog.sig.consts


_TOKENS = ["a", "f", "X", " ", ".", ":", "(", ")", "{", "}", "-o", "->", "-@", "*", "1", "-1", "2.5", "3.", "0",
           '"s"', '"', '\\', "-", "1.2.3", "12ab", "#query", "#exec", "num_add", "number", "%"]


@settings(max_examples=300, **SETTINGS)
@given(st.lists(st.sampled_from(_TOKENS), max_size=20).map(" ".join))
def test_garbage_with_literals_only_raises_syntax_errors(text):
    for parse in (parse_program, parse_expr):
        try:
            parse(text)
        except SyntaxError_ as e:
            assert e.pos is not None and e.pos.line >= 1 and e.pos.col >= 1
            assert not any(n in e.message for n in ("NUMLIT", "STRING", "NUMBER", "$END", "Token("))


def test_a_builtin_error_on_the_command_line_says_it_is_an_extension(tmp_path, capsys):
    """Celf has no built-in numbers: their errors are not put in one of Celf's categories, but said
    to be the extension's (it had no note at all, unlike every other error)."""
    from roar_formal.cli import main
    f = tmp_path / "g.clf"
    f.write_text("g : number -> type.\n#query * 1 * 1 num_add X 1 2.\n", encoding="utf-8")
    with pytest.raises(SystemExit) as e:
        main(["clf", str(f)])
    err = capsys.readouterr().err
    assert e.value.code == 2 and f"{f}:2:1: built-in 'num_add': its inputs must be ground" in err
    assert "(an error of the built-in numbers and strings, an extension Celf does not have)" in err
