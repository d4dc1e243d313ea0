"""Shared set-up of the tests of roar_formal.testing: pytester, the project's paths, a plain console."""

from pathlib import Path

import pytest

pytest_plugins = ["pytester"]


@pytest.fixture(scope="session")
def root() -> Path:
    return Path(__file__).resolve().parents[2]


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


def cli(capsys, *argv) -> tuple[int, str, str]:
    """Run ``roar-verify`` in-process: (exit status, stdout, stderr)."""
    from roar_formal.cli import main
    code = 0
    try:
        main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def run_cli(capsys, plain_console):
    return lambda *argv: cli(capsys, *argv)
