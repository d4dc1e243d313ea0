"""B5: the TCA logic in Z3 (see benchmarks.md B5).

Measured, medians over the repeats:
  * every obligation of the axiom set (``roar-verify prove``): theorems, the
    induction lemma's base and step, refutations with their countermodel, and
    the consistency checks; target under 1 s each;
  * the Ambler model's claims (ordering claims and the metric plan-ahead bound);
  * checking a trace of a 1,011-message Ambler walk (10 arcs of 25 steps)
    against the axioms, with the goals' achievement intervals in the trace and
    without them (then Z3 decides their existence); target under 10 s;
  * the peak memory of ``tca-check`` on 4,000-message traces (a deep chain of
    goals with contradicting declarations, the shape that once made the
    solver's core minimisation quadratic, and an Ambler walk), each in a fresh
    process (VmHWM); target far within 2 GB.
Baselines from the same run: an empty Z3 check for the obligations, and just
reading the trace and building its task tree for the trace check.

Run: ``python bench/b5_tca.py`` (or ``python bench/run.py b5``).
"""

from __future__ import annotations

import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import z3  # noqa: E402

from roar_formal.tca.check import check_trace  # noqa: E402
from roar_formal.tca.metric import metric_outcome  # noqa: E402
from roar_formal.tca.model import load_model  # noqa: E402
from roar_formal.tca.prover import prove  # noqa: E402
from roar_formal.tca.schedule import sample_timing, simulate  # noqa: E402
from roar_formal.tca.tasktree import build_tree  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "tca"))   # trace shapes shared with the tests
from trace_shapes import deep_chain  # noqa: E402
from roar_formal.tca.theorems import OBLIGATIONS  # noqa: E402
from roar_formal.tca.trace_events import dumps, read_events  # noqa: E402
from roar_formal.tca.unroll import unroll  # noqa: E402
from roar_formal.tca.window import claim_obligation  # noqa: E402

NAME = "b5"
TITLE = "TCA axioms in Z3: obligations and trace checking"
AMBLER = Path(__file__).resolve().parents[1] / "models" / "ambler" / "ambler.toml"
OBLIGATION_TARGET_S = 1.0
TRACE_TARGET_S = 10.0


def _median(fn, repeats: int):
    times, last = [], None
    for _ in range(repeats):
        began = time.perf_counter()
        last = fn()
        times.append(time.perf_counter() - began)
    return statistics.median(times), last


def _empty_check() -> None:
    s = z3.Solver()
    s.add(z3.BoolVal(True))
    s.check()


def _obligations(repeats: int) -> list[dict]:
    model = load_model(AMBLER)
    rows = []
    for ob in OBLIGATIONS:
        seconds, outcome = _median(lambda: prove(ob), repeats)
        rows.append({"obligation": ob.name, "expected": ob.expect, "result": outcome.status, "seconds": seconds})
    for claim in model.claims:
        if claim.metric:
            seconds, outcome = _median(lambda: metric_outcome(model, claim), repeats)
        else:
            ob = claim_obligation(model, claim)
            seconds, outcome = _median(lambda: prove(ob), repeats)
        rows.append({"obligation": f"{model.name}:{claim.name}", "expected": claim.expect,
                     "result": outcome.status, "seconds": seconds})
    return rows


def _trace_checks(repeats: int, quick: bool) -> list[dict]:
    model = load_model(AMBLER)
    sizes = {"arcs": 2, "steps": 5} if quick else {"arcs": 10, "steps": 25}
    inst = unroll(model, sizes)
    timing = sample_timing(inst, random.Random(5))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for achievement in (True, False):
            path = Path(tmp) / f"walk_{achievement}.jsonl"
            path.write_text(dumps(simulate(inst, timing, achievement)), encoding="utf-8")
            base, _ = _median(lambda: build_tree(read_events(path)), repeats)
            seconds, report = _median(lambda: check_trace(path), repeats)
            rows.append({"messages": len(inst.nodes), "achievement_in_trace": achievement,
                         "violations": len(report.violations), "instances": report.instances,
                         "solved_by_z3": report.residual, "read_s": base, "check_s": seconds,
                         "ratio": seconds / base})
    return rows


