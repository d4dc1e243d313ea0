"""Forward chaining inside the monad (forward.clf): persistent and affine facts,
fresh names, rules in the context, backward premises, the step bound of a
query; and the explorer API (program.steps / program.successor) on small
states whose successors are counted by hand."""

from __future__ import annotations


import pytest

from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, show_context, with_big_stack
from roar_formal.clf.rules import PERS
from roar_formal.clf.terms import Param
from repo import ROOT

MODELS = ROOT / "models" / "clf"


def run(name: str | None = None, text: str | None = None, seed: int = 0, fair: bool = False, trace=False):
    prog = Program.from_file(MODELS / name) if name else Program.from_text(text)
    lines: list[str] = []
    res = with_big_stack(run_directives, prog, seed=seed, emit=lines.append, fair=fair, trace=trace)
    return prog, res, lines


def by_kind(res, kind):
    return [r for r in res if r.kind == kind]


# -- forward.clf ----------------------------------------------------------------

@pytest.mark.parametrize("fair", [False, True])
def test_forward_model(fair):
    _, res, _ = run("forward.clf", fair=fair)
    execs = by_kind(res, "exec")
    queries = by_kind(res, "query")
    key3, forge, linear_key, food, seeds, ping1, ping_bang, ret, keep = execs
    # persistent facts
    assert (key3.steps, show_context(key3.final)) == (3, ["!key", "open", "open", "open"])
    assert (forge.steps, show_context(forge.final)) == (3, ["!key", "open", "open"])
    assert (linear_key.steps, show_context(linear_key.final)) == (0, ["door", "key"])
    # affine facts serve linear premises
    assert (food.steps, show_context(food.final)) == (2, ["full", "full"])
    # rules in the context
    assert (ping1.steps, show_context(ping1.final)) == (1, ["ping", "pong"])
    assert (ping_bang.steps, show_context(ping_bang.final)) == (2, ["!(ping -o {pong})", "pong", "pong"])
    assert ret.steps == 1
    assert show_context(ret.final) in (["got (s z)", "ret z"], ["got z", "ret (s z)"])
    assert not ret.final.rules  # the linear rule fired once and is gone
    # a persistent premise proved by backward chaining
    assert (keep.steps, show_context(keep.final)) == (2, ["item (s (s (s z)))", "kept (s z)", "kept z"])
    # affine leftovers, fresh-name matching, the step bound
    assert [q.solutions for q in queries] == [1, 0, 1, 1, 1, 1, 0, 0, 2, 1, 1]
    assert queries[-2].answers == [{"V": "s (s z)"}]
    assert queries[-1].answers == [{"V": "z"}]
    # fresh names
    assert seeds.steps == 3


def test_exists_makes_distinct_fresh_names():
    _, res, _ = run("forward.clf")
    seeds = by_kind(res, "exec")[4]
    nodes = [(t, n) for mode, t, n in seeds.final.facts() if t.head.name == "node"]
    assert all(n == 1 for _, n in nodes) and len(nodes) == 3
    names = [t.args[0].head for t, _ in nodes]
    assert all(isinstance(h, Param) for h in names)
    assert len(set(names)) == 3
    assert [show for show in show_context(seeds.final) if not show.startswith("node")] == ["seed z"]


def test_rule_in_context_fires_once_per_seed():
    prog = Program.from_file(MODELS / "forward.clf")
    ret_start = [d for d in prog.sig.directives if d.__class__.__name__ == "ExecDirective"][7].start
    finals = set()
    for seed in range(20):
        ctx = prog.start_context(ret_start)
        assert len(ctx.rules) == 1
        steps, quiescent = prog.run(ctx, None, seed=seed)
        assert steps == 1 and quiescent and not ctx.rules
        finals.add(tuple(show_context(ctx)))
    # the scheduler may pick either return; both outcomes are legitimate
    assert finals <= {("got (s z)", "ret z"), ("got z", "ret (s z)")}


def test_trace_prints_every_step():
    _, res, lines = run(text="nat : type. z : nat. s : nat -> nat. count : nat -> type.\n"
                             "tick : count (s N) -o {count N}.\n#trace * count (s (s (s z))).\n")
    assert res[0].steps == 3 and show_context(res[0].final) == ["count z"]
    # Celf's shape: the context before the first step and after each of the three
    assert [x for x in lines if x.startswith("-- ")] == [
        "-- count (s (s (s z))) lin", "-- count (s (s z)) lin", "-- count (s z) lin", "-- count z lin"]
    assert lines[-1] == "Success: 3 steps"


# -- the explorer API on small states -------------------------------------------

