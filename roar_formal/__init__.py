"""roar-formal: verification toolkit for ROAR robot control architectures.

Parts: ``clf`` (the CLF engine), ``tca`` (Simmons' task-tree axioms in Z3),
``explore`` (explicit-state model checking), ``roar`` (agent specs compiled to
CLF), ``robot`` (pymunk reference robot), ``trace`` (the shared trace format),
``testing`` (strategies, assertion helpers and a pytest plugin).

The public API (docs/testing.md) is importable from here::

    import roar_formal as rf
    spec = rf.load_spec("specs/pick.roar")
    print(spec.run("cell::lifted == true", faults=["close_jaws:1"]))
    rf.load("models/clf/arith.clf").explore(["deadlock"])

Its names load on first use, so that ``import roar_formal.errors`` (and the
command line) do not pay for them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: public name -> module that defines it
_PUBLIC = {
    "load": "roar_formal.testing.api",
    "load_spec": "roar_formal.testing.api",
    "load_clf": "roar_formal.testing.api",
    "AgentSpec": "roar_formal.testing.api",
    "ClfModel": "roar_formal.testing.api",
    "ClfRun": "roar_formal.testing.api",
    "RunReport": "roar_formal.testing.api",
    "Exploration": "roar_formal.testing.api",
    "Counterexample": "roar_formal.testing.api",
    "Job": "roar_formal.testing.api",
    "load_job": "roar_formal.testing.api",
    "load_jobs": "roar_formal.testing.api",
    "replay": "roar_formal.testing.api",
    "Replay": "roar_formal.testing.api",
    "Budget": "roar_formal.explore.search",
    "RoarError": "roar_formal.errors",
}

__all__ = ["__version__", *_PUBLIC]

if TYPE_CHECKING:  # pragma: no cover - for type checkers: the lazy names are these
    from .errors import RoarError
    from .explore.search import Budget
    from .testing.api import (AgentSpec, ClfModel, ClfRun, Counterexample, Exploration, Job, Replay, RunReport,
                              load, load_clf, load_job, load_jobs, load_spec, replay)


def __getattr__(name: str) -> Any:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'roar_formal' has no attribute {name!r}")
    import importlib
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
