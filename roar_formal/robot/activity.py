"""Activities: what a primitive of the functional layer does on the robot, in simulated time.

A robot-backed primitive returns either a plain value (it takes no time:
``mk_point``, ``distance``) or an :class:`Activity`. The simulation starts
the activity on the robot, advances the physics, and ticks it after every
physics step until it ends with a :class:`CallResult`; that result is what
the agents receive. Activities are plain objects holding only data, so that a
robot snapshot (a pickle) taken while one is under way restores it too.

A :class:`CallResult` keeps the concrete outcome: the value the spec sees,
whether the call failed, a status word (``arrived``, ``blocked``,
``timeout`` ...) and details (numbers only) that the declared outcomes'
``covers`` predicates read to classify the result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

__all__ = ["CallResult", "Activity", "Read", "Sleep", "ok", "failed"]


@dataclass(frozen=True)
class CallResult:
    """The concrete result of one primitive call on the robot."""

    value: Any = None            # what the spec sees (None for a failed call of a non-bool function)
    failed: bool = False         # a primitive failure (the call fails; for bool functions: false)
    status: str = "done"         # a word for people and for classification
    detail: dict = field(default_factory=dict, hash=False)   # numbers and strings only

    @property
    def ok(self) -> bool:
        """Did the call succeed (a bool function that returned false did not)?"""
        return not self.failed and self.value is not False

    def as_json(self) -> dict:
        return {"value": jsonable(self.value), "failed": self.failed, "status": self.status,
                "detail": {k: jsonable(v) for k, v in self.detail.items()}}

    @staticmethod
    def from_json(d: dict) -> "CallResult":
        return CallResult(d.get("value"), bool(d.get("failed", False)), str(d.get("status", "done")),
                          dict(d.get("detail") or {}))


def ok(value: Any = True, status: str = "done", **detail) -> CallResult:
    return CallResult(value, False, status, detail)


def failed(status: str, value: Any = None, **detail) -> CallResult:
    return CallResult(value, True, status, detail)


def jsonable(v):
    if isinstance(v, float):
        return round(v, 6) if math.isfinite(v) else None
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if v is None or isinstance(v, (bool, int, str)):
        return v
    return repr(v)


class Activity:
    """A primitive under way on the robot.

    ``start`` is called once, at the simulated time of the call, and may
    return a result at once; ``tick`` is called after each physics step until
    it returns one. ``timeout`` (simulated seconds) ends the activity with a
    ``timeout`` failure if nothing else ended it.
    """

    name = "activity"
    timeout: Optional[float] = None

    def start(self, robot) -> Optional[CallResult]:
        return None

    def tick(self, robot) -> Optional[CallResult]:
        return None

    def on_timeout(self, robot) -> CallResult:
        return failed("timeout")

    def describe(self) -> str:
        return self.name

    # An activity may define ``state_key(robot) -> tuple``: what of it decides its future, with
    # times relative to ``robot.time`` (robot-backed exploration compares states by it). Without
    # one, the activity's plain attributes and the clock are compared: never a wrong merge.


class Read(Activity):
    """A read of the robot's state that takes no time: ``fn(robot)`` is the result.

    Ends in :meth:`start`, so it is never part of a snapshot (``fn`` may be a
    closure)."""

    name = "read"

    def __init__(self, fn: Callable[[Any], Any], name: str = "read"):
        self.fn = fn
        self.name = name

    def start(self, robot) -> CallResult:
        v = self.fn(robot)
        return v if isinstance(v, CallResult) else ok(v)


class Sleep(Activity):
    """Take ``seconds`` of simulated time, then call the robot's method ``read`` (a sensor
    with a period). The method is named, not passed, so a snapshot can hold the activity."""

    name = "sleep"

    def __init__(self, seconds: float, read: Optional[str] = None, *args, name: str = "sleep"):
        self.seconds = float(seconds)
        self.read = read
        self.args = args
        self.name = name
        self.until = 0.0

    def start(self, robot) -> Optional[CallResult]:
        self.until = robot.time + self.seconds - 1e-9
        return None

    def tick(self, robot) -> Optional[CallResult]:
        if robot.time < self.until:
            return None
        v = getattr(robot, self.read)(*self.args) if self.read else True
        return v if isinstance(v, CallResult) else ok(v)

    def state_key(self, robot) -> tuple:
        return (self.read, repr(self.args), round((self.until - robot.time) / robot.world.dt))
