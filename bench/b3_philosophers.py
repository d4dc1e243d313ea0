"""B3: the explorer on the dining philosophers (benchmarks.md).

Each configuration runs in its own process, so its peak memory is its own.
Reported per configuration: states, transitions (checked against the
benchmark's figures), search time, states/s, peak RSS, and the verdicts. As a
baseline measured in the same run, a plain Python breadth-first search over
tuples (no CLF, the philosophers hand-coded) explores the same space; the
ratio is explorer time / plain time. The ``ll`` livelock at N = 12 is found
the way ``roar-verify check`` finds it: growing state budgets, stopping at the
first fair cycle.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import textwrap
from pathlib import Path

NAME = "b3"
TITLE = "B3 explorer: dining philosophers through the CLF engine (ground backend)"
ROOT = Path(__file__).resolve().parents[1]

FIGURES = {("dl", 5): (572, 1970), ("dl", 8): (25888, 142768), ("ok", 5): (417, 1343),
           ("ok", 8): (18837, 99620), ("ok", 10): (238941, 1593082), ("ok", 12): (3030885, 24386480),
           ("ll", 5): (572, 2470), ("ll", 8): (25888, 178896)}

FULL = [("dl", 5), ("dl", 8), ("ok", 5), ("ok", 8), ("ok", 10), ("ok", 12), ("ll", 5), ("ll", 8)]
QUICK = [("dl", 5), ("ok", 8), ("ll", 8)]

EXPLORE = textwrap.dedent("""
    import json, sys, time, importlib.util
    sys.path.insert(0, {root!r})
    spec = importlib.util.spec_from_file_location("gen", {root!r} + "/models/philosophers/generate.py")
    gen = importlib.util.module_from_spec(spec); spec.loader.exec_module(gen)
    from roar_formal.clf.program import Program
    from roar_formal.explore.system import Options
    from roar_formal.explore.ground import GroundExplorer, GroundModel
    from roar_formal.explore.properties import check_deadlock, check_livelock
    from roar_formal.explore.search import rss_mb
    t0 = time.perf_counter()
    p = Program.from_text(gen.program({variant!r}, {n}))
    m = GroundModel(p, p.start_context(p.sig.directives[0].start), Options(progress_rules=("eat",)))
    t1 = time.perf_counter()
    gx = GroundExplorer(m); g = gx.run()
    t2 = time.perf_counter()
    d = check_deadlock(g)
    t3 = time.perf_counter()
    l = check_livelock(g) if {livelock} else None
    t4 = time.perf_counter()
    print(json.dumps(dict(states=g.n_states, transitions=g.n_edges, ground_s=t1 - t0, search_s=t2 - t1,
                          deadlock_s=t3 - t2, livelock_s=t4 - t3, rss_mb=rss_mb(), deadlock=d.status,
                          deadlock_len=d.counterexample.length() if d.counterexample else None,
                          livelock=l.status if l else None)))
""")

LIVELOCK = textwrap.dedent("""
    import json, sys, time, importlib.util, tempfile, pathlib
    sys.path.insert(0, {root!r})
    spec = importlib.util.spec_from_file_location("gen", {root!r} + "/models/philosophers/generate.py")
    gen = importlib.util.module_from_spec(spec); spec.loader.exec_module(gen)
    from roar_formal.verify.check import run_job
    from roar_formal.verify.jobs import load_job
    from roar_formal.explore.search import rss_mb
    d = pathlib.Path(tempfile.mkdtemp())
    (d / "ll.clf").write_text(gen.program("ll", {n}))
    (d / "job.toml").write_text('model = "ll.clf"\\nproperties = "{root}/properties/philosophers.toml"\\n'
                                '[expect]\\nlivelock = "violated"\\n')
    job = load_job(d / "job.toml"); job.props.check = ["livelock"]
    t0 = time.perf_counter(); r = run_job(job); t1 = time.perf_counter()
    v = r.verdicts["livelock"]
    print(json.dumps(dict(seconds=t1 - t0, states=r.graph.n_states, status=v.status, rss_mb=rss_mb(),
                          prefix=len(v.counterexample.prefix), cycle=len(v.counterexample.cycle))))
