"""Property-based and exhaustive tests of agent specs and CLF models (docs/testing.md).

* the public API (:mod:`.api`, also exported by ``roar_formal``): load, run, explore;
* assertion helpers (:mod:`.assertions`) whose failure message is the printed
  counterexample and the path of its replayable trace;
* hypothesis strategies (:mod:`.strategies`): CLF terms and programs, agent
  specs that pass the static checks, requests, fault schedules, paths;
* a ``RuleBasedStateMachine`` over the executable model (:mod:`.stateful`);
* the pytest plugin (:mod:`.plugin`, registered through ``pytest11``).

Names load on first use: the pytest plugin imports this package in every
test run, and hypothesis and the compiler are not needed for that.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

_PUBLIC = {
    **{n: "api" for n in ("load", "load_spec", "load_clf", "load_job", "load_jobs", "AgentSpec", "ClfModel", "ClfRun",
                          "RunReport", "Exploration", "Counterexample", "Job", "Budget", "RoarError", "Replay",
                          "replay")},
    **{n: "assertions" for n in ("RoarAssertionError", "TestSettings", "DEFAULT_BUDGET", "current_settings",
                                 "using_settings", "assert_no_deadlock", "assert_no_livelock",
                                 "assert_sequential_achievement", "assert_invariant", "assert_conforms",
                                 "assert_succeeds")},
    **{n: "strategies" for n in ("clf_terms", "clf_programs", "specs", "requests", "spec_requests",
                                 "fault_schedules", "paths", "ModelPath", "STATEMENT_KINDS", "statement_kinds")},
    **{n: "stateful" for n in ("RoarMachine",)},
}

__all__ = sorted(_PUBLIC)

if TYPE_CHECKING:  # pragma: no cover
    from .api import (AgentSpec, Budget, ClfModel, ClfRun, Counterexample, Exploration, Job, Replay, RoarError,
                      RunReport, load, load_clf, load_job, load_jobs, load_spec, replay)
    from .assertions import (DEFAULT_BUDGET, RoarAssertionError, TestSettings, assert_conforms, assert_invariant,
                             assert_no_deadlock, assert_no_livelock, assert_sequential_achievement, assert_succeeds,
                             current_settings, using_settings)
    from .stateful import RoarMachine
    from .strategies import (STATEMENT_KINDS, ModelPath, clf_programs, clf_terms, fault_schedules, paths,
                             requests, spec_requests, specs, statement_kinds)


def __getattr__(name: str) -> Any:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'roar_formal.testing' has no attribute {name!r}")
    import importlib
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
