"""Assertion helpers for tests of agent specs and CLF models.

Each helper explores (or runs) its target and, when the property fails,
raises :class:`RoarAssertionError` whose message is the counterexample as
``roar-verify check`` prints it, followed by the path of its replayable
trace. A search that runs out of budget is a failure too ("not decided"),
never a pass, unless the caller allows it.

Budgets and the trace folder come from :func:`current_settings`: the pytest
plugin sets them per test (``@pytest.mark.roar_budget``, ``--roar-budget``,
``--roar-traces``); outside pytest the defaults apply.
"""

from __future__ import annotations

import contextlib
import contextvars
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterator, Optional, Sequence, Union

from ..errors import RoarError
from ..explore.search import Budget
from .api import AgentSpec, BudgetLike, ClfModel, Exploration, FaultLike, RunReport, scratch_folder, as_budget, load

__all__ = [
    "RoarAssertionError", "TestSettings", "DEFAULT_BUDGET", "current_settings", "using_settings",
    "assert_no_deadlock", "assert_no_livelock", "assert_sequential_achievement", "assert_invariant",
    "assert_conforms", "assert_succeeds",
]

#: the budget of an exploration in a test when nothing else says: a test must end
DEFAULT_BUDGET = Budget(max_states=200_000, max_seconds=120)

Target = Union[AgentSpec, ClfModel, str, Path]


class RoarAssertionError(AssertionError):
    """A property of a spec or model does not hold; the message is the printed counterexample."""

    def __init__(self, message: str, exploration: Optional[Exploration] = None, trace: Optional[Path] = None,
                 run: Optional[RunReport] = None):
        super().__init__(message)
        self.exploration = exploration
        self.trace = trace
        self.run = run


@dataclass(frozen=True)
class TestSettings:
    """What the helpers use when a call does not say: the exploration budget and the folder
    where counterexample traces are written (None: a scratch folder of the process)."""

    __test__ = False   # not a test class, whatever pytest thinks of the name

    budget: Budget = field(default_factory=lambda: DEFAULT_BUDGET)
    traces: Optional[Path] = None

    def traces_folder(self) -> Path:
        folder = self.traces if self.traces is not None else scratch_folder() / "roar-traces"
        folder.mkdir(parents=True, exist_ok=True)
        return folder


_SETTINGS: contextvars.ContextVar[Optional[TestSettings]] = contextvars.ContextVar("roar_formal_test_settings",
                                                                                    default=None)


def current_settings() -> TestSettings:
    """The settings of :func:`using_settings`, else the pytest plugin's for the running test, else
    the defaults."""
    s = _SETTINGS.get()
    if s is not None:
        return s
    from .session import PLUGIN
    given = PLUGIN.get()
    if given is None:
        return TestSettings()
    budget, traces = given
    return TestSettings(replace(DEFAULT_BUDGET, **budget), traces())


@contextlib.contextmanager
def using_settings(settings: TestSettings) -> Iterator[TestSettings]:
    """Use ``settings`` within the block (the plugin wraps each test in one)."""
    token = _SETTINGS.set(settings)
    try:
        yield settings
    finally:
        _SETTINGS.reset(token)


def _budget(budget: BudgetLike) -> Budget:
    """The call's budget, keys it leaves out taken from the current settings."""
    base = current_settings().budget
    if budget is None:
        return base
    b = as_budget(budget)
    return replace(base, **{k: v for k, v in vars(b).items() if v is not None})


def _target(target: Target) -> Union[AgentSpec, ClfModel]:
    if isinstance(target, (AgentSpec, ClfModel)):
        return target
    if isinstance(target, (str, Path)):
        return load(target)
    raise TypeError(f"expected an AgentSpec, a ClfModel or a path, not {type(target).__name__}")


def _explore(target: Target, request: Optional[str], props: list[str], budget: BudgetLike, **kw: Any) -> Exploration:
    t = _target(target)
    if isinstance(t, AgentSpec):
        if request is None:
            raise RoarError(f"{t.name}: exploring an agent spec needs a request, e.g. 'agent::done == true'")
        for k in ("start", "fairness", "accept"):
            if kw.pop(k, None) is not None:
                raise RoarError(f"'{k}' is for .clf models, not agent specs")
        return t.explore(request, props, budget=_budget(budget), **kw)
    if request is not None:
        raise RoarError(f"{t.name}: a .clf model takes no request (its start state is an #exec directive)")
    for k in ("sequence_recipes", "kept"):
        if kw.pop(k, None):
            raise RoarError(f"'{k}' reads ROAR events: it is for agent specs")
    kw = {k: v for k, v in kw.items() if v is not None}
    return t.explore(props, budget=_budget(budget), **kw)


def _verdict(res: Exploration, prop: str, allow_incomplete: bool) -> Exploration:
    __tracebackhide__ = True
    v = res.verdict(prop)
    if v.status == "holds" or (v.status == "incomplete" and allow_incomplete):
        return res
    if v.status == "incomplete":
        raise RoarAssertionError(
            f"{prop} not decided on {res.title}: {v.message}\n"
            f"  a test passes only on a complete search: raise the budget with "
            f"@pytest.mark.roar_budget(max_states=..., max_seconds=...) or --roar-budget, "
            f"or pass allow_incomplete=True", res)
    cx = res.counterexample(prop)
    assert cx is not None
    trace = cx.save(current_settings().traces_folder())
    raise RoarAssertionError(f"{prop} violated on {res.title}\n{cx.format()}", res, trace)


