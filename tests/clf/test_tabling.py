"""Tabled goals in backward chaining (``Backward.tabled``): the same answers as the untabled
search and as a plain enumerator of walks, on random graphs under a doubling transitivity
clause; and the ROAR compiler's entailment queries, tabled, give the compiled model the
untabled search gives."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roar_formal.clf.backward import Backward
from roar_formal.clf.program import Program
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.terms import show, zonk
from repo import ROOT

NODES = 5

# eq N A B: a walk of length 1 to 2^N from A to B along the undirected edges e
HEADER = "\n".join([
    "node : type.", *[f"n{i} : node." for i in range(NODES)],
    "nat : type.", "z : nat.", "s : nat -> nat.",
    "e : node -> node -> type.",
    "eq : nat -> node -> node -> type.",
    "eq_base : eq N A B <- e A B.",
    "eq_sym : eq N A B <- e B A.",
    "eq_trans : eq (s N) A C <- eq N A B <- eq N B C.",
])


def nat(k: int) -> str:
    return "z" if k == 0 else f"(s {nat(k - 1)})"


def walks(edges: set, k: int, start: int) -> set:
    """The plain enumerator: the nodes a walk of 1 to 2^k edges reaches from ``start``."""
    adj = {i: set() for i in range(NODES)}
    for a, b in edges:
        adj[a].add(b)
        adj[b].add(a)
    out: set = set()
    frontier = {start}
    for _ in range(2 ** k):
        frontier = {y for x in frontier for y in adj[x]}
        out |= frontier
    return out


def answers(text: str, tabled: bool) -> list:
    """Per query, the values of its logic variables in each proof found (distinct)."""
    prog = Program.from_text(text)
    out = []
    for d in [d for d in prog.sig.directives if hasattr(d, "goal")]:
        bw = Backward(prog)
        if tabled:
            bw.tabled = frozenset({"eq"})
        got = set()
        for _pf in bw.solve(d.goal):
            got.add(tuple(show(zonk(x)) for _name, x in d.logic_vars))
        out.append(got)
    return out


EDGES = st.sets(st.tuples(st.integers(0, NODES - 1), st.integers(0, NODES - 1)), max_size=6)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(EDGES, st.integers(0, 3), st.integers(0, NODES - 1), st.one_of(st.none(), st.tuples(
    st.integers(0, NODES - 1), st.integers(0, NODES - 1))))
def test_tabled_answers_are_the_search_s_and_the_walks(edges, k, start, assumed):
    facts = "\n".join(f"e{i} : e n{a} n{b}." for i, (a, b) in enumerate(sorted(edges)))
    goal = f"eq {nat(k)} n{start} Y"
    if assumed is not None:   # an edge assumed as a hypothesis of the goal (tabled under it)
        goal = f"e n{assumed[0]} n{assumed[1]} -> {goal}"
    text = f"{HEADER}\n{facts}\n#query * * * 1 {goal}.\n"
    plain = with_big_stack(answers, text, False)
    tabled = with_big_stack(answers, text, True)
    assert tabled == plain
    reach = walks(edges | ({assumed} if assumed else set()), k, start)
    assert plain == [{(f"n{y}",) for y in reach}]


def test_a_linear_hypothesis_is_never_tabled():
    """A linear hypothesis may be used once: answers found with it are not the goal's in
    general, so the search runs untabled (the same answers)."""
    text = (f"{HEADER}\ne0 : e n0 n1.\n"
            "#query * * * 1 e n1 n2 -o eq (s z) n0 Y.\n")
    assert with_big_stack(answers, text, True) == with_big_stack(answers, text, False)


PARITY = ROOT / "tests" / "roar" / "parity"


@pytest.mark.parametrize("spec, request_", [
    ("models/faulty/aim.roar", "arm::pos == 5"),
    ("models/faulty/ensure_slammed.roar", "user::done == true"),
    ("models/conflict.roar", "mission::done == true"),
    ("tests/roar/parity/where_two_clauses.roar", "a::done == true"),
])
def test_the_compiler_s_tabled_entailment_gives_the_untabled_model(spec, request_, monkeypatch):
    import roar_formal.roar.compile as compile_mod
    from roar_formal.roar.spec import load_spec

    def text() -> str:
        return with_big_stack(compile_mod.compile_spec, load_spec(ROOT / spec), request_).spec_text

    tabled = text()
    monkeypatch.setattr(compile_mod, "TABLED", frozenset())
    assert text() == tabled
    assert "cands" in tabled