PEAK = """
import json, re, sys, time
from pathlib import Path
from roar_formal.tca.check import check_trace
t = time.perf_counter()
r = check_trace(sys.argv[1])
hwm = int(re.search(r"VmHWM:\\s+(\\d+) kB", Path("/proc/self/status").read_text()).group(1))
print(json.dumps({"messages": len(r.tree.messages), "violations": len(r.violations),
                  "seconds": time.perf_counter() - t, "peak_mb": hwm / 1024}))
"""


def _peaks(quick: bool) -> list[dict]:
    """tca-check's peak memory on 4,000-message traces, each in a fresh process."""
    import json
    import subprocess
    if not Path("/proc/self/status").exists():
        return []
    n = 400 if quick else 4000
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        chain = Path(tmp) / "chain.jsonl"
        chain.write_text(deep_chain(n, 50))
        walk = Path(tmp) / "walk.jsonl"
        inst = unroll(load_model(AMBLER), {"arcs": 2, "steps": 50 if quick else 500})
        walk.write_text(dumps(simulate(inst, sample_timing(inst, random.Random(5)), True)), encoding="utf-8")
        for shape, path in (("deep chain", chain), ("Ambler walk", walk)):
            out = subprocess.run([sys.executable, "-c", PEAK, str(path)], capture_output=True, text=True,
                                 timeout=1200, env={**__import__("os").environ,
                                                    "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
            if out.returncode != 0:
                raise RuntimeError(out.stderr)
            rows.append({"shape": shape, **json.loads(out.stdout)})
    return rows


def run(repeats: int = 5, quick: bool = False) -> dict:
    baseline, _ = _median(_empty_check, max(repeats, 5))
    obligations = _obligations(1 if quick else repeats)
    traces = _trace_checks(1 if quick else repeats, quick)
    peaks = _peaks(quick)
    pk_rows = [[r["shape"], r["messages"], r["violations"], f"{r['seconds']:.2f}", f"{r['peak_mb']:.0f}",
                "ok" if r["peak_mb"] < 2048 else "MISSED"] for r in peaks]
    ob_rows = [[r["obligation"], r["expected"], r["result"], f"{r['seconds']:.3f}",
                f"{r['seconds'] / baseline:.0f}",
                "ok" if r["seconds"] < OBLIGATION_TARGET_S and r["result"] == r["expected"] else "MISSED"]
               for r in obligations]
    tr_rows = [[r["messages"], "yes" if r["achievement_in_trace"] else "no", r["violations"], r["instances"],
                r["solved_by_z3"], f"{r['read_s']:.3f}", f"{r['check_s']:.3f}", f"{r['ratio']:.1f}",
                "ok" if r["check_s"] < TRACE_TARGET_S and r["violations"] == 0 else "MISSED"] for r in traces]
    return {
        "name": NAME,
        "title": TITLE,
        "repeats": repeats,
        "baseline": f"empty Z3 check {baseline * 1e3:.2f} ms; reading the trace (same run)",
        "obligations": obligations,
        "traces": traces,
        "peaks": peaks,
        "tables": [
            {"title": "obligations (median seconds; x = over an empty Z3 check)",
             "columns": ["obligation", "expected", "result", "s", "x empty", "target < 1 s"], "rows": ob_rows},
            {"title": "trace check of an Ambler walk (median seconds)",
             "columns": ["messages", "ach. in trace", "violations", "instances", "by Z3", "read s", "check s",
                         "x read", "target < 10 s"], "rows": tr_rows},
            {"title": "peak memory of tca-check (a fresh process each)",
             "columns": ["trace", "messages", "violations", "s", "peak MB", "target < 2 GB"], "rows": pk_rows},
        ],
        "notes": [f"medians of {repeats} runs" + (" (quick: one run, small trace)" if quick else ""),
                  "check includes reading the file; 'by Z3' counts instances left to the solver"],
    }


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from run import main

    sys.exit(main(["b5", *sys.argv[1:]]))
