"""The reference robot: the pymunk world plus the software a functional layer keeps running.

:class:`World` is physics only. A real robot's functional layer also keeps
state between calls: the map it built, the path it planned, the controller
that is driving the base, the latest lidar scan. :class:`Robot` holds all of
that next to the world, runs it at every physics step (the path follower
commands the wheels, the lidar delivers a scan every period) and ticks the
activities that primitive calls started. Everything is plain data, so
:meth:`snapshot` (a pickle) captures a run at any event and :meth:`restore`
continues it bit for bit.
"""

from __future__ import annotations

import math
import pickle

import numpy as np
from typing import Optional

from .activity import Activity, CallResult, failed, ok
from .planning import OccupancyGrid, PurePursuit, plan_path, wheel_speeds
from .world import World

__all__ = ["Robot", "Handle"]

#: the base is blocked when its remaining distance shrinks by less than this in BLOCKED_WINDOW s
BLOCKED_PROGRESS = 0.05
BLOCKED_WINDOW = 3.0
#: an obstacle seen closer than this on the path ahead stops the base (it waits, it does not push)
SAFETY_DISTANCE = 0.7
#: the safety stop halts for a scan point closer than the robot's radius and this to the path ahead
SAFETY_MARGIN = 0.05
#: a base waiting this long for an obstacle on its path to go away gives up (blocked)
WAIT_LIMIT = 5.0
#: the path follower's control loop runs at this period (20 Hz, as on a real base)
CONTROL_PERIOD = 0.05
#: trajectory samples for traces and pictures, every this many seconds
SAMPLE_PERIOD = 0.1


class Handle:
    """An opaque value a primitive hands to the agents (a cloud, a trajectory): they pass it on, never look inside."""

    def __init__(self, kind: str, payload):
        self.kind = kind
        self.payload = payload

    def __repr__(self) -> str:
        return f"<{self.kind}>"


