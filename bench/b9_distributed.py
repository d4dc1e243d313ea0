"""B9: the distributed breadth-first search: states/s in one process, and on 1 and 2 local Dask workers.

For a few ROAR models (bundled jobs and the generated networks of B8, ``b8_roar_scale.network``)
the compiled spec is explored breadth-first three ways, each until the state space is complete or
the time budget runs out:

* ``single``: ``explore.search.Explorer`` in this process (the oracle of the tests);
* ``1 worker`` and ``2 workers``: ``explore.distributed.DistributedExplorer`` on a local cluster
  of that many worker processes (one thread each), started before the clock starts.

The figure is states per second of the search itself (the workers' compile of the spec, done once
per worker when the search opens, is reported apart as "setup s"). A distributed search pays for
what one process does not: each successor is written as bytes, sent to the worker that owns it,
read back and re-indexed before it is expanded, and every level ends with an exchange (a round
trip through the scheduler). On a machine with 2 cores, 2 workers share them with the scheduler
and the driver. Reports, never asserts.

``python bench/b9_distributed.py [--quick] [--max-seconds S] [--workers 1,2]``
(``python bench/run.py b9`` runs it with the other benchmarks).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import tempfile
import time
from pathlib import Path

NAME = "b9"
TITLE = "B9 distributed breadth-first search: states/s, single process vs 1 and 2 local Dask workers"
ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def _b8():
    """bench/b8_roar_scale.py (its generated networks), loaded from its file."""
    spec = importlib.util.spec_from_file_location("_roar_bench_b8_roar_scale", ROOT / "bench" / "b8_roar_scale.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, mod)
    spec.loader.exec_module(mod)
    return mod


def targets(quick: bool, folder: Path) -> list[tuple[str, Path, str | None]]:
    """(name, job file or spec, request or None for a job file)."""
    out: list = [("conflict", ROOT / "checker" / "conflict.toml", None),
                 ("ordered_pick", ROOT / "checker" / "ordered_pick.toml", None)]
    b8 = _b8()
    for shape, n in ((("fan", 5),) if quick else (("chain", 8), ("fan", 5), ("fan", 6))):
        text, req = b8.network(shape, n)
        path = folder / f"{shape}-{n}.roar"
        path.write_text(text, encoding="utf-8")
        out.append((f"{shape}-{n}", path, req))
    return out


def job_of(path: Path, request: str | None):
    from roar_formal.verify.jobs import Job, load_job
    if request is None:
        return load_job(path)
    return Job(path=path, name=path.stem, model=None, spec=path, request=request)


def system_of(job):
    from roar_formal.verify.cluster import JobSystem
    return JobSystem(job, None).build()


def single(job, max_seconds: float) -> dict:
    from roar_formal.clf.query import with_big_stack
    from roar_formal.explore.search import Budget, Explorer

    def go():
        ex = Explorer(system_of(job))
        t = time.perf_counter()
        g = ex.run(Budget(max_seconds=max_seconds))
        secs = time.perf_counter() - t
        return {"states": g.n_states, "transitions": g.n_edges, "complete": bool(g.complete), "seconds": secs,
                "states_per_s": g.n_states / secs}
    return with_big_stack(go)


def on_cluster(client, job, max_seconds: float) -> dict:
    from roar_formal.clf.query import with_big_stack
    from roar_formal.explore.distributed import DistributedExplorer
    from roar_formal.explore.search import Budget
    from roar_formal.verify.cluster import JobSystem, job_fingerprint

    def go():
        system = system_of(job)
        t = time.perf_counter()
        ex = DistributedExplorer(system, client, JobSystem(job, job_fingerprint(job)))
        setup = time.perf_counter() - t
        t = time.perf_counter()
        g = ex.run(Budget(max_seconds=max_seconds))
        secs = time.perf_counter() - t
        ex.close()
        return {"states": g.n_states, "transitions": g.n_edges, "complete": bool(g.complete), "seconds": secs,
                "states_per_s": g.n_states / secs, "setup_seconds": setup, "levels": ex.level,
                "rounds": ex.rounds, "busy": ex.worker_seconds / (secs * len(ex.workers))}
    return with_big_stack(go)


def measure(quick: bool, max_seconds: float, worker_counts: list[int]) -> list[dict]:
    import logging
    from distributed import Client, LocalCluster
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        ts = targets(quick, Path(tmp))
        jobs = {name: job_of(path, req) for name, path, req in ts}
        for name, _p, _r in ts:
            rows.append({"model": name, "mode": "single", **single(jobs[name], max_seconds)})
        for n in worker_counts:
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                   silence_logs=logging.ERROR)
            client = Client(cluster)
            client.wait_for_workers(n, timeout=120)
            try:
                for name, _p, _r in ts:
                    rows.append({"model": name, "mode": f"{n} worker{'s' if n != 1 else ''}",
                                 **on_cluster(client, jobs[name], max_seconds)})
            finally:
                client.close()
                cluster.close()
    base = {r["model"]: r["states_per_s"] for r in rows if r["mode"] == "single"}
    for r in rows:
        r["speedup"] = r["states_per_s"] / base[r["model"]]
    order = {"single": 0}
    rows.sort(key=lambda r: (r["model"], order.get(r["mode"], 1), r["mode"]))
    return rows


COLUMNS = ["model", "mode", "states", "complete", "search s", "states/s", "vs single", "setup s", "levels",
           "workers busy"]


def table(rows: list[dict]) -> list[list[str]]:
    return [[r["model"], r["mode"], f"{r['states']:,}", "yes" if r["complete"] else "no (budget)",
             f"{r['seconds']:.1f}", f"{r['states_per_s']:,.0f}", f"{r['speedup']:.2f}",
             f"{r['setup_seconds']:.1f}" if "setup_seconds" in r else "",
             str(r.get("levels", "")), f"{r['busy']:.0%}" if "busy" in r else ""] for r in rows]


def run(repeats: int = 1, quick: bool = False) -> dict:
    rows = measure(quick, 30.0 if quick else 120.0, [1, 2])
    return {"rows": rows, "tables": [(TITLE, COLUMNS, table(rows))]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-seconds", type=float, default=120.0, help="time budget of each search")
    ap.add_argument("--quick", action="store_true", help="fewer generated networks")
    ap.add_argument("--workers", default="1,2", help="worker counts of the local clusters (default 1,2)")
    ap.add_argument("--json", default=None, help="also write the rows to this file")
    args = ap.parse_args(argv)
    rows = measure(args.quick, args.max_seconds, [int(x) for x in args.workers.split(",")])
    print(" | ".join(COLUMNS))
    for r in table(rows):
        print(" | ".join(r))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
