"""Held ensures are re-checked (4.4: an ensure holds its constraint until aborted; 5.2).

A held ensure whose predicate stops holding, or an ensure whose predicate does not hold once its
tasks ran, goes to temporary failure with the breach in its error context, releases its tasks,
decides again, and its emitter pauses meanwhile (figure 3). Before, a held ensure was never
looked at again: ``ensure_broken.roar`` blocked its user forever, and the seeded fault
``models/faulty/ensure_slammed.roar`` ended in success with the door shut under an ensure that
claimed it open.
"""

from __future__ import annotations

from pathlib import Path

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from repo import ROOT

DATA = Path(__file__).parent / "data"


def _runs(path: Path, seeds: int = 5, max_steps: int = 100_000):
    model = compile_spec(load_spec(path), "user::done == true")
    return model, [run_model(model, seed=seed, max_steps=max_steps) for seed in range(seeds)]


def _texts(r):
    return [(e.step, e.agent, e.text) for e in r.events]


def test_a_broken_held_ensure_pauses_its_emitter_and_is_re_established():
    model, runs = _runs(DATA / "ensure_broken.roar", 6)
    assert "ensure_broken_" + model.request_cst not in model.spec_text   # R0 is a make: no re-check rule
    broken_runs = 0
    for r in runs:
        assert r.outcome == "success", r.error_context
        ev = _texts(r)
        broke = [i for i, (_s, _a, t) in enumerate(ev) if t.startswith("R1 success -> temporary failure")]
        if not broke:   # the door was slammed before R1's final check: R1 was re-activated from there
            assert any(t.startswith("R1 running -> temporary failure") for _s, _a, t in ev), ev
            continue
        broken_runs += 1
        step = ev[broke[0]][0]
        # in the same step the user's recipe pauses (its request shows paused) ...
        assert ("user", "R0 running -> paused  (user::done == true)") in [(a, t) for s, a, t in ev if s == step]
        # ... then the door reopens (R1 running again, open_it chosen again) and the user resumes
        later = [t for s, _a, t in ev if s > step]
        assert "R1 temporary failure -> running  (door::open == true)" in later
        assert "R0 paused -> running  (user::done == true)" in later
        assert later.index("door::open = true") > later.index("R1: task open_it, recipe push")
    assert broken_runs >= 3


def test_a_held_ensure_that_cannot_be_re_established_fails_with_the_breach():
    _model, runs = _runs(ROOT / "models" / "faulty" / "ensure_slammed.roar", 6)
    failed = 0
    for r in runs:
        assert any("R1 success -> temporary failure" in t or "R1 running -> temporary failure" in t
                   for _s, _a, t in _texts(r))
        if r.outcome == "failure":
            failed += 1
            assert r.error_context[-1] == "ensured constraint stopped holding: door::open == true", r.error_context
        else:   # the door reopened between the slam's two writes, before slammed was set: a real interleaving
            assert r.outcome == "success"
    assert failed >= 3


def test_the_fixed_twin_breaks_nothing():
    _model, runs = _runs(ROOT / "models" / "faulty" / "ensure_slammed_fixed.roar")
    for r in runs:
        assert r.outcome == "success"
        assert not any("temporary failure" in t for _s, _a, t in _texts(r))


def test_an_ensure_whose_tasks_never_establish_it_is_a_cycle_mission_completion_reports():
    """The door's rule says a latched door is open; its only task latches without opening. The
    ensure is handled again and again (a monitoring robot would do the same): no run ends, and
    the default mission-completion check reports the cycle, with the reason on the lasso."""
    from roar_formal import load_spec as api_load
    spec = api_load(DATA / "ensure_never_met.roar")
    # (runs that never end: 2,000 steps re-handle R1 over a hundred times, the default bound took 40 s)
    model, runs = _runs(DATA / "ensure_never_met.roar", 3, max_steps=2_000)
    assert model.candidates and any(ts == [("door", "latch")] for ts in model.candidates.values())
    for r in runs:   # (the independent check: plain runs never end, and keep re-handling R1)
        assert r.outcome != "success"
        unmet = [t for _s, _a, t in _texts(r)
                 if t.startswith("R1 running -> temporary failure") and "tasks ran but the ensured" in t]
        assert len(unmet) > 10
    ex = spec.explore("user::done == true", properties=["deadlock", "mission-completion", "mission-failure"])
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "holds"
    v = ex.verdicts["mission-completion"]
    assert v.status == "violated"
    text = str(ex)
    assert "-- cycle (repeats forever) --" in text
    cycle = text.split("-- cycle (repeats forever) --")[1]
    assert "R1: task latch, recipe turn" in cycle and "the ensured predicate does not hold" in cycle
