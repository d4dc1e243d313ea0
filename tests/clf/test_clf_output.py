"""``roar-verify clf`` output in Celf's shape: the context layout after ``#exec``/``#trace``,
``--proof``/``--no-proof``, colours only on a terminal, Celf's checks of ``#query`` bounds
(library level), and a pipeline cut short."""

from __future__ import annotations

import io
import subprocess
import sys

import pytest

from roar_formal.cli import main
from roar_formal.cli.clf import line_printer
from roar_formal.clf.program import Program
from roar_formal.clf.query import MalformedQueryError, context_layout, run_directives, with_big_stack

SIG = "a : type. b : type. k : type. t : type. long_name_of_a_fact : type.\n"


def final_context(text: str):
    prog = Program.from_text(SIG + text, "<t>")
    res = with_big_stack(run_directives, prog, emit=lambda s: None)
    return res[-1].final


def test_context_layout_modes_and_order():
    ctx = final_context("#exec * b * !k * @t * a * a.\n")
    assert context_layout(ctx) == ["-- a lin, a lin, b lin, k pers, t aff"]


def test_context_layout_nothing():
    ctx = final_context("r : a -o {1}.\n#exec * a.\n")
    assert context_layout(ctx) == ["-- (nothing)"]


def test_context_layout_wraps_past_80_columns():
    ctx = final_context("#exec * " + " * ".join(["long_name_of_a_fact"] * 9) + ".\n")
    lines = context_layout(ctx)
    assert len(lines) == 3 and lines[0].startswith("-- long_name_of_a_fact lin, ")
    assert all(len(x) <= 80 for x in lines)
    assert all(x.startswith("   long_name_of_a_fact lin") for x in lines[1:])
    assert " ".join(x.strip() for x in lines) == "-- " + ", ".join(["long_name_of_a_fact lin"] * 9)
    assert context_layout(ctx, width=1000) == ["-- " + ", ".join(["long_name_of_a_fact lin"] * 9)]


def test_rules_in_the_context_are_listed():
    ctx = final_context("go : type.\nr : go -o {a -o {b}}.\n#exec * go.\n")
    assert context_layout(ctx) == ["-- a -o {b} lin"]


