"""The bundled verification jobs' results, explored once per test session and shared by every
test that reads them (the bundled networks are the suite's slowest inputs). A module of its own
name: test modules import it directly (``conftest`` is not unique across the test folders)."""

from __future__ import annotations

import gc
from repo import ROOT

_CHECKER_RESULTS: dict = {}


def checker_result(name: str):
    """The result of the bundled job ``checker/<name>``, explored once per test session and
    shared by every test that reads it (the bundled networks are the suite's slowest inputs)."""
    if name not in _CHECKER_RESULTS:
        from roar_formal.clf.query import with_big_stack
        from roar_formal.verify.check import run_job
        from roar_formal.verify.jobs import load_job
        path = ROOT / "checker" / name
        _CHECKER_RESULTS[name] = with_big_stack(lambda: run_job(load_job(path)))
        # kept for the session: out of the cyclic collector's sight, so that the millions of
        # objects of an explored network do not slow every later collection
        gc.collect()
        gc.freeze()
    return _CHECKER_RESULTS[name]


