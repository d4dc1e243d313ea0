"""Building CLF trees in code (clf/build.py): what a compiler builds is what the parser reads
from its printed text, so the printed model is the model."""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import pytest
from hypothesis import given, settings, strategies as st

from roar_formal.clf import surface as s
from roar_formal.clf.build import (Comment, Rule, args_of, backward, decl, exec_, fact, format_items, head_of,
                                   name, number, q, query, string)
from roar_formal.clf.parser import parse_program


def plain(e):
    """A tree without positions (and without the text a number was written as)."""
    if isinstance(e, s.Node):
        return (type(e).__name__,) + tuple(plain(getattr(e, f.name)) for f in dataclasses.fields(e)
                                           if f.name not in ("pos", "text", "bounds_pos"))
    if isinstance(e, tuple):
        return tuple(plain(x) for x in e)
    return e


def reparsed(items):
    return [plain(x) for x in parse_program(format_items(items), "<printed>").items]


def test_a_template_is_the_parse_of_its_text_with_the_holes_filled():
    built = q("ctl I m_run (ccons {} C) {}", "pp1_set", q("vcons H1 E"))
    parsed = parse_program("x : ctl I m_run (ccons pp1_set C) (vcons H1 E).", "t").items[0].classifier
    assert plain(built) == plain(parsed)
    assert head_of(built) == "ctl" and [plain(a) for a in args_of(built)] == [plain(q(x)) for x in (
        "I", "m_run", "ccons pp1_set C", "vcons H1 E")]
    assert head_of(q("!peval S E vnil X (vbool tt)")) == "peval"


def test_values_never_pass_through_text():
    tricky = 'say "hi"\n\\ % } .'
    e = q("vstr {}", string(tricky))
    assert args_of(e)[0] == string(tricky)
    [item] = parse_program(format_items([fact("f", "msg {}", string(tricky))]), "t").items
    assert args_of(item.classifier)[0].value == tricky


def test_wrong_values_are_compiler_errors():
    with pytest.raises(ValueError, match="holes"):
        q("a {} {}", "x")
    with pytest.raises(ValueError, match="identifier"):
        q("a {}", "(b c)")           # a fragment of text where a tree belongs
    with pytest.raises(ValueError, match="identifier"):
        name("in")                   # a keyword
    with pytest.raises(ValueError, match="braces"):
        q("{x}")
    with pytest.raises(TypeError):
        q("a {}", object())


def test_the_number_one_is_the_tree_the_parser_makes():
    assert isinstance(number(1), s.One) and plain(number(Fraction(5, 2))) == ("Num", Fraction(5, 2))
    assert reparsed([fact("n", "id_of t {} {}", 1, -3)]) == [plain(fact("n", "id_of t {} {}", 1, -3))]


def test_rules_backward_clauses_and_directives_print_as_they_are_built():
    rule = Rule("r1", [q("a X"), q("!b X Y")], [q("c Y r"), q("d")], fresh=("r",))
    items = [decl("k", "type"), decl("f", q("k -> type")), Comment("a remark\nover two lines"), rule.item(),
             backward("p1", q("p (s N)"), [q("p N"), q("e N")]), query(q("p z")), exec_(q("Exists r0. f r0"))]
    assert reparsed(items) == [plain(x) for x in items if not isinstance(x, Comment)]
    text = format_items(items)
    assert "% a remark\n% over two lines" in text
    assert "r1 : a X -o !b X Y -o {Exists r. c Y r * d}." in text


def test_a_rule_takes_more_premises_and_conclusions_by_appending():
    rule = Rule("r", [q("a X")], [q("b X")])
    rule.premises.append(q("!ok X"))
    rule.conclusions.append(q("c"))
    assert rule.has_premise(q("!ok X")) and not rule.has_premise(q("c"))
    assert format_items([rule]).strip() == "r : a X -o !ok X -o {b X * c}."


names = st.from_regex(r"[a-z][a-z0-9_]{0,5}", fullmatch=True).filter(lambda x: x not in ("type", "in", "let"))
leaves = st.one_of(names.map(name), st.integers(-5, 5).map(number),
                   st.fractions(max_denominator=4).filter(lambda f: f.denominator in (1, 2, 4)).map(number),
                   st.text(st.sampled_from('ab "\\\n\t%}.'), max_size=4).map(string))
terms = st.recursive(leaves, lambda inner: st.tuples(names, st.lists(inner, min_size=1, max_size=3)).map(
    lambda fa: q(fa[0] + " {}" * len(fa[1]), *fa[1])), max_leaves=8)


@settings(max_examples=60, deadline=None)
@given(premises=st.lists(terms, min_size=1, max_size=3), conclusions=st.lists(terms, max_size=3),
       bang=st.booleans())
def test_any_built_rule_reads_back_as_itself(premises, conclusions, bang):
    """An independent reading: the printer and the parser, against the tree built directly."""
    if bang:
        premises = premises[:-1] + [q("!{}", premises[-1])]
    rule = Rule("r", premises, conclusions)
    assert reparsed([rule]) == [plain(rule.item())]


def test_a_long_rule_prints_one_premise_a_line_and_reads_back():
    premises = [q("contains {} V{}".format(f"v_cell_number_{i}", i)) for i in range(6)] + [q("!peval vnil E vnil X Y")]
    rule = Rule("long", premises, [q("done {}", f"V{i}") for i in range(3)], fresh=("r",))
    text = format_items([rule])
    assert text.count("\n    -o ") == len(premises) and max(len(x) for x in text.splitlines()) <= 100
    assert reparsed([rule]) == [plain(rule.item())]