class Robot:
    """World + functional-layer state; the simulation's unit of snapshot."""

    def __init__(self, scenario, seed: Optional[int] = None, faults=(), resolution: float = 0.1):
        self.world = World(scenario, seed=seed, faults=faults)
        self.scenario = scenario
        geo = self.world.geometry()
        self.resolution = resolution
        # what the robot knows beforehand: the floor plan (walls and fixed obstacles, doors open)
        plan_geo = dict(geo, doors=[dict(d, open=True) for d in geo["doors"]], objects=[])
        self.floor_plan = OccupancyGrid.from_geometry(plan_geo, resolution)
        self.map = OccupancyGrid(geo["bounds"], resolution)       # built from scans by `fuse`
        self.path: Optional[list] = None           # the current plan
        self.plans: list = []                      # (time, label, path) of every plan, for pictures
        self.follower: Optional[PurePursuit] = None
        self.follow_state = "idle"                 # idle following waiting arrived blocked
        self._progress = (0.0, math.inf)           # (time, remaining) at the last real progress
        self.activities: dict[int, Activity] = {}
        self._deadlines: dict[int, float] = {}
        self._next_handle = 0
        self.scans = 0                              # scans delivered so far (a stamp)
        self.last_scan: list = []
        self.last_scan_pose = self.world.base.odometry
        self._next_scan = 0.0
        self.last_scan_time = -math.inf
        self._points: Optional[list] = None         # the latest scan as world points (cached)
        self._ahead = None                          # the obstacle the scan shows on the path ahead, or False (cached)
        self.blocked_why: dict = {}                 # why the follower last gave up (FollowPath's result says it)
        self._waiting_for = (math.nan, math.nan)    # the obstacle the base waits for
        self.trajectory: list = []
        self.pan: list = []                         # (time, angle, target) of the pan unit, when there is one
        self._next_control = 0.0
        self._next_sample = 0.0
        self.memo: dict = {}                        # what a binding remembers between calls (snapshotted)
        self._sample()

    # ------------------------------------------------------------------ time and stepping
    @property
    def time(self) -> float:
        return self.world.time

    @property
    def horizon(self) -> float:
        return float(self.scenario.horizon)

    def start(self, activity: Activity) -> tuple[int, Optional[CallResult]]:
        """Start ``activity`` now; (handle, result if it ended at once)."""
        res = activity.start(self)
        h = self._next_handle
        self._next_handle += 1
        if res is None:
            self.activities[h] = activity
            if activity.timeout is not None:
                self._deadlines[h] = self.time + float(activity.timeout)
        return h, res

    def step(self) -> list[tuple[int, CallResult]]:
        """One physics step with everything the functional layer runs; the activities that ended."""
        control = self.time + 1e-9 >= self._next_control
        if control:
            self._next_control += CONTROL_PERIOD
            self._control()
        self.world.step()
        if self.time + 1e-9 >= self._next_scan:
            self._next_scan += self.world.lidar.period
            scan = self.world.lidar.scan()
            if scan:   # a dropout delivers nothing: the stamp does not move
                self.scans += 1
                self.last_scan = scan
                self.last_scan_pose = self.world.base.odometry
                self.last_scan_time = self.time
                self._points = None
                self._ahead = None
        if control:
            self._watch_follower()
        if self.time + 1e-9 >= self._next_sample:
            self._sample()
        done = []
        for h in sorted(self.activities):
            act = self.activities[h]
            res = act.tick(self)
            if res is None and h in self._deadlines and self.time >= self._deadlines[h]:
                res = act.on_timeout(self)
            if res is not None:
                done.append((h, res))
                del self.activities[h]
                self._deadlines.pop(h, None)
        return done

    def _sample(self) -> None:
        x, y, th = self.world.base.pose
        self.trajectory.append((round(self.time, 4), x, y, th))
        ptu = self.world.ptu
        if ptu is not None:
            self.pan.append((round(self.time, 4), ptu.angle_deg, ptu.target_deg))
        self._next_sample = self.time + SAMPLE_PERIOD

    # ------------------------------------------------------------------ snapshots
    def snapshot(self) -> bytes:
        return pickle.dumps(self, protocol=pickle.HIGHEST_PROTOCOL)

    @staticmethod
    def restore(data: bytes) -> "Robot":
        return pickle.loads(data)

    # ------------------------------------------------------------------ the base's controller
    def follow(self, path: list, speed: float = 0.5) -> bool:
        """Start driving along ``path`` (background: the base keeps going between calls)."""
        if not path or len(path) < 2:
            self.stop()
            return False
        self.path = [tuple(p) for p in path]
        self._ahead = None
        self.follower = PurePursuit(self.path, lookahead=0.4, speed=speed, goal_tolerance=0.08)
        self.follow_state = "following"
        self._progress = (self.time, self.follower.remaining(self.world.base.odometry))
        self._next_control = self.time   # the controller takes the new path at the next step
        return True

    def stop(self) -> None:
        self.follower = None
        if self.follow_state in ("following", "waiting"):
            self.follow_state = "idle"
        self.world.base.set_wheel_speeds(0.0, 0.0)

    def _control(self) -> None:
        f = self.follower
        if f is None or self.follow_state not in ("following", "waiting"):
            return
        pose = self.world.base.odometry
        if f.done(pose):
            self.follow_state = "arrived"
            self.follower = None
            self.world.base.set_wheel_speeds(0.0, 0.0)
            return
        if self._ahead is None:   # judged once per scan: the safety stop reacts to scans
            self._ahead = self._obstacle_ahead(pose)
        if self._ahead:
            if self.follow_state != "waiting":
                self._progress = (self.time, f.remaining(pose))
            self._waiting_for = self._ahead
            self.follow_state = "waiting"
            self.world.base.set_wheel_speeds(0.0, 0.0)
            return
        if self.follow_state == "waiting":   # the way is clear again: progress counts from now
            self._progress = (self.time, f.remaining(pose))
        self.follow_state = "following"
        v, w = f.command(pose)
        cfg = self.scenario.robot
        left, right = wheel_speeds(v, w, cfg.wheel_base, cfg.wheel_radius, cfg.max_wheel_speed)
        self.world.base.set_wheel_speeds(left, right)

    def _watch_follower(self) -> None:
        """A base that makes no progress for BLOCKED_WINDOW seconds is blocked (the follower gives up)."""
        if self.follower is None or self.follow_state not in ("following", "waiting"):
            return
        rem = self.follower.remaining(self.world.base.odometry)
        t0, best = self._progress
        if self.follow_state == "waiting":   # stopped on purpose: blocked only when it lasts
            if self.time - t0 > WAIT_LIMIT:
                ox, oy = self._waiting_for
                self.blocked_why = {"why": "obstacle ahead", "ox": ox, "oy": oy, "waited": self.time - t0}
                self.follow_state = "blocked"
                self.follower = None
                self.world.base.set_wheel_speeds(0.0, 0.0)
        elif rem < best - BLOCKED_PROGRESS:
            self._progress = (self.time, rem)
        elif self.time - t0 > BLOCKED_WINDOW:
            self.blocked_why = {"why": "no progress", "waited": self.time - t0}
            self.follow_state = "blocked"
            self.follower = None
            self.world.base.set_wheel_speeds(0.0, 0.0)

    def _obstacle_ahead(self, pose):
        """The point of the latest scan closest to the robot on the path within SAFETY_DISTANCE
        ahead (closer to a point of the path than the robot's radius and a 5 cm margin), or False."""
        pts = self.scan_points()
        if not pts or self.path is None:
            return False
        x, y, th = pose
        radius = self.scenario.robot.radius
        ahead = [p for p in self._path_ahead(pose, SAFETY_DISTANCE)]
        best = None
        for px, py in pts:
            d = math.hypot(px - x, py - y)
            if d > SAFETY_DISTANCE + radius or (best is not None and d >= best[0]):
                continue
            for ax, ay in ahead:
                if math.hypot(px - ax, py - ay) < radius + SAFETY_MARGIN:
                    best = (d, px, py)
                    break
        return False if best is None else (best[1], best[2])

    def _path_ahead(self, pose, dist: float, step: float = 0.1) -> list:
        """Points every ``step`` along the current path from the pose's nearest point, ``dist`` long."""
        path = self.path or []
        if len(path) < 2:
            return []
        x, y, _ = pose
        best, k0 = math.inf, 0
        for k in range(len(path) - 1):
            d = _seg_dist((x, y), path[k], path[k + 1])
            if d < best:
                best, k0 = d, k
        out, left = [], dist
        cur = (x, y)
        for k in range(k0, len(path) - 1):
            nx, ny = path[k + 1]
            seg = math.hypot(nx - cur[0], ny - cur[1])
            n = int(min(seg, left) / step)
            for i in range(1, n + 1):
                t = i * step / seg if seg else 1.0
                out.append((cur[0] + (nx - cur[0]) * t, cur[1] + (ny - cur[1]) * t))
            left -= seg
            cur = (nx, ny)
            if left <= 0:
                break
        return out

    # ------------------------------------------------------------------ reads for bindings
    def scan_points(self) -> list:
        """The latest scan as world points, placed with the odometry pose it was taken at."""
        if self._points is None:
            x, y, th = self.last_scan_pose
            self._points = [(x + rng * math.cos(th + ang), y + rng * math.sin(th + ang))
                            for ang, rng in self.last_scan if rng is not None]
        return self._points

    def odometry_xy(self) -> dict:
        x, y, _ = self.world.base.odometry
        return {"x": round(x, 4), "y": round(y, 4)}   # a tenth of a millimetre: what an encoder resolves

    def odometry_metres(self) -> int:
        """x by odometry to the nearest metre (a 1-D robot's position)."""
        return int(round(self.world.base.odometry[0]))

    def front_clear(self, distance: float = 1.0, half_angle_deg: float = 20.0) -> bool:
        """Nothing in the latest scan within ``distance`` ahead (a sonar's view)."""
        half = math.radians(half_angle_deg)
        return all(rng is None or rng > distance for ang, rng in self.last_scan if abs(ang) <= half)

    def lidar_up(self) -> bool:
        """The lidar delivered a scan within the last two periods."""
        return self.time - self.last_scan_time <= 2 * self.world.lidar.period + 1e-9

    def seen_grid(self) -> OccupancyGrid:
        """What the latest scan shows (a closed door, a box), as a grid of its own."""
        g = OccupancyGrid(self.floor_plan.bounds, self.resolution)
        g.update(self.last_scan_pose, self.last_scan, self.world.lidar.range)
        return g

    def picture_grid(self) -> OccupancyGrid:
        """The floor plan with the latest scan laid over it (occupied where either is), for pictures."""
        g = self.seen_grid()
        g.log_odds = np.maximum(g.log_odds, self.floor_plan.log_odds)
        return g

    def known_grid(self):
        """The cells the planner treats as occupied: the floor plan's, and what the latest scan shows."""
        return self.floor_plan.occupied() | self.seen_grid().occupied()

    def plan_to(self, goal, label: str = "plan") -> Optional[list]:
        x, y, _ = self.world.base.odometry
        # room beyond the safety stop's margin where there is some (a cell more: the grid's rounding)
        path = plan_path(self.known_grid(), (x, y), tuple(goal), self.scenario.robot.radius,
                         resolution=self.resolution, origin=self.floor_plan.origin,
                         clearance=SAFETY_MARGIN + self.resolution)
        if path is not None:
            self.plans.append((round(self.time, 3), label, path))
        return path

    def path_blocked(self) -> bool:
        """The latest scan shows an obstacle on the current path (anywhere ahead, within lidar range)."""
        if self.path is None:
            return False
        pose = self.world.base.odometry
        pts = self.scan_points()
        if not pts:
            return False
        radius = self.scenario.robot.radius
        ahead = self._path_ahead(pose, self.world.lidar.range)
        if not ahead:
            return False
        p = np.asarray(pts)
        a = np.asarray(ahead)
        d2 = ((p[:, None, :] - a[None, :, :]) ** 2).sum(axis=2)
        return bool((d2 < radius * radius).any())


