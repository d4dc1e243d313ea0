"""Backward chaining outside the monad: exhaustive backtracking counts (perm.clf,
subsets.clf, checked against brute force), &, T, persistent and affine
premises, and logic variables printed per solution (backward.clf)."""

from __future__ import annotations

import itertools
import re

import pytest

from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, with_big_stack
from repo import ROOT

MODELS = ROOT / "models" / "clf"


def run(name: str | None = None, text: str | None = None, seed: int = 0):
    prog = Program.from_file(MODELS / name) if name else Program.from_text(text)
    lines: list[str] = []
    res = with_big_stack(run_directives, prog, seed=seed, emit=lines.append)
    return res, lines


def as_list(printed: str) -> tuple[str, ...]:
    """``cons c (cons a nil)`` -> ('c', 'a')."""
    assert printed.endswith("nil" + ")" * printed.count("("))
    return tuple(re.findall(r"cons (\w+)", printed))


def arrangements(linear: list[str], affine: list[str]) -> set[tuple[str, ...]]:
    """Brute force: sequences of distinct items in hand that use every linear item."""
    items = linear + affine
    out = set()
    for k in range(len(items) + 1):
        for seq in itertools.permutations(items, k):
            if set(linear) <= set(seq):
                out.add(seq)
    return out


# -- perm.clf -------------------------------------------------------------------

def test_perm_counts_and_lists():
    res, lines = run("perm.clf")
    four, three, none, fixed, twice, missing, first5 = res
    assert four.solutions == 24
    lists = [as_list(a["L"]) for a in four.answers]
    assert len(set(lists)) == 24
    assert set(lists) == set(itertools.permutations("abcd"))
    assert {as_list(a["L"]) for a in three.answers} == set(itertools.permutations("abc"))
    assert three.solutions == 6
    assert none.answers == [{"L": "nil"}]
    assert fixed.solutions == 1 and fixed.answers == [{}]
    # two hypotheses `have a` are two proofs of the one list [a, a]
    assert twice.solutions == 2 and {as_list(a["L"]) for a in twice.answers} == {("a", "a")}
    assert missing.solutions == 0
    # l = 5 stops after five solutions: the first five of the exhaustive run
    assert first5.answers == four.answers[:5]
    assert sum(1 for x in lines if x.startswith(" #L = ")) == 24 + 6 + 1 + 2 + 5


def test_perm_brute_force_count():
    assert len(arrangements(list("abcd"), [])) == 24 == 4 * 3 * 2 * 1


# -- subsets.clf ----------------------------------------------------------------

def test_subset_counts_match_brute_force():
    # by hand: 1 + 4 + 12 + 24 + 24 = 65; 1 + 3 + 6 + 6 = 16; 1 + 4 + 6 = 11
    assert len(arrangements([], list("abcd"))) == 65
    assert len(arrangements([], list("abc"))) == 16
    assert len(arrangements(["a"], ["b", "c"])) == 11
    res, _ = run("subsets.clf")
    expected = [arrangements([], list("abcd")), arrangements([], list("abcd")),
                arrangements([], list("abc")), arrangements(["a"], ["b", "c"])]
    for r, want in zip(res, expected):
        got = [as_list(a["L"]) for a in r.answers]
        assert r.solutions == len(got) == len(want)
        assert set(got) == want  # every arrangement exactly once


# -- backward.clf ---------------------------------------------------------------

def test_backward_counts():
    res, _ = run("backward.clf")
    counts = [r.solutions for r in res]
    assert counts == [
        1, 0, 1, 2,  # & : a&a, a&b, pab&pab, bothq
        1, 1, 1, 0, 1,  # T
        0, 1, 0, 1, 0,  # -> premises
        1, 0, 1,  # -@ premises
        1, 1, 0,  # implications as subgoals
        3, 1, 1,  # logic variables (the last: up to 2 attempts, the first one finds the 1 expected)
    ]


def test_logic_variables_printed():
    res, lines = run("backward.clf")
    add2, add12, twice = res[-3:]
    assert add2.answers == [{"X": "z", "Y": "s (s z)"}, {"X": "s z", "Y": "s z"}, {"X": "s (s z)", "Y": "z"}]
    assert add12.answers == [{"N": "s (s (s z))"}]
    assert twice.answers == [{"N": "s (s z)"}]  # the first attempt met the expectation: no second one
    i = lines.index("Query (*, 3, *, 1) add X Y (s (s z)).")
    assert lines[i + 1:i + 8] == ["Solution: _", " #X = z", " #Y = s (s z)", "Solution: _", " #X = s z",
                                  " #Y = s z", "Solution: _"]
    assert lines.count("Iteration 1") == 1 and lines.count("Iteration 2") == 0


def test_with_requires_same_resources():
    text = """
    a : type. b : type. q : type. r : type.
    q_a : q o- a.
    q_b : q o- b.
    r_i : r o- (q & q) o- q.
    #query * 2 * 1 a -o b -o r.
    #query * 0 * 1 a -o (q & b).
    #query * 1 * 1 a -o (q & a & T).
    """
    # by hand: (q & q) uses a for both halves or b for both, the last q takes the other: 2.
    # a -o (q & b): the left half uses a, the right half has no b: 0.
    # a -o (q & a & T): every half uses exactly {a}: 1.
    res, _ = run(text=text)
    assert [r.solutions for r in res] == [2, 0, 1]


def test_top_is_one_solution_not_one_per_subset():
    res, _ = run(text="a : type. b : type. c : type.\n#query * 1 * 1 a -o b -o c -o T.\n"
                      "#query * 1 * 1 a -@ b -@ T.\n#query * 1 * 1 a -> T.\n")
    assert [r.solutions for r in res] == [1, 1, 1]


def test_linear_hypotheses_are_distinct_outside_the_monad():
    """Two identical linear hypotheses give two proofs (the order they are used in)."""
    res, _ = run(text="tok : type. two : type. two_i : two o- tok o- tok.\n#query * 2 * 1 tok -o tok -o two.\n")
    assert res[0].solutions == 2


def test_with_hypothesis_projects():
    res, _ = run(text="a : type. b : type.\n#query * * * 1 (a & b) -o a.\n#query * * * 1 (a & b) -o b.\n"
                      "c : type. ab : c & b.\n#query * * * 1 c.\n")
    assert [r.solutions for r in res] == [1, 1, 1]


def test_monad_match_counts_identical_facts_like_celf():
    res, _ = run(text="tok : type.\n#query * * * 1 tok -o tok -o {tok * tok}.\n")
    assert res[0].solutions == 2
