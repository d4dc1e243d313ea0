"""Celf's lexical rules (parser.tokenize), a directive's view of the program (Program.at),
mode checking, the persistent facts a backward-proved premise sees, and the start-up path
of ``roar-verify clf`` (issue 13)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from roar_formal.cli.clf import fast_args
from roar_formal.clf.parser import parse_program, tokenize
from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives
from roar_formal.clf.signature import ModeError, elaborate
from roar_formal.errors import QueryError, SyntaxError_, TypeError_


def kinds(text):
    return [(t.type, str(t)) for t in tokenize(text)]


@pytest.mark.parametrize("text,expected", [
    ("nat-less", [("ID", "nat-less")]),
    ("lt/z ==> 1+ S* 1'", [("ID", "lt/z"), ("ID", "==>"), ("ID", "1+"), ("ID", "S*"), ("ID", "1'")]),
    ("a*b a * b", [("ID", "a*b"), ("ID", "a"), ("STAR", "*"), ("ID", "b")]),
    ("-o o- -> <- -@ @- -D", [("LOLLI", "-o"), ("RLOLLI", "o-"), ("ARROW", "->"), ("RARROW", "<-"),
                             ("AFFI", "-@"), ("RAFFI", "@-"), ("MINUSD", "-D")]),
    ("-oo a-o o-a", [("ID", "-oo"), ("ID", "a-o"), ("ID", "o-a")]),
    ("= < > + - & _", [("_EQUAL", "="), ("LANGLE", "<"), ("_RANGLE", ">"), ("PLUS", "+"), ("MINUS", "-"),
                       ("AMP", "&"), ("UNDERSCORE", "_")]),
    ("1 12 12ab -3 2.5 1.", [("ONE", "1"), ("NUM", "12"), ("ID", "12ab"), ("NUMLIT", "-3"), ("NUMLIT", "2.5"),
                             ("ONE", "1"), ("_DOT", ".")]),
    ("let in PI EXISTS Pi Exists type #1 #query #foo", [
        ("LET", "let"), ("IN", "in"), ("LPI", "PI"), ("LEXISTS", "EXISTS"), ("PI", "Pi"), ("EXISTS", "Exists"),
        ("TYPE", "type"), ("PROJ", "#1"), ("QUERY", "#query"), ("ID", "#foo")]),
    ("x.y:z", [("ID", "x"), ("_DOT", "."), ("ID", "y"), ("_COLON", ":"), ("ID", "z")]),
    ("a-@b", [("ID", "a-"), ("AT", "@"), ("ID", "b")]),  # longest match: `a-` before `-@`
])
def test_tokens(text, expected):
    assert kinds(text) == expected


def test_token_positions_and_comments():
    toks = list(tokenize("% c\n  ab %{ x\n y }% cd\n\tef"))
    assert [(str(t), t.line, t.column) for t in toks] == [("ab", 2, 3), ("cd", 3, 7), ("ef", 4, 2)]


def test_minus_and_plus_may_be_declared_and_used():
    prog = parse_program("nat : type. - : nat -> nat -> type. + : type. c : - X Y.")
    assert [d.name for d in prog.items] == ["nat", "-", "+", "c"]
    elaborate(prog)


def test_a_directive_sees_only_the_declarations_before_it_in_the_library_too():
    text = "a : type. b : type. c : type.\nr1 : a -o {b}.\n#query * 1 * 1 a -o {b}.\nr2 : a -o {c}.\n"
    program = Program.from_text(text)
    (q,) = program.sig.directives
    assert q.prefix == 4 and len(program.sig.consts) == 5
    assert program.at(q.prefix).rule_names == ["r1"] and program.at(-1) is program
    for seed in range(8):
        (res,) = run_directives(program, seed=seed, emit=lambda line: None)
        assert res.solutions == 1


def test_query_attempts_stop_at_the_first_success():
    program = Program.from_text("a : type. b : type. c : type.\nr1 : a -o {b}.\nr2 : a -o {c}.\n"
                                "#query * 1 * 20 a -o {b}.\n")
    for seed in range(8):
        lines = []
        (res,) = run_directives(program, seed=seed, emit=lines.append)
        assert res.ok and res.solutions == 1
        assert lines[-1] == "Query ok." and lines.count("Solution: _") == 1
    # no attempt can succeed: every one is made, then the query fails
    program = Program.from_text("a : type. b : type. c : type.\nr2 : a -o {c}.\n#query * 1 * 3 a -o {b}.\n")
    lines = []
    with pytest.raises(QueryError, match="in any of 3 attempts"):
        run_directives(program, emit=lines.append)
    assert [x for x in lines if x.startswith("Iteration")] == ["Iteration 1", "Iteration 2", "Iteration 3"]


def test_mode_check():
    ok = ("nat : type. z : nat. s : nat -> nat.\nplus : nat -> nat -> nat -> type.\n#mode plus + + -.\n"
          "plus_z : plus z N N.\nplus_s : plus (s M) N (s P) <- plus M N P.\n")
    elaborate(parse_program(ok))
    with pytest.raises(ModeError, match="mode error: P not necessarily ground") as info:
        elaborate(parse_program(ok + "bad : plus z N P.\n"))
    assert info.value.pos.line == 6 and isinstance(info.value, TypeError_)
    # a clause declared before the #mode is not checked (one declaration at a time)
    elaborate(parse_program("nat : type.\np : nat -> nat -> type.\np_any : p X Y.\n#mode p + -.\n"))
    with pytest.raises(TypeError_, match="gives 1 modes in braces for 0 implicit"):
        elaborate(parse_program("nat : type.\np : nat -> type.\n#mode p {+} +.\n"))


def test_premise_families_close_over_clauses():
    program = Program.from_text("a : type. b : type. c : type. d : type. go : type.\n"
                                "b_a : b <- a.\nc_b : c <- b <- d.\nr : go -o c -> {1}.\n")
    fams = {f.name for f in program.premise_families(next(f for f in program.clauses if f.name == "c"))}
    assert {"a", "b", "c", "d"} <= fams


def test_pattern_binders_are_refused_when_the_type_does_not_fit():
    with pytest.raises(TypeError_, match="needs a type '!A'"):
        parse_program("a : type. r : {EXISTS !x : a. 1}.")
    with pytest.raises(TypeError_, match="needs a tensor type"):
        parse_program("a : type. r : PI [!x, _] : !a. {1}.")
    with pytest.raises(SyntaxError_, match="persistent"):
        parse_program("a : type. r : PI @x : @a. {1}.")


def test_fast_args():
    assert fast_args(["f.clf"])["file"].name == "f.clf"
    assert fast_args(["--seed", "3", "f.clf", "--trace"])["seed"] == 3
    assert fast_args(["--seed=4", "--fair", "--proof", "f.clf"]) == {
        "seed": 4, "trace": False, "fair": True, "proof": True, "max_steps": None,
        "file": fast_args(["f.clf"])["file"]}
    assert fast_args(["--max-steps", "7", "f.clf"])["max_steps"] == fast_args(["--max-steps=7", "f.clf"])["max_steps"] == 7
    assert fast_args(["f.clf"])["proof"] is True  # Celf prints every solution's term
    assert fast_args(["--no-proof", "f.clf"])["proof"] is False
    for bad in ([], ["a", "b"], ["--help"], ["--seed", "x", "f"], ["--nope", "f"], ["--max-steps", "-1", "f"]):
        assert fast_args(bad) is None


def test_clf_command_imports_only_what_it_needs(tmp_path):
    f = tmp_path / "one.clf"
    f.write_text("a : type.\n#query * 0 * 1 a.\n")
    code = ("import sys\nfrom roar_formal.cli import main\n"
            f"try:\n    main(['clf', {str(f)!r}])\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
            "loaded = [m for m in ('roar_formal.explore', 'roar_formal.robot', 'roar_formal.roar', "
            "'roar_formal.tca', 'roar_formal.trace', 'typer', 'click', 'rich', 'pydantic', 'z3', 'numpy', "
            "'scipy', 'pymunk', 'networkx', 'matplotlib') if m in sys.modules]\n"
            "assert not loaded, loaded\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "Query ok." in p.stdout


def test_cli_app_lists_every_command():
    from roar_formal import cli
    names = {c.name for c in cli.app.registered_commands}
    assert {"clf", "check", "run", "prove"} <= names


def test_run_file_on_an_empty_program_and_rules_after_the_last_directive(tmp_path):
    from roar_formal.clf.query import run_file
    from roar_formal.errors import UnsupportedError
    empty = tmp_path / "e.clf"
    empty.write_text("% nothing\n")
    assert run_file(empty, emit=lambda line: None) == []
    late = tmp_path / "l.clf"
    # a rule whose built-in premise's input no premise determines (a Pi variable only in the
    # head is a logic variable, as in Celf, and accepted)
    late.write_text("a : type. b : number -> type.\n#query * 0 * 1 a.\nr : num_lt X 1 -> {b X}.\n")
    lines = []
    with pytest.raises(UnsupportedError):
        run_file(late, emit=lines.append)
    assert "Query ok." in lines  # the query ran before the later rule was refused
