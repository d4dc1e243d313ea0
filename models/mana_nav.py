"""Functional layer of mana_nav.roar: a simulated lidar, sonar, mapper, planner and base.

``registry()`` builds a fresh simulation for each run; each primitive also
declares the abstract outcomes the explorer branches on.
"""

import math

from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    robot = {"x": 0.0, "y": 0.0, "path": None}

    def mk_point(x, y):
        return {"x": x, "y": y}

    def distance(a, b):
        ax, ay = (a["x"], a["y"]) if isinstance(a, dict) else a
        bx, by = (b["x"], b["y"]) if isinstance(b, dict) else b
        return math.hypot(float(ax) - float(bx), float(ay) - float(by))

    def astar(version, goal):
        return ("astar", version, goal["x"], goal["y"])

    def straight(goal):
        return ("straight", goal["x"], goal["y"])

    def follow(traj):
        robot["path"] = (float(traj[-2]), float(traj[-1]))
        return True

    def odom():
        # the base moves 1 m along the path at each reading, and stops on the goal
        if robot["path"] is not None:
            gx, gy = robot["path"]
            dx, dy = gx - robot["x"], gy - robot["y"]
            d = math.hypot(dx, dy)
            if d <= 1.0:
                robot["x"], robot["y"] = gx, gy
            else:
                robot["x"] += dx / d
                robot["y"] += dy / d
        return {"x": round(robot["x"], 6), "y": round(robot["y"], 6)}

    reg.register("grab", lambda: object(), outcomes=[Outcome("cloud", True)])
    reg.register("lidar_ok", lambda: True, outcomes=[Outcome("up", True), Outcome("down", False)])
    reg.register("sonar_ok", lambda: True, outcomes=[Outcome("up", True), Outcome("down", False)])
    reg.register("fuse", lambda cloud, version: version + 1, outcomes=[Outcome("fused", True, result=1)])
    reg.register("mk_point", mk_point, outcomes=[Outcome("point", True, result={"x": 3.0, "y": 4.0})])
    reg.register("distance", distance, outcomes=[Outcome("there", True, result=0.0),
                                                 Outcome("far", True, result=5.0)])
    reg.register("astar", astar, outcomes=[Outcome("path", True), Outcome("no_path", False)])
    reg.register("straight", straight, outcomes=[Outcome("line", True)])
    reg.register("follow", follow, outcomes=[Outcome("following", True), Outcome("stuck", False)])
    reg.register("odom", odom, outcomes=[Outcome("at_goal", True, result={"x": 3.0, "y": 4.0})])
    return reg
