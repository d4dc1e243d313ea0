"""Property-based tests of the CLF engine against independent plain oracles.

Forward chaining: random small multiset-rewriting programs (3-4 atom families
of arity 0 or 1 over 2-3 constants; 1-4 rules, each consuming 1-2 linear atoms,
optionally requiring a persistent one, and producing 0-3 atoms, some ``!`` or
``@``) and random start states. The oracle is a plain enumerator written here
over ``Counter``s, sharing no code with the engine: a state is (linear
multiset, affine multiset, persistent set) of printed atoms; a step
instantiates a rule's variables with constants, takes each linear premise from
a linear or an affine copy (consumed) or from a persistent fact (kept), checks
the persistent premises, and adds the head. Properties:

* every step of a committed-choice run (random seeds, random or fair, bounded)
  is a step of the plain semantics, so its final state is one the enumerator
  reaches in exactly as many steps;
* a run reports quiescence exactly when the plain semantics has no step;
* at every state reachable through the explorer API (bounded), the successors
  given by ``program.steps``/``program.successor`` are legal and are exactly
  the plain successors, and computing them leaves the state unchanged.

Backward chaining: random stratified propositional programs (clauses
``q o- p1 o- ... o- pm`` with premises below their head, some premises
persistent ``<-``) and goals ``h1 -o h2 -> h3 -@ ... goal`` over linear,
persistent and affine hypotheses. The number of solutions ``#query`` finds by
exhaustive backtracking is compared with a brute-force count of proof terms:
proofs of an atom that use exactly a given set of linear/affine hypotheses,
summed over the sets of affine hypotheses used.
"""

from __future__ import annotations

import itertools
from collections import Counter
from functools import lru_cache

from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from roar_formal.clf.printer import show
from roar_formal.clf.program import Program
from roar_formal.clf.query import run_query

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# =====================================================================
# Forward chaining: the plain model
# =====================================================================
#
# A program is a dict:
#   consts: ["c0", "c1", ...]
#   fams:   {"p0": 0, "p1": 1, ...}          (family -> arity)
#   rules:  [Rule], a Rule = (lin_premises, pers_premises, head)
#           premises: tuples of atoms; head: tuple of (mode, atom)
#   start:  tuple of (mode, ground atom)
# A mode is LIN, AFF ("@", affine) or PERS ("!"). An atom is (family, arg) with
# arg None (arity 0), a constant, or a variable "X"/"Y" (rules only).
# A state is (linear multiset, affine multiset, persistent set) of printed atoms.

VARS = ("X", "Y")
LIN, AFF, PERS = "lin", "aff", "pers"


def atom_text(a) -> str:
    fam, arg = a
    return fam if arg is None else f"{fam} {arg}"


def rule_vars(rule) -> list[str]:
    lin, pers, _head = rule
    return sorted({arg for _f, arg in lin + pers if arg in VARS})


def subst_atom(a, env: dict):
    fam, arg = a
    return (fam, env.get(arg, arg))


def plain_successors(state, prog) -> set:
    """Every state one step away from ``state`` (a frozen (lin, aff, pers) triple)."""
    lin_items, aff_items, pers = state
    lin = Counter(dict(lin_items))
    aff = Counter(dict(aff_items))
    out = set()
    for rule in prog["rules"]:
        lin_p, pers_p, head = rule
        vs = rule_vars(rule)
        for vals in itertools.product(prog["consts"], repeat=len(vs)):
            env = dict(zip(vs, vals))
            need_pers = [atom_text(subst_atom(a, env)) for a in pers_p]
            if any(a not in pers for a in need_pers):
                continue
            prem = [atom_text(subst_atom(a, env)) for a in lin_p]
            # each linear premise is served by a linear or an affine copy (consumed) or by a
            # persistent fact (kept)
            for sources in itertools.product((LIN, AFF, PERS), repeat=len(prem)):
                if any(src == PERS and a not in pers for a, src in zip(prem, sources)):
                    continue
                take_lin = Counter(a for a, src in zip(prem, sources) if src == LIN)
                take_aff = Counter(a for a, src in zip(prem, sources) if src == AFF)
                if any(lin[a] < k for a, k in take_lin.items()) or any(aff[a] < k for a, k in take_aff.items()):
                    continue
                new = {LIN: lin - take_lin, AFF: aff - take_aff}
                new_pers = set(pers)
                for mode, a in head:
                    t = atom_text(subst_atom(a, env))
                    if mode == PERS:
                        new_pers.add(t)
                    else:
                        new[mode][t] += 1
                out.add(freeze(new[LIN], new[AFF], new_pers))
    return out