def _seg_dist(p, a, b) -> float:
    ax, ay = a
    bx, by = b
    dx, dy = bx - ax, by - ay
    n = dx * dx + dy * dy
    t = 0.0 if n == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / n))
    return math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy)


# ---------------------------------------------------------------------- standard activities


class FollowPath(Activity):
    """Drive along a path until arrival (ok), blocked (failure) or timeout (failure)."""

    name = "follow"

    def __init__(self, path: Optional[list] = None, timeout: float = 60.0, speed: float = 0.5):
        self.path = path
        self.timeout = timeout
        self.speed = speed
        self.t0 = 0.0

    def start(self, robot) -> Optional[CallResult]:
        self.t0 = robot.time
        path = self.path if self.path is not None else robot.path
        if not robot.follow(path or [], self.speed):
            return failed("no_path")
        return None

    def tick(self, robot) -> Optional[CallResult]:
        st = robot.follow_state
        x, y, _ = robot.world.base.odometry
        if st == "arrived":
            return ok(True, "arrived", x=x, y=y, seconds=robot.time - self.t0)
        if st == "blocked":
            return failed("blocked", False, x=x, y=y, seconds=robot.time - self.t0, **robot.blocked_why)
        return None

    def on_timeout(self, robot) -> CallResult:
        robot.stop()
        x, y, _ = robot.world.base.odometry
        return failed("timeout", False, x=x, y=y, seconds=robot.time - self.t0)

    def state_key(self, robot) -> tuple:
        """What decides how it ends (the follower's state is the robot's; the start time only
        goes into the result's details)."""
        return (self.speed,)


