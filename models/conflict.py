"""Functional layer of conflict.roar: the pan-tilt unit's motors.

``registry()`` is the abstract binding (the motors always reach the
heading; the explorer branches on both declared outcomes). ``robot_registry()``
drives the reference robot's pan unit (scenario ``models/scenarios/ptu_cable.toml``):
``turn_to`` commands the rate-limited motor and answers when the pan reaches
the heading (``turned``), stalls short of it, as when the cable snags
(``blocked``), or runs out of time (``blocked`` too: the agents cannot tell
the difference).
"""

from roar_formal.robot.robot import Turn
from roar_formal.roar.functional import Outcome, Registry

TURNED = Outcome("turned", True)
BLOCKED = Outcome("blocked", False)


def registry() -> Registry:
    reg = Registry()
    reg.register("turn_to", lambda heading: True, outcomes=[TURNED, BLOCKED])
    return reg


def robot_registry() -> Registry:
    reg = Registry()
    reg.register("turn_to", lambda heading: Turn(float(heading), timeout=10.0), outcomes=[TURNED, BLOCKED])
    return reg