""")

PLAIN = textwrap.dedent("""
    import json, time
    from collections import deque
    def run(variant, n):
        def forks(i):
            l, r = i, (i + 1) % n
            return (r, l) if variant == "ok" and i == n - 1 else (l, r)
        F = [forks(i) for i in range(n)]
        s0 = ((0,) * n, (False,) * n)
        seen = {{s0}}; q = deque([s0]); trans = 0
        while q:
            loc, held = q.popleft()
            for i in range(n):
                a, b = F[i]; l = loc[i]; nl = list(loc); nh = list(held)
                if l == 0 and not held[a]: nl[i] = 1; nh[a] = True
                elif l == 1 and not held[b]: nl[i] = 2; nh[b] = True
                elif l == 1 and variant == "ll": nl[i] = 0; nh[a] = False
                elif l == 2: nl[i] = 3
                elif l == 3: nl[i] = 4; nh[b] = False
                elif l == 4: nl[i] = 0; nh[a] = False
                else: continue
                trans += 1
                t = (tuple(nl), tuple(nh))
                if t not in seen: seen.add(t); q.append(t)
        return len(seen), trans
    t0 = time.perf_counter(); s, t = run({variant!r}, {n}); t1 = time.perf_counter()
    print(json.dumps(dict(states=s, transitions=t, seconds=t1 - t0)))
""")


def _py(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def run(repeats: int = 3, quick: bool = False) -> dict:
    configs = QUICK if quick else FULL
    rows = []
    for variant, n in configs:
        big = n >= 12
        reps = 1 if big else repeats
        samples = [_py(EXPLORE.format(root=str(ROOT), variant=variant, n=n, livelock=not big))
                   for _ in range(reps)]
        plain = [_py(PLAIN.format(variant=variant, n=n)) for _ in range(1 if n >= 10 else reps)]
        s = samples[0]
        search = statistics.median(x["search_s"] for x in samples)
        plain_s = statistics.median(x["seconds"] for x in plain)
        fig = FIGURES.get((variant, n))
        rows.append({
            "variant": variant, "n": n, "states": s["states"], "transitions": s["transitions"],
            "matches_figures": fig is None or fig == (s["states"], s["transitions"]),
            "matches_plain": (plain[0]["states"], plain[0]["transitions"]) == (s["states"], s["transitions"]),
            "ground_s": statistics.median(x["ground_s"] for x in samples), "search_s": search,
            "states_per_s": s["states"] / search, "rss_mb": max(x["rss_mb"] for x in samples),
            "deadlock": s["deadlock"], "deadlock_len": s["deadlock_len"], "livelock": s["livelock"],
            "livelock_s": statistics.median(x["livelock_s"] for x in samples),
            "plain_s": plain_s, "ratio_to_plain": search / plain_s, "samples": samples,
        })
    ll = [_py(LIVELOCK.format(root=str(ROOT), n=n)) for n in ((8,) if quick else (8, 12))]
    tables = [{
        "title": TITLE,
        "columns": ["variant", "N", "states", "transitions", "as B3", "search s", "states/s", "peak MiB",
                    "deadlock", "livelock", "plain BFS s", "ratio"],
        "rows": [[r["variant"], str(r["n"]), f"{r['states']:,}", f"{r['transitions']:,}",
                  "yes" if r["matches_figures"] and r["matches_plain"] else "NO", f"{r['search_s']:.2f}",
                  f"{r['states_per_s']:,.0f}", f"{r['rss_mb']:,.0f}",
                  r["deadlock"] + (f" ({r['deadlock_len']} steps)" if r["deadlock_len"] else ""),
                  r["livelock"] or "-", f"{r['plain_s']:.2f}", f"{r['ratio_to_plain']:.2f}"] for r in rows],
    }, {
        "title": "B3 ll: fair livelock found by growing budgets (as roar-verify check does)",
        "columns": ["N", "verdict", "seconds", "states explored", "prefix", "cycle", "peak MiB"],
        "rows": [[str(n), x["status"], f"{x['seconds']:.2f}", f"{x['states']:,}", str(x["prefix"]),
                  str(x["cycle"]), f"{x['rss_mb']:,.0f}"] for n, x in zip((8,) if quick else (8, 12), ll)],
    }]
    return {"name": NAME, "title": TITLE, "repeats": repeats, "baseline": "plain Python BFS over tuples, same run",
            "rows": rows, "livelock": ll, "tables": tables}