class Plan(Activity):
    """Plan a path to ``goal`` on what the robot knows; the answer comes after ``seconds`` of computation."""

    name = "plan"

    def __init__(self, goal, seconds: float = 0.3, label: str = "plan", handle: bool = False):
        self.goal = (float(goal[0]), float(goal[1]))
        self.handle = handle          # return the path as an opaque trajectory (else true)
        self.seconds = seconds
        self.label = label
        self.result: Optional[CallResult] = None
        self.until = 0.0

    def start(self, robot) -> Optional[CallResult]:
        path = robot.plan_to(self.goal, self.label)
        if path is None:
            self.result = failed("no_path", False, gx=self.goal[0], gy=self.goal[1])
        else:
            robot.path = path
            if robot.follow_state in ("following", "waiting", "blocked"):   # the base follows the new plan
                robot.follow(path, robot.follower.speed if robot.follower is not None else 0.5)
            length = sum(math.dist(path[k], path[k + 1]) for k in range(len(path) - 1))
            self.result = ok(Handle("trajectory", path) if self.handle else True, "planned", length=length,
                             waypoints=len(path))
        self.until = robot.time + self.seconds - 1e-9
        return None

    def tick(self, robot) -> Optional[CallResult]:
        return self.result if robot.time >= self.until else None

    def state_key(self, robot) -> tuple:
        res = self.result
        return (self.goal, self.handle, None if res is None else (res.failed, res.status, repr(res.value)),
                round((self.until - robot.time) / robot.world.dt))


