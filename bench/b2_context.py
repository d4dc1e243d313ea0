"""B2: the CLF engine's forward chaining in a large context (see docs/benchmarks B2).

One rule, ``use : item K -o token K -o {done K}``, and a start context of N
linear facts ``item k_i`` (distinct constants) and T linear tokens
``token k_j`` for T evenly spaced keys: exactly T steps to quiescence, leaving
N - T items and T ``done`` facts.

The start context is built through the library API: the atoms are made with
``roar_formal.clf.terms.const`` (the constants ``k_i`` are not declared: the
forward engine does not type-check facts), tensored into a balanced tree and
loaded with ``program.start_context``; ``build s`` times that. Parsing and
elaborating the same start state as a ``#exec`` text with N constant
declarations is reported separately for the smaller sizes (``text route``):
it is far slower than the run itself.

Measured per (N, T), medians over the repeats: the run to quiescence
(``program.run``), as forward steps per second. The baseline is N = T = 1,000
in the same run: ``ratio`` is steps/s over the baseline's, so a flat engine
shows ratios near 1.0 as N grows 100-fold.

Run: ``python bench/run.py b2`` (or ``python bench/b2_context.py``).
"""

from __future__ import annotations

import gc
import statistics
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from roar_formal.clf.program import Program  # noqa: E402
from roar_formal.clf.query import with_big_stack  # noqa: E402
from roar_formal.clf.terms import Const, One, Tensor, const  # noqa: E402

NAME = "b2"
TITLE = "B2 CLF engine: item K * token K -o {done K} in a large context"
CONFIGS = ((1_000, 1_000), (10_000, 1_000), (100_000, 1_000), (10_000, 10_000), (100_000, 10_000))
QUICK_CONFIGS = ((1_000, 1_000), (10_000, 1_000))
TEXT_SIZES = (1_000, 10_000)
QUICK_TEXT_SIZES = (1_000,)
TARGET_STEPS_PER_S = 50_000
MIN_STEPS = 5_000  # a sample runs ceil(MIN_STEPS / T) fresh contexts, so it is long enough to time

SIGNATURE = r"""
key : type.
item : key -> type.
token : key -> type.
done : key -> type.
use : item K -o token K -o {done K}.
"""


