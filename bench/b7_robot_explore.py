"""B7: robot-backed exploration against the abstract search of the same spec.

Runs the robot-backed jobs of ``checker/robot/`` (the comparison with the
abstract model turned off, so that only the robot-backed search is timed) and
the abstract search of the same spec and request (the primitives as their
declared outcomes), and reports states per second for both and their ratio,
with where the robot-backed time goes: robot states made, restores from
snapshots (each replays the world from its start), physics ticks run.

The abstract door_nav search does not finish (its state space grows with every
poll of ``at_goal``); it is timed on its first 20,000 states.

Run: ``python bench/b7_robot_explore.py`` (or ``python bench/run.py b7``).
"""

from __future__ import annotations

import copy
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ROOT = Path(__file__).resolve().parents[1]
NAME = "b7"
TITLE = "Robot-backed exploration: states per second against the abstract search"
JOBS = [("door (door closes at drive)", "door_nav.toml"), ("door stays closed", "door_nav_stuck.toml"),
        ("pan unit, cable", "conflict_cable.toml")]
ABSTRACT_STATES = 20_000


def _robot(path: Path) -> dict:
    from roar_formal.verify.check import run_job
    from roar_formal.verify.jobs import load_job
    job = load_job(path)
    job.robot.compare = False
    t = time.perf_counter()
    res = run_job(job)
    el = time.perf_counter() - t
    st = res.robot.tree.stats()
    return {"states": res.graph.n_states, "seconds": el, "states_per_s": res.graph.n_states / el,
            "complete": bool(res.graph.complete), "memory_mb": res.memory_mb, **st,
            "verdicts": {p: v.status for p, v in res.verdicts.items()}}


def _abstract(path: Path, max_states: int) -> dict:
    from roar_formal.verify.check import run_job
    from roar_formal.verify.jobs import load_job
    job = copy.copy(load_job(path))
    job.robot = None
    job.expect = {}
    job.budget.max_states = max_states
    job.budget.max_seconds = 600
    t = time.perf_counter()
    res = run_job(job)
    el = time.perf_counter() - t
    return {"states": res.graph.n_states, "seconds": el, "states_per_s": res.graph.n_states / el,
            "complete": bool(res.graph.complete), "verdicts": {p: v.status for p, v in res.verdicts.items()}}


def run(repeats: int = 1, quick: bool = False) -> dict:
    cases, rows, where = [], [], []
    for label, name in JOBS:
        path = ROOT / "checker" / "robot" / name
        r = _robot(path)
        a = _abstract(path, 5_000 if quick else ABSTRACT_STATES)
        ratio = r["states_per_s"] / a["states_per_s"]
        cases.append({"case": label, "robot": r, "abstract": a, "ratio": ratio})
        rows.append([label, f"{r['states']:,}", f"{r['seconds']:.1f}", f"{r['states_per_s']:,.0f}",
                     f"{a['states']:,}{'' if a['complete'] else ' (budget)'}", f"{a['states_per_s']:,.0f}",
                     f"{ratio:.2f}"])
        where.append([label, f"{r['robot_states']:,}", f"{r['restores']:,}", f"{r['physics_ticks']:,}",
                      f"{r['memory_mb']:,.0f}"])
    return {
        "cases": cases,
        "tables": [
            {"title": "B7: robot-backed vs abstract search (states per second)",
             "columns": ["case", "robot states", "robot s", "robot st/s", "abstract states", "abstract st/s",
                         "ratio"], "rows": rows},
            {"title": "B7: robot-backed work", "columns": ["case", "robot states", "restores", "physics ticks",
                                                            "process peak MiB"], "rows": where},
        ],
    }


if __name__ == "__main__":
    from run import main
    sys.exit(main(["b7"] + sys.argv[1:]))
