"""Functional layer of bump.roar: `forward(d)` drives straight, blind, for d metres (or 8 s)."""

import math

from roar_formal.roar.functional import Outcome, Registry
from roar_formal.robot.activity import Activity, failed, ok

OUTCOMES = [Outcome("moved", True), Outcome("stuck", False)]


class Forward(Activity):
    name = "forward"

    def __init__(self, distance: float):
        self.distance = float(distance)
        self.timeout = 8.0
        self.x0 = None

    def start(self, robot):
        self.x0 = tuple(robot.world.base.pose[:2])
        robot.world.base.set_wheel_speeds(6.0, 6.0)
        return None

    def tick(self, robot):
        x, y, _ = robot.world.base.pose
        if math.hypot(x - self.x0[0], y - self.x0[1]) >= self.distance:
            robot.world.base.set_wheel_speeds(0.0, 0.0)
            return ok(True, "moved")
        return None

    def on_timeout(self, robot):
        robot.world.base.set_wheel_speeds(0.0, 0.0)
        return failed("stuck", False)

    def state_key(self, robot):
        x, y, _ = robot.world.base.pose
        return (self.distance, round(self.distance - math.hypot(x - self.x0[0], y - self.x0[1]), 2))


def registry() -> Registry:
    reg = Registry()
    reg.register("forward", lambda d: True, outcomes=OUTCOMES)
    return reg


def robot_registry() -> Registry:
    reg = Registry()
    reg.register("forward", lambda d: Forward(d), outcomes=OUTCOMES)
    return reg
