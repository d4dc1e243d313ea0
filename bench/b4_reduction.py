"""B4: partial-order reduction (stubborn sets) on the general backend.

For each model with a general-backend start state: compiled ROAR models
(the seeded faulty models and their fixes, demo_loco; deadlock against ROAR
final states, agents as processes), the dining philosophers
(N = 4, 5, variants dl/ok/ll), every ``#exec`` start of ``models/clf/*.clf``
whose state space is finite (explored completely within a small budget), and
k independent three-step processes: states, transitions and search time with
and without reduction, the reduction factor (states without / states with)
and whether the deadlock verdict agrees. The reduction keeps every quiescent
state (see ``roar_formal/explore/reduction.py``); the cycle proviso of the
breadth-first search limits it on models whose processes cycle.
"""

from __future__ import annotations

import importlib.util
import statistics
import time
from pathlib import Path

NAME = "b4"
TITLE = "B4 partial-order reduction (general backend): states with and without"
ROOT = Path(__file__).resolve().parents[1]
PROBE = 20_000  # a start state whose space exceeds this is left out (not finite enough for a benchmark)


def _gen():
    spec = importlib.util.spec_from_file_location("phil_gen", ROOT / "models/philosophers/generate.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def independent(k: int) -> str:
    return ("pid : type.\n" + "".join(f"q{i} : pid.\n" for i in range(k))
            + "a : pid -> type. b : pid -> type. d : pid -> type. e : pid -> type.\n"
            + "ab : a P -o {b P}.\nbd : b P -o {d P}.\nde : d P -o {e P}.\n"
            + "#exec * " + " * ".join(f"a q{i}" for i in range(k)) + ".\n")


def _explore(program, start, reduction: bool, budget, roar=None):
    """Explore with or without reduction; ``roar`` (a compiled ROAR model) uses the ROAR
    system (agents as groups) and ROAR final states for the deadlock verdict."""
    from roar_formal.explore.properties import check_deadlock
    from roar_formal.explore.search import Explorer
    from roar_formal.explore.system import ClfSystem, Options

    if roar is not None:
        from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem, roar_final
        system = RoarSystem(roar, start, Options(progress_rules=PROGRESS_RULES, reduction=reduction))
    else:
        system = ClfSystem(program, start, Options(reduction=reduction))
    ex = Explorer(system)
    t0 = time.perf_counter()
    g = ex.run(budget)
    dt = time.perf_counter() - t0
    accept = (lambda sid: roar_final(ex.states[sid])) if roar is not None else None
    return g, dt, check_deadlock(g, accept).status


ROAR_CASES = [("faulty/mutual_make.roar", "arm::started == true", None),
              ("faulty/mutual_make_fixed.roar", "arm::started == true", None),
              ("faulty/retry_bounded.roar", "hand::holding == true", None),
              ("faulty/ordered_pick.roar", "cell::done == true", "faulty/reliable_tools.py"),
              ("faulty/ordered_pick_fixed.roar", "cell::done == true", "faulty/reliable_tools.py"),
              ("demo_loco", "demo_loco::pos == demo_loco::goal where demo_loco::goal == 5", None)]


def _roar_cases():
    """Compiled ROAR models (functional layer as outcome rules), with their start states."""
    from roar_formal.clf.signature import ExecDirective
    from roar_formal.roar.functional import functional_module, load_registry
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.spec import load_spec

    for spec, request, fn in ROAR_CASES:
        path = ROOT / "models" / spec
        reg = load_registry(functional_module(path, ROOT / "models" / fn if fn else None))
        model = compile_spec(load_spec(path), request, registry=reg, functional="abstract")
        p = model.program()
        start = next(d for d in p.sig.directives if isinstance(d, ExecDirective)).start
        yield f"roar {spec}", p, p.start_context(start), model


def _cases(quick: bool):
    from roar_formal.clf.program import Program
    from roar_formal.clf.signature import ExecDirective

    yield from _roar_cases()
    gen = _gen()
    ns = (4,) if quick else (4, 5)
    for variant in ("dl", "ok", "ll"):
        for n in ns:
            p = Program.from_text(gen.program(variant, n))
            yield f"philosophers {variant} N={n}", p, p.start_context(p.sig.directives[-1].start), None
    for k in ((4, 6) if quick else (4, 5, 6)):
        p = Program.from_text(independent(k))
        yield f"{k} independent processes", p, p.start_context(p.sig.directives[-1].start), None
    for f in sorted((ROOT / "models/clf").glob("*.clf")):
        try:
            p = Program.from_file(f)
        except Exception:  # noqa: BLE001 - a model the engine refuses is not benchmarked
            continue
        execs = [d for d in p.sig.directives if isinstance(d, ExecDirective)]
        for i, d in enumerate(execs, 1):
            try:
                yield f"clf/{f.name} #exec {i}", p, p.start_context(d.start), None
            except Exception:  # noqa: BLE001
                continue


def _run(repeats: int, quick: bool) -> dict:
    from roar_formal.explore.search import Budget

    rows, data = [], []
    probe = Budget(max_states=PROBE, max_seconds=5 if quick else 10)
    for name, program, start, roar in _cases(quick):
        g_full, _, _ = _explore(program, start, False, probe, roar)
        if not g_full.complete:
            continue  # infinite or too large: not part of the benchmark
        t_full, t_red = [], []
        for _ in range(max(1, repeats)):
            g_full, dt, st_full = _explore(program, start, False, Budget(), roar)
            t_full.append(dt)
            g_red, dt, st_red = _explore(program, start, True, Budget(), roar)
            t_red.append(dt)
        rec = {"model": name, "states": g_full.n_states, "transitions": g_full.n_edges,
               "seconds": statistics.median(t_full), "states_reduced": g_red.n_states,
               "transitions_reduced": g_red.n_edges, "seconds_reduced": statistics.median(t_red),
               "factor": g_full.n_states / max(1, g_red.n_states), "deadlock": st_full,
               "deadlock_reduced": st_red, "agree": st_full == st_red}
        data.append(rec)
        rows.append([name, f"{rec['states']:,}", f"{rec['transitions']:,}", f"{rec['seconds']:.3f}",
                     f"{rec['states_reduced']:,}", f"{rec['transitions_reduced']:,}",
                     f"{rec['seconds_reduced']:.3f}", f"{rec['factor']:.2f}",
                     rec["deadlock"] + ("" if rec["agree"] else " != " + rec["deadlock_reduced"])])
    cols = ["model", "states", "transitions", "s", "states (POR)", "transitions (POR)", "s (POR)",
            "factor", "deadlock"]
    prop_rows, prop_data = _property_rows(quick)
    return {"results": data, "property_results": prop_data,
            "tables": [{"title": TITLE, "columns": cols, "rows": rows},
                       {"title": "B4 reduction with other properties: an invariant (a forbidden pattern kept in "
                                 "every stubborn set) and progress-free cycles (progress steps visible, no fairness)",
                        "columns": ["model", "property", "states", "states (POR)", "factor", "verdict",
                                    "verdict (POR)"],
                        "rows": prop_rows}]}


def _property_rows(quick: bool):
    """Invariants and livelock without fairness, with and without reduction."""
    from roar_formal.clf.program import Program
    from roar_formal.verify.check import make_never
    from roar_formal.explore.properties import check_livelock, check_states
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import ClfSystem, Options

    gen = _gen()
    cases = []
    for k in ((4, 6) if quick else (4, 5, 6)):
        src = independent(k)
        cases.append((f"{k} independent processes", src, "invariant", "e q0 * e q1"))
        cases.append((f"{k} independent processes", src, "livelock", "de"))
    for n in ((4,) if quick else (4, 5)):
        cases.append((f"philosophers ok N={n}", gen.program("ok", n), "invariant", "at3 p0 * at3 p1"))
        cases.append((f"philosophers ll N={n}", gen.program("ll", n), "livelock", "eat"))
    rows, data = [], []
    for name, src, prop, arg in cases:
        p = Program.from_text(src)
        never = make_never(src, name, [(arg, None)]) if prop == "invariant" else None
        out = {}
        for red in (False, True):
            opts = Options(reduction=red, fairness="none")
            if never is not None:
                opts.observers = never.templates
            else:
                opts.progress_rules = (arg,)
            ex = Explorer(ClfSystem(p, p.start_context(p.sig.directives[-1].start), opts))
            g = ex.run(Budget())
            v = (check_states(g, "invariant", lambda sid, ex=ex: never(ex.states[sid])) if never is not None
                 else check_livelock(g))
            out[red] = (g.n_states, v.status)
        rec = {"model": name, "property": prop, "states": out[False][0], "states_reduced": out[True][0],
               "verdict": out[False][1], "verdict_reduced": out[True][1]}
        data.append(rec)
        rows.append([name, f"{prop} ({arg})", f"{rec['states']:,}", f"{rec['states_reduced']:,}",
                     f"{rec['states'] / max(1, rec['states_reduced']):.2f}", rec["verdict"], rec["verdict_reduced"]])
    return rows, data


def run(repeats: int = 1, quick: bool = False) -> dict:
    from roar_formal.clf.query import with_big_stack

    return with_big_stack(_run, repeats, quick)


if __name__ == "__main__":
    out = run(1, quick=False)
    for t in out["tables"]:
        print(t["title"])
        print(" | ".join(t["columns"]))
        for r in t["rows"]:
            print(" | ".join(r))
