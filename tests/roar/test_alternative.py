"""The calling-context search (5.3) switches a holder onto an alternative recipe only when that
recipe is acceptable now (its pre-conditions hold); before, the alternative was decided from the
recipes' constraint domains alone, the holder was switched onto a recipe that could not run, and
what is a conflict was reported as the holder's task failure."""

from __future__ import annotations

from pathlib import Path

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec

DATA = Path(__file__).parent / "data"


def _runs(which: str, seeds: int = 6):
    model = compile_spec(load_spec(DATA / f"alt_{which}.roar"), "mission::done == true")
    out = []
    for seed in range(seeds):
        r = run_model(model, seed=seed)
        verdicts = [e.text.split(": ", 1)[1] for e in r.events if e.kind == "calling-context"]
        out.append((r, verdicts))
    return out


def test_an_unacceptable_alternative_is_no_alternative():
    for r, verdicts in _runs("unacceptable"):
        # the tracker's wide_angle recipe cannot run (its camera is out): the search goes up to the
        # outside, and the inspector's constraint fails with the concurrency issue
        assert verdicts == ["the emitter of R2 has no alternative: asking its caller",
                            "the emitter of R1 has no alternative: asking its caller",
                            "the emitter of R0 is a request from outside: the conflict cannot be resolved"]
        assert r.outcome == "failure"
        assert "constraint failed: inspector::inspected == true" in r.error_context
        assert not any("tracker::track" in e for e in r.error_context), r.error_context
        assert not any(e.kind == "recipe" and "wide_angle" in e.text for e in r.events)


def test_an_acceptable_alternative_reconfigures():
    for r, verdicts in _runs("acceptable"):
        assert verdicts == ["the emitter of R2 has an alternative: it reconfigures"]
        assert r.outcome == "success", r.error_context
        assert any(e.kind == "recipe" and "wide_angle" in e.text for e in r.events)
