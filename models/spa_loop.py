"""Functional layer of spa_loop.roar: a lidar, planner and base.

``registry()`` is the abstract binding (a small dictionary simulation for
``roar-verify run``; the explorer branches on the declared outcomes).
``robot_registry()`` binds the primitives to the pymunk reference robot
(``roar-verify simulate``; scenarios ``slip`` and ``clear``). The goal is an
integer: the robot drives along the line y = its start's y to x = goal
metres. ``scan_stamp`` counts the lidar's scans; ``compute_plan`` plans with
A*; ``track`` starts the pure-pursuit controller on the plan (planning one
itself if there is none yet); ``odometry`` reads x to the nearest metre.

The outcomes with fixed values are written for the request
``exec::arrived == true where exec::goal == 7``. A stamp is classified
``new_scan()`` tells whether a scan arrived since the previous call (the
functional layer keeps the stamp it last saw): its outcomes ``scan`` and
``none`` are exact, true and false.
"""

from roar_formal.robot.activity import Read, Sleep, ok
from roar_formal.robot.robot import Plan
from roar_formal.roar.functional import Outcome, Registry

GOAL = 7

OUTCOMES = {
    "new_scan": [Outcome("scan", True, covers=lambda r: r.ok),
                 Outcome("none", False, covers=lambda r: not r.failed and r.value is False)],
    "compute_plan": [Outcome("planned", True), Outcome("no_path", False)],
    "track": [Outcome("tracking", True), Outcome("lost", False)],
    "odometry": [Outcome("at_goal", True, result=GOAL, covers=lambda r: r.ok and r.value == GOAL),
                 Outcome("moving", True, result=3, covers=lambda r: r.ok and r.value != GOAL)],
}


def registry() -> Registry:
    reg = Registry()
    state = {"scans": 0, "target": None, "pos": 0}

    def new_scan():
        # one scan arrives, then the lidar keeps reporting it
        seen, state["scans"] = state["scans"], 1
        return state["scans"] > seen

    def compute_plan(goal):
        return True

    def track(goal):
        state["target"] = goal
        return True

    def odometry():
        # the base moves one unit towards the tracked target at each reading
        t = state["target"]
        if t is not None and state["pos"] != t:
            state["pos"] += 1 if t > state["pos"] else -1
        return state["pos"]

    reg.register("new_scan", new_scan, outcomes=OUTCOMES["new_scan"])
    reg.register("compute_plan", compute_plan, outcomes=OUTCOMES["compute_plan"])
    reg.register("track", track, outcomes=OUTCOMES["track"])
    reg.register("odometry", odometry, outcomes=OUTCOMES["odometry"])
    return reg


def _target(robot, goal):
    return (float(goal), robot.scenario.robot.start[1])


def robot_registry() -> Registry:
    reg = Registry()

    def new_scan():
        def read(robot):
            prev = robot.memo.get("stamp", 0)
            robot.memo["stamp"] = robot.scans
            return ok(robot.scans > prev, "new_scan", stamp=robot.scans, previous=prev)
        return Read(read, "new_scan")

    def compute_plan(goal):
        return _PlanTo(goal)

    def track(goal):
        def read(robot):
            path = robot.path or robot.plan_to(_target(robot, goal), "track")
            return robot.follow(path or [])
        return Read(read, "track")

    reg.register("new_scan", new_scan, outcomes=OUTCOMES["new_scan"])
    reg.register("compute_plan", compute_plan, outcomes=OUTCOMES["compute_plan"])
    reg.register("track", track, outcomes=OUTCOMES["track"])
    reg.register("odometry", lambda: Sleep(0.05, "odometry_metres", name="odometry"), outcomes=OUTCOMES["odometry"])
    return reg


class _PlanTo(Plan):
    """Plan to x = goal on the start's line (the goal is known only once the robot is there)."""

    def __init__(self, goal):
        super().__init__((float(goal), 0.0), seconds=0.3, label="compute_plan")
        self.x = float(goal)

    def start(self, robot):
        self.goal = _target(robot, self.x)
        return super().start(robot)
