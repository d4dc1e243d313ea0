"""Successors keyed before they are built, expanded states dropped and rebuilt from an ancestor,
rules without a match remembered (benchmark B8: states per second, bytes per state). Each is
checked against the search it replaces: the same graph edge for edge, the same states with the
same fresh names, the same step descriptions."""

from __future__ import annotations

import itertools

import pytest

from roar_formal.clf import forward, terms
from roar_formal.clf.context import FrozenContext
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.signature import ExecDirective
from roar_formal.explore import search
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import Options
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem
from roar_formal.roar.spec import load_spec

from repo import ROOT

SPECS = [
    (ROOT / "models" / "faulty" / "camera_retry.roar", "camera::taken == true"),
    (ROOT / "models" / "faulty" / "ensure_slammed.roar", "user::done == true"),
]


def _system(model, start, lazy: bool):
    system = RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent"))
    if not lazy:
        system.lazy_successors = lambda state: None   # every successor built, none dropped
    return system


def _explore(model, start, lazy: bool, first_id: int) -> tuple:
    """The graph, every state and every step as printed (fresh names included), the fresh ids taken."""
    terms._param_ids = itertools.count(first_id)   # both searches number their fresh names alike
    ex = Explorer(_system(model, start, lazy))
    ex.run(Budget(max_states=1200))
    g = ex.graph
    arrays = [list(a) for a in (g.src, g.dst, g.label, g.group, g.progress, g.parent, g.depth)]
    return (arrays, [g.describe_state(i) for i in range(g.n_states)], [g.describe_edge(e) for e in range(g.n_edges)],
            terms.next_param_id()), ex


@pytest.mark.parametrize("spec,request_", SPECS, ids=[s[0].stem for s in SPECS])
def test_lazy_successors_dropped_states_and_remembered_misses_change_nothing(spec, request_, monkeypatch):
    def go():
        model = compile_spec(load_spec(spec), request_)
        program = model.program()
        d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        start = program.start_context(d.start)
        first_id = terms.next_param_id() + 1_000_000   # (past every name made so far)
        with monkeypatch.context() as m:
            m.setattr(forward, "_zero_remember", lambda key, ids: None)   # no memo of missing matches
            eager, _ = _explore(model, start, False, first_id)
        lazy, ex = _explore(model, start, True, first_id)
        assert any(k[0] in program.templates for k in forward._zero_memo)   # (the memo was used)
        return eager, lazy, ex

    eager, lazy, ex = with_big_stack(go)
    assert len(lazy[1]) == len(eager[1]) > 50
    assert lazy == eager   # graph, states, steps and fresh names
    # most expanded states were dropped, and are rebuilt as thawing would give them
    dropped = [i for i, x in enumerate(ex.states.items) if x is None]
    assert len(dropped) > len(ex.states.items) // 3
    for i in dropped[::5]:
        ex.states.recent.clear()
        a = ex.states[i]
        b = FrozenContext(a).thaw()
        assert list(map(str, a.facts())) == list(map(str, b.facts()))
        assert [(c.rule, c.consumed) for c in ex.system.program.steps(a)] == \
               [(c.rule, c.consumed) for c in ex.system.program.steps(b)]
    assert all(ex.states.items[i] is not None for i in range(ex.graph.n_states)
               if ex.graph.depth[i] % search.REPLAY_SPAN == 0)
