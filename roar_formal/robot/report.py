"""Robot runs as traces (the project's JSON Lines format) and as pictures.

A robot trace is a run trace (one line per CLF step, with its ROAR event)
whose steps also carry the simulated time and the base's true pose, and
whose functional-layer steps carry the call: function, arguments, the
concrete result on the robot and the declared outcome it falls into. The
header names the spec, the request, the scenario with its fingerprint, the
seed and faults, and holds the driven trajectory and the planned paths.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Optional

from ..trace.format import write_trace
from .sim import SimResult

__all__ = ["write_robot_trace", "step_records", "draw_sim", "sources_fingerprint", "TRACE_KIND"]

TRACE_KIND = "roar-robot-run"


def sources_fingerprint(files) -> str:
    """sha256 over the contents of the spec's files (where they live does not matter): a trace
    made from other sources is stale."""
    parts = sorted(hashlib.sha256(Path(f).read_bytes()).hexdigest() for f in files if Path(f).is_file())
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def _r(x: float, k: int = 4) -> float:
    return round(float(x), k)


_FRESH = re.compile(r"([A-Za-z_][A-Za-z0-9_']*)#(\d+)")


class _Renamer:
    """Fresh names numbered in order of first appearance in the run (the engine numbers them per
    process), so one seed gives one trace file, byte for byte, whatever ran before it."""

    def __init__(self):
        self.names: dict = {}

    def __call__(self, text: str) -> str:
        def sub(m):
            n = self.names.setdefault(m.group(0), len(self.names) + 1)
            return f"{m.group(1)}#{n}"
        return _FRESH.sub(sub, text)


def step_records(res: SimResult) -> list[dict]:
    """One record per CLF step: rule, facts, ROAR event, simulated time, true pose, and the call it answers."""
    ren = _Renamer()
    by_step: dict[int, list] = {}
    for e in res.events:
        by_step.setdefault(e.step, []).append(e.as_json())
    calls = {c.step_end: c for c in res.calls if c.step_end is not None}
    steps = []
    for i, (rule, consumed, produced) in enumerate(res.run.steps, 1):
        evs = by_step.get(i)
        x, y, th = res.poses[i - 1]
        rec = {"step": i, "rule": rule, "consumed": [ren(x) for x in consumed],
               "produced": [ren(x) for x in produced],
               "event": (evs[0] if len(evs) == 1 else {"kind": "several", "events": evs}) if evs else None,
               "loop": False, "time": _r(res.times[i - 1]), "pose": [_r(x), _r(y), _r(th)]}
        if i in calls:
            rec["call"] = calls[i].as_json()
        steps.append(rec)
    return steps


def write_robot_trace(path, res: SimResult, spec: str, request: str, scenario_path: Optional[str],
                      spec_files=()) -> None:
    steps = [{k: v for k, v in r.items() if k != "step"} for r in step_records(res)]
    from ..roar.explore import sequential_pairs
    sc = res.robot.scenario
    pairs = [[p.a, p.b, p.where, p.a_text, p.b_text] for p in sequential_pairs(res.run.model)]
    header = {"kind": TRACE_KIND, "seq_pairs": pairs, "spec": str(spec), "request": request, "seed": res.seed,
              "faults": list(res.faults), "primitive_faults": list(res.prim_faults),
              "scenario": scenario_path, "scenario_name": sc.name, "scenario_fingerprint": sc.fingerprint,
              "spec_fingerprint": sources_fingerprint(spec_files) if spec_files else None,
              "outcome": res.outcome, "end": res.end, "requests": res.run.requests,
              "duration": _r(res.robot.time),
              "trajectory": [[_r(t, 3), _r(x), _r(y), _r(th)] for t, x, y, th in res.robot.trajectory],
              "plans": [[_r(t, 3), label, [[_r(px), _r(py)] for px, py in pts]] for t, label, pts in res.robot.plans]}
    write_trace(path, header, steps)


def draw_sim(path_png, res: SimResult, title: Optional[str] = None, marks=()) -> None:
    """The scenario, the map the robot knew, the planned paths, the driven trajectory and the events."""
    from .draw import draw_run
    robot = res.robot
    if robot.world.ptu is not None and robot.pan and not robot.plans:
        draw_robot(path_png, robot, title or f"{robot.scenario.name}: request {res.outcome} at t={robot.time:.1f}s")
        return
    events = []
    seen = set()
    for e in res.events:   # the first time each state change, pause or resume happens
        if e.kind in ("state", "pause", "resume") and (e.agent, e.text) not in seen:
            seen.add((e.agent, e.text))
            x, y, _ = res.poses[e.step - 1]
            events.append((res.times[e.step - 1], x, y, f"{e.agent}: {e.text}"))
    planned = []
    seen = set()
    for t, label, pts in robot.plans:
        key = tuple(map(tuple, pts))
        if key in seen:
            continue
        seen.add(key)
        planned.append((f"{label} t={t:.1f}s", pts))
    planned = planned[:6]
    draw_run(path_png, robot.world.geometry(), grid=robot.picture_grid(), planned=planned,
             driven=robot.trajectory, events=events, marks=marks,
             title=title or f"{robot.scenario.name}: request {res.outcome} at t={robot.time:.1f}s")


def draw_robot(path_png, robot, title: str, marks=()) -> None:
    """A robot's run without the agents' events: the pan angle over time when the scenario is about
    the pan unit (it does not drive), else the map and the driven trajectory."""
    from .draw import draw_ptu, draw_run
    if robot.world.ptu is not None and robot.pan and not robot.plans:
        ptu = robot.scenario.ptu
        on = list(robot.world.faults) + [name for name, _t in robot.world.armed]
        cable = [robot.scenario.faults[f].max_deg for f in on if robot.scenario.faults[f].kind == "ptu_cable"]
        limits = (-cable[0], cable[0]) if cable else (ptu.min_deg, ptu.max_deg)
        draw_ptu(path_png, [p[0] for p in robot.pan], [p[1] for p in robot.pan], [p[2] for p in robot.pan],
                 limits=limits, title=title)
        return
    draw_run(path_png, robot.world.geometry(), grid=robot.picture_grid(), driven=robot.trajectory, marks=marks,
             title=title)
