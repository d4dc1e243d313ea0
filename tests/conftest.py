"""Shared test helpers: the command line run in-process, as a user runs it off a terminal."""

from __future__ import annotations

import pytest


def run_roar_verify(capsys, *argv) -> tuple[int, str, str]:
    """Run ``roar-verify ARGV`` in-process: (exit status, stdout, stderr); never a traceback through."""
    from roar_formal.cli import main
    code = 0
    try:
        main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def roar_cli(capsys, monkeypatch):
    """``roar_cli(*argv) -> (status, stdout, stderr)`` with no colours and wide lines."""
    for var in ("FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE", "ROAR_DEBUG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("COLUMNS", "400")
    monkeypatch.setenv("NO_COLOR", "1")
    return lambda *argv: run_roar_verify(capsys, *argv)


@pytest.fixture
def checker_job():
    """``checker_job(name)``: the shared result of ``checker/<name>`` (tests/checker_cache.py)."""
    from checker_cache import checker_result
    return checker_result