def freeze(lin: Counter, aff: Counter, pers) -> tuple:
    return (tuple(sorted((a, k) for a, k in lin.items() if k > 0)),
            tuple(sorted((a, k) for a, k in aff.items() if k > 0)), frozenset(pers))


def plain_start(prog) -> tuple:
    lin, aff, pers = Counter(), Counter(), set()
    for mode, a in prog["start"]:
        if mode == PERS:
            pers.add(atom_text(a))
        else:
            (lin if mode == LIN else aff)[atom_text(a)] += 1
    return freeze(lin, aff, pers)


def plain_levels(prog, depth: int, cap: int = 3000) -> list[set] | None:
    """levels[d] = the states reachable in exactly d steps (None when a level exceeds ``cap``)."""
    levels = [{plain_start(prog)}]
    for _ in range(depth):
        nxt = set()
        for s in levels[-1]:
            nxt |= plain_successors(s, prog)
            if len(nxt) > cap:
                return None
        levels.append(nxt)
    return levels


# =====================================================================
# Forward chaining: programs as CLF text, and engine states as plain states
# =====================================================================


def clf_atom(a, mode: str = LIN) -> str:
    t = atom_text(a)
    if mode == PERS:
        return f"!({t})"
    if mode == AFF:
        return f"@({t})"
    return t if a[1] is None else f"({t})"


def program_text(prog) -> str:
    lines = ["k : type."]
    lines += [f"{c} : k." for c in prog["consts"]]
    for fam, ar in prog["fams"].items():
        lines.append(f"{fam} : type." if ar == 0 else f"{fam} : k -> type.")
    for i, (lin, pers, head) in enumerate(prog["rules"]):
        prems = "".join(f"{clf_atom(a)} -o " for a in lin) + "".join(f"{clf_atom(a)} -> " for a in pers)
        body = " * ".join(clf_atom(a, p) for p, a in head) if head else "1"
        lines.append(f"r{i} : {prems}{{{body}}}.")
    start = " * ".join(clf_atom(a, p) for p, a in prog["start"]) if prog["start"] else "1"
    lines.append(f"#exec * {start}.")
    return "\n".join(lines) + "\n"


def engine_state(ctx) -> tuple:
    assert not ctx.rules and not ctx.inert, "only facts are expected"
    lin, aff = Counter(), Counter()
    for t, k in ctx.lin.items():
        assert k > 0
        lin[show(t)] += k
    for t, k in ctx.aff.items():
        assert k > 0
        aff[show(t)] += k
    return freeze(lin, aff, {show(t) for t in ctx.pers})


def load(prog):
    text = program_text(prog)
    program = Program.from_text(text, "<property>")
    return program, text


def start_ctx(program):
    return program.start_context(program.sig.directives[0].start)


# =====================================================================
# Forward chaining: strategies
# =====================================================================


@st.composite
def programs(draw):
    nconst = draw(st.integers(2, 3))
    consts = [f"c{i}" for i in range(nconst)]
    nfam = draw(st.integers(3, 4))
    arities = draw(st.lists(st.integers(0, 1), min_size=nfam, max_size=nfam))
    fams = {f"p{i}": ar for i, ar in enumerate(arities)}
    fam_names = list(fams)

    def atom(allowed_args):
        fam = draw(st.sampled_from(fam_names))
        if fams[fam] == 0:
            return (fam, None)
        return (fam, draw(st.sampled_from(allowed_args)))

    # mostly linear facts; persistent and affine ones now and then
    modes = st.sampled_from((LIN, LIN, LIN, PERS, PERS, AFF))
    rules = []
    for _ in range(draw(st.integers(1, 4))):
        lin = tuple(atom(consts + list(VARS)) for _ in range(draw(st.integers(1, 2))))
        pers = tuple(atom(consts + list(VARS)) for _ in range(draw(st.integers(0, 1))))
        bound = sorted({arg for _f, arg in lin + pers if arg in VARS})
        head = tuple((draw(modes), atom(consts + bound)) for _ in range(draw(st.integers(0, 3))))
        rules.append((lin, pers, head))
    # the start state holds the ground premises of some rules (so that steps are enabled
    # more often than not), plus random atoms
    start = []
    for lin, pers, _head in rules:
        if draw(st.integers(0, 2)) == 0:
            continue
        env = {v: draw(st.sampled_from(consts)) for v in VARS}
        start += [(draw(st.sampled_from((LIN, LIN, LIN, AFF))), subst_atom(a, env)) for a in lin]
        start += [(PERS, subst_atom(a, env)) for a in pers]
    start += [(draw(modes), atom(consts)) for _ in range(draw(st.integers(0, 3)))]
    start = tuple(draw(st.permutations(start)))
    return {"consts": consts, "fams": fams, "rules": rules, "start": start}


