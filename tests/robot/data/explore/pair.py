"""Functional layer of pair.roar: `look()` waits 0.2 s and reports whether the lidar is up;
`nudge()` drives the base forward for 0.3 s (it fails on a slippery floor: it moved too little)."""

from roar_formal.roar.functional import Outcome, Registry
from roar_formal.robot.activity import Activity, Sleep, failed, ok

LOOK = [Outcome("up", True), Outcome("down", False)]
NUDGE = [Outcome("moved", True), Outcome("slipped", False)]


class Nudge(Activity):
    name = "nudge"

    def __init__(self):
        self.left = 30          # ticks of driving left
        self.x0 = 0.0

    def start(self, robot):
        self.x0 = robot.world.base.pose[0]
        robot.world.base.set_wheel_speeds(4.0, 4.0)
        return None

    def tick(self, robot):
        self.left -= 1
        if self.left > 0:
            return None
        robot.world.base.set_wheel_speeds(0.0, 0.0)
        moved = robot.world.base.pose[0] - self.x0
        return ok(True, "moved", moved=moved) if moved > 0.02 else failed("slipped", False, moved=moved)

    def state_key(self, robot):
        return (self.left,)


def registry() -> Registry:
    reg = Registry()
    reg.register("look", lambda: True, outcomes=LOOK)
    reg.register("nudge", lambda: True, outcomes=NUDGE)
    return reg


def robot_registry() -> Registry:
    reg = Registry()
    reg.register("look", lambda: Sleep(0.2, "lidar_up"), outcomes=LOOK)
    reg.register("nudge", lambda: Nudge(), outcomes=NUDGE)
    return reg
