"""A run of a spec as a trace (the project's JSON Lines format, trace/format.py)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Optional

from ..trace.format import write_trace
from .explore import sequential_pairs
from .sources import spec_fingerprint

__all__ = ["write_run_trace", "run_records", "jsonable"]


def jsonable(v):
    """A ROAR value as JSON: fractions as numbers, tuples as lists."""
    if isinstance(v, Fraction):
        return float(v)
    if isinstance(v, tuple):
        return [jsonable(x) for x in v]
    return v


def write_run_trace(path: Path, res, spec, request: str, seed: int, faults,
                    functional: Optional[Path] = None) -> None:
    """The run as a JSON Lines trace: one line per CLF step, with its ROAR events; the header
    names the sequential-achievement pairs (for ``tca-check``) and the sources' fingerprint
    (so that replaying it on other sources is refused)."""
    header, steps = run_records(res, spec, request, seed, faults, functional)
    write_trace(path, header, steps)


def run_records(res, spec, request: str, seed: int, faults, functional: Optional[Path] = None) \
        -> tuple[dict, list[dict]]:
    """(header, step records) of a run, as :func:`write_run_trace` writes them."""
    by_step: dict[int, list] = {}
    for e in res.events:
        by_step.setdefault(e.step, []).append(e.as_json())
    steps = []
    for i, (rule, consumed, produced) in enumerate(res.steps, 1):
        evs = by_step.get(i)
        steps.append({"rule": rule, "consumed": consumed, "produced": produced,
                      "event": (evs[0] if len(evs) == 1 else {"kind": "several", "events": evs}) if evs else None,
                      "loop": False})
    header = {"kind": "roar-run", "seq_pairs": [[p.a, p.b, p.where, p.a_text, p.b_text]
                                                for p in sequential_pairs(res.model)],
              "spec": str(spec), "request": request, "seed": seed, "faults": list(faults),
              "outcome": res.outcome, "requests": res.requests,
              "fingerprint": spec_fingerprint(Path(spec), res.model.spec, functional)}
    crashes = getattr(res.model, "crashes", None)
    if crashes:   # compiled with crashes (--crash: crash_setup); replay recompiles the same model
        header["crash"], header["max_crashes"] = list(crashes.agents), crashes.bound
    timing = getattr(res.model, "timing", None)
    if timing:   # the timed model (replay recompiles the same one)
        header.update(timing.header())
    return header, steps
