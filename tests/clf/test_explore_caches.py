"""The explorer's shortcuts in the engine, each against the plain computation it replaces:

* ``Context.copy`` (indexes shared per family until one side changes them, the other
  families rebuilt) against a copy made by re-adding every fact, as the engine did: same
  facts and the same order in every bag (the explorer's order of steps follows it), and
  neither context sees the other's later changes;
* ``enabled_steps`` (templates ruled out by their rigid paths, matches collected by
  ``all_matches``) against ``find_matches`` over every template;
* ``canonical_key``'s result cached on the context, against recomputing it;
* the memo of proved premises, against proving afresh (same steps, same fresh-name
  numbering afterwards).
"""

from __future__ import annotations

import random
from collections import deque

import pytest

from roar_formal.clf import backward, state
from roar_formal.clf.context import Context
from roar_formal.clf.forward import multiset_key, enabled_steps, find_matches
from roar_formal.clf.program import Program
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.rules import AFF, LIN, PERS
from roar_formal.clf.signature import ExecDirective
from roar_formal.clf.state import canonical_key
from roar_formal.clf.terms import Const, Param, Root
from repo import ROOT

MODELS = ROOT / "models" / "clf"


# ---------------------------------------------------------------- Context.copy

def reference_copy(ctx: Context) -> Context:
    """A copy made by re-adding every fact and rule (the engine's original ``copy``)."""
    c = Context()
    for mode, t, n in ctx.facts():
        for _ in range(n):
            c.add_fact(t, mode)
    for r in ctx.rules.values():
        c.add_rule(r.alts, r.env, r.mode, r.source, r.uid)
    c.inert = list(ctx.inert)
    c.implicit = ctx.implicit
    return c


def layout(ctx: Context) -> tuple:
    """Facts per mode in order, and every non-empty bag of the indexes in order."""
    index = {fam: list(b.items) for fam, b in ctx.index.items() if b.items}
    by_arg = {}
    for fam, per in ctx.by_arg.items():
        dicts = tuple({a: list(b.items) for a, b in d.items() if b.items} for d in per)
        if any(dicts):
            by_arg[fam] = dicts
    return list(ctx.lin.items()), list(ctx.aff.items()), list(ctx.pers), index, by_arg


def consistent(ctx: Context) -> bool:
    """The indexes hold exactly the facts present, each under its arguments."""
    present = set(ctx.lin) | set(ctx.aff) | set(ctx.pers)
    indexed = {t for b in ctx.index.values() for t in b.items}
    if indexed != present:
        return False
    for t in present:
        for j, a in enumerate(t.args):
            if t not in ctx.by_arg[t.head][j][a]:
                return False
    return True


def _universe() -> list:
    c = [Root(Const(f"c{i}"), ()) for i in range(3)] + [Root(Param("p"), ()) for _ in range(2)]
    facts = [Root(Const("f0"), (a,)) for a in c]
    facts += [Root(Const("f1"), (a, b)) for a in c for b in c[:3]]
    facts += [Root(Const("f2"), (a, c[0], b)) for a in c[:3] for b in c]
    facts += [Root(Const("g"), ())]
    return facts


@pytest.mark.parametrize("seed", range(12))
def test_copy_keeps_the_order_re_adding_gives_and_isolates_both_sides(seed):
    rng = random.Random(seed)
    facts = _universe()
    # each context of the pool is mirrored by one built the original way (fresh rebuilds)
    first = Context()
    pool = [(first, Context())]
    for _ in range(400):
        k = rng.randrange(len(pool))
        ctx, mirror = pool[k]
        op = rng.random()
        if op < 0.45:
            t, mode = rng.choice(facts), rng.choice((LIN, LIN, LIN, AFF, PERS))
            ctx.add_fact(t, mode)
            mirror.add_fact(t, mode)
        elif op < 0.85:
            have = [(LIN, t) for t in ctx.lin] + [(AFF, t) for t in ctx.aff]
            if not have:
                continue
            mode, t = rng.choice(have)
            ctx.remove_fact(t, mode)
            mirror.remove_fact(t, mode)
        else:
            new = ctx.copy()
            assert layout(new) == layout(reference_copy(ctx))
            pool.append((new, reference_copy(mirror)))
            if len(pool) > 8:
                pool.pop(rng.randrange(len(pool) - 1))
        for c, m in pool:
            assert layout(c) == layout(m)
            assert consistent(c)


def test_a_copy_of_an_untouched_copy_shares_and_still_isolates():
    facts = _universe()
    a = Context()
    for t in facts[:10]:
        a.add_fact(t, LIN)
    b = a.copy()
    c = b.copy()  # b is unchanged since it was made: c shares every family with it
    assert all(c.index[f] is b.index[f] for f in c.index)
    c.remove_fact(facts[0], LIN)
    c.add_fact(facts[12], LIN)
    assert facts[0] in b.index[facts[0].head].items and facts[0] not in c.index[facts[0].head].items
    assert layout(b) == layout(reference_copy(a))
    assert consistent(b) and consistent(c)


