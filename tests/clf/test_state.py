"""States as values: equal up to renaming of fresh names, never merged otherwise."""

from hypothesis import given, settings, strategies as st

from roar_formal.clf.program import Program
from roar_formal.clf.state import canonical_key

SRC = """
dest : type.
tok : dest -> type.
link : dest -> dest -> type.
go : type.
stop : type.
mk : go -o {Exists a. Exists b. tok a * link a b}.
swap : tok A * link A B -o {tok B * link A B}.
"""


def _run(program, start, seed, steps=None):
    ctx = program.start_context(start)
    program.run(ctx, steps, seed=seed)
    return ctx


def test_runs_with_different_fresh_names_are_one_state():
    p = Program.from_text(SRC.replace("swap :", "% swap :") + "#exec 2 go * go.")
    start = p.sig.directives[0].start
    a = _run(p, start, seed=1)
    b = _run(p, start, seed=5)
    names_a = {f.args[0].head for f in a.lin if f.head.name == "tok"}
    names_b = {f.args[0].head for f in b.lin if f.head.name == "tok"}
    assert names_a.isdisjoint(names_b)  # really different fresh names
    assert canonical_key(a) == canonical_key(b)


def test_different_link_structure_is_not_merged():
    p = Program.from_text(SRC + "#exec 3 go * go.")
    two = p.start_context(p.sig.directives[0].start)
    for _ in range(2):  # fire mk twice: tok a1, link a1 b1, tok a2, link a2 b2
        (mk,) = [c for c in p.steps(two) if c.rule == "mk"]
        two, _ = p.successor(two, mk)
    three = two.copy()
    choices = [c for c in p.steps(three) if c.rule == "swap"]
    assert len(choices) == 2  # either token can move along its link
    moved, _ = p.successor(three, choices[0])
    assert canonical_key(moved) != canonical_key(two)
    # moving either token gives isomorphic states
    other, _ = p.successor(three, choices[1])
    assert canonical_key(moved) == canonical_key(other)


def test_successor_leaves_the_state_unchanged():
    p = Program.from_text(SRC + "#exec * go.")
    ctx = p.start_context(p.sig.directives[0].start)
    before = canonical_key(ctx)
    (choice,) = p.steps(ctx)
    after, step = p.successor(ctx, choice)
    assert canonical_key(ctx) == before
    assert step.rule == "mk"
    assert canonical_key(after) != before


# ---------------------------------------------------------------- keys of scrambled copies

# Two continuations of one rule, each holding fresh names of its own (one of them with a fact
# of its own too): refinement leaves the names tied, and numbering them in the order the
# context held them gave isomorphic states two keys.
TIED = """k : type. k0 : k. k1 : k.
p : k -> type. c0 : k -> type. c2 : k -> type. c3 : k -> type.
r2 : c2 X -o {Exists n22:k. Exists n23:k. c0 n22 * !(Pi y24:k. c0 y24 -o {p n23 * p k0})}.
r3 : c3 Y -o {c2 k1}.
#exec * @c3 k0 * @c3 k0.
"""


def _scrambled(ctx, rnd):
    """A copy of ``ctx`` with its fresh names renamed (new names) and its facts and rules put
    in in another order: isomorphic to ``ctx`` by construction."""
    from roar_formal.clf.context import Context
    from roar_formal.clf.terms import Node, Param
    from roar_formal.clf.state import _rename

    ren = {p: Param(p.hint) for p in _names(ctx)}
    new = lambda t: _rename(t, ren, {}) if isinstance(t, Node) else t
    items = [("f", m, t) for m, t, n in ctx.facts() for _ in range(n)]
    items += [("r", r, None) for r in ctx.rules.values()]
    rnd.shuffle(items)
    out = Context()
    out.implicit = ctx.implicit
    for kind, a, b in items:
        if kind == "f":
            out.add_fact(new(b), a)
        else:
            out.add_rule(a.alts, tuple(new(v) for v in a.env), a.mode, new(a.source))
    return out


def _reached(src: str, limit: int = 400):
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import ClfSystem, Options

    prog = Program.from_text(src)
    ex = Explorer(ClfSystem(prog, prog.start_context(prog.sig.directives[-1].start), Options()))
    g = ex.run(Budget(max_states=limit, max_seconds=20))
    return [ex.states[s] for s in range(g.n_states)]


def test_isomorphic_states_with_tied_names_in_rules_get_one_key():
    import random
    rnd = random.Random(3)
    states = _reached(TIED)
    tied = [s for s in states if len(s.rules) == 2]
    assert tied
    for s in tied:
        for _ in range(6):
            assert canonical_key(_scrambled(s, rnd)) == canonical_key(s)


