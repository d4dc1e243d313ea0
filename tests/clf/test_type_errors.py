"""Malformed programs (tests/clf/type_errors/*.clf) through ``roar-verify clf``:
exit status 2, a ``file:line:col: message`` line on stderr, and no traceback.
Each file's first line is ``% expect: LINE:COL <substring of the message>``."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from roar_formal.cli import main
from roar_formal.clf.builtins import BuiltinError
from roar_formal.clf.program import Program
from roar_formal.clf.query import run_directives, with_big_stack
from roar_formal.errors import QueryError, RoarError, TypeError_, UnsupportedError

HERE = Path(__file__).resolve().parent
CASES = sorted((HERE / "type_errors").glob("*.clf"))
EXPECT = re.compile(r"%\s*expect:\s*(\d+):(\d+)\s+(.*\S)")


def cli(capsys, *args) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as info:
        main(["clf", *map(str, args)])
    out, err = capsys.readouterr()
    code = info.value.code
    return (0 if code is None else code), out, err


def expectation(path: Path) -> tuple[int, int, str]:
    m = EXPECT.match(path.read_text(encoding="utf-8").splitlines()[0])
    assert m, f"{path.name}: first line must be '% expect: LINE:COL message'"
    return int(m[1]), int(m[2]), m[3]


def test_suite_is_large_enough():
    assert len(CASES) >= 10
    # the kinds of error the suite must cover
    names = {p.stem for p in CASES}
    assert {"unknown_constant", "unknown_family", "family_arity", "wrong_argument_type", "const_as_family",
            "family_as_term", "positive_outside_monad", "undetermined_builtin_input", "duplicate", "query_count",
            "exec_unbound"} <= names


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_type_error_cli(path, capsys):
    line, col, fragment = expectation(path)
    code, out, err = cli(capsys, path)
    assert code == 2, (out, err)
    assert "Traceback" not in err and "Traceback" not in out
    first = err.strip().splitlines()[0]
    assert first.startswith("error: ")
    assert first[len("error: "):].startswith(f"{path}:{line}:{col}: "), first
    assert fragment in err, err


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_type_error_library(path):
    """The library raises a located RoarError of the right class (no other exception)."""
    line, col, fragment = expectation(path)
    with pytest.raises(RoarError) as info:
        with_big_stack(lambda: run_directives(Program.from_file(path), emit=lambda s: None))
    err = info.value
    assert (err.pos.file, err.pos.line, err.pos.col) == (str(path), line, col)
    assert fragment in err.format()
    if path.stem == "query_count":
        assert isinstance(err, QueryError)
    elif path.stem.startswith("undetermined_"):
        assert isinstance(err, UnsupportedError)
    elif path.stem == "builtin_not_ground":
        assert isinstance(err, BuiltinError)
    else:
        assert isinstance(err, TypeError_)


def test_error_names_the_argument_text(capsys):
    """A mismatching compound argument is named by its text, not as 'an application'."""
    path = HERE / "type_errors" / "miniml_ill_typed.clf"
    _, _, err = cli(capsys, path)
    assert "'value (vnum z)'" in err and "an application" not in err
    assert "expected: exp (tref T)" in err and "found:    exp tnat" in err


def test_missing_file_is_a_user_error(tmp_path, capsys):
    code, out, err = cli(capsys, tmp_path / "nope.clf")
    assert code != 0 and "Traceback" not in err


def test_error_path_with_brackets(tmp_path, capsys):
    d = tmp_path / "[red]x"
    d.mkdir()
    f = d / "e.clf"
    f.write_text("a : type.\nb : c.\n", encoding="utf-8")
    code, _, err = cli(capsys, f)
    assert code == 2 and f"{f}:2:5: unknown type family 'c'" in err
