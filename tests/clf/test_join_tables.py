"""The explorer's table of joins (``forward._table_steps``), against the plain search it replaces.

A state made by a step keeps its parent's joins that use no consumed fact and adds those that
use an added one; its steps must be exactly those of the plain search (``find_matches`` over
every template, the engine's reference enumeration), in the same order, with the same fresh ids
taken by the proved premises. Checked step by step along random walks over random contexts of
a small program (joins over shared slots, constants and nested patterns, persistent proved
premises, several matches of one rule, fresh names), the walk going through planned successors
(which carry the table), plain successors, copies and thawed states (which find it afresh);
then on compiled ROAR models, whole explorations with and without tables compared edge for
edge, state for state and name for name. The helpers the table uses (rigid paths per family,
the premises a fact may match) are checked against what they stand for.
"""

from __future__ import annotations

import itertools
import random

import pytest

from roar_formal.clf import forward, terms
from roar_formal.clf.context import FrozenContext
from roar_formal.clf.forward import (build_planned, enabled_steps, find_matches, multiset_key, plan_successor,
                                     successor)
from roar_formal.clf.program import Program
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.signature import ExecDirective
from roar_formal.clf.terms import next_param_id

from repo import ROOT

SIG = """
nat : type.
z : nat.
s : nat -> nat.
d : type.
d1 : d.
d2 : d.
d3 : d.
plus : nat -> nat -> nat -> type.
plus_z : plus z N N.
plus_s : plus (s M) N (s K) <- plus M N K.
lt : nat -> nat -> type.
lt_z : lt z (s N).
lt_s : lt (s M) (s N) <- lt M N.
a : d -> nat -> type.
b : d -> d -> type.
c : nat -> type.
tok : type.
r1 : a X N * b X Y -o {a Y N * b Y X}.
r2 : a X N * c M * !plus N M K * !lt K (s (s (s (s z)))) -o {a X K}.
r3 : a X N * a Y M * !lt N M -o {b X Y}.
r4 : c (s N) -o {c N * tok}.
r5 : tok * a X z -o {Exists y. a y (s z) * b X y}.
r6 : b X X * tok -o {c z}.
r7 : a X (s (s N)) * b Y X * !plus N N M -o {c M}.
r8 : b X Y * b Y X * c N -o {a X N}.
"""

NATS = ["z", "(s z)", "(s (s z))", "(s (s (s z)))"]
DS = ["d1", "d2", "d3"]


def _random_start(rng: random.Random) -> str:
    facts = set()
    for _ in range(rng.randint(2, 9)):
        kind = rng.choice("aabbct")
        if kind == "a":
            facts.add(f"a {rng.choice(DS)} {rng.choice(NATS)}")
        elif kind == "b":
            facts.add(f"b {rng.choice(DS)} {rng.choice(DS)}")
        elif kind == "c":
            facts.add(f"c {rng.choice(NATS)}")
        else:
            facts.add("tok")
    return " * ".join(sorted(facts))


def reference_steps(templates, ctx, prover) -> list:
    """Every distinct enabled step by ``find_matches`` over every template, in order."""
    out = []
    seen: set = set()
    for t in templates:
        if not t.forward:
            continue
        b = [None] * t.nslots
        for consumed in find_matches(ctx, t, b, -1, prover, all_modes=True):
            key = (id(t), tuple(b), multiset_key(consumed))
            if key not in seen:
                seen.add(key)
                out.append((t, tuple(b), tuple(consumed)))
    return out


def _table_path_taken(program, ctx) -> bool:
    return forward._joins_meta(forward._filters(program.templates)[0]) is not None and \
        not ctx.aff and not ctx.pers and len(ctx.lin) == sum(ctx.lin.values())


@pytest.mark.parametrize("seed", range(30))
def test_steps_by_tables_are_the_plain_searchs_step_by_step(seed):
    rng = random.Random(seed)
    p = Program.from_text(SIG + "".join(f"#exec * {_random_start(rng)}.\n" for _ in range(8)))
    prover = p.prover()
    starts = [d.start for d in p.sig.directives]

    def go():
        ctx = p.start_context(starts.pop())
        carried = 0
        for _ in range(60):
            if ctx._delta is not None and ctx._delta[0] is not None:
                carried += 1   # (made by a step from a state with a table: its table is carried)
            first = next_param_id()
            choices = list(enabled_steps(p.templates, ctx, prover))
            used = next_param_id() - first
            got = [(c.template, c.bindings, c.consumed) for c in choices]
            first = next_param_id()
            want = reference_steps(p.templates, ctx, prover)
            assert got == want
            assert used == next_param_id() - first   # the fresh ids the proofs take
            if _table_path_taken(p, ctx):
                assert ctx._table is not None
            if not got:
                if not starts:
                    break
                ctx = p.start_context(starts.pop())   # (a walk ended: another start)
                continue
            choice = rng.choice(choices)
            how = rng.random()
            if how < 0.7:
                planned = plan_successor(ctx, choice)
                nxt = build_planned(ctx, planned[1]) if planned is not None else successor(ctx, choice)[0]
            elif how < 0.85:
                nxt = successor(ctx, choice)[0]
            else:
                nxt = FrozenContext(successor(ctx, choice)[0]).thaw()   # (no table: found afresh)
            if rng.random() < 0.1:
                nxt = nxt.copy()
            ctx = nxt
        return carried

    assert with_big_stack(go) >= 3   # (states whose steps came from their parent's table)