def token_keys(n: int, t: int) -> list[int]:
    return [(j * n) // t for j in range(t)]


def balanced_tensor(atoms: list):
    """``a1 * ... * an`` as a balanced tree (loading it recurses only log n deep)."""
    if not atoms:
        return One()
    if len(atoms) == 1:
        return atoms[0]
    m = len(atoms) // 2
    return Tensor(balanced_tensor(atoms[:m]), balanced_tensor(atoms[m:]))


def start_state(n: int, t: int):
    keys = [const(f"k{i}") for i in range(n)]
    atoms = [const("item", k) for k in keys] + [const("token", keys[j]) for j in token_keys(n, t)]
    return balanced_tensor(atoms)


def check_final(ctx, n: int, t: int) -> bool:
    item, done, token = Const("item"), Const("done"), Const("token")
    counts = {item: 0, done: 0, token: 0}
    for fact, mult in ctx.lin.items():
        counts[fact.head] = counts.get(fact.head, 0) + mult
    want_done = {const("done", const(f"k{j}")) for j in token_keys(n, t)}
    return (counts[item] == n - t and counts[done] == t and counts[token] == 0
            and all(ctx.lin.get(d) == 1 for d in want_done) and not ctx.aff and not ctx.pers)


def _one_context(prog: Program, n: int, t: int, seed: int, freeze: bool) -> tuple[float, float, int, bool]:
    gc.collect()
    t0 = time.perf_counter()
    ctx = prog.start_context(start_state(n, t))
    t_build = time.perf_counter() - t0
    gc.collect()
    if freeze:
        gc.freeze()  # the start state (and everything older) leaves the collector's scans
    try:
        t0 = time.perf_counter()
        steps, quiescent = prog.run(ctx, seed=seed)
        t_run = time.perf_counter() - t0
    finally:
        if freeze:
            gc.unfreeze()
    ok = quiescent and steps == t and check_final(ctx, n, t)
    return t_build, t_run, steps, ok


def _one(prog: Program, n: int, t: int, seed: int, freeze: bool = False) -> dict:
    """One sample: enough fresh contexts for MIN_STEPS steps; build time excluded from run_s."""
    k = max(1, -(-MIN_STEPS // t))
    build = run = 0.0
    steps = 0
    ok = True
    for i in range(k):
        b, r, s, c = _one_context(prog, n, t, seed * k + i, freeze)
        build += b
        run += r
        steps += s
        ok = ok and c
    return {"contexts": k, "build_s": build / k, "run_s": run, "steps": steps, "correct": ok}


def program_text(n: int, t: int) -> str:
    decls = "".join(f"k{i} : key.\n" for i in range(n))
    start = " * ".join([f"item k{i}" for i in range(n)] + [f"token k{j}" for j in token_keys(n, t)])
    return SIGNATURE + decls + f"#exec * {start}.\n"


def _text_route(n: int, t: int) -> dict:
    text = program_text(n, t)
    gc.collect()
    t0 = time.perf_counter()
    prog = Program.from_text(text, f"<b2 n={n}>")
    t_parse = time.perf_counter() - t0
    t0 = time.perf_counter()
    ctx = prog.start_context(prog.sig.directives[0].start)
    t_load = time.perf_counter() - t0
    t0 = time.perf_counter()
    steps, quiescent = prog.run(ctx, seed=0)
    t_run = time.perf_counter() - t0
    return {"parse_s": t_parse, "load_s": t_load, "run_s": t_run, "steps": steps,
            "correct": quiescent and steps == t and check_final(ctx, n, t)}


def run(repeats: int = 5, quick: bool = False, configs=None, text_sizes=None) -> dict:
    configs = tuple(configs or (QUICK_CONFIGS if quick else CONFIGS))
    text_sizes = tuple(text_sizes if text_sizes is not None else (QUICK_TEXT_SIZES if quick else TEXT_SIZES))
    prog = Program.from_text(SIGNATURE, "<b2>")
    rows = []
    for n, t in configs:
        samples = [_one(prog, n, t, seed) for seed in range(repeats)]
        frozen = [_one(prog, n, t, seed, freeze=True) for seed in range(repeats)]
        steps = samples[0]["steps"]
        run_s = statistics.median(s["run_s"] for s in samples)
        frozen_s = statistics.median(s["run_s"] for s in frozen)
        rows.append({
            "items": n, "tokens": t, "contexts_per_sample": samples[0]["contexts"], "steps": steps,
            "correct": all(s["correct"] for s in samples + frozen),
            "build_s": statistics.median(s["build_s"] for s in samples),
            "run_s": run_s,
            "steps_per_s": steps / run_s if run_s else None,
            "us_per_step": 1e6 * run_s / steps if steps else None,
            "frozen_run_s": frozen_s,
            "frozen_steps_per_s": steps / frozen_s if frozen_s else None,
            "samples": samples,
            "frozen_samples": frozen,
        })
    base = rows[0]
    for r in rows:
        r["ratio"] = r["steps_per_s"] / base["steps_per_s"]
        r["meets_target"] = r["steps_per_s"] >= TARGET_STEPS_PER_S
    text_rows = []
    for n in text_sizes:
        t = max(1, n // 10)
        samples = [with_big_stack(_text_route, n, t) for _ in range(max(1, min(repeats, 3)))]
        text_rows.append({
            "items": n, "tokens": t,
            "parse_s": statistics.median(s["parse_s"] for s in samples),
            "load_s": statistics.median(s["load_s"] for s in samples),
            "run_s": statistics.median(s["run_s"] for s in samples),
            "correct": all(s["correct"] for s in samples),
        })
    tables = [{
        "title": TITLE,
        "columns": ["items", "tokens", "steps/sample", "correct", "build s", "run s", "us/step", "steps/s",
                    "ratio", f">= {TARGET_STEPS_PER_S:,}/s", "steps/s, gc.freeze"],
        "rows": [[f"{r['items']:,}", f"{r['tokens']:,}", f"{r['steps']:,}", "yes" if r["correct"] else "NO",
                  f"{r['build_s']:.3f}", f"{r['run_s']:.4f}", f"{r['us_per_step']:.1f}",
                  f"{r['steps_per_s']:,.0f}", f"{r['ratio']:.2f}", "yes" if r["meets_target"] else "NO",
                  f"{r['frozen_steps_per_s']:,.0f}"]
                 for r in rows],
    }]
    if text_rows:
        tables.append({
            "title": "B2 text route: the same start state as a parsed #exec (N constant declarations)",
            "columns": ["items", "tokens", "correct", "parse+elab s", "load s", "run s"],
            "rows": [[f"{r['items']:,}", f"{r['tokens']:,}", "yes" if r["correct"] else "NO",
                      f"{r['parse_s']:.3f}", f"{r['load_s']:.3f}", f"{r['run_s']:.4f}"] for r in text_rows],
        })
    return {
        "name": NAME,
        "title": TITLE,
        "repeats": repeats,
        "baseline": f"steps/s at items={base['items']}, tokens={base['tokens']} (same run)",
        "target_steps_per_s": TARGET_STEPS_PER_S,
        "rows": rows,
        "text_route": text_rows,
        "tables": tables,
        "notes": [
            f"medians of {repeats} samples; a sample runs ceil({MIN_STEPS:,}/T) fresh contexts to quiescence",
            "build = making the atoms and loading them with program.start_context, per context (not in steps/s)",
            "gc.freeze = the same runs with the start state frozen out of the cyclic GC (gc.freeze() after "
            "loading): the collector's share of the step cost",
            "ratio = steps/s over the baseline's; flat means ratios near 1.0",
            "correct = quiescent after exactly T steps with N-T items and the T expected done facts",
            "text route: parse+elab grows with the text (100,000 items took about 12.6 s once); "
            "hence the API-built start state",
        ],
    }


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from run import main

    sys.exit(main(["b2", *sys.argv[1:]]))