@settings(max_examples=60, deadline=None)
@given(st.randoms(use_true_random=False))
def test_every_reached_state_and_its_scrambled_copies_have_one_key(rnd):
    """Leveled random programs (fresh names in facts and in rules of every mode, nested): each
    state reached, rebuilt with new names in a random order, keeps its key."""
    from leveled import leveled_program

    for s in _reached(leveled_program(rnd), 150):
        assert canonical_key(_scrambled(s, rnd)) == canonical_key(s)


def _names(ctx) -> list:
    """The fresh names of a state, in the order its facts, then its rules, hold them."""
    from roar_formal.clf.terms import Node, params_of
    names: dict = {}
    for _m, t, _n in ctx.facts():
        params_of(t, names)
    for r in ctx.rules.values():
        for v in r.env:
            if isinstance(v, Node):
                params_of(v, names)
    return list(names)


def _plain(ctx, ren: dict):
    """The state's hypotheses with its names renamed by ``ren``, as a multiset (no canonical form)."""
    from collections import Counter
    from roar_formal.clf.state import _rename
    from roar_formal.clf.terms import Node
    new = (lambda t: _rename(t, ren, {}) if isinstance(t, Node) else t)
    c: Counter = Counter()
    for m, t, n in ctx.facts():
        c[(m, new(t))] += n
    for r in ctx.rules.values():
        c[("rule", id(r.alts[0]) if r.alts else 0, tuple(new(v) for v in r.env), r.mode)] += 1
    return c


def _isomorphic(a, b) -> bool:
    """By brute force: some bijection between the two states' fresh names maps one onto the other."""
    import itertools
    na, nb = _names(a), _names(b)
    if len(na) != len(nb):
        return False
    target = _plain(b, {})
    return any(_plain(a, dict(zip(na, perm))) == target for perm in itertools.permutations(nb))


@settings(max_examples=25, deadline=None)
@given(st.randoms(use_true_random=False))
def test_keys_are_equal_exactly_for_isomorphic_states(rnd):
    """Soundness and completeness against brute force: the exact states a search reaches (compared
    without renaming) grouped by canonical key; within a group every state is an isomorphic copy
    of the first, and no two groups' first states are isomorphic (states with at most 5 names)."""
    from leveled import leveled_program
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import ClfSystem, Options

    prog = Program.from_text(leveled_program(rnd))
    ex = Explorer(ClfSystem(prog, prog.start_context(prog.sig.directives[-1].start), Options(canonical=False)))
    g = ex.run(Budget(max_states=120, max_seconds=20))
    groups: dict = {}
    for s in range(g.n_states):
        st_ = ex.states[s]
        if len(_names(st_)) <= 5:
            groups.setdefault(canonical_key(st_), []).append(st_)
    firsts = [v[0] for v in groups.values()]
    for members in groups.values():
        for other in members[1:]:
            assert _isomorphic(members[0], other)
    for i, a in enumerate(firsts):
        for b in firsts[i + 1:]:
            assert not _isomorphic(a, b)


_FACTS = st.lists(st.tuples(st.sampled_from(["t", "l", "m"]), st.lists(st.integers(0, 3), min_size=3, max_size=3)),
                  min_size=1, max_size=6)


def _context(facts, names):
    """A context of linear facts ``t A``, ``l A B``, ``m A B C`` over the fresh names ``names``."""
    from roar_formal.clf.context import Context
    from roar_formal.clf.terms import Const, Root
    arity = {"t": 1, "l": 2, "m": 3}
    ctx = Context()
    for head, args in facts:
        ctx.add_fact(Root(Const(head), tuple(names[i] for i in args[:arity[head]])), "1")
    return ctx


@settings(max_examples=300, deadline=None)
@given(_FACTS, st.permutations(range(4)), st.integers(0, 5), st.randoms(use_true_random=False))
def test_keys_of_small_states_agree_with_brute_force(facts, perm, which, rnd):
    """A state of facts over four fresh names, and a renamed copy with one fact's arguments
    permuted (often not isomorphic: `l a b` against `l b a` where a and b differ otherwise):
    equal keys exactly when brute force finds an isomorphism."""
    from roar_formal.clf.terms import Param, Root
    names = [Root(Param("x"), ()) for _ in range(4)]
    other = [Root(Param("y"), ()) for _ in range(4)]
    a = _context(facts, names)
    changed = [list(f) for f in facts]
    i = which % len(changed)
    args = list(changed[i][1])
    rnd.shuffle(args)
    changed[i][1] = args
    rnd.shuffle(changed)
    b = _context(changed, [other[perm[j]] for j in range(4)])
    assert (canonical_key(a) == canonical_key(b)) == _isomorphic(a, b)
