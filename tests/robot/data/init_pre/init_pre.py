"""Functional layer of init_pre.roar: ``odometry()`` (x to the nearest metre, a sensor that takes
50 ms) and ``front_clear()`` (the latest lidar scan shows nothing within 1 m ahead), on the
reference robot (``robot_registry()``) and abstractly (``registry()``)."""

from roar_formal.robot.activity import Read, Sleep
from roar_formal.roar.functional import Outcome, Registry

OUTCOMES = {
    "odometry": [Outcome("west", True, result=1, covers=lambda r: r.ok and r.value < 3),
                 Outcome("east", True, result=4, covers=lambda r: r.ok and r.value >= 3)],
    "front_clear": [Outcome("clear", True), Outcome("blocked", False)],
}


def registry() -> Registry:
    reg = Registry()
    reg.register("odometry", lambda: 1, outcomes=OUTCOMES["odometry"])
    reg.register("front_clear", lambda: True, outcomes=OUTCOMES["front_clear"])
    return reg


def robot_registry() -> Registry:
    reg = Registry()
    reg.register("odometry", lambda: Sleep(0.05, "odometry_metres", name="odometry"),
                 outcomes=OUTCOMES["odometry"])
    reg.register("front_clear", lambda: Read(lambda robot: robot.front_clear(), "front_clear"),
                 outcomes=OUTCOMES["front_clear"])
    return reg