def assert_no_deadlock(target: Target, request: Optional[str] = None, *, budget: BudgetLike = None,
                       start: Optional[int] = None, accept: Optional[str] = None,
                       allow_incomplete: bool = False) -> Exploration:
    """No reachable deadlock: on a spec, a quiescent state where a request is not final or a
    recipe is still live; on a .clf model, a quiescent state ``accept`` does not match."""
    __tracebackhide__ = True
    return _verdict(_explore(target, request, ["deadlock"], budget, start=start, accept=accept),
                    "deadlock", allow_incomplete)


def assert_no_livelock(target: Target, request: Optional[str] = None, *, progress: Sequence[str] = (),
                       budget: BudgetLike = None, start: Optional[int] = None, fairness: Optional[str] = None,
                       allow_incomplete: bool = False) -> Exploration:
    """No fair cycle without progress (on a spec: without a request reaching a final state)."""
    __tracebackhide__ = True
    return _verdict(_explore(target, request, ["livelock"], budget, progress=progress, start=start,
                             fairness=fairness), "livelock", allow_incomplete)


def assert_sequential_achievement(spec: Target, request: str, *, recipes: Sequence[str] = (),
                                  kept: Union[bool, Sequence[str]] = False,
                                  budget: BudgetLike = None, allow_incomplete: bool = False) -> Exploration:
    """TCA sequential achievement for every ``make A; make B`` (of ``recipes``, 'agent.task.recipe');
    with ``kept`` (True, or recipe names), also that an achieved sub-goal still holds when a later
    one of its block is achieved and when its recipe ends (a property file's ``kept``)."""
    __tracebackhide__ = True
    return _verdict(_explore(spec, request, ["sequential-achievement"], budget, sequence_recipes=recipes,
                             kept=kept),
                    "sequential-achievement", allow_incomplete)


def assert_invariant(target: Target, request: Optional[str] = None, *, never: Sequence[str] = (),
                     exclusive_writes: bool = False, budget: BudgetLike = None, start: Optional[int] = None,
                     allow_incomplete: bool = False) -> Exploration:
    """No reachable state satisfies a ``never`` predicate or matches a ``never`` pattern: on a spec,
    as a job file's ``[invariant] never``, predicates in the spec's terms (``"cell::rate == 5"``) or
    CLF patterns; on a .clf model, CLF patterns (docs/checking.md "Invariants"). With
    ``exclusive_writes`` (specs), no variable is written by two live where clauses."""
    __tracebackhide__ = True
    if isinstance(never, str):
        never = [never]
    props = (["exclusive-writes"] if exclusive_writes else []) + (["invariant"] if never else [])
    if not props:
        raise RoarError("assert_invariant needs never=[...] patterns or exclusive_writes=True")
    res = _explore(target, request, props, budget, never=list(never), start=start)
    for p in props:
        _verdict(res, p, allow_incomplete)
    return res


def assert_conforms(spec: Target, request: str, scenario: Union[str, Path], *, runs: int = 3, seed: int = 0,
                    faults: Sequence[str] = (), random_faults: bool = True) -> Any:
    """The robot agrees with the model: every result of ``runs`` seeded robot runs falls into a
    declared outcome and every run is a path of the model (``roar-verify conform``)."""
    __tracebackhide__ = True
    t = _target(spec)
    if not isinstance(t, AgentSpec):
        raise RoarError(f"{t.name}: conformance is checked for agent specs with a robot binding")
    rep = t.conform(request, scenario, runs=runs, seed=seed, faults=faults, random_faults=random_faults)
    if not rep.sound:
        lines = "\n".join(text for text, _style in rep.lines())
        raise RoarAssertionError(f"{t.name} does not conform to the robot of {scenario}\n{lines}")
    return rep


def assert_succeeds(spec: Target, request: str, *, seed: int = 0, faults: Sequence[FaultLike] = (),
                    max_steps: int = 100_000, scenario: Optional[Union[str, Path]] = None,
                    strict_faults: Optional[bool] = None) -> RunReport:
    """One run of ``request`` ends in success; otherwise the message is the run's ROAR-level trace
    (as ``roar-verify run`` prints it) and the path of its JSON Lines trace. A fault that names no
    function of the spec, or that matched no call, is a :class:`RoarError` as in
    :meth:`AgentSpec.run` (``strict_faults=False``: listed in the report's ``unused_faults``)."""
    __tracebackhide__ = True
    t = _target(spec)
    if not isinstance(t, AgentSpec):
        raise RoarError(f"{t.name}: a request runs on an agent spec, not a .clf model")
    run = t.run(request, seed=seed, faults=faults, max_steps=max_steps, scenario=scenario,
                strict_faults=strict_faults)
    if run.ok:
        return run
    stem = re.sub(r"[^A-Za-z0-9_-]", "_", Path(t.name.strip("<>")).stem) or "spec"
    trace = run.save_trace(current_settings().traces_folder() / f"{stem}.run.jsonl")
    how = (f"ended in {run.outcome}, not success" if run.quiescent else
           f"did not finish within {max_steps:,} steps (its request is {run.outcome}; max_steps raises the bound)")
    raise RoarAssertionError(f"request {request} {how}\n{run.format()}\n"
                             f"  trace: {trace}", trace=trace, run=run)
