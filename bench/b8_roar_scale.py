"""B8: ROAR exploration at scale: states per second and bytes kept per visited state.

For every job of ``checker/`` on a ROAR spec, and for generated networks of 4, 6 and 8 agents
in two shapes, the spec is compiled as ``roar-verify check`` compiles it and explored
breadth-first (every interleaving and outcome, agents as fairness groups) until the state space
is complete or the time budget runs out. Each exploration runs in a fresh process, so the
engine's caches start cold and the memory figure is that search's own: the growth of the
process's peak resident set during the search divided by the states visited (the bytes a
visited state costs, with its transitions, key and the engine's bounded caches amortised).

Generated networks (``network(shape, n)``):

* ``chain-N``: agent ``a1`` makes a constraint on ``a2``, whose recipe makes one on ``a3``,
  and so on; the last calls a primitive that may fail, retried at most twice. One agent acts
  at a time: the state space grows linearly with N.
* ``fan-N``: a planner ensures a constraint on each of N-1 workers at once, waits for all,
  aborts the ensures; each worker calls a primitive that may fail (retried at most twice).
  The workers interleave: the state space grows exponentially with N.

* ``twins-N`` (only with ``--symmetry``): the planner calls the primitive itself, and N-1
  identical workers no agent sends anything: a verified symmetry of order (N-1)! that reduces
  nothing (the workers never move), so its rows measure what symmetry reduction costs a state.

``--symmetry`` measures every model a second time with symmetry reduction (``roar/symmetry.py``:
the verified symmetries of the compiled model, the time to find and verify them counted in the
search's) and prints what each found. Figures (2026-11-27, same machine, same load caveat;
``--only fan-4,fan-6,twins-4,twins-6 --max-states 6000 --symmetry``):

=====================  ======  =========  ============  ===========  ================================
model                  states  states/s   states/cpu-s  bytes/state  symmetry
=====================  ======  =========  ============  ===========  ================================
fan-4                  6,001   1,362      2,056         4,718
fan-4 (symmetry)       6,001   1,335      2,070         4,761        none found (refused: see below)
fan-6                  6,001   954        1,954         11,074
fan-6 (symmetry)       6,001   642        1,901         11,096       none found (refused)
twins-4                58      1,002      2,097         4,520
twins-4 (symmetry)     58      443        877           4,520        w1, w2, w3: order 6
twins-6                58      579        1,803         4,520
twins-6 (symmetry)     58      55         227           11,299       w1..w5: order 120
=====================  ======  =========  ============  ===========  ================================

The fan workers are identical, but the planner sends to w1 first (and its ``cdom`` list, its
environment and its aborts name them in order): exchanging two workers maps the planner's code
onto code the model does not have, so verification refuses the candidate (``declaration
'cdom_r_planner_work_r' has no image``) and the search is the plain one (same states; the
states/s difference on fan-6 is the loaded machine: the CPU columns agree). Every agent of a
spec that acts is fixed by any symmetry of its compiled model (docs/checking.md, Symmetry
reduction), so on specs symmetry reduction is exact but saves nothing; on ``.clf`` models with
interchangeable processes it does (tests/explore/test_symmetry.py: 88 states to 6, 20 to 7).
The twins rows show the cost: one key per element of the group, per state.

``python bench/run.py b8 [--quick]``; ``python bench/b8_roar_scale.py --python-path OLD`` runs
the same measurements with another checkout of roar_formal first on ``sys.path`` (a before/after
comparison); ``--only NAMES`` and ``--max-states N`` narrow it (the same work on both sides).
Besides wall-clock states/s, each row gives the search's CPU time and states per CPU-second,
which a shared, loaded machine still measures fairly. Reports, never asserts.

Figures (2026-11-27, one core of a shared 2-core machine under heavy load from other jobs, so
read the CPU columns; ``--only M --max-states 6000``, each model old then new in turn; bytes per
state are meaningless below a few hundred states, where they are a page or two of RSS):

=====================  ===========  ====================  ====================
model                  states       states/cpu-s old→new  bytes/state old→new
=====================  ===========  ====================  ====================
conflict               2,658        690 → 1,061           5,276 → 2,614
ensure_slammed         2,341        945 → 1,338           3,359 → 2,016
ensure_slammed_fixed   1,631        873 → 1,332           3,295 → 1,527
ordered_pick           1,730        879 → 1,361           2,803 → 1,136
chain-8                331          541 → 669             3,960 → 2,376
fan-4 (budget)         6,000        534 → 1,107           9,263 → 5,679
fan-6 (budget)         6,000        437 → 863             14,760 → 10,768
fan-8 (budget)         6,000        396 → 816             15,569 → 11,534
=====================  ===========  ====================  ====================

On the fan networks (a wide frontier) most of the memory was the 2,048 frontier states kept
live. Since every state is built in the order thawing gives it (``Context.in_order``), freezing
a waiting state changes nothing in the graph, and ``LIVE_FRONTIER`` is 256: fan-6 at 30,000
states went from 2,976 to 2,121 bytes per state at the same speed (2026-11-27).

Larger networks (2026-11-27, same machine): fan-6 and fan-8 to 100,000 states (``--only fan-6,fan-8
--max-states 100000``) run at 1,369 and 1,302 states per CPU-second and keep 2,214 and 2,496
bytes a state; chains explore completely: chain-32 1,267 states in 2.6 s, chain-64 2,515 in 12 s,
chain-128 5,011 in 78 s (the largest network explored here, well within 10 minutes and 8 GB).
A state costs more as the network grows: on chain-64 a third of the time is the recipe choice's
proof (``best``), which walks the request's error context, as long as the chain below it.
Deriving a state's enabled steps from its parent's (the parent's less those using a consumed
fact, plus matches seeded at each produced fact) gave the same steps in the same order but no
end-to-end gain (170 to 155 µs of enumeration a state) and cost 1.0 to 1.4 KB a waiting state
on wide frontiers; it is not kept.

Keys by colour rank (2026-11-29, same machine, ``--only conflict,fan-4,fan-6,fan-8 --max-states
20000``): a canonical key numbers each item it holds through a table kept for the whole search.
An activation's control fact holds several fresh names (its locals), and with the names numbered
by their colours (hashes) nearly every state made a new item: the table grew by about 450 bytes
a visited state on fan-8 (21,460 items at 20,000 states). Numbered by the rank of their colour
among the state's, the items recur (4,902 items): bytes per state went from 2,789 to 2,186 on
fan-8 and from 2,196 to 1,807 on fan-6 (fan-4, whose facts hold one name each, 1,823 to 1,681),
at the same speed within this machine's noise (fan-4 old/new back to back: 1,294/1,145 then
1,414/1,415 states per CPU-second). What remains at 20,000 states on fan-8, traced by
``tracemalloc``: the interned facts the kept states share (about 540 bytes a state; a sweep of
those nothing else refers to freed under a tenth of them, so it is not kept), the keys (290), the
frozen states' facts (300), the packed steps of the transitions (about 350), the graph's arrays
(150).

Where it came from: canonical keys by colours when the refinement ends discrete (no sort, no
renaming of every fact; ``clf/state.py``), 4-byte key words, the merged matcher with a cheaper
premise selection (``clf/forward.py``), rigid paths kept per family bag, transitions' steps
kept packed (``explore/system.py``). The state graphs are the old ones edge for edge.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

NAME = "b8"
TITLE = "B8 ROAR exploration: states/s and bytes per visited state"
ROOT = Path(__file__).resolve().parents[1]


def network(shape: str, n: int) -> tuple[str, str]:
    """(spec text, request) of a generated network of ``n`` agents."""
    def agent(name: str, body: str, flags: str = "", funcs: str = "", private: str = "") -> str:
        return (f"{name} = ability {{\n  context = {{\n    {{ }}\n    {{ bool done = false; {flags}}}\n"
                f"    {{ {private}}}\n  }}\n  export = {{\n    {{ }}\n    {{ {funcs}}}\n    {{ }}\n  }}\n"
                f"  tasks = {{\n    work = task {{\n      pre = {{ }}\n      post = {{ {{done == true}} }}\n"
                f"      recipes = {{\n        r = recipe {{\n          pre = {{ {{tries < 2}} }}\n"
                f"          body = {{\n{body}          }}\n        }}\n      }}\n    }}\n  }}\n}}\n")
    worker = "            set tries tries + 1;\n            assert(op());\n            set done true;\n"
    if shape == "chain":
        out = []
        for i in range(1, n + 1):
            if i < n:
                body = f"            set tries tries + 1;\n            make(a{i + 1}::done == true);\n            set done true;\n"
                out.append(agent(f"a{i}", body, private="int tries = 0; "))
            else:
                out.append(agent(f"a{i}", worker, funcs="bool op(); ", private="int tries = 0; "))
        return "\n".join(out), "a1::done == true"
    if shape == "fan":
        ws = [f"w{i}" for i in range(1, n)]
        body = "".join(f"            let h{i} ensure({w}::done == true, 100);\n" for i, w in enumerate(ws, 1))
        body += "            wait(" + " && ".join(f"{w}::done == true" for w in ws) + ", 100);\n"
        body += "".join(f"            abort h{i};\n" for i in range(1, len(ws) + 1))
        body += "            set tries tries + 1;\n            set done true;\n"
        out = [agent("planner", body, private="int tries = 0; ")]
        out += [agent(w, worker, funcs="bool op(); ", private="int tries = 0; ") for w in ws]
        return "\n".join(out), "planner::done == true"
    if shape == "twins":
        # the planner calls the primitive itself; N-1 identical workers no agent sends anything: a
        # verified symmetry of order (N-1)! that reduces nothing (they never move), so its rows
        # measure what symmetry reduction costs per state (a key per element of the group)
        ws = [f"w{i}" for i in range(1, n)]
        out = [agent("planner", worker, funcs="bool op(); ", private="int tries = 0; int spare = 0; ")]
        out += [agent(w, worker, funcs="bool op(); ", private="int tries = 0; ") for w in ws]
        return "\n".join(out), "planner::done == true"
    raise ValueError(shape)


def one(target: str, request: str | None, max_seconds: float, max_states: int | None = None,
        symmetry: bool = False) -> dict:
    """Explore one job (a .toml) or generated spec (a .roar with ``request``) in this process; with
    ``symmetry``, keyed up to the model's verified symmetries (roar/symmetry.py), the time to find
    and verify them included in the search's."""
    import resource
    from roar_formal.clf.query import with_big_stack

    def go() -> dict:
        import time
        from roar_formal.clf.signature import ExecDirective
        from roar_formal.explore.search import Budget, Explorer
        from roar_formal.explore.system import Options
        from roar_formal.roar.compile import compile_spec
        from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem
        from roar_formal.roar.functional import functional_module, load_registry
        from roar_formal.roar.spec import load_spec
        from roar_formal.verify.jobs import load_job

        if request is None:
            job = load_job(Path(target))
            spec_path, req, fn = job.spec, job.request, job.functional
            name = job.name
        else:
            spec_path, req, fn, name = Path(target), request, None, Path(target).stem
        reg = load_registry(functional_module(spec_path, fn))
        model = compile_spec(load_spec(spec_path), req, registry=reg, functional="abstract")
        program = model.program()
        start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        start = program.start_context(start_d.start)
        system = RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent"))
        from roar_formal.explore.search import current_rss_mb
        # bytes per state: the resident size now, not the peak, before and after (the peak before the
        # search is the compiler's: a compiler that peaks lower made the search's growth past it look
        # larger, with the same memory retained)
        before = current_rss_mb()
        t = time.perf_counter()
        c = time.process_time()
        note = ""
        if symmetry:
            from roar_formal.explore.symmetry import SymmetricSystem
            from roar_formal.roar.symmetry import discover
            sym = discover(model, start)
            note = sym.note()
            if sym.order > 1:
                system = SymmetricSystem(system, sym.group, note)
        explorer = Explorer(system)
        g = explorer.run(Budget(max_seconds=max_seconds, max_states=max_states))
        cpu = time.process_time() - c
        secs = time.perf_counter() - t
        after = current_rss_mb()
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        if symmetry:
            name += " (symmetry)"
        return {"name": name, "symmetry": note, "states": g.n_states, "transitions": g.n_edges, "complete": bool(g.complete),
                "seconds": secs, "states_per_s": g.n_states / secs, "cpu_seconds": cpu,
                "states_per_cpu_s": g.n_states / max(cpu, 1e-9),
                "bytes_per_state": (after - before) * 1024 * 1024 / max(g.n_states, 1), "peak_mb": peak}

    return with_big_stack(go)


