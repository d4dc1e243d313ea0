"""The example programs of models/clf: each runs clean through ``roar-verify clf``
(its directives carry exact expected counts), and the values they compute are
the ones derived by hand in their header comments or by an independent
brute-force computation here.
"""

from __future__ import annotations

import collections
import subprocess
import sys

import pytest

from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, show_context, with_big_stack
from roar_formal.cli import main
from roar_formal.errors import QueryError
from repo import ROOT

MODELS = ROOT / "models" / "clf"
ALL_MODELS = sorted(MODELS.glob("*.clf"))


def run(name: str, seed: int = 0, fair: bool = False):
    """Load a model and run its directives; returns (program, results, output lines)."""
    prog = Program.from_file(MODELS / name)
    lines: list[str] = []
    res = with_big_stack(run_directives, prog, seed=seed, emit=lines.append, fair=fair)
    return prog, res, lines


def cli(capsys, *args) -> tuple[int, str, str]:
    """``roar-verify clf ARGS`` in process: (exit status, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main(["clf", *map(str, args)])
    out, err = capsys.readouterr()
    code = info.value.code
    return (0 if code is None else code), out, err


def unary(n: int) -> str:
    """The printed unary numeral: unary(2) == 's (s z)'."""
    return "z" if n == 0 else ("s z" if n == 1 else f"s ({unary(n - 1)})")


# -- every model runs clean through the CLI ------------------------------------

def test_required_models_exist():
    names = {p.name for p in ALL_MODELS}
    for n in ["petri.clf", "arith.clf", "miniml.clf", "counter.clf", "perm.clf", "subsets.clf",
              "deadlock.clf", "backward.clf", "forward.clf"]:
        assert n in names


@pytest.mark.parametrize("path", ALL_MODELS, ids=[p.stem for p in ALL_MODELS])
def test_model_passes_cli(path, capsys):
    code, out, err = cli(capsys, path)
    assert code == 0, err
    assert "error" not in err.lower() and "Traceback" not in err
    assert " error." not in out
    # each model's header explains it
    assert path.read_text(encoding="utf-8").startswith(f"% {path.name} --")


# -- petri.clf: a confluent producer/consumer net ------------------------------

PETRI_FINAL = ["cready", "done", "done", "done", "ready", "slot", "slot"]


def test_petri_final_marking():
    _, res, _ = run("petri.clf")
    star, exact, query = res
    assert star.steps == 12 and show_context(star.final) == PETRI_FINAL
    assert exact.steps == 12 and show_context(exact.final) == PETRI_FINAL
    assert query.solutions == 1


@pytest.mark.parametrize("fair", [False, True])
def test_petri_is_confluent_across_seeds(fair):
    prog = Program.from_file(MODELS / "petri.clf")
    start = prog.sig.directives[0].start
    for seed in range(25):
        ctx = prog.start_context(start)
        buffer_sizes = []

        def on_step(step, c):
            buffer_sizes.append(show_context(c).count("item"))

        steps, quiescent = prog.run(ctx, None, seed=seed, fair=fair, on_step=on_step)
        assert quiescent and steps == 12
        assert show_context(ctx) == PETRI_FINAL
        assert max(buffer_sizes) <= 2  # the buffer's bound


# An independent model of the same net: markings as place -> count, transitions
# as (inputs, outputs).  Used to enumerate every interleaving.
PETRI_NET = {
    "produce": (("ready", "todo"), ("made",)),
    "put": (("made", "slot"), ("item", "ready")),
    "take": (("cready", "item"), ("got", "slot")),
    "use": (("got",), ("done", "cready")),
}


def _petri_successors(marking: tuple) -> list[tuple]:
    m = collections.Counter(dict(marking))
    out = []
    for ins, outs in PETRI_NET.values():
        need = collections.Counter(ins)
        if all(m[p] >= k for p, k in need.items()):
            n = m.copy()
            n.subtract(need)
            n.update(outs)
            out.append(tuple(sorted((p, k) for p, k in n.items() if k)))
    return out


def _key(ctx) -> tuple:
    return tuple(sorted(collections.Counter(show_context(ctx)).items()))


def test_petri_all_interleavings_match_brute_force():
    prog = Program.from_file(MODELS / "petri.clf")
    start = prog.start_context(prog.sig.directives[0].start)
    # the engine's state graph
    seen = {_key(start): start}
    frontier = [start]
    terminal = set()
    edges = 0
    while frontier:
        ctx = frontier.pop()
        choices = prog.steps(ctx)
        if not choices:
            terminal.add(_key(ctx))
        for ch in choices:
            nxt, _ = prog.successor(ctx, ch)
            edges += 1
            k = _key(nxt)
            if k not in seen:
                seen[k] = nxt
                frontier.append(nxt)
    # the plain Python net's state graph
    m0 = tuple(sorted({"ready": 1, "cready": 1, "todo": 3, "slot": 2}.items()))
    bf_seen = {m0}
    bf_frontier = [m0]
    bf_terminal = set()
    bf_edges = 0
    while bf_frontier:
        m = bf_frontier.pop()
        succ = _petri_successors(m)
        if not succ:
            bf_terminal.add(m)
        for n in succ:
            bf_edges += 1
            if n not in bf_seen:
                bf_seen.add(n)
                bf_frontier.append(n)
    assert set(seen) == bf_seen
    assert edges == bf_edges
    assert terminal == bf_terminal == {tuple(sorted(collections.Counter(PETRI_FINAL).items()))}
    # the invariants of the header comment hold in every reachable marking
    for m in bf_seen:
        d = collections.Counter(dict(m))
        assert d["slot"] + d["item"] == 2 and d["ready"] + d["made"] == 1 and d["cready"] + d["got"] == 1


def test_petri_successors_by_hand():
    """Start: only produce is enabled (three identical todo tokens are one choice);
    then only put; then produce and take."""
    prog = Program.from_file(MODELS / "petri.clf")
    ctx = prog.start_context(prog.sig.directives[0].start)
    ch = prog.steps(ctx)
    assert [c.rule for c in ch] == ["produce"]
    ctx, step = prog.successor(ctx, ch[0])
    assert step.rule == "produce"
    ch = prog.steps(ctx)
    assert [c.rule for c in ch] == ["put"]
    ctx2, _ = prog.successor(ctx, ch[0])
    assert sorted(c.rule for c in prog.steps(ctx2)) == ["produce", "take"]
    # successor leaves its argument unchanged
    assert show_context(ctx) == ["cready", "made", "slot", "slot", "todo", "todo"]


# -- arith.clf ------------------------------------------------------------------

def test_arith_values():
    _, res, lines = run("arith.clf")
    values = [r.answers[0]["V"] for r in res if r.kind == "query" and r.answers]
    # 1+2, 3*4, (1+1)*3, 0*5, 2*0
    assert values == [unary(3), unary(12), unary(6), unary(0), unary(0)]
    assert f" #V = {unary(12)}" in lines
    wrong = [r for r in res if r.kind == "query"][5]
    assert wrong.solutions == 0
    execs = [r for r in res if r.kind == "exec"]
    for e in execs:
        assert e.steps == 26
        (line,) = show_context(e.final)
        assert line.startswith(f"return ({unary(12)}) d")


def test_arith_independent_of_seed():
    for seed in (1, 7, 42):
        _, res, _ = run("arith.clf", seed=seed)
        assert [r.answers[0]["V"] for r in res if r.answers][:2] == [unary(3), unary(12)]
        assert all(r.steps == 26 for r in res if r.kind == "exec")


# -- miniml.clf -----------------------------------------------------------------

def vnum(n: int) -> str:
    return f"vnum ({unary(n)})" if n else "vnum z"


def test_miniml_references():
    _, res, _ = run("miniml.clf")
    q1, q1_no_cell, q2, q3, e15, estar = res
    assert q1.answers == [{"V": vnum(2), "W": vnum(2)}]  # let r = newref 1 in r := 2; !r
    assert q1_no_cell.solutions == 0  # the cell is a linear leftover
    assert q2.answers == [{"V": vnum(5), "W": vnum(5)}]  # aliasing
    assert q3.answers == [{"V": vnum(1), "W": vnum(0)}]  # two separate cells
    for e in (e15, estar):
        assert e.steps == 15
        lines = show_context(e.final)
        assert len(lines) == 2
        assert lines[0].startswith("contains c") and lines[0].endswith(f" ({vnum(2)})")
        assert lines[1].startswith(f"return ({vnum(2)}) d")


def test_miniml_is_deterministic():
    """Every state of P1's run has exactly one enabled step (the header's claim)."""
    prog = Program.from_file(MODELS / "miniml.clf")
    ctx = prog.start_context(prog.sig.directives[4].start)
    n = 0
    while True:
        ch = prog.steps(ctx)
        if not ch:
            break
        assert len(ch) == 1, [c.rule for c in ch]
        ctx, _ = prog.successor(ctx, ch[0])
        n += 1
    assert n == 15


# -- counter.clf ----------------------------------------------------------------

def test_counter_exact_steps():
    _, res, _ = run("counter.clf")
    got = [(r.steps, show_context(r.final)) for r in res]
    assert got == [
        (5, ["count z"]),
        (5, ["count z"]),
        (2, [f"count ({unary(3)})"]),
        (4, [f"ctr ({unary(4)})"]),
        (3, ["left z", f"right ({unary(4)})"]),
        (2, ["even (s z)"]),
        (0, ["count z"]),
    ]


def test_counter_wrong_exact_count_fails(tmp_path, capsys):
    text = (MODELS / "counter.clf").read_text(encoding="utf-8")
    bad = tmp_path / "counter_bad.clf"
    lines = text.splitlines()
    lines.append("#exec 6 count (s (s (s (s (s z))))).")
    bad.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(QueryError) as info:
        with_big_stack(run_directives, Program.from_file(bad), emit=lambda s: None)
    assert "expected exactly 6 steps" in info.value.message
    code, out, err = cli(capsys, bad)
    assert code == 2
    assert f"{bad}:{len(lines)}:1: #exec expected exactly 6 steps, but the program quiesced after 5" in err
    assert "Exec failed, expected 6 steps but only 5 taken" in out.splitlines() and "Traceback" not in err


def test_counter_wrong_count_console_script(tmp_path):
    """The installed entry point, in a separate process: non-zero status, located message."""
    bad = tmp_path / "c.clf"
    bad.write_text("nat : type.\nz : nat.\ns : nat -> nat.\ncount : nat -> type.\n"
                   "tick : count (s N) -o {count N}.\n#exec 3 count (s (s z)).\n", encoding="utf-8")
    p = subprocess.run([sys.executable, "-c", "from roar_formal.cli import main; main()", "clf", str(bad)],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert f"{bad}:6:1: #exec expected exactly 3 steps, but the program quiesced after 2" in p.stderr
    assert "Traceback" not in p.stderr


# -- deadlock.clf ---------------------------------------------------------------

DEADLOCK = ["p1", "q1"]
COMPLETED = ["free l1", "free l2", "pdone", "qdone"]


def _deadlock_run(prog, seed):
    ctx = prog.start_context(prog.sig.directives[0].start)
    steps, quiescent = prog.run(ctx, None, seed=seed)
    assert quiescent
    return steps, show_context(ctx)


def test_deadlock_depends_on_seed(capsys):
    prog = Program.from_file(MODELS / "deadlock.clf")
    outcomes: dict = {}
    for seed in range(40):
        steps, final = _deadlock_run(prog, seed)
        assert (steps, final) in [(2, DEADLOCK), (6, COMPLETED)]
        outcomes.setdefault(tuple(final), seed)
    assert set(outcomes) == {tuple(DEADLOCK), tuple(COMPLETED)}
    # the CLI with those seeds prints the same final contexts
    for final, seed in outcomes.items():
        code, out, _ = cli(capsys, MODELS / "deadlock.clf", "--seed", seed)
        assert code == 0
        shown = [x for x in out.splitlines() if x.startswith("-- ")]
        assert shown == ["-- " + ", ".join(f + " lin" for f in final)]


def test_printing_is_per_program():
    miniml = Program.from_file(MODELS / "miniml.clf")
    res = with_big_stack(run_directives, miniml, emit=lambda s: None)
    before = show_context(res[-1].final)
    Program.from_file(MODELS / "arith.clf")  # `return` again, with no implicit argument
    assert show_context(res[-1].final) == before


def test_deadlock_state_space_by_hand():
    prog = Program.from_file(MODELS / "deadlock.clf")
    start = prog.start_context(prog.sig.directives[0].start)
    assert sorted(c.rule for c in prog.steps(start)) == ["p_a", "q_a"]
    after_pa, _ = prog.successor(start, next(c for c in prog.steps(start) if c.rule == "p_a"))
    assert sorted(c.rule for c in prog.steps(after_pa)) == ["p_b", "q_a"]
    seen = {_key(start)}
    frontier = [start]
    terminal = []
    while frontier:
        ctx = frontier.pop()
        ch = prog.steps(ctx)
        if not ch:
            terminal.append(show_context(ctx))
        for c in ch:
            nxt, _ = prog.successor(ctx, c)
            if _key(nxt) not in seen:
                seen.add(_key(nxt))
                frontier.append(nxt)
    assert len(seen) == 13
    assert sorted(terminal) == sorted([DEADLOCK, COMPLETED])
