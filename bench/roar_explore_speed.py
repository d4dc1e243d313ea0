"""Explicit-state exploration speed on ROAR specs: states per second of the general backend.

``python bench/roar_explore_speed.py [JOB.toml ...] [--repeats N] [--max-states N] [--max-seconds S]``

For each job on a ROAR spec (default: ``checker/conflict.toml``) the spec is
compiled as ``roar-verify check`` compiles it, then the state space is explored
breadth-first (every interleaving and every outcome, agents as fairness groups)
until it is complete or the budget runs out; only the search is timed. Each run
is a fresh process, so the engine's caches (hash-consed terms, proof and
canonical-key memos) start cold every time, as in ``roar-verify``. Medians over
the runs are printed; the machine's noise shows in the min-max column. Reports,
never asserts (the test suite does not run it).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def one(job_path: str, max_states: int | None, max_seconds: float | None) -> dict:
    """Compile and explore one job in this process; the figures of that run."""
    from roar_formal.clf.query import with_big_stack

    def go() -> dict:
        from roar_formal.clf.signature import ExecDirective
        from roar_formal.verify.jobs import load_job
        from roar_formal.explore.search import Budget, Explorer
        from roar_formal.explore.system import Options
        from roar_formal.roar.functional import functional_module, load_registry
        from roar_formal.roar.compile import compile_spec
        from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem
        from roar_formal.roar.spec import load_spec

        t0 = time.perf_counter()
        job = load_job(Path(job_path))
        if not job.is_roar:
            raise SystemExit(f"{job_path}: not a job on a ROAR spec")
        reg = load_registry(functional_module(job.spec, job.functional))
        model = compile_spec(load_spec(job.spec), job.request, registry=reg, functional="abstract")
        program = model.program()
        start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        start = program.start_context(start_d.start)
        options = Options(progress_rules=tuple(job.props.progress) or PROGRESS_RULES, fairness="agent",
                          canonical=job.canonical)
        system = RoarSystem(model, start, options)
        compile_s = time.perf_counter() - t0
        explorer = Explorer(system, job.search)
        t1 = time.perf_counter()
        g = explorer.run(Budget(max_states=max_states if max_states is not None else job.budget.max_states,
                                max_seconds=max_seconds if max_seconds is not None else job.budget.max_seconds))
        explore_s = time.perf_counter() - t1
        return {"job": job.name, "states": g.n_states, "transitions": g.n_edges, "complete": g.complete,
                "stop": g.stop_reason, "compile_s": compile_s, "explore_s": explore_s}

    return with_big_stack(go)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("jobs", nargs="*", default=[str(ROOT / "checker/conflict.toml")])
    ap.add_argument("--repeats", type=int, default=5, help="runs per job, each in a fresh process (medians)")
    ap.add_argument("--max-states", type=int, default=None, help="state budget (default: the job's)")
    ap.add_argument("--max-seconds", type=float, default=None, help="time budget of the search (default: the job's)")
    ap.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # a single run, JSON on stdout
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.jobs[0], args.max_states, args.max_seconds)))
        return 0
    print(f"{'job':24s} {'states':>8s} {'trans':>8s} {'complete':>8s} {'explore s':>10s} {'min-max':>15s} "
          f"{'states/s':>9s} {'ms/state':>9s} {'compile s':>9s}")
    for job in args.jobs:
        runs = []
        for _ in range(args.repeats):
            cmd = [sys.executable, __file__, job, "--one"]
            if args.max_states is not None:
                cmd += ["--max-states", str(args.max_states)]
            if args.max_seconds is not None:
                cmd += ["--max-seconds", str(args.max_seconds)]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True)
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        ex = [r["explore_s"] for r in runs]
        med = statistics.median(ex)
        r0 = runs[0]
        print(f"{r0['job']:24s} {r0['states']:8d} {r0['transitions']:8d} {str(r0['complete']):>8s} {med:10.2f} "
              f"{min(ex):7.2f}-{max(ex):<7.2f} {r0['states'] / med:9.0f} {1000 * med / r0['states']:9.2f} "
              f"{statistics.median(r['compile_s'] for r in runs):9.2f}", flush=True)
        if len({(r["states"], r["transitions"]) for r in runs}) > 1:
            print("  (state or transition counts differ between runs: a time budget cut the search)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