def targets(quick: bool, folder: Path, symmetry: bool = False) -> list[tuple[str, str | None]]:
    from roar_formal.verify.jobs import load_job
    out: list[tuple[str, str | None]] = []
    for p in sorted((ROOT / "checker").glob("*.toml")):
        if load_job(p).is_roar:
            out.append((str(p), None))
    for shape in ("chain", "fan") + (("twins",) if symmetry else ()):
        for n in ((4, 6) if quick else (4, 6, 8)):
            text, req = network(shape, n)
            path = folder / f"{shape}-{n}.roar"
            path.write_text(text, encoding="utf-8")
            out.append((str(path), req))
    return out


def measure(python_path: str | None, quick: bool, max_seconds: float, max_states: int | None = None,
            only: str | None = None, symmetry: bool = False) -> list[dict]:
    """Every target measured; with ``symmetry``, each one a second time with symmetry reduction."""
    rows = []
    env = dict(os.environ)
    if python_path:
        env["PYTHONPATH"] = python_path
    with tempfile.TemporaryDirectory() as tmp:
        for target, req in targets(quick, Path(tmp), symmetry):
            if only and not any(w in Path(target).stem for w in only.split(",")):
                continue
            for sym in ((False, True) if symmetry else (False,)):
                cmd = [sys.executable, __file__, "--one", target, "--max-seconds", str(max_seconds)]
                if max_states is not None:
                    cmd += ["--max-states", str(max_states)]
                if req is not None:
                    cmd += ["--request", req]
                if sym:
                    cmd += ["--symmetry"]
                out = subprocess.run(cmd, capture_output=True, text=True, env=env)
                if out.returncode != 0:
                    rows.append({"name": Path(target).stem + (" (symmetry)" if sym else ""),
                                 "error": out.stderr.strip().splitlines()[-1:]})
                    continue
                rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    return rows