def test_a_changed_context_forgets_its_table():
    p = Program.from_text(SIG + "#exec * a d1 z * b d1 d2 * c (s z) * tok.")
    ctx = p.start_context(p.sig.directives[0].start)
    steps = p.steps(ctx)
    assert ctx._table is not None
    planned = plan_successor(ctx, steps[0])
    nxt = build_planned(ctx, planned[1])
    assert nxt._delta is not None and nxt._delta[0] is ctx._table
    a = next(t for t in nxt.lin if t.head.name == "a")
    nxt.remove_fact(a, "1")   # a change the delta does not describe
    assert nxt._delta is None
    prover = p.prover()
    assert [(c.template, c.bindings, c.consumed) for c in enabled_steps(p.templates, nxt, prover)] == \
        reference_steps(p.templates, nxt, prover)


@pytest.mark.parametrize("seed", range(6))
def test_rigid_paths_per_family_and_premises_a_fact_may_match(seed):
    rng = random.Random(seed)
    p = Program.from_text(SIG + f"#exec * {_random_start(rng)}.")
    pairs = forward._filters(p.templates)[0]
    meta = forward._joins_meta(pairs)
    assert meta is not None
    ctx = p.start_context(p.sig.directives[0].start)
    for _ in range(15):
        have = forward._context_paths(ctx)
        for t, need in pairs:
            assert forward._has_paths(ctx, t) == (need <= have)
        for fact in ctx.lin:
            listed = set(forward._premises_of(meta, fact))
            for i, (t, _need) in enumerate(pairs):
                plan, ctx_list, _back = forward._plans(t)
                for j, prem in enumerate(ctx_list):
                    b = [None] * t.nslots
                    if prem.family is fact.head and forward.match(prem.pattern, fact, b, []):
                        assert (i, j) in listed   # a premise the fact matches is never missed
        steps = p.steps(ctx)
        if not steps:
            break
        ctx, _ = p.successor(ctx, rng.choice(steps))


# ---------------------------------------------------------------- ROAR models, whole explorations

SPECS = [
    (ROOT / "models" / "faulty" / "camera_retry.roar", "camera::taken == true", 400),
    (ROOT / "models" / "faulty" / "ensure_slammed.roar", "user::done == true", 700),
]


def _explore(model, start, first_id: int, budget: int) -> tuple:
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import Options
    from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem

    terms._param_ids = itertools.count(first_id)   # both searches number their fresh names alike
    ex = Explorer(RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent")))
    ex.run(Budget(max_states=budget))
    g = ex.graph
    arrays = [list(a) for a in (g.src, g.dst, g.label, g.group, g.progress, g.parent, g.depth)]
    return arrays, [g.describe_state(i) for i in range(g.n_states)], \
        [g.describe_edge(e) for e in range(g.n_edges)], terms.next_param_id() - first_id


@pytest.mark.parametrize("spec,request_,budget", SPECS, ids=[s[0].stem for s in SPECS])
def test_roar_explorations_with_tables_are_those_without(spec, request_, budget, monkeypatch):
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.spec import load_spec

    calls = []
    real = forward._delta_entry

    def counting(*a):
        calls.append(1)
        return real(*a)

    def go():
        model = compile_spec(load_spec(spec), request_)
        program = model.program()
        d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        start = program.start_context(d.start)
        first_id = terms.next_param_id() + 1_000_000
        with monkeypatch.context() as m:
            m.setattr(forward, "_joins_meta", lambda pairs: None)   # the plain search in every state
            plain = _explore(model, start, first_id, budget)
        with monkeypatch.context() as m:
            m.setattr(forward, "_delta_entry", counting)
            tables = _explore(model, start, first_id, budget)
        return plain, tables

    plain, tables = with_big_stack(go)
    assert len(plain[1]) > 50
    assert tables == plain   # graph, states, steps, fresh names and ids taken
    assert len(calls) > len(plain[1])   # (the tables were carried from state to state)


# ---------------------------------------------------------------- the one-pass key of linear contexts

@pytest.mark.parametrize("spec,request_,budget", SPECS[:1] + [(s, r, 300) for s, r, _b in SPECS[1:]],
                         ids=[s[0].stem for s in SPECS])
def test_one_pass_keys_of_linear_contexts_are_the_general_loops(spec, request_, budget, monkeypatch):
    """``state._lin_key`` (one pass over a context of linear facts) gives the bytes the general
    loop of ``state._fast_key`` gives, on every state of an exploration and on each successor
    planned from it; and the keys tell states apart as the first-occurrence numbering does."""
    from roar_formal.clf import state
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import Options
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem
    from roar_formal.roar.spec import load_spec

    def go():
        model = compile_spec(load_spec(spec), request_)
        program = model.program()
        d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        ex = Explorer(RoarSystem(model, program.start_context(d.start),
                                 Options(progress_rules=PROGRESS_RULES, fairness="agent")))
        ex.run(Budget(max_states=budget))
        views = []
        for i in range(ex.graph.n_states):
            ctx = ex.states[i]
            views.append(ctx)
            for choice in program.steps(ctx):
                planned = plan_successor(ctx, choice)
                if planned is not None:
                    views.append(planned[0])
        fast = [state._lin_key(v.lin) for v in views]
        with monkeypatch.context() as m:
            m.setattr(state, "_lin_key", lambda lin: None)   # the general loop only
            general = [state._fast_key(v, 3) for v in views]
        numbered = [state._numbered_key(v, 3) for v in views]
        return fast, general, numbered

    fast, general, numbered = with_big_stack(go)
    assert sum(k is not None for k in fast) > len(fast) // 2
    for a, b in zip(fast, general):
        assert a is None or a == b
    # the same partition of the states as the numbering by first occurrence (where it is exact)
    pairs = {}
    for g, n in zip(general, numbered):
        if g is not None:
            assert pairs.setdefault(g, n) == n
