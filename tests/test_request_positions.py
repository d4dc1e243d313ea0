"""An error inside a request is reported where the request is written: a job file's line and the
column inside its quotes, the ``--request`` option, a test's own line (not ``<request>:1:1``)."""

from __future__ import annotations

import pytest

from roar_formal import load_spec
from roar_formal.cli import main
from roar_formal.errors import Pos, RoarError, relocate, written_at
from roar_formal.roar.checks import SpecCheckError

from repo import ROOT

SPEC = ROOT / "models" / "conflict.roar"


def _cli(capsys, *args) -> tuple[int, str]:
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize("request_text, fragment, message", [
    ("mission::dne == true", "mission::dne", "no variable 'dne'"),
    ("mission::done ==", None, "unexpected end of file"),
    ("mission::done == true where mission::nope == 1", "mission::nope", "nope"),
])
def test_a_job_files_request_error_is_at_its_line_and_column(tmp_path, capsys, request_text, fragment, message):
    job = tmp_path / "job.toml"
    lines = ['name = "located"', f'spec = "{SPEC}"', "", f'request   =   "{request_text}"']
    job.write_text("\n".join(lines) + "\n", encoding="utf-8")
    code, err = _cli(capsys, "check", job)
    assert code == 2 and "Traceback" not in err, err
    start = lines[3].index('"') + 2   # the column of the request's first character
    col = start + (request_text.index(fragment) if fragment else len(request_text))
    assert err.startswith(f"error: {job}:4:{col}: "), err
    assert message in err, err


def test_a_command_line_request_error_names_the_option(capsys):
    request = "mission::done == true where mission::nope == 1"
    code, err = _cli(capsys, "check", SPEC, "--request", request)
    assert code == 2
    assert err.startswith(f"error: --request:1:{request.index('mission::nope') + 1}: "), err


def test_an_api_request_error_is_at_the_tests_line():
    spec = load_spec(SPEC)
    with pytest.raises(SpecCheckError) as info:
        spec.explore("mission::dne == true", ["deadlock"])
    pos = info.value.pos
    assert pos.file == __file__
    with open(__file__, encoding="utf-8") as f:
        line = f.read().splitlines()[pos.line - 1]
    assert line[pos.col - 1:].startswith("mission::dne"), (line, pos)


def test_relocation_moves_every_position_of_the_text_and_nothing_else():
    origin = Pos("job.toml", 7, 12)
    exc = RoarError("bad", Pos("<request>", 1, 5), notes=["<request>:2:3: second", "other.roar:1:1: kept"])
    relocate(exc, "<request>", origin)
    assert exc.pos == Pos("job.toml", 7, 16)
    assert exc.notes == ["job.toml:8:3: second", "other.roar:1:1: kept"]
    elsewhere = RoarError("in the spec", Pos("spec.roar", 3, 4))
    with pytest.raises(RoarError) as info:
        with written_at("<request>", origin):
            raise elsewhere
    assert info.value.pos == Pos("spec.roar", 3, 4)