def _explain(text: str) -> str:
    return "program:\n" + text


# =====================================================================
# Forward chaining: properties
# =====================================================================


@settings(max_examples=300, **SETTINGS)
@given(prog=programs(), seeds=st.lists(st.integers(0, 2**31 - 1), min_size=1, max_size=3),
       bound=st.integers(0, 12), fair=st.booleans())
def test_committed_choice_runs_follow_the_plain_semantics(prog, seeds, bound, fair):
    program, text = load(prog)
    levels = plain_levels(prog, min(bound, 4))
    for seed in seeds:
        ctx = start_ctx(program)
        assert engine_state(ctx) == plain_start(prog), _explain(text)
        trace = [engine_state(ctx)]
        steps, quiescent = program.run(ctx, max_steps=bound, seed=seed, fair=fair,
                                       on_step=lambda step, c: trace.append(engine_state(c)))
        final = engine_state(ctx)
        assert steps == len(trace) - 1 <= bound, _explain(text)
        assert trace[-1] == final, _explain(text)
        # every committed step is a step of the plain semantics
        for i, (before, after) in enumerate(zip(trace, trace[1:])):
            assert after in plain_successors(before, prog), f"step {i + 1} is illegal\n" + _explain(text)
        # so the final state is reachable, in exactly that many steps
        if levels is not None and steps < len(levels):
            assert final in levels[steps], _explain(text)
        # quiescence is reported exactly when the plain semantics has no step
        enabled = plain_successors(final, prog)
        if steps < bound:
            assert quiescent, _explain(text)
        assert quiescent == (not enabled), _explain(text)


@settings(max_examples=300, **SETTINGS)
@given(prog=programs(), depth=st.integers(1, 3))
def test_explorer_successors_are_exactly_the_plain_successors(prog, depth):
    program, text = load(prog)
    frontier = [start_ctx(program)]
    seen = {engine_state(frontier[0])}
    for _ in range(depth):
        nxt = []
        for ctx in frontier:
            here = engine_state(ctx)
            expected = plain_successors(here, prog)
            got = set()
            for choice in program.steps(ctx):
                c2, _step = program.successor(ctx, choice)
                s2 = engine_state(c2)
                assert s2 in expected, f"illegal successor {s2} of {here}\n" + _explain(text)
                got.add(s2)
                if s2 not in seen and len(seen) < 150:
                    seen.add(s2)
                    nxt.append(c2)
            assert engine_state(ctx) == here, "enumerating successors changed the state\n" + _explain(text)
            assert got == expected, (f"at {here}: missing {expected - got}, extra {got - expected}\n"
                                     + _explain(text))
        frontier = nxt


# =====================================================================
# Backward chaining: solution counts
# =====================================================================
#
# Atoms q0 < q1 < q2 < goal. A clause is (head, premises) with premises
# ((persistent?, atom), ...) strictly below the head: proof search terminates.
# Hypotheses: (mode, atom) with mode "lin" (-o), "pers" (->) or "aff" (-@).

ATOMS = ("q0", "q1", "q2", "goal")
ARROW = {"lin": "-o", "pers": "->", "aff": "-@"}


