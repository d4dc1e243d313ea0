"""The ground backend's compact graph (GroundGraph) against the general backend, edge for edge.

The ground backend stores edges as target, instance and per-state out-degree, a state's
creating edge as its position among its parent's edges, and its states under a key that
leaves out the columns place invariants fix; every other column is computed when read. These
tests read every column and compare it with the general backend's eagerly built graph (states
matched through their printed facts, so numbering differences cannot hide a wrong edge), and
check the key reduction on random nets.
"""

from __future__ import annotations

import importlib.util
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from roar_formal.clf.program import Program
from roar_formal.explore.ground import GroundExplorer, GroundModel, key_basis
from roar_formal.explore.properties import check_deadlock, check_livelock
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import ClfSystem, Options

from repo import ROOT

_spec = importlib.util.spec_from_file_location("phil_gen", ROOT / "models/philosophers/generate.py")
gen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen)

OPTIONS = Options(progress_rules=("eat",))


def _state_names(g) -> list:
    return [tuple(sorted(x.strip() for x in g.describe_state(s))) for s in range(g.n_states)]


def _edge_multiset(g) -> Counter:
    names = _state_names(g)
    a = g.arrays()
    return Counter((names[int(s)], g.labels.names[int(lb)], g.groups.names[int(gr)], bool(p), names[int(d)])
                   for s, d, lb, gr, p in zip(a["src"], a["dst"], a["label"], a["group"], a["progress"]))


def _consistent(g) -> None:
    """Every lazily computed column agrees with the others."""
    a = g.arrays()
    n = g.n_states
    assert len(a["src"]) == len(a["dst"]) == len(a["label"]) == len(a["group"]) == len(a["progress"]) == g.n_edges
    assert np.all(np.diff(a["src"]) >= 0)  # edges by source
    assert np.array_equal(g.out_degree(), np.bincount(a["src"], minlength=n))
    assert np.array_equal(np.asarray(g.src), a["src"]) and np.array_equal(np.asarray(g.dst), a["dst"])
    assert np.array_equal(np.asarray(g.progress).astype(bool), a["progress"])
    assert int(g.parent[0]) == -1 and int(g.parent_edge[0]) == -1 and int(g.depth[0]) == 0
    for s in range(1, n):
        e = int(g.parent_edge[s])
        assert int(a["src"][e]) == int(g.parent[s]) and int(a["dst"][e]) == s
        assert int(g.depth[s]) == int(g.depth[int(g.parent[s])]) + 1
        # the creating edge is the first edge into s (breadth-first discovery order)
        assert e == int(np.flatnonzero(a["dst"] == s)[0])
    assert list(g.path_to(n - 1)) == [int(x) for x in g.path_to(n - 1)]


def _both(src: str, opts: Options):
    p = Program.from_text(src)
    start = p.start_context(p.sig.directives[0].start)
    return (GroundExplorer(GroundModel(p, start, opts)).run(), Explorer(ClfSystem(p, start, opts)).run())


@pytest.mark.parametrize("variant", ["dl", "ok", "ll"])
@pytest.mark.parametrize("n", [3, 4])
def test_the_compact_graph_is_the_general_backends_graph(variant, n):
    g1, g2 = _both(gen.program(variant, n), OPTIONS)
    _consistent(g1)
    assert (g1.n_states, g1.n_edges) == (g2.n_states, g2.n_edges)
    assert _edge_multiset(g1) == _edge_multiset(g2)
    assert sorted(_state_names(g1)) == sorted(_state_names(g2))
    # breadth-first depth of each state, and the verdicts with their counterexample lengths
    d1 = dict(zip(_state_names(g1), np.asarray(g1.depth).tolist()))
    d2 = dict(zip(_state_names(g2), np.asarray(g2.depth).tolist()))
    assert d1 == d2
    for check in (check_deadlock, check_livelock):
        a, b = check(g1), check(g2)
        assert a.status == b.status
        if check is check_deadlock and a.counterexample:
            assert a.counterexample.length() == b.counterexample.length()


def test_a_deadlock_counterexample_is_a_path_of_the_model():
    g, _ = _both(gen.program("dl", 5), OPTIONS)
    v = check_deadlock(g)
    assert v.violated and v.counterexample.length() == 5
    a = g.arrays()
    state = 0
    for e in v.counterexample.prefix:
        assert int(a["src"][e]) == state
        assert g.describe_edge(e)["rule"] == "take_first"
        state = int(a["dst"][e])
    assert state == v.counterexample.final_state and g.out_degree()[state] == 0
    assert sorted(x for x in g.describe_state(state) if x.startswith("at")) == [f"at1 p{i}" for i in range(5)]


def test_a_partial_search_expands_a_prefix_of_the_states():
    p = Program.from_text(gen.program("ok", 5))
    start = p.start_context(p.sig.directives[0].start)
    g = GroundExplorer(GroundModel(p, start, OPTIONS)).run(Budget(max_states=100))
    assert not g.complete and "state budget" in g.stop_reason
    _consistent(g)
    exp = np.asarray(g.expanded, dtype=bool)
    k = int(exp.sum())
    assert exp[:k].all() and not exp[k:].any() and k < g.n_states
    assert np.all(g.out_degree()[k:] == 0) and np.all(g.out_degree()[:k] > 0)


@st.composite
def nets(draw):
    m = draw(st.integers(1, 6))
    n = draw(st.integers(1, 8))
    delta = np.array(draw(st.lists(st.lists(st.integers(-2, 2), min_size=n, max_size=n), min_size=m, max_size=m)),
                     dtype=np.int64)
    # make some columns combinations of others, as place invariants do
    if n >= 3 and draw(st.booleans()):
        delta[:, -1] = -delta[:, 0] - delta[:, 1]
    return delta


@settings(max_examples=200, deadline=None)
@given(nets(), st.data())
def test_the_key_reduction_is_exact(delta, data):
    basis, dropped, coef = key_basis(delta)
    assert sorted(np.concatenate([basis, dropped]).tolist()) == list(range(delta.shape[1]))
    start = np.array(data.draw(st.lists(st.integers(0, 5), min_size=delta.shape[1], max_size=delta.shape[1])))
    for _ in range(5):
        x = np.array(data.draw(st.lists(st.integers(0, 4), min_size=len(delta), max_size=len(delta))))
        row = start + x @ delta
        rebuilt = start[dropped] + (row[basis] - start[basis]) @ coef
        assert np.array_equal(rebuilt, row[dropped])


def test_without_targets_the_deadlock_check_is_the_same_and_reading_targets_fails_loudly():
    from roar_formal.explore.ground import TargetsNotKept
    for variant in ("dl", "ok"):
        p = Program.from_text(gen.program(variant, 5))
        start = p.start_context(p.sig.directives[0].start)
        full = GroundExplorer(GroundModel(p, start, OPTIONS)).run()
        lean = GroundExplorer(GroundModel(p, start, OPTIONS), keep_targets=False).run()
        assert (lean.n_states, lean.n_edges) == (full.n_states, full.n_edges)
        a, b = check_deadlock(full), check_deadlock(lean)
        assert (a.status, a.message) == (b.status, b.message)
        if a.counterexample:
            assert a.counterexample.prefix == b.counterexample.prefix
            assert [lean.describe_edge(e) for e in b.counterexample.prefix] == \
                [full.describe_edge(e) for e in a.counterexample.prefix]
            assert [int(lean.group[e]) for e in b.counterexample.prefix] == \
                [int(full.group[e]) for e in a.counterexample.prefix]
        with pytest.raises(TargetsNotKept):
            check_livelock(lean)