def run_cli(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main(["clf", *map(str, args)])
    out, err = capsys.readouterr()
    return info.value.code or 0, out, err


def test_proof_terms_by_default_and_no_proof(tmp_path, capsys):
    f = tmp_path / "p.clf"
    f.write_text("a : type. b : type. r : a -o {b}.\n#query * 1 * 1 a -o {b}.\n")
    code, out, _ = run_cli(capsys, f)
    assert code == 0 and out.splitlines()[1] == "Solution: \\X1. {let {X2} = r X1 in X2}"
    code, out, _ = run_cli(capsys, f, "--no-proof")
    assert code == 0 and out.splitlines()[1] == "Solution: _"
    code, out, _ = run_cli(capsys, "--no-proof", "--proof", f)  # the last one wins
    assert code == 0 and out.splitlines()[1].startswith("Solution: \\X1.")


def test_typer_route_has_the_same_options(tmp_path, capsys):
    """Arguments the fast reader leaves to Typer (here `--` before the file) give the same run."""
    from roar_formal.cli.clf import fast_args
    f = tmp_path / "p.clf"
    f.write_text("a : type. r : a.\n#query * 1 * 1 a.\n")
    assert fast_args(["--no-proof", "--", str(f)]) is None
    code, out, _ = run_cli(capsys, "--no-proof", "--", f)
    assert code == 0 and out.splitlines() == ["Query (*, 1, *, 1) a.", "Solution: _", "Query ok."]
    code, out, _ = run_cli(capsys, "--", f)
    assert code == 0 and out.splitlines()[1] == "Solution: r"


def test_colours_only_on_a_terminal(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    plain = io.StringIO()
    line_printer(plain)("Query ok.")
    assert plain.getvalue() == "Query ok.\n"
    monkeypatch.delenv("NO_COLOR", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    tty = Tty()
    emit = line_printer(tty)
    emit("Query ok.")
    emit("Exec failed, expected 3 steps but only 1 taken")
    emit("-- a lin")
    assert tty.getvalue().splitlines() == ["\x1b[32mQuery ok.\x1b[0m",
                                           "\x1b[31mExec failed, expected 3 steps but only 1 taken\x1b[0m",
                                           "-- a lin"]
    monkeypatch.setenv("NO_COLOR", "1")
    tty = Tty()
    line_printer(tty)("Query ok.")
    assert tty.getvalue() == "Query ok.\n"
    # control characters from the input are shown, never sent
    plain = io.StringIO()
    line_printer(plain)("Solution: \x1b[2J")
    assert plain.getvalue() == "Solution: \\x1b[2J\n"


@pytest.mark.parametrize("bounds, ok", [
    ("* 1 2 1", True), ("* * 1 1", True), ("* 1 3 1", True), ("* 1 * 3", True),
    ("* 1 1 1", False), ("* 2 1 1", False), ("* 1 1 2", False), ("* * 3 2", False),
    ("* 5 0 1", True), ("* 2 1 0", True),  # ignored before the bounds are checked
])
def test_library_checks_bounds_when_the_query_runs(bounds, ok):
    prog = Program.from_text(f"a : type. r : a.\n#query {bounds} a.\n", "<q>")  # reading accepts them
    lines: list[str] = []
    if ok:
        with_big_stack(run_directives, prog, emit=lines.append)
    else:
        with pytest.raises(MalformedQueryError) as info:
            with_big_stack(run_directives, prog, emit=lines.append)
        assert info.value.message.startswith("malformed query (D,E,L,A): ")
        assert info.value.pos.line == 2
    assert lines[0] == f"Query ({', '.join(bounds.split())}) a."


def test_a_pipeline_cut_short_stops_quietly(tmp_path):
    f = tmp_path / "many.clf"
    # (about 300 KB of solutions, more than a pipe holds: the writer is still writing when the
    # reader leaves, however fast it ran; with 47 KB it could finish first and exit 0)
    f.write_text("a : type.\n" + "".join(f"r{i} : a.\n" for i in range(20000)) + "#query * * * 1 a.\n")
    code = ("import sys\nfrom roar_formal.cli import main\nmain(['clf', sys.argv[1]])\n")
    p = subprocess.Popen([sys.executable, "-c", code, str(f)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = p.stdout.readline()
    p.stdout.close()  # the reader leaves (as `| head -1` does)
    err = p.stderr.read().decode()
    p.wait(timeout=120)
    assert first.startswith(b"Query (")
    assert p.returncode == 141 and "Traceback" not in err and "internal error" not in err, err


HOAS = """tm : type.
lam : (tm -> tm) -> tm.
app : tm -> tm -> tm.
step : tm -> tm -> type.
beta : step (app (lam \\!x. M x) N) (M N).
#query * 1 * 1 step (app (lam \\!x. app x x) (lam \\!y. y)) R.
"""


def test_printed_answers_read_back_as_input():
    """A lambda in an answer is a persistent function and prints as Celf writes one (``\\!x.``):
    the answer, pasted into a program, type-checks and denotes the same term."""
    lines: list[str] = []
    prog = Program.from_text(HOAS, "<t>")
    with_big_stack(run_directives, prog, emit=lines.append)
    answer = next(x for x in lines if x.startswith(" #R = "))[len(" #R = "):]
    assert answer == "app (lam (\\!x. x)) (lam (\\!x. x))", lines
    back = Program.from_text(HOAS + f"same : step (app (lam \\!x. app x x) (lam \\!y. y)) ({answer}).\n", "<t>")
    lines = []
    with_big_stack(run_directives, back, emit=lines.append)
    assert any(x.startswith(" #R = ") for x in lines)


def test_fresh_names_in_proof_terms_keep_their_number_apart():
    """A fresh name's hint and its number are told apart in a proof term (``d1_7``, not ``d17``)."""
    lines: list[str] = []
    text = ("dest : type. r : type. done : type. e : dest -> type.\n"
            "mk : r -o {Exists d1. e d1}.\nuse : e D -o {done}.\n#query * 1 * 1 r -o {done}.\n")
    with_big_stack(run_directives, Program.from_text(text, "<t>"), emit=lines.append, proofs=True)
    sol = next(x for x in lines if x.startswith("Solution:"))
    import re
    assert re.search(r"let \{\[!d1_\d+, X\d+\]\}", sol), sol   # e.g. let {[!d1_7, X2]} = mk X1


ROUND_TRIP = """nat : type. z : nat. s : nat -> nat.
p : nat -> type.
q : Pi x:nat. p x.
r : Pi x:nat. p x -> p (s x).
item : type. a : item.
got : item -> type. tok : item -> type.
ra : tok a -o {got a}.
proc : type. ready : proc -> type. token : proc -> type. next : proc -> proc -> type.
log : proc -> type. spawn : type. budget : type.
sp : spawn -o {Exists p:proc. Exists q:proc. ready p * ready q * !next p q * !next q p * token p}.
pass : token P * !next P Q * budget -o {token Q * @log P}.
dest : type. val : type. vn : nat -> val.
eval : nat -> dest -> type. ret : val -> dest -> type.
ev_z : eval z D -o {ret (vn z) D}.
ev_s : eval (s E) D -o {Exists d1. eval E d1 * (Pi V. ret (vn V) d1 -o {ret (vn (s V)) D})}.
pz : nat -> type.
r5 : Pi x:nat. pz x -o {got a}.
"""
GOALS = ["p (s (s z))", "got a -o got a -o {got a * got a}", "tok a -o tok a -o {got a * got a}",
         "spawn -o budget -o budget -o {Exists p:proc. Exists q:proc. token p * ready p * ready q}",
         "spawn -o budget -o {Exists p:proc. @log p * Exists q:proc. token q * ready p * ready q}",
         "Pi d:dest. eval (s (s z)) d -o {ret (vn (s (s z))) d}", "pz (s z) -o {got a}"]


@pytest.mark.parametrize("goal", GOALS)
def test_printed_proof_terms_read_back_as_definitions(goal):
    """Every proof term a query prints (explicit Pi arguments, '!' and '@' marks, Exists
    witnesses, the order of equal facts) is accepted back as a definition of the goal's type: the
    type checker, independent of the search, confirms each one is a proof."""
    lines: list[str] = []
    with_big_stack(run_directives, Program.from_text(ROUND_TRIP + f"#query * * 4 1 {goal}.\n", "<t>"),
                   emit=lines.append, proofs=True)
    sols = [x[len("Solution: "):] for x in lines if x.startswith("Solution: ")]
    assert sols and len(set(sols)) == len(sols), lines   # distinct proofs print distinctly
    for k, sol in enumerate(sols):
        Program.from_text(ROUND_TRIP + f"pf{k} : {goal} = {sol}.\n", "<t>")   # raises if it does not check


@pytest.mark.parametrize("route", [(), ("--",)])   # the fast reader and Typer's
def test_max_steps_stops_an_exec_that_never_quiesces(tmp_path, capsys, route):
    loop = tmp_path / "loop.clf"
    loop.write_text("a : type.\nr : a -o {a}.\n#exec * a.\n")
    code, out, err = run_cli(capsys, "--max-steps", "50", *route, loop)
    assert code == 2 and "Exec stopped after 50 steps (--max-steps 50): the program had not quiesced" in out
    assert "loop.clf:3:1: #exec * did not quiesce within 50 steps" in err
    # a program that quiesces at the bound, or before it, succeeds as without the option
    three = tmp_path / "three.clf"
    three.write_text("a : type. b : type. c : type. d : type.\nr1 : a -o {b}.\nr2 : b -o {c}.\n"
                     "r3 : c -o {d}.\n#exec * a.\n")
    for bound, ok in ((2, False), (3, True), (4, True)):
        code, out, _err = run_cli(capsys, f"--max-steps={bound}", *route, three)
        assert (code == 0) == ok and (("Success: 3 steps" in out) == ok), (bound, out)
    # an explicit bound is the program's: the option bounds '*' only
    three.write_text(three.read_text().replace("#exec *", "#exec 3"))
    code, out, _err = run_cli(capsys, "--max-steps", "1", *route, three)
    assert code == 0 and "Success: 3 steps" in out
    code, _out, err = run_cli(capsys, "--max-steps", "0", *route, three)
    assert code == 2 and "--max-steps is a number of steps above 0, not 0" in err
