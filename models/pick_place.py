"""Functional layer of pick_place.roar: the base and the gripper.

``registry()`` is the abstract binding (everything succeeds; the explorer
branches on the declared outcomes). ``robot_registry()`` binds the
primitives to the pymunk reference robot (scenario
``models/scenarios/gripper.toml``): ``go_to`` plans to a place of the
scenario with A* and drives there, or, for an object, drives straight at it
until the object is between the jaws; ``close_jaws`` succeeds only when the
jaws close around an object; ``has_object`` asks the gripper.
"""

import math

from roar_formal.robot.activity import Read, failed
from roar_formal.robot.robot import FollowPath, Grip
from roar_formal.roar.functional import Outcome, Registry

OUTCOMES = {
    "go_to": [Outcome("arrived", True), Outcome("failed", False)],
    "close_jaws": [Outcome("holding", True), Outcome("empty", False)],
    "open_jaws": [Outcome("opened", True), Outcome("stuck", False)],
    "has_object": [Outcome("yes", True), Outcome("no", False)],
}


def registry() -> Registry:
    reg = Registry()
    reg.register("go_to", lambda name: True, outcomes=OUTCOMES["go_to"])
    reg.register("close_jaws", lambda: True, outcomes=OUTCOMES["close_jaws"])
    reg.register("open_jaws", lambda: True, outcomes=OUTCOMES["open_jaws"])
    reg.register("has_object", lambda: True, outcomes=OUTCOMES["has_object"])
    return reg


class GoTo(FollowPath):
    """Drive to a place of the scenario (A*), or up to an object so that it sits between the jaws."""

    name = "go_to"

    def __init__(self, target: str):
        super().__init__(None, timeout=60.0, speed=0.4)
        self.target = str(target)

    def start(self, robot):
        w = robot.world
        x, y, _ = w.base.odometry
        if self.target in w.objects:
            body = w.objects[self.target]
            ox, oy = body.position
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
    reg.register("open_jaws", lambda: Grip(close=False), outcomes=OUTCOMES["open_jaws"])
    reg.register("has_object", lambda: Read(lambda robot: robot.world.gripper.holding is not None, "has_object"),
                 outcomes=OUTCOMES["has_object"])
    return reg