class Turn(Activity):
    """Turn the pan-tilt unit to ``angle`` degrees: reached (ok), blocked (stalled short of it) or timeout."""

    name = "turn"

    def __init__(self, angle_deg: float, timeout: float = 10.0, tolerance: float = 1.0, stall: float = 0.5):
        self.angle = float(angle_deg)
        self.timeout = timeout
        self.tolerance = tolerance
        self.stall = stall
        self.still_since: Optional[float] = None

    def start(self, robot) -> Optional[CallResult]:
        ptu = robot.world.ptu
        if ptu is None:
            return failed("no_ptu", False)
        lo, hi = robot.scenario.ptu.min_deg, robot.scenario.ptu.max_deg
        if not lo <= self.angle <= hi:
            return failed("out_of_range", False, angle=ptu.angle_deg, target=self.angle)
        ptu.command(self.angle)
        return None

    def tick(self, robot) -> Optional[CallResult]:
        ptu = robot.world.ptu
        if ptu.at_target(self.tolerance):
            return ok(True, "reached", angle=ptu.angle_deg, target=self.angle)
        if abs(ptu.rate_deg) < 1.0:
            if self.still_since is None:
                self.still_since = robot.time
            elif robot.time - self.still_since >= self.stall:
                return failed("blocked", False, angle=ptu.angle_deg, target=self.angle)
        else:
            self.still_since = None
        return None

    def on_timeout(self, robot) -> CallResult:
        return failed("timeout", False, angle=robot.world.ptu.angle_deg, target=self.angle)

    def state_key(self, robot) -> tuple:
        still = None if self.still_since is None else round((robot.time - self.still_since) / robot.world.dt)
        return (self.angle, self.tolerance, self.stall, still)


class Grip(Activity):
    """Close (or open) the gripper; closing succeeds only with an object between the jaws."""

    name = "grip"

    def __init__(self, close: bool = True, timeout: float = 2.0):
        self.close = close
        self.timeout = timeout

    def start(self, robot) -> Optional[CallResult]:
        g = robot.world.gripper
        if g is None:
            return failed("no_gripper", False)
        g.close() if self.close else g.open()
        return None

    def tick(self, robot) -> Optional[CallResult]:
        g = robot.world.gripper
        if g.busy:
            return None
        if not self.close:
            return ok(True, "opened")
        if g.holding is None:
            return failed("empty", False)
        return ok(True, "holding", object=g.holding)

    def state_key(self, robot) -> tuple:
        return (self.close,)
