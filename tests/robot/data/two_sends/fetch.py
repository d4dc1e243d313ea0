"""Functional layer of fetch.roar: abstract registry and a robot binding (gripper scenario)."""
import math

from roar_formal.roar.functional import Outcome, Registry
from roar_formal.robot.activity import Read, failed
from roar_formal.robot.robot import FollowPath, Grip

OUTCOMES = {
    "go_to": [Outcome("arrived", True), Outcome("failed", False)],
    "close_jaws": [Outcome("holding", True), Outcome("empty", False)],
    "in_reach": [Outcome("yes", True), Outcome("no", False)],
    "has_object": [Outcome("yes", True), Outcome("no", False)],
}


def registry() -> Registry:
    reg = Registry()
    reg.register("go_to", lambda name: True, outcomes=OUTCOMES["go_to"])
    reg.register("close_jaws", lambda: True, outcomes=OUTCOMES["close_jaws"])
    reg.register("in_reach", lambda: True, outcomes=OUTCOMES["in_reach"])
    reg.register("has_object", lambda: True, outcomes=OUTCOMES["has_object"])
    return reg


def _in_reach(robot):
    x, y, _ = robot.world.base.odometry
    ox, oy = robot.world.objects["cup"].position
    return math.hypot(ox - x, oy - y) < 0.6


class GoTo(FollowPath):
    """Drive to a place (A*), or up to an object so that it sits between the jaws (from models/pick_place.py)."""

    name = "go_to"

    def __init__(self, target):
        super().__init__(None, timeout=60.0, speed=0.4)
        self.target = str(target)

    def start(self, robot):
        w = robot.world
        x, y, _ = w.base.odometry
        if self.target in w.objects:
            ox, oy = w.objects[self.target].position
            d = math.hypot(ox - x, oy - y)
            if d < 1e-6:
                return failed("at_object", False)
            cfg = robot.scenario.robot
            back = cfg.radius + cfg.gripper.reach / 2.0
            self.path = [(x, y), (ox - (ox - x) * back / d, oy - (oy - y) * back / d)]
        elif self.target in robot.scenario.places:
            path = robot.plan_to(robot.scenario.places[self.target], f"go_to {self.target}")
            if path is None:
                return failed("no_path", False)
            self.path = path
        else:
            return failed("unknown_place", False)
        return super().start(robot)


def robot_registry() -> Registry:
    reg = Registry()
    reg.register("go_to", lambda name: GoTo(name), outcomes=OUTCOMES["go_to"])
    reg.register("close_jaws", lambda: Grip(close=True), outcomes=OUTCOMES["close_jaws"])
    reg.register("in_reach", lambda: Read(_in_reach, "in_reach"), outcomes=OUTCOMES["in_reach"])
    reg.register("has_object", lambda: Read(lambda robot: robot.world.gripper.holding is not None, "has_object"),
                 outcomes=OUTCOMES["has_object"])
    return reg
