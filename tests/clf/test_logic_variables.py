"""Celf's semantics for logic variables in the forward context, premises proved by
backward chaining that consume facts, and proof terms as input (issue 13): the
general (unification) path is chosen per rule, bindings are undone on
backtracking, and proof-term definitions are checked with Celf's linearity."""

from __future__ import annotations

import pytest

from roar_formal.clf.context import Context
from roar_formal.clf.forward import Run, open_families
from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, show_context, with_big_stack
from roar_formal.clf.terms import const, zonk
from roar_formal.errors import TypeError_

HALF = """
nat : type. z : nat. s : nat -> nat.
go : type. tick : type. tock : type.
half : nat -> nat -> type. res : nat -> type.
start : go -o {half (s (s (s (s z)))) H * res H}.
h_ss : half (s (s N)) (s H) -o {half N H}.
h_z : half z z -o {1}.
other : tick -o {tock}.
"""


def run(text: str, seed: int = 0):
    prog = Program.from_text(text)
    lines: list[str] = []
    res = with_big_stack(run_directives, prog, seed=seed, emit=lines.append)
    return prog, res, lines


def test_the_general_path_is_chosen_per_rule():
    prog = Program.from_text(HALF)
    names = {t.name: t for t in prog.templates}
    assert names["start"].open_slots  # H: only in the head
    opened, general = open_families(prog.templates, Context(), prog)
    assert {c.name for c in opened} == {"half", "res"}
    assert {t.name for t in general} == {"h_ss", "h_z"}  # `start` and `other` keep the ground path
    run_ = Run(prog.templates, prog.start_context(const("go")), prover=prog.prover())
    assert run_.general is not None and {t.name for t in run_.general} == {"h_ss", "h_z"}


def test_no_general_path_without_logic_variables():
    prog = Program.from_text("a : type. b : type. r : a -o {b}.\n")
    run_ = Run(prog.templates, prog.start_context(const("a")), prover=prog.prover())
    assert run_.general is None


def test_exec_instantiates_the_logic_variable():
    prog, (res,), _ = run(HALF + "#exec * go * tick.\n")
    assert res.steps == 5 and show_context(res.final) == ["res (s (s z))", "tock"]
    assert not res.final.open or all(not zonk(t).evars for _m, t in res.final.open)


def test_query_bindings_made_by_forward_chaining_are_undone():
    text = ("t : type. e1 : t. e2 : t. c : t -> type. d : t -> type.\n"
            "r1 : c e1 -o {d e1}.\nr2 : c e2 -o {d e2}.\n#query * 1 * 1 c S -o {d S}.\n")
    seen = set()
    for seed in range(6):
        prog, (res,), lines = run(text, seed)
        assert res.ok and res.solutions == 1
        seen.add(res.answers[0]["S"])
        (name, x), = prog.sig.directives[0].logic_vars
        assert x.head.ref is None  # unbound again once the query is done
    assert seen <= {"e1", "e2"}


def test_open_fact_left_in_the_context_fails_the_monad():
    # c S is never consumed (no rule matches c e2): a linear leftover, so no solution
    text = "t : type. e1 : t. e2 : t. c : t -> type.\nr : c e1 -o {1}.\n#query * 0 * 1 c e2 -o {1}.\n"
    _, (res,), _ = run(text)
    assert res.ok and res.solutions == 0


def test_linear_premise_proof_consumes_facts_of_the_context():
    text = ("a : type. b : type. c : type. go : type.\nb_from_a : b o- a.\nr : go -o b -o {c}.\n"
            "#exec * go * a.\n")
    _, (res,), _ = run(text)
    assert res.steps == 1 and show_context(res.final) == ["c"]


def test_affine_premise_sees_no_linear_fact():
    text = ("a : type. b : type. c : type. go : type.\nb_from_a : b o- a.\nr : go -o b -@ {c}.\n"
            "#exec * go * a.\n#exec * go * @a.\n")
    _, (lin, aff), _ = run(text)
    assert lin.steps == 0 and sorted(show_context(lin.final)) == ["a", "go"]
    assert aff.steps == 1 and show_context(aff.final) == ["c"]


@pytest.mark.parametrize("ty, body, fragment", [
    ("b * b * c", r"\x. {let {[y, z]} = r x in [y, y, z]}", "the linear variable 'y' is used 2 times"),
    ("b * c * c", r"\x. {let {[y, z]} = r x in [y, z, z]}", "the linear variable 'z' is used 2 times"),
    ("b", r"\x. {let {[y, z]} = r x in y}", "the linear variable 'z' is used 0 times"),
    ("b * c", r"\x. {let {[y, z]} = r x in [y, !z]}", "expected a term, found '!'"),
    ("b * c", r"\x. {let {1} = r x in 1}", "the pattern does not match the type b * c"),
])
def test_proof_term_typing_errors(ty, body, fragment):
    text = f"a : type. b : type. c : type.\nr : a -o {{b * c}}.\npr : a -o {{{ty}}} = {body}.\n"
    with pytest.raises(TypeError_) as info:
        Program.from_text(text)
    assert fragment in info.value.message, info.value.message
    assert info.value.pos is not None and info.value.pos.line == 3


def test_proof_term_persistent_positions_use_no_linear_variable():
    text = ("a : type. b : type.\nf : a -> {b}.\n"
            "bad : a -o {b} = \\x. {let {y} = f !x in y}.\n")
    with pytest.raises(TypeError_) as info:
        Program.from_text(text)
    assert "persistent" in info.value.message and info.value.pos.line == 3


def test_proof_term_pair_halves_use_the_same_resources():
    text = ("a : type. b : type.\nr : a -o {b}.\n"
            "bad : a -o {b} & ({b} -o {b}) = \\x. < r x, \\y. y >.\n")
    with pytest.raises(TypeError_) as info:
        Program.from_text(text)
    assert "same linear variables" in info.value.message


def test_proof_term_definition_is_not_a_clause():
    prog = Program.from_text("a : type. b : type.\nr : a -o {b}.\npr : a -o {b} = \\x. {let {y} = r x in y}.\n")
    assert prog.rule_names == ["r"]
    info = prog.sig.consts["pr"]
    assert info.proof and info.definition is not None
