"""Shared set-up of the tests of roar_formal.testing: pytester, the project's paths, a plain console."""

import re
from pathlib import Path

import pytest
from repo import ROOT

pytest_plugins = ["pytester"]


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def examples(root) -> Path:
    return root / "docs" / "examples"


@pytest.fixture(scope="session")
def models(root) -> Path:
    return root / "models"


@pytest.fixture
def plain_console(monkeypatch):
    """The command line's output without colours or wrapping, to compare with the API's."""
    for var in ("FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE", "ROAR_DEBUG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("COLUMNS", "10000")
    monkeypatch.setenv("NO_COLOR", "1")


@pytest.fixture
def run_cli(roar_cli, plain_console):
    """The shared in-process command line (tests/conftest.py), with this folder's wider lines."""
    return roar_cli


def _norm(line: str) -> str:
    return re.sub(r"^E\s+", "", line.strip()).strip("= ").strip()


@pytest.fixture(scope="session")
def docs_shows(root):
    """``docs_shows(name, output)``: every line of the ```text block after ``<!-- output: NAME -->``
    in docs/testing.md is a line of ``output``, in order ("..." stands for anything; pytest's "E"
    prefixes and indentation are ignored)."""
    text = (root / "docs" / "testing.md").read_text(encoding="utf-8")

    def check(name: str, output: str) -> None:
        m = re.search(rf"<!-- output: {name} -->\n```text\n(.*?)\n```", text, re.S)
        assert m, f"docs/testing.md has no output block {name!r}"
        lines = [_norm(x) for x in output.splitlines()]
        i = 0
        for want in m.group(1).splitlines():
            if want.strip() == "...":
                continue
            pattern = re.compile(re.escape(_norm(want)).replace(re.escape("..."), ".*"))
            while i < len(lines) and not pattern.fullmatch(lines[i]):
                i += 1
            assert i < len(lines), f"docs/testing.md ({name}): not in the output (in order): {want!r}\n{output}"
            i += 1

    return check