SMALL = """
item : type.  a : item.  b : item.
p : item -> type.  q : item -> item -> type.  r : item -> type.
tok : type.  done : type.
pair : p X -o p Y -o {q X Y}.
single : p X -o tok -o {r X}.
use : tok -o {done}.
"""


def small_state(start: str):
    prog = Program.from_text(SMALL + f"#exec * {start}.\n")
    return prog, prog.start_context(prog.sig.directives[0].start)


def successors(prog, ctx) -> list[tuple[str, tuple]]:
    out = []
    for ch in prog.steps(ctx):
        nxt, step = prog.successor(ctx, ch)
        assert step.rule == ch.rule
        out.append((ch.rule, tuple(show_context(nxt))))
    return sorted(out)


def test_successors_two_premises_by_hand():
    """p a, p b, tok: pair with (X, Y) = (a, b) or (b, a); single with X = a or b;
    use on tok.  5 steps, 5 different successors."""
    prog, ctx = small_state("p a * p b * tok")
    before = show_context(ctx)
    assert successors(prog, ctx) == [
        ("pair", ("q a b", "tok")),
        ("pair", ("q b a", "tok")),
        ("single", ("p a", "r b")),
        ("single", ("p b", "r a")),
        ("use", ("done", "p a", "p b")),
    ]
    assert show_context(ctx) == before  # successor copies


def test_successors_identical_facts_are_one_choice():
    """tok, tok: using either copy gives the same state, so one step."""
    prog, ctx = small_state("tok * tok")
    assert successors(prog, ctx) == [("use", ("done", "tok"))]


def test_successors_fact_modes_are_distinct_choices():
    """tok and @tok: consuming the linear or the affine copy leads to different states."""
    prog, ctx = small_state("tok * @tok")
    assert successors(prog, ctx) == [("use", ("@tok", "done")), ("use", ("done", "tok"))]


def test_successors_persistent_fact_is_kept():
    prog, ctx = small_state("!tok")
    (ch,) = prog.steps(ctx)
    nxt, _ = prog.successor(ctx, ch)
    assert show_context(nxt) == ["!tok", "done"]
    assert len(prog.steps(nxt)) == 1  # still enabled: the fact persists
    assert ch.consumed[0][0] == PERS


def test_successors_context_rules():
    prog = Program.from_text("nat : type. z : nat. s : nat -> nat. ret : nat -> type. got : nat -> type.\n"
                             "ping : type. pong : type.\n"
                             "#exec * ret z * ret (s z) * (Pi N. ret N -o {got N}).\n"
                             "#exec * ping * ping * (ping -o {pong}).\n")
    ctx = prog.start_context(prog.sig.directives[0].start)
    # the rule can take either return: 2 steps (a rule of the start context is named "init")
    assert successors(prog, ctx) == [("init", ("got (s z)", "ret z")), ("init", ("got z", "ret (s z)"))]
    assert all(ch.ctx_rule is not None for ch in prog.steps(ctx))
    for ch in prog.steps(ctx):
        nxt, _ = prog.successor(ctx, ch)
        assert prog.steps(nxt) == []  # the rule is used up
        assert len(ctx.rules) == 1  # but still in the original state
    ctx2 = prog.start_context(prog.sig.directives[1].start)
    (ch,) = prog.steps(ctx2)
    nxt, _ = prog.successor(ctx2, ch)
    assert show_context(nxt) == ["ping", "pong"] and prog.steps(nxt) == []


def test_successors_backward_premise():
    prog = Program.from_file(MODELS / "forward.clf")
    keep_start = [d for d in prog.sig.directives if d.__class__.__name__ == "ExecDirective"][8].start
    ctx = prog.start_context(keep_start)
    # item 0 and item 1 satisfy le N 2, item 3 does not: two steps
    assert sorted(show_context(prog.successor(ctx, ch)[0]) for ch in prog.steps(ctx)) == [
        ["item (s (s (s z)))", "item (s z)", "kept z"],
        ["item (s (s (s z)))", "item z", "kept (s z)"],
    ]


def test_a_proved_premise_determines_its_outputs():
    # C is bound only by proving `add A B C` backwards: that is enough for forward chaining
    src = """
nat : type. z : nat. s : nat -> nat.
add : nat -> nat -> nat -> type.
add_z : add z N N.
add_s : add (s M) N (s K) <- add M N K.
c : nat -> type.
sum : c A -o c B -o add A B C -> {c C}.
#exec * c (s z) * c (s (s z)).
"""
    (res,) = with_big_stack(run_directives, Program.from_text(src), emit=lambda s: None)
    assert show_context(res.final) == ["c (s (s (s z)))"]
