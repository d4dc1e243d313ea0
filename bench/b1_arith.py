"""B1: the CLF engine on destination-passing arithmetic (see docs/benchmarks B1).

A DPS evaluator for unary naturals (``num``, ``plus``, ``times``; ``times`` by
repeated addition through a continuation) answers

    #query * 1 * 1 Pi d. eval (times (num n) (num n)) d -o {return V d}.

for n = 10, 20, 40, 100, 200. The forward run inside the monad takes exactly
n^2 + 3n + 5 steps (the evaluation is confluent, so the count does not depend
on the seed): ev_times, two ev_num and the continuation (4); n+1 ``mulv``
steps; for each of the n pending additions of n, the continuation, n
``addv_s`` and one ``addv_z`` (n(n+2)).

Measured per n (medians over the repeats):
  * ``parse``: parsing and elaborating the generated program text;
  * ``solve``: the proof search up to the first solution (forward steps
    counted through ``Backward.monad_runs``); ``us/step`` is solve / steps;
  * ``query``: the whole ``#query`` directive through ``run_query``
    (solve, then zonk and print the answer, a numeral of depth n^2).
The baseline is n = 40 of the same run: ``step ratio`` is
(us/step at n) / (us/step at the baseline), 1.0 meaning cost linear in steps.

Run: ``python bench/run.py b1`` (or ``python bench/b1_arith.py``).
"""

from __future__ import annotations

import gc
import statistics
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from roar_formal.clf.backward import Backward  # noqa: E402
from roar_formal.clf.program import Program  # noqa: E402
from roar_formal.clf.query import run_query, with_big_stack  # noqa: E402
from roar_formal.clf.terms import Const, Root, zonk  # noqa: E402

NAME = "b1"
TITLE = "B1 CLF engine: destination-passing arithmetic, times (num n) (num n)"
SIZES = (10, 20, 40, 100, 200)
QUICK_SIZES = (10, 20, 40)
BASELINE_N = 40  # n=10 and 20 are too few steps (135, 465) to time reliably
TARGETS_S = {40: 0.5, 200: 10.0}  # whole query (parse + directive), one core
CELF_ANCHOR = "Celf (SML/NJ): n=20 in 0.4 s, n=40 in about 124 s"

SIGNATURE = r"""
nat : type.
z : nat.
s : nat -> nat.

exp : type.
num : nat -> exp.
plus : exp -> exp -> exp.
times : exp -> exp -> exp.

dest : type.
eval : exp -> dest -> type.
return : nat -> dest -> type.
addv : nat -> nat -> dest -> type.
mulv : nat -> nat -> dest -> type.

ev_num : eval (num N) D -o {return N D}.
ev_plus : eval (plus E1 E2) D -o {Exists d1. Exists d2. eval E1 d1 * eval E2 d2 *
            (Pi V1. Pi V2. return V1 d1 -o return V2 d2 -o {addv V1 V2 D})}.
ev_times : eval (times E1 E2) D -o {Exists d1. Exists d2. eval E1 d1 * eval E2 d2 *
            (Pi V1. Pi V2. return V1 d1 -o return V2 d2 -o {mulv V1 V2 D})}.

addv_z : addv z N D -o {return N D}.
addv_s : addv (s M) N D -o {addv M (s N) D}.

mulv_z : mulv z N D -o {return z D}.
mulv_s : mulv (s M) N D -o {Exists d. mulv M N d * (Pi V. return V d -o {addv N V D})}.
"""


def numeral(n: int) -> str:
    return "(s " * n + "z" + ")" * n


def program_text(n: int) -> str:
    return (SIGNATURE + f"\n#query * 1 * 1 Pi d. eval (times (num {numeral(n)}) (num {numeral(n)})) d"
            " -o {return V d}.\n")


def expected_steps(n: int) -> int:
    return n * n + 3 * n + 5


_NONE = object()


def unary_value(t) -> int | None:
    """The integer a closed unary numeral denotes (iteratively: it may be deep)."""
    s, z = Const("s"), Const("z")
    k = 0
    while type(t) is Root and t.head is s and len(t.args) == 1:
        t = t.args[0]
        k += 1
    return k if type(t) is Root and t.head is z and not t.args else None


