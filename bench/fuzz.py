"""Fuzz the command line: ``python bench/fuzz.py --cases 10000 [--jobs N] [--timeout S] [--seed K]``.

Draws grammar-aware mutations of every input kind (roar_formal/fuzz/mutate.py) with
hypothesis, runs ``roar-verify`` on each in-process in a forked child with a time bound
(roar_formal/fuzz/runner.py) and prints the tallies: exit codes, internal errors, hangs,
input errors without a location, per input kind, and the distinct failures found (the
first case of each). ``--jobs`` shards the cases over processes (each its own hypothesis
seed). Exit status 0 when there is no internal error, no hang and no unlocated error.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def shard(n: int, seed: int, timeout: float, out: Path) -> None:
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hseed

    from roar_formal.fuzz import cases, run_case
    from roar_formal.fuzz.mutate import counterexample_trace
    from roar_formal.fuzz.runner import warm_up

    counterexample_trace()   # computed once, before the forks
    warm_up()
    rows = []
    sink = out.open("w")

    @hseed(seed)
    @settings(max_examples=n, database=None, phases=[Phase.generate], deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(case=cases())
    def one(case):
        o = run_case(case, timeout=timeout)
        bad = o.verdict in ("internal-error", "unlocated", "hang")
        row = {"kind": case.kind, "verdict": o.verdict, "status": o.status, "seconds": round(o.seconds, 3),
               "error": o.first_error_line() if bad else "", "case": case.describe()[:2000] if bad else ""}
        rows.append(row)
        sink.write(json.dumps(row) + "\n")   # one line per case: a run stopped early still has its tallies
        sink.flush()
        if len(rows) % 100 == 0:
            print(f"  shard {seed}: {len(rows)} cases", file=sys.stderr, flush=True)

    one()
    sink.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=float, default=20.0, help="seconds a case may take before it is a hang")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shard", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--keep", type=Path, default=None, help="keep the per-shard case logs (JSON Lines) here")
    ap.add_argument("--json", type=Path, default=None, help="also write every failing case here")
    ap.add_argument("--tally", type=Path, default=None, help="only print the tallies of the case logs in this "
                    "folder (a --keep folder, of a run finished or stopped)")
    a = ap.parse_args()
    if a.shard is not None:
        shard(a.cases, a.shard, a.timeout, a.out)
        return 0
    if a.tally is not None:
        rows = [json.loads(x) for f in sorted(a.tally.glob("shard*.jsonl")) for x in f.read_text().splitlines()
                if x.strip()]
        return summarise(rows, None, len(list(a.tally.glob("shard*.jsonl"))), a.json) if rows else 3
    began = time.monotonic()
    jobs = max(1, min(a.jobs, a.cases))
    with tempfile.TemporaryDirectory() as d:
        procs = []
        for k in range(jobs):
            n = a.cases // jobs + (1 if k < a.cases % jobs else 0)
            out = (a.keep or Path(d)) / f"shard{k}.jsonl"
            procs.append((out, subprocess.Popen([sys.executable, __file__, "--cases", str(n), "--shard",
                                                 str(a.seed * 1000 + k), "--timeout", str(a.timeout),
                                                 "--out", str(out)])))
        rows = []
        failed = False
        for out, p in procs:
            p.wait()
            if p.returncode != 0:   # the harness broke, not roar-verify: say so, and tally what ran
                print(f"a shard of the harness failed (exit {p.returncode})", file=sys.stderr)
                failed = True
            if out.exists():
                rows += [json.loads(x) for x in out.read_text().splitlines() if x.strip()]
    elapsed = time.monotonic() - began
    if not rows:
        return 3
    code = summarise(rows, elapsed, jobs, a.json)
    return 3 if failed else code


def summarise(rows: list, elapsed, jobs: int, json_out) -> int:
    tally = collections.Counter(r["verdict"] for r in rows)
    by_kind: dict = collections.defaultdict(collections.Counter)
    for r in rows:
        by_kind[r["kind"]][r["verdict"]] += 1
    took = f"in {elapsed:.0f} s " if elapsed is not None else ""
    print(f"{len(rows)} cases {took}({jobs} processes), slowest case {max(r['seconds'] for r in rows):.1f} s")
    for v in sorted(tally):
        print(f"  {v:<16} {tally[v]:>6}")
    print("per input kind:")
    for k in sorted(by_kind):
        print(f"  {k:<10} " + ", ".join(f"{v} {n}" for v, n in sorted(by_kind[k].items())))
    bad = [r for r in rows if r["verdict"] in ("internal-error", "hang", "unlocated")]
    print(f"internal errors: {tally['internal-error']}, hangs: {tally['hang']}, unlocated errors: {tally['unlocated']}")
    groups: dict = {}
    for r in bad:
        key = (r["verdict"], re.sub(r"\d+", "N", r["error"])[:120])
        groups.setdefault(key, []).append(r)
    for (v, _), rs in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        print(f"\n[{v}] x{len(rs)}: {rs[0]['error']}\n    e.g. {rs[0]['case'][:400]}")
    if json_out:
        json_out.write_text(json.dumps(bad, indent=1))
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
