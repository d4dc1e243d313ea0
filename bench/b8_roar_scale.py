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

``python bench/run.py b8 [--quick]``; ``python bench/b8_roar_scale.py --python-path OLD`` runs
the same measurements with another checkout of roar_formal first on ``sys.path`` (a before/after
comparison). Reports, never asserts.
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
    raise ValueError(shape)


def one(target: str, request: str | None, max_seconds: float) -> dict:
    """Explore one job (a .toml) or generated spec (a .roar with ``request``) in this process."""
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
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        explorer = Explorer(system)
        t = time.perf_counter()
        g = explorer.run(Budget(max_seconds=max_seconds))
        secs = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return {"name": name, "states": g.n_states, "transitions": g.n_edges, "complete": bool(g.complete),
                "seconds": secs, "states_per_s": g.n_states / secs,
                "bytes_per_state": (after - before) * 1024 / max(g.n_states, 1), "peak_mb": after / 1024}

    return with_big_stack(go)


def targets(quick: bool, folder: Path) -> list[tuple[str, str | None]]:
    from roar_formal.verify.jobs import load_job
    out: list[tuple[str, str | None]] = []
    for p in sorted((ROOT / "checker").glob("*.toml")):
        if load_job(p).is_roar:
            out.append((str(p), None))
    for shape in ("chain", "fan"):
        for n in ((4, 6) if quick else (4, 6, 8)):
            text, req = network(shape, n)
            path = folder / f"{shape}-{n}.roar"
            path.write_text(text, encoding="utf-8")
            out.append((str(path), req))
    return out


def measure(python_path: str | None, quick: bool, max_seconds: float) -> list[dict]:
    rows = []
    env = dict(os.environ)
    if python_path:
        env["PYTHONPATH"] = python_path
    with tempfile.TemporaryDirectory() as tmp:
        for target, req in targets(quick, Path(tmp)):
            cmd = [sys.executable, __file__, "--one", target, "--max-seconds", str(max_seconds)]
            if req is not None:
                cmd += ["--request", req]
            out = subprocess.run(cmd, capture_output=True, text=True, env=env)
            if out.returncode != 0:
                rows.append({"name": Path(target).stem, "error": out.stderr.strip().splitlines()[-1:]})
                continue
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    return rows


def table(rows: list[dict]) -> list[list[str]]:
    return [[r["name"], "error: " + " ".join(r["error"]), "", "", "", ""] if "error" in r else
            [r["name"], f"{r['states']:,}", "yes" if r["complete"] else "no (budget)", f"{r['seconds']:.1f}",
             f"{r['states_per_s']:,.0f}", f"{r['bytes_per_state']:,.0f}"] for r in rows]


COLUMNS = ["model", "states", "complete", "search s", "states/s", "bytes/state"]


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
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.one, args.request, args.max_seconds)))
        return 0
    rows = measure(args.python_path, args.quick, args.max_seconds)
    print(" | ".join(COLUMNS))
    for r in table(rows):
        print(" | ".join(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
