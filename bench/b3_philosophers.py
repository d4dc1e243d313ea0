"""B3: the explorer on the dining philosophers (benchmarks.md).

Each configuration runs in its own process, so its peak memory is its own.
Reported per configuration: states, transitions (checked against the
benchmark's figures), search time, states/s, peak RSS, and the verdicts. As a
baseline measured in the same run, a plain Python breadth-first search over
tuples (no CLF, the philosophers hand-coded) explores the same space; the
ratio is explorer time / plain time. The ``ll`` livelock at N = 12 is found
the way ``roar-verify check`` finds it: growing state budgets, stopping at the
first fair cycle.

Side by side with SPIN (table "B3 vs SPIN", also ``python bench/b3_philosophers.py --spin``,
which writes ``bench/results/b3_spin.json``): the same model in Promela
(``generate.py --promela``: one d_step per CLF rule, so SPIN's "states, stored" is our state
count and its "transitions" our transition count plus one), run in the same benchmark run,
interleaved with ours, each configuration ``repeats`` times (medians). Each side runs in a
child process measured by ``wait4`` from a small launcher (CPU = user + system time of the
child, peak = its maximum resident set): ours is the whole Python process (start-up,
imports, grounding, search and the deadlock check); SPIN's is ``pan`` alone, with the time of
``spin -a`` and ``gcc -O2`` reported apart. SPIN's options: ``-DSAFETY`` (a safety search:
invalid end states, i.e. deadlocks, and assertions), ``-DNOREDUCE`` (no partial-order
reduction: every state, like our search), SPIN's default full state storage (no
``-DCOLLAPSE``/``-DHC``/bitstate) and default hash table (``-w24``), ``./pan -c0`` (count
errors, do not stop at the first, so a deadlocking model is still explored in full). Two
searches: breadth-first (``-DBFS``, our algorithm: shortest counterexamples, no search stack)
and SPIN's default depth-first one, whose stack must be as deep as the search goes or the
search is cut short; it is given ``-m`` = the state count (found by the breadth-first run),
the only depth bound known beforehand that guarantees a complete search. When ``spin`` (or
``gcc``) is not installed the table says so and shows our columns only.
"""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
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

#: what both child scripts start with: the model generator and the ground backend
PRELUDE = textwrap.dedent("""
    import json, sys, time, importlib.util
    sys.path.insert(0, {root!r})
    spec = importlib.util.spec_from_file_location("gen", {root!r} + "/models/philosophers/generate.py")
    gen = importlib.util.module_from_spec(spec); spec.loader.exec_module(gen)
    from roar_formal.clf.program import Program
    from roar_formal.explore.system import Options
    from roar_formal.explore.ground import GroundExplorer, GroundModel
""")

