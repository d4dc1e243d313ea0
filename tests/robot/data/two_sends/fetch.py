"""Functional layer of fetch.roar: abstract registry and a robot binding (gripper scenario)."""
import math

from roar_formal.roar.functional import Outcome, Registry
from roar_formal.robot.activity import Read
from roar_formal.robot.robot import Grip

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


def _bundled_go_to():
    """The bundled pick-and-place model's GoTo (drive to a place by A*, or up to an object so that
    it sits between the jaws): loaded from models/pick_place.py rather than copied."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[4] / "models" / "pick_place.py"
    spec = importlib.util.spec_from_file_location("_two_sends_pick_place", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.GoTo


GoTo = _bundled_go_to()


def robot_registry() -> Registry:
    reg = Registry()
    reg.register("go_to", lambda name: GoTo(name), outcomes=OUTCOMES["go_to"])
    reg.register("close_jaws", lambda: Grip(close=True), outcomes=OUTCOMES["close_jaws"])
    reg.register("in_reach", lambda: Read(_in_reach, "in_reach"), outcomes=OUTCOMES["in_reach"])
    reg.register("has_object", lambda: Read(lambda robot: robot.world.gripper.holding is not None, "has_object"),
                 outcomes=OUTCOMES["has_object"])
    return reg