# ---------------------------------------------------------------- enabled_steps

def reference_steps(templates, ctx: Context, prover) -> list:
    """Every distinct enabled step, by ``find_matches`` over every template (the engine's
    original ``enabled_steps``)."""
    seen: set = set()
    out = []
    for t in templates:
        if not t.forward:
            continue
        b = [None] * t.nslots
        for consumed in find_matches(ctx, t, b, -1, prover, all_modes=True):
            key = (id(t), tuple(b), multiset_key(consumed))
            if key not in seen:
                seen.add(key)
                out.append((t, None, tuple(b), tuple(consumed)))
    for r in list(ctx.rules.values()):
        for t in r.alts:
            if t.forward:
                b = list(r.env)
                for consumed in find_matches(ctx, t, b, -1, prover, all_modes=True):
                    out.append((t, r.uid, tuple(b), tuple(consumed)))
    return out


def _steps(program, ctx) -> list:
    return [(c.template, c.ctx_rule, c.bindings, c.consumed)
            for c in enabled_steps(program.templates, ctx, program.prover())]


def _starts():
    out = []
    for path in sorted(MODELS.glob("*.clf")):
        program = Program.from_file(path)
        execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
        for i, d in enumerate(execs):
            out.append(pytest.param(program, d.start, id=f"{path.stem}-{i + 1}"))
    return out


@pytest.mark.parametrize("program,start", _starts())
def test_enabled_steps_are_those_of_find_matches_in_the_same_order(program, start):
    def go():
        ctx0 = program.start_context(start)
        queue = deque([ctx0])
        seen = {canonical_key(ctx0)}
        n = 0
        while queue and n < 60:
            ctx = queue.popleft()
            n += 1
            steps = _steps(program, ctx)
            assert steps == reference_steps(program.templates, ctx, program.prover())
            first = list(enabled_steps(program.templates, ctx, program.prover(), first_only=True))
            assert [(c.template, c.ctx_rule, c.bindings, c.consumed) for c in first] == steps[:1]
            for choice in program.steps(ctx):
                nxt, _ = program.successor(ctx, choice)
                k = canonical_key(nxt)
                if k not in seen:
                    seen.add(k)
                    queue.append(nxt)

    with_big_stack(go)


# ---------------------------------------------------------------- canonical_key's cache

SRC = """
dest : type.
tok : dest -> type.
link : dest -> dest -> type.
go : type.
mk : go -o {Exists a. Exists b. tok a * link a b}.
"""


def test_the_cached_key_follows_every_change_of_the_context():
    p = Program.from_text(SRC + "#exec * go * go.")
    ctx = p.start_context(p.sig.directives[0].start)
    (choice,) = {c.rule: c for c in p.steps(ctx)}.values()
    nxt, _ = p.successor(ctx, choice)
    k = canonical_key(nxt)
    assert canonical_key(nxt) is k  # cached
    tok = next(t for t in nxt.lin if t.head.name == "tok")
    for change in (lambda: nxt.add_fact(tok, LIN), lambda: nxt.remove_fact(tok, LIN),
                   lambda: nxt.remove_fact(tok, LIN), lambda: nxt.add_fact(tok, PERS),
                   lambda: nxt.inert.append((LIN, tok))):
        change()
        assert canonical_key(nxt) == state._canonical_key(nxt, 3) == canonical_key(reference_copy(nxt))
    assert canonical_key(nxt) != k


# ---------------------------------------------------------------- the premise memo

PROVED = """
nat : type.
z : nat.
s : nat -> nat.
plus : nat -> nat -> nat -> type.
plus_z : plus z N N.
plus_s : plus (s M) N (s K) <- plus M N K.
cnt : nat -> type.
inc : nat -> type.
step : cnt A * inc B * !plus A B C -o {cnt C}.
again : cnt A -o {inc A}.
"""


def test_memoised_premises_give_the_same_steps_and_fresh_name_numbering():
    p = Program.from_text(PROVED + "#exec 3 cnt (s z) * inc (s (s z)).")
    start = p.sig.directives[0].start

    def go():
        ctx = p.start_context(start)
        p.__dict__.pop("_premise_memo", None)
        before = backward._next_param_id()
        cold = _steps(p, ctx)
        used = backward._next_param_id() - before
        assert p._premise_memo  # the proof was memoised
        before = backward._next_param_id()
        warm = _steps(p, ctx)
        assert warm == cold
        assert backward._next_param_id() - before == used  # the ids the search would have taken
        assert [c[0].name for c in cold] == ["step", "again"]

    with_big_stack(go)
