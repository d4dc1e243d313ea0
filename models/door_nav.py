"""Functional layer of door_nav.roar: the declared outcomes, an abstract registry and the robot binding.

``registry()`` answers calls without a robot (``roar-verify run``; the
explorer branches on the outcomes instead). ``robot_registry()`` binds each
primitive to the pymunk reference robot (``roar-verify simulate``): the
planner plans with A* on the floor plan and the latest lidar scan, the base
follows the path with a pure-pursuit controller. Each outcome says which
concrete robot results it stands for (``covers``); ``roar-verify conform``
checks that every result the robot produces falls into one.
"""

import math

from roar_formal.robot.activity import Read
from roar_formal.robot.robot import Plan
from roar_formal.roar.functional import Outcome, Registry

#: how close to the goal (m, by odometry) counts as there
GOAL_TOLERANCE = 0.15

PLANNED = Outcome("planned", True)
NO_PATH = Outcome("no_path", False)
BLOCKED = Outcome("blocked", True)          # path_blocked() returns true
CLEAR = Outcome("clear", False)
DRIVING = Outcome("driving", True)
NOT_DRIVING = Outcome("not_driving", False)
THERE = Outcome("there", True)
NOT_YET = Outcome("not_yet", False)

OUTCOMES = {"compute_path": [PLANNED, NO_PATH], "path_blocked": [BLOCKED, CLEAR],
            "drive": [DRIVING, NOT_DRIVING], "at_goal": [THERE, NOT_YET]}


def registry() -> Registry:
    """Without a robot: plans always succeed, the path stays clear, the base arrives at its second reading."""
    reg = Registry()
    readings = {"n": 0}

    def at_goal(gx, gy):
        readings["n"] += 1
        return readings["n"] >= 2

    reg.register("compute_path", lambda gx, gy: True, outcomes=OUTCOMES["compute_path"])
    reg.register("path_blocked", lambda: False, outcomes=OUTCOMES["path_blocked"])
    reg.register("drive", lambda: True, outcomes=OUTCOMES["drive"])
    reg.register("at_goal", at_goal, outcomes=OUTCOMES["at_goal"])
    return reg


def robot_registry() -> Registry:
    """Bound to the reference robot."""
    reg = Registry()

    def at_goal(gx, gy):
        def read(robot):
            x, y, _ = robot.world.base.odometry
            return math.hypot(x - float(gx), y - float(gy)) < GOAL_TOLERANCE
        return Read(read, "at_goal")

    reg.register("compute_path", lambda gx, gy: Plan((gx, gy), seconds=0.3), outcomes=OUTCOMES["compute_path"])
    reg.register("path_blocked", lambda: Read(lambda robot: robot.path_blocked(), "path_blocked"),
                 outcomes=OUTCOMES["path_blocked"])
    reg.register("drive", lambda: Read(lambda robot: robot.follow(robot.path or []), "drive"),
                 outcomes=OUTCOMES["drive"])
    reg.register("at_goal", at_goal, outcomes=OUTCOMES["at_goal"])
    return reg