EXPLORE = PRELUDE + textwrap.dedent("""
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
    spin = spin_side_by_side(repeats, quick)
    tables.append(spin["table"])
    return {"name": NAME, "title": TITLE, "repeats": repeats, "baseline": "plain Python BFS over tuples, same run",
            "rows": rows, "livelock": ll, "spin": spin, "tables": tables, "notes": spin["notes"]}


# ------------------------------------------------------------------ side by side with SPIN

SPIN_CONFIGS = [("dl", 8), ("ok", 8), ("ok", 10), ("ok", 12)]
SPIN_QUICK = [("dl", 5), ("ok", 8)]

# A launcher as small as possible (no site packages): Linux starts a child's peak resident size
# at its parent's size at the fork, so the child is forked from this, not from the benchmark.
LAUNCH = textwrap.dedent("""
    import json, os, sys
    out = open(sys.argv[1], "wb")
    pid = os.fork()
    if pid == 0:
        os.chdir(sys.argv[2])
        os.dup2(out.fileno(), 1)
        os.dup2(out.fileno(), 2)
        os.execvp(sys.argv[3], sys.argv[3:])
    _, status, ru = os.wait4(pid, 0)
    print(json.dumps(dict(status=os.waitstatus_to_exitcode(status), cpu_s=ru.ru_utime + ru.ru_stime,
                          user_s=ru.ru_utime, sys_s=ru.ru_stime, peak_mb=ru.ru_maxrss / 1024.0)))
""")

OURS = PRELUDE + textwrap.dedent("""
    from roar_formal.explore.properties import check_deadlock
    t0 = time.perf_counter()
    p = Program.from_text(gen.program({variant!r}, {n}))
    m = GroundModel(p, p.start_context(p.sig.directives[0].start), Options(progress_rules=("eat",)))
    t1 = time.perf_counter()
    g = GroundExplorer(m, keep_targets={keep}).run()
    t2 = time.perf_counter()
    d = check_deadlock(g)
    t3 = time.perf_counter()
    print(json.dumps(dict(states=g.n_states, transitions=g.n_edges, ground_s=t1 - t0, search_s=t2 - t1,
                          deadlock_s=t3 - t2, deadlock=d.status,
                          deadlock_len=d.counterexample.length() if d.counterexample else None)))
""")


def _launch(cmd: list[str], cwd: str) -> tuple[dict, str]:
    """Run ``cmd`` in ``cwd`` from the small launcher: (its measurement, its output)."""
    with tempfile.NamedTemporaryFile("rb", suffix=".out") as out:
        r = subprocess.run([sys.executable, "-S", "-c", LAUNCH, out.name, cwd, *cmd],
                           capture_output=True, text=True, check=True)
        m = json.loads(r.stdout.strip().splitlines()[-1])
        text = out.read().decode("utf-8", "replace")
    if m["status"] != 0:
        raise RuntimeError(f"{cmd[0]} exited with {m['status']}: {text[-2000:]}")
    return m, text


def spin_available() -> str:
    """"" when SPIN can run here, else why not."""
    missing = [t for t in ("spin", "gcc") if shutil.which(t) is None]
    if missing:
        return (f"SPIN not installed ({' and '.join(missing)} not found; Debian: apt-get install spin gcc): "
                "SPIN columns skipped")
    return ""


def _pan_figures(text: str) -> dict:
    def num(pat):
        m = re.search(pat, text)
        return float(m.group(1)) if m else None
    errors = num(r"errors: (\d+)")
    return {"states": int(num(r"(\d+) states, stored") or 0),
            "transitions": int(num(r"(\d+) transitions \(= stored\+matched\)") or 0),
            "errors": int(errors) if errors is not None else None,
            "invalid_end_states": len(re.findall(r"invalid end state \(", text)),
            "depth": int(num(r"depth reached (\d+)") or 0),
            "truncated": "max search depth too small" in text,
            "pan_total_mb": num(r"([\d.]+)\s+total actual memory usage")}


class _Spin:
    """One model compiled twice (breadth-first and depth-first pan) in a temporary folder."""

    FLAGS = ["-O2", "-DSAFETY", "-DNOREDUCE"]

    def __init__(self, variant: str, n: int) -> None:
        spec = importlib.util.spec_from_file_location("gen", ROOT / "models/philosophers/generate.py")
        gen = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(gen)
        self.dir = tempfile.mkdtemp(prefix=f"b3spin-{variant}{n}-")
        Path(self.dir, "model.pml").write_text(gen.promela(variant, n), encoding="utf-8")
        self.compile_s = 0.0
        m, _ = _launch(["spin", "-a", "model.pml"], self.dir)
        self.compile_s += m["cpu_s"]
        for name, extra in (("pan_bfs", ["-DBFS"]), ("pan_dfs", [])):
            m, _ = _launch(["gcc", *self.FLAGS, *extra, "-o", name, "pan.c"], self.dir)
            self.compile_s += m["cpu_s"]
        self.depth_bound = None

    def run(self, search: str) -> dict:
        args = ["-c0"]
        if search == "dfs":
            args.append(f"-m{self.depth_bound}")
        m, text = _launch([f"./pan_{search}", *args], self.dir)
        fig = _pan_figures(text)
        if search == "bfs" and self.depth_bound is None:
            self.depth_bound = max(10_000, fig["states"] + 1)
        return {**m, **fig, "options": " ".join(self.FLAGS + (["-DBFS"] if search == "bfs" else []))
                + " ; ./pan " + " ".join(args)}

    def close(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)


def spin_side_by_side(repeats: int = 3, quick: bool = False) -> dict:
    """Ours and SPIN on the same models in the same run, interleaved: medians of ``repeats``."""
    configs = SPIN_QUICK if quick else SPIN_CONFIGS
    why_not = spin_available()
    rows = []
    for variant, n in configs:
        spin = None if why_not else _Spin(variant, n)
        ours, lean, bfs, dfs = [], [], [], []
        try:
            for _ in range(repeats):
                for keep, xs in ((True, ours), (False, lean)):
                    m, text = _launch([sys.executable, "-c", OURS.format(root=str(ROOT), variant=variant, n=n,
                                                                         keep=keep)], str(ROOT))
                    xs.append({**m, **json.loads(text.strip().splitlines()[-1])})
                if spin is not None:
                    bfs.append(spin.run("bfs"))
                    dfs.append(spin.run("dfs"))
        finally:
            if spin is not None:
                spin.close()
        med = lambda xs, k: statistics.median(x[k] for x in xs) if xs else None  # noqa: E731
        o = ours[0]
        row = {"variant": variant, "n": n, "states": o["states"], "transitions": o["transitions"],
               "deadlock": o["deadlock"], "deadlock_len": o["deadlock_len"],
               "cpu_s": med(ours, "cpu_s"), "peak_mb": med(ours, "peak_mb"),
               "search_s": med(ours, "search_s"), "ours": ours,
               "no_targets": {"cpu_s": med(lean, "cpu_s"), "peak_mb": med(lean, "peak_mb"), "samples": lean,
                              "same": all((x["states"], x["transitions"], x["deadlock"], x["deadlock_len"])
                                          == (o["states"], o["transitions"], o["deadlock"], o["deadlock_len"])
                                          for x in lean)}}
        for name, xs in (("spin_bfs", bfs), ("spin_dfs", dfs)):
            if not xs:
                row[name] = None
                continue
            x = xs[0]
            row[name] = {"states": x["states"], "transitions": x["transitions"], "errors": x["errors"],
                         "truncated": x["truncated"], "depth": x["depth"], "options": x["options"],
                         "cpu_s": med(xs, "cpu_s"), "peak_mb": med(xs, "peak_mb"),
                         "pan_total_mb": x["pan_total_mb"], "compile_s": spin.compile_s, "samples": xs,
                         "same_states": x["states"] == o["states"] and x["transitions"] == o["transitions"] + 1,
                         "same_deadlock": (x["errors"] or 0) > 0 if o["deadlock"] == "violated"
                         else x["errors"] == 0 and o["deadlock"] == "holds"}
            row[name]["cpu_ratio"] = row["cpu_s"] / max(row[name]["cpu_s"], 1e-9)
            row[name]["peak_ratio"] = row["peak_mb"] / max(row[name]["peak_mb"], 1e-9)
        rows.append(row)
    cols = ["variant", "N", "states", "transitions", "deadlock", "CPU s", "peak MiB",
            "lean CPU s", "lean MiB"]
    if not why_not:
        cols += ["SPIN", "SPIN states", "agree", "SPIN CPU s", "SPIN MiB", "CPU ratio", "MiB ratio", "spin+gcc s"]
    table_rows = []
    for r in rows:
        base = [r["variant"], str(r["n"]), f"{r['states']:,}", f"{r['transitions']:,}",
                r["deadlock"] + (f" ({r['deadlock_len']})" if r["deadlock_len"] else ""),
                f"{r['cpu_s']:.2f}", f"{r['peak_mb']:,.0f}",
                f"{r['no_targets']['cpu_s']:.2f}" + ("" if r["no_targets"]["same"] else " (DIFFERENT)"),
                f"{r['no_targets']['peak_mb']:,.0f}"]
        if why_not:
            table_rows.append(base)
            continue
        for name, label in (("spin_bfs", "BFS"), ("spin_dfs", "DFS")):
            x = r[name]
            table_rows.append(base + [label, f"{x['states']:,}",
                                      "yes" if x["same_states"] and x["same_deadlock"] and not x["truncated"]
                                      else "NO", f"{x['cpu_s']:.2f}", f"{x['peak_mb']:,.0f}",
                                      f"{x['cpu_ratio']:.2f}", f"{x['peak_ratio']:.2f}", f"{x['compile_s']:.2f}"])
            base = [""] * len(base)
    notes = ["CPU s, peak MiB: ours, the ground backend's search and deadlock check as roar-verify check runs "
             "them in one round (a full StateGraph); lean: GroundExplorer(keep_targets=False), the graph without "
             "edge targets, which a deadlock-only job needs not (same states, transitions and verdict); "
             "deadlock (k): a counterexample of k steps"]
    notes += [why_not] if why_not else [
        "SPIN 'agree': same states stored, transitions = ours + 1 (SPIN counts the initial state), "
        "a deadlock (invalid end state) exactly when ours finds one, and no truncated search",
        "CPU = user + system time of the child process; peak = its maximum resident set; medians of "
        f"{repeats} interleaved runs; ratios are ours / SPIN's",
        "SPIN: spin -a; gcc " + " ".join(_Spin.FLAGS) + " [-DBFS]; ./pan -c0 [-m<states+1> for the "
        "depth-first search]; default full state storage and hash table (-w24)",
    ]
    table = {"title": "B3 vs SPIN: ground backend (deadlock search) and SPIN on the same model, same run",
             "columns": cols, "rows": table_rows}
    return {"spin": None if why_not else subprocess.run(["spin", "-V"], capture_output=True, text=True).stdout.strip(),
            "spin_missing": why_not or None, "rows": rows, "table": table, "notes": notes}


def _spin_main(argv: list[str]) -> int:
    import argparse
    ap = argparse.ArgumentParser(description="B3 side by side with SPIN")
    ap.add_argument("--spin", action="store_true", required=True)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from run import machine, write_json_atomic, RESULTS_DIR
    import datetime as _dt
    res = spin_side_by_side(args.repeats, args.quick)
    t = res["table"]
    print(t["title"])
    print(" | ".join(t["columns"]))
    for r in t["rows"]:
        print(" | ".join(r))
    for note in res["notes"]:
        print("  " + note)
    if not args.no_write:
        out = RESULTS_DIR / "b3_spin.json"
        write_json_atomic(out, {"name": "b3_spin", "title": t["title"], "repeats": args.repeats, **res,
                                "tables": [t],
                                "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                                "machine": machine(), "quick": args.quick})
        print(f"  wrote {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(_spin_main(sys.argv[1:]))