def _one(n: int) -> dict:
    """One measurement at size n (runs inside a big-stack thread)."""
    text = program_text(n)
    gc.collect()
    t0 = time.perf_counter()
    prog = Program.from_text(text, f"<b1 n={n}>")
    t_parse = time.perf_counter() - t0
    q = prog.sig.directives[0]

    gc.collect()
    bw = Backward(prog, seed=0)
    t0 = time.perf_counter()
    search = bw.solve(q.goal)
    found = next(search, _NONE) is not _NONE  # solve yields one item (a proof term) per solution
    t_solve = time.perf_counter() - t0
    steps = sum(r.steps for r in bw.monad_runs)
    value = unary_value(zonk(q.logic_vars[0][1])) if found else None
    search.close()

    lines: list[str] = []
    gc.collect()
    t0 = time.perf_counter()
    res = run_query(prog, q, seed=0, emit=lines.append)
    t_query = time.perf_counter() - t0
    return {"parse_s": t_parse, "solve_s": t_solve, "query_s": t_query, "steps": steps,
            "value": value, "solutions": res.solutions}


def run(repeats: int = 5, quick: bool = False, sizes=None) -> dict:
    sizes = tuple(sizes or (QUICK_SIZES if quick else SIZES))
    Program.from_text(SIGNATURE, "<b1 warm-up>")  # load the grammar before timing anything
    rows = []
    for n in sizes:
        samples = [with_big_stack(_one, n) for _ in range(repeats)]
        med = {k: statistics.median(s[k] for s in samples) for k in ("parse_s", "solve_s", "query_s")}
        steps = samples[0]["steps"]
        ok = all(s["steps"] == expected_steps(n) and s["value"] == n * n and s["solutions"] == 1
                 for s in samples)
        total = med["parse_s"] + med["query_s"]
        row = {
            "n": n,
            "steps": steps,
            "expected_steps": expected_steps(n),
            "correct": ok,
            "parse_s": med["parse_s"],
            "solve_s": med["solve_s"],
            "solve_cold_s": samples[0]["solve_s"],
            "query_s": med["query_s"],
            "total_s": total,
            "us_per_step": 1e6 * med["solve_s"] / steps if steps else None,
            "samples": samples,
        }
        if n in TARGETS_S:
            row["target_s"] = TARGETS_S[n]
            row["meets_target"] = total < TARGETS_S[n]
        rows.append(row)
    base = next((r for r in rows if r["n"] == BASELINE_N), rows[0])
    for r in rows:
        r["step_ratio"] = (r["us_per_step"] / base["us_per_step"]) if base["us_per_step"] else None
    table_rows = []
    for r in rows:
        target = ""
        if "target_s" in r:
            target = f"< {r['target_s']:g} s: {'yes' if r['meets_target'] else 'NO'}"
        table_rows.append([
            str(r["n"]), f"{r['steps']:,}", "yes" if r["correct"] else "NO",
            f"{r['parse_s']:.3f}", f"{r['solve_cold_s']:.3f}", f"{r['solve_s']:.3f}", f"{r['query_s']:.3f}",
            f"{r['total_s']:.3f}",
            f"{r['us_per_step']:.1f}", f"{r['step_ratio']:.2f}", target,
        ])
    return {
        "name": NAME,
        "title": TITLE,
        "repeats": repeats,
        "baseline": f"us/step at n={base['n']} (same run)",
        "anchor": CELF_ANCHOR,
        "rows": rows,
        "tables": [{
            "title": TITLE,
            "columns": ["n", "steps", "correct", "parse s", "cold solve s", "solve s", "query s", "total s",
                        "us/step", "step ratio", "target"],
            "rows": table_rows,
        }],
        "notes": [
            f"medians of {repeats} runs; steps must equal n^2 + 3n + 5 and V must be n^2 ('correct')",
            "solve = proof search to the first solution; query = whole #query directive incl. printing V",
            "cold solve = the first run at that n (its numerals not yet hash-consed in the process); "
            "the others reuse them",
            "total = parse + query; step ratio = us/step over the baseline's (1.0 = linear in steps)",
            "anchor: " + CELF_ANCHOR,
        ],
    }


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from run import main

    sys.exit(main(["b1", *sys.argv[1:]]))