def brute_force_count(clauses, hyps) -> int:
    """The number of proof terms of ``h1 => ... => goal`` (linear hypotheses used once,
    affine at most once, persistent any number of times)."""
    by_head: dict[str, list] = {}
    for head, prems in clauses:
        by_head.setdefault(head, []).append(prems)
    label = {i: a for i, (_m, a) in enumerate(hyps)}
    pers_count = Counter(a for m, a in hyps if m == "pers")

    @lru_cache(maxsize=None)
    def proofs(atom: str, used: frozenset) -> int:
        """Proofs of ``atom`` using exactly the linear/affine hypotheses ``used``."""
        total = 0
        if not used:
            total += pers_count[atom]
        if len(used) == 1 and label[next(iter(used))] == atom:
            total += 1
        for prems in by_head.get(atom, ()):
            lin_idx = [k for k, (p, _a) in enumerate(prems) if not p]
            # each used hypothesis goes to exactly one linear premise; persistent premises get
            # none (with no linear premise, only ``used`` empty has its one, empty, assignment)
            for assign in itertools.product(lin_idx, repeat=len(used)):
                parts = {k: set() for k in range(len(prems))}
                for h, k in zip(sorted(used), assign):
                    parts[k].add(h)
                ways = 1
                for k, (_p, a) in enumerate(prems):
                    ways *= proofs(a, frozenset(parts[k]))
                    if not ways:
                        break
                total += ways
        return total

    linear = frozenset(i for i, (m, _a) in enumerate(hyps) if m == "lin")
    affine = [i for i, (m, _a) in enumerate(hyps) if m == "aff"]
    total = 0
    for r in range(len(affine) + 1):
        for subset in itertools.combinations(affine, r):
            total += proofs("goal", linear | frozenset(subset))
    return total


@st.composite
def backward_problems(draw, with_affine: bool = True):
    clauses = []
    for j, head in enumerate(ATOMS):
        below = list(ATOMS[:j])
        n = draw(st.integers(0, 2) if head != "goal" else st.integers(1, 3))
        for _ in range(n):
            if not below:
                prems = ()
            else:
                prems = tuple((draw(st.integers(0, 3)) == 0, draw(st.sampled_from(below)))
                              for _ in range(draw(st.integers(0, 3))))
            clauses.append((head, prems))
    modes = ["lin", "pers"] + (["aff"] if with_affine else [])
    hyps = tuple((draw(st.sampled_from(modes)), draw(st.sampled_from(ATOMS[:3])))
                 for _ in range(draw(st.integers(0, 4))))
    return clauses, hyps


def backward_text(clauses, hyps) -> str:
    lines = [f"{a} : type." for a in ATOMS]
    for i, (head, prems) in enumerate(clauses):
        body = "".join(f" {'<-' if p else 'o-'} {a}" for p, a in prems)
        lines.append(f"c{i} : {head}{body}.")
    goal = "".join(f"{a} {ARROW[m]} " for m, a in hyps) + "goal"
    lines.append(f"#query * * * 1 {goal}.")
    return "\n".join(lines) + "\n"


def query_count(text: str) -> int:
    program = Program.from_text(text, "<property>")
    (q,) = program.sig.directives
    res = run_query(program, q, emit=lambda line: None)
    return res.solutions


def test_brute_force_count_by_hand():
    """The oracle itself on cases counted by hand."""
    # goal o- q0 o- q0 with two linear q0 hypotheses: two proofs (either goes first)
    assert brute_force_count([("goal", ((False, "q0"), (False, "q0")))], (("lin", "q0"), ("lin", "q0"))) == 2
    # a linear hypothesis that cannot be used: no proof
    assert brute_force_count([("goal", ())], (("lin", "q0"),)) == 0
    # an affine one may be dropped; a persistent q0 and an axiom q0 give two proofs of q0
    assert brute_force_count([("goal", ((False, "q0"),)), ("q0", ())], (("aff", "q1"), ("pers", "q0"))) == 2
    # persistent premise: may not use the linear hypothesis
    assert brute_force_count([("goal", ((True, "q0"),))], (("lin", "q0"),)) == 0


MAX_SOLUTIONS = 300  # the search enumerates every proof: keep examples cheap


@settings(max_examples=300, **SETTINGS)
@given(problem=backward_problems(with_affine=False))
def test_query_solution_count_equals_brute_force_linear_persistent(problem):
    clauses, hyps = problem
    expected = brute_force_count(clauses, hyps)
    assume(expected <= MAX_SOLUTIONS)
    text = backward_text(clauses, hyps)
    assert query_count(text) == expected, text


@settings(max_examples=200, **SETTINGS)
@given(problem=backward_problems(with_affine=True))
def test_query_solution_count_equals_brute_force_with_affine(problem):
    clauses, hyps = problem
    expected = brute_force_count(clauses, hyps)
    assume(expected <= MAX_SOLUTIONS)
    text = backward_text(clauses, hyps)
    assert query_count(text) == expected, text
