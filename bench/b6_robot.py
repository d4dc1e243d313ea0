"""B6: the reference robot in the loop, in simulated time against real time.

Runs ``models/door_nav.roar`` on the navigation scenarios with the pymunk
robot (``roar-verify simulate`` without printing) and reports, medians over
the repeats:

  * simulated seconds per real second (target: at least 50);
  * where the real time goes: the agents (CLF engine steps and the
    simulation's bookkeeping), the physics (pymunk and the wheel model), the
    lidar (ray queries), path planning (A*) and the path follower;
  * the per-step costs: one physics step, one 90-ray scan, one plan.

The breakdown wraps the functions that do each part with a timer for one
extra run, so it adds a little overhead of its own; the headline figure comes
from runs without it.

Run: ``python bench/b6_robot.py`` (or ``python bench/run.py b6``).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ROOT = Path(__file__).resolve().parents[1]
NAME = "b6"
TITLE = "Reference robot in the loop: simulated time per real time"
TARGET = 50.0
SPEC = ROOT / "models" / "door_nav.roar"
CASES = [
    ("door, door stays open", "door.toml", (), "base::arrived == true where base::gx == 9.0 && base::gy == 3.0"),
    ("door, door closes and reopens", "door.toml", ("door_closes",),
     "base::arrived == true where base::gx == 9.0 && base::gy == 3.0"),
    ("clear room", "clear.toml", (), "base::arrived == true where base::gx == 10.5 && base::gy == 3.0"),
]


def _prepare(scenario: str, request: str):
    from roar_formal.robot.setup import prepare
    spec_ast, model, binding, sc = prepare(SPEC, request, ROOT / "models" / "scenarios" / scenario)
    model.program()   # compile once, outside the timing
    return model, binding, sc


def _one(model, binding, sc, faults, seed=0):
    from roar_formal.robot.sim import simulate
    began = time.perf_counter()
    res = simulate(model, binding.robot, sc, seed=seed, faults=list(faults))
    return time.perf_counter() - began, res


class _Timer:
    """Wraps methods with an accumulating timer (for the breakdown run only)."""

    def __init__(self):
        self.spent: dict[str, float] = {}
        self.undo: list = []

    def wrap(self, owner, attr: str, label: str) -> None:
        fn = getattr(owner, attr)
        spent = self.spent
        spent.setdefault(label, 0.0)

        def timed(*a, **k):
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[label] += time.perf_counter() - t

        setattr(owner, attr, timed)
        self.undo.append((owner, attr, fn))

    def restore(self) -> None:
        for owner, attr, fn in reversed(self.undo):
            setattr(owner, attr, fn)


def _breakdown(model, binding, sc, faults) -> dict:
    from roar_formal.clf.forward import Run
    from roar_formal.robot import robot as robot_mod, world as world_mod
    t = _Timer()
    t.wrap(world_mod.World, "step", "physics (pymunk, wheels, doors)")
    t.wrap(world_mod.Lidar, "scan", "lidar (ray queries)")
    t.wrap(robot_mod, "plan_path", "planning (A*)")
    t.wrap(robot_mod.Robot, "_control", "path follower and safety stop")
    t.wrap(Run, "run", "agents (CLF engine)")
    try:
        total, res = _one(model, binding, sc, faults)
    finally:
        t.restore()
    parts = dict(t.spent)
    parts["other (simulation loop, activities, events)"] = total - sum(parts.values())
    return {"total": total, "simulated": res.robot.time, "parts": parts, "clf_steps": len(res.run.steps),
            "physics_steps": res.robot.world.steps}


def _unit_costs(sc) -> dict:
    from roar_formal.robot.robot import Robot
    r = Robot(sc, seed=0)
    w = r.world
    n = 2000
    t = time.perf_counter()
    for _ in range(n):
        w.step()
    step = (time.perf_counter() - t) / n
    t = time.perf_counter()
    for _ in range(100):
        w.lidar.scan()
    scan = (time.perf_counter() - t) / 100
    t = time.perf_counter()
    for _ in range(20):
        r.plan_to(sc.places.get("goal", (9.0, 3.0)))
    plan = (time.perf_counter() - t) / 20
    return {"physics_step_ms": step * 1000, "scan_ms": scan * 1000, "plan_ms": plan * 1000}


def run(repeats: int = 5, quick: bool = False) -> dict:
    repeats = 2 if quick else repeats
    rows, cases = [], []
    breakdown_rows = []
    for label, scenario, faults, request in CASES:
        model, binding, sc = _prepare(scenario, request)
        _one(model, binding, sc, faults)   # warm-up: first imports (scipy for planning) and caches
        times, sim = [], None
        for _ in range(repeats):
            dt, res = _one(model, binding, sc, faults)
            times.append(dt)
            sim = res.robot.time
        med = statistics.median(times)
        ratio = sim / med
        cases.append({"case": label, "simulated_s": sim, "real_s": med, "ratio": ratio, "outcome": res.outcome,
                      "clf_steps": len(res.run.steps), "met": ratio >= TARGET})
        rows.append([label, f"{sim:.1f}", f"{med:.3f}", f"{ratio:.0f}x", res.outcome,
                     "yes" if ratio >= TARGET else "NO"])
        if faults:   # where the time goes, on the case with the most going on
            b = _breakdown(model, binding, sc, faults)
            cases[-1]["breakdown"] = b
            for part, spent in sorted(b["parts"].items(), key=lambda kv: -kv[1]):
                breakdown_rows.append([part, f"{spent:.3f}", f"{100 * spent / b['total']:.0f}%"])
    units = _unit_costs(_prepare(CASES[0][1], CASES[0][3])[2])
    return {
        "target_ratio": TARGET,
        "cases": cases,
        "units": units,
        "tables": [
            {"title": f"B6: simulated seconds per real second (medians of {repeats}; target >= {TARGET:.0f}x)",
             "columns": ["case", "simulated s", "real s", "ratio", "outcome", "met"], "rows": rows},
            {"title": "B6: where the time goes (door closes and reopens, one run with timers)",
             "columns": ["part", "real s", "share"], "rows": breakdown_rows},
            {"title": "B6: unit costs", "columns": ["what", "ms"],
             "rows": [["one physics step", f"{units['physics_step_ms']:.3f}"],
                      ["one 90-ray lidar scan", f"{units['scan_ms']:.3f}"],
                      ["one A* plan across the door map", f"{units['plan_ms']:.2f}"]]},
        ],
    }


if __name__ == "__main__":
    from run import main
    sys.exit(main(["b6"] + sys.argv[1:]))
