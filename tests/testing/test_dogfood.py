"""The project's central cross-checks, written with roar_formal.testing's own strategies and API.

* every committed-choice run (``AgentSpec.run``, any seed, any ``fault_schedules``) is a path of
  the explorer's graph (``AgentSpec.explore``): each step of the run is an enabled step of the
  state before it (a functional-layer answer, the outcome step with the same facts), and every
  state it passes through is a state the explorer visited;
* compiled specs pass the static checks they were generated to pass: the spec's checks when
  generated (``specs``), and CLF's type checker on the program the compiler made of it;
* every ROAR trace is a TCA task tree that satisfies the axioms: ``tca-check`` on the trace a
  run writes, and on random paths through an explored model (``paths``), finds nothing but
  broken sequential-achievement constraints (which a spec may break; the explorer's monitor
  decides those, tests/tca/test_roar_runs.py).

Compiling a generated spec costs about a second (the spec, then its CLF program): few examples
of those; the bundled spec is compiled and explored once, and its runs are cheap.
"""

from __future__ import annotations

import re
import tempfile
from collections import Counter
from pathlib import Path

from hypothesis import HealthCheck, given, settings, strategies as st

from roar_formal.clf.printer import show
from roar_formal.clf.terms import Root
from roar_formal.tca.check import check_events, check_trace
from roar_formal.tca.roar_runs import task_tree_events
from roar_formal.testing import fault_schedules, load_spec, paths, spec_requests
from repo import ROOT

FEW = settings(max_examples=4, deadline=None, database=None, derandomize=True,
               suppress_health_check=list(HealthCheck))
SEEDS = st.lists(st.integers(0, 10**6), min_size=1, max_size=2, unique=True)

_FRESH = re.compile(r"[A-Za-z_][A-Za-z0-9_']*#\d+")


def _facts(printed: list[str]) -> Counter:
    """Printed facts with fresh names forgotten: a run and the enumerator number them differently."""
    return Counter(_FRESH.sub("#", x) for x in printed)


def _same_step(run_step: tuple, step) -> bool:
    _rule, consumed, produced = run_step
    return (_facts(consumed) == _facts([show(f) for _m, f in step.consumed if type(f) is Root])
            and _facts(produced) == _facts([show(f) for _m, f in step.produced if type(f) is Root]))


def _walk(run, start, system, visited) -> None:
    """Re-take a run on the explorer's system: every step an enabled step of the state before it
    (a functional-layer answer: the model's outcome step with the same facts), every state one the
    explorer visited; where the run stopped, the model stops too."""
    state = start
    for i, run_step in enumerate(run.result.steps, 1):
        rule = run_step[0]
        for choice in system.program.steps(state):
            if choice.rule != rule and not (rule == "functional_layer" and choice.rule.startswith("outcome_")):
                continue
            nxt, step = system.program.successor(state, choice)
            if _same_step(run_step, step):
                state = nxt
                break
        else:
            raise AssertionError(f"step {i} ({rule}) of the run is not a step of the model\n{run}")
        assert system.key(state) in visited, f"step {i} ({rule}) reaches a state the explorer did not visit\n{run}"
    if run.quiescent:
        assert not system.program.steps(state), f"the run stopped where the model can go on\n{run}"


def _no_broken_axiom(report) -> None:
    assert report.tree.messages, "a run sends its request: the tree has a goal"
    broken = [v for v in report.violations if "seq_ach" not in v.rule]
    assert not broken, [v.explanation for v in broken]


PICK = load_spec(ROOT / "docs" / "examples" / "pick_fixed" / "pick.roar")
PICK_REQUEST = "cell::lifted == true"
_EXPLORED: dict = {}


def _explored(spec, request):
    """(start, system, visited state keys) of the spec's whole state space, explored once."""
    key = (spec.name, request)
    if key not in _EXPLORED:
        res = spec.explore(request, ["deadlock"])
        assert res.complete
        _model, start, explorer = res.result.roar
        _EXPLORED[key] = (start, explorer.system, {explorer.system.key(s) for s in explorer.states})
    return _EXPLORED[key]


@settings(FEW, max_examples=15)
@given(fault_schedules(PICK, max_faults=2), st.integers(0, 10**6))
def test_committed_choice_runs_are_paths_of_the_explorers_graph_and_task_trees(faults, seed):
    """Seeded runs under fault schedules, on a spec with a functional layer; each run's trace is
    also checked against the TCA axioms (``run --trace`` then ``tca-check``)."""
    start, system, visited = _explored(PICK, PICK_REQUEST)
    run = PICK.run(PICK_REQUEST, seed=seed, faults=faults)
    _walk(run, start, system, visited)
    with tempfile.TemporaryDirectory() as tmp:
        _no_broken_axiom(check_trace(run.save_trace(Path(tmp) / "run.jsonl")))


@settings(FEW, max_examples=3)
@given(spec_requests(max_statements=3), SEEDS)
def test_generated_specs_compile_to_checked_programs_whose_runs_are_paths_and_task_trees(spec_and_request,
                                                                                          seeds):
    """Generated specs (which pass the spec's static checks, tests/testing/test_strategies.py)
    compile to programs that pass CLF's type checker, their runs end, and the runs, for any seed,
    are paths of the explorer's graph and task trees that satisfy the axioms."""
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import Options
    from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem
    spec, request = spec_and_request
    model = spec.compile(request, "abstract")
    program = model.program()       # type-checked: a compiler bug is an error here
    start = program.start_context(next(d for d in program.sig.directives if hasattr(d, "start")).start)
    system = RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent"))
    explorer = Explorer(system, "bfs")
    complete = explorer.run(Budget(max_states=5_000)).complete
    visited = {system.key(s) for s in explorer.states}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            run = spec.run(request, seed=seed, max_steps=500)
            assert run.outcome in ("success", "failure", "running", "pending", "paused", "temporary failure")
            assert run.events and run.events[0].text.startswith("R0 sent -> pending")
            if complete:
                _walk(run, start, system, visited)
            _no_broken_axiom(check_trace(run.save_trace(Path(tmp) / f"run{seed}.jsonl")))


ORDERED = load_spec(ROOT / "models" / "faulty" / "ordered_pick.roar")
ORDERED_REQUEST = "cell::done == true"


@settings(FEW, max_examples=12)
@given(paths(ORDERED, ORDERED_REQUEST, max_length=80))
def test_every_path_of_an_explored_model_is_a_task_tree_that_satisfies_the_axioms(path):
    """The traces of counterexamples and replays (paths of the explorer, not runs): the same."""
    model = ORDERED.compile(ORDERED_REQUEST, "abstract")
    per: list = [[] for _ in path.steps]
    for ev in path.events:
        per[ev.step - 1].append(ev.as_json())
    records = [{"rule": rule, "step": i, "consumed": [show(f) for _m, f in step.consumed if type(f) is Root],
                "produced": [show(f) for _m, f in step.produced if type(f) is Root],
                "event": (evs[0] if len(evs) == 1 else {"kind": "several", "events": evs}) if evs else None}
               for i, (rule, step, evs) in enumerate(zip(path.rules, path.steps, per), 1)]
    from roar_formal.roar.explore import sequential_pairs
    pairs = [[p.a, p.b] for p in sequential_pairs(model)]
    assert pairs, "ordered_pick has a `make A; make B` pair"
    report = check_events(task_tree_events({"trace": "roar-formal", "seq_pairs": pairs}, records))
    broken = [v for v in report.violations if "seq_ach" not in v.rule]
    assert not broken, [v.explanation for v in broken]
