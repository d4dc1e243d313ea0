"""States as values: equal up to renaming of fresh names, never merged otherwise."""

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