def table(rows: list[dict]) -> list[list[str]]:
    return [[r["name"], "error: " + " ".join(r["error"]), "", "", "", "", "", ""] if "error" in r else
            [r["name"], f"{r['states']:,}", "yes" if r["complete"] else "no (budget)", f"{r['seconds']:.1f}",
             f"{r['states_per_s']:,.0f}", f"{r.get('cpu_seconds', float('nan')):.1f}",
             f"{r.get('states_per_cpu_s', float('nan')):,.0f}", f"{r['bytes_per_state']:,.0f}"] for r in rows]


#: states/s is wall-clock; states/cpu-s divides by the search's CPU time (what a shared, loaded
#: machine still measures fairly: compare a before/after pair on the same column)
COLUMNS = ["model", "states", "complete", "search s", "states/s", "cpu s", "states/cpu-s", "bytes/state"]


def run(repeats: int = 1, quick: bool = False) -> dict:
    rows = measure(None, quick, 30.0 if quick else 120.0)
    return {"rows": rows, "tables": [(TITLE, COLUMNS, table(rows))]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", metavar="TARGET", help=argparse.SUPPRESS)
    ap.add_argument("--request", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--max-seconds", type=float, default=120.0, help="time budget of each search")
    ap.add_argument("--python-path", default=None, help="measure another checkout (put first on PYTHONPATH)")
    ap.add_argument("--quick", action="store_true", help="networks of 4 and 6 agents only")
    ap.add_argument("--max-states", type=int, default=None, help="state budget of each search (default: none)")
    ap.add_argument("--only", default=None, metavar="NAMES",
                    help="comma-separated parts of the names of the models to measure (default: all)")
    ap.add_argument("--symmetry", action="store_true",
                    help="measure each model a second time with symmetry reduction (its verified symmetries, "
                         "or none: the row says which)")
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.one, args.request, args.max_seconds, args.max_states, args.symmetry)))
        return 0
    rows = measure(args.python_path, args.quick, args.max_seconds, args.max_states, args.only, args.symmetry)
    print(" | ".join(COLUMNS))
    for r in table(rows):
        print(" | ".join(r))
    for r in rows:
        if r.get("symmetry"):
            print(f"{r['name']}: {r['symmetry']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
