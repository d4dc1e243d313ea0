"""Functional layer of mana_nav.roar: a lidar, sonar, mapper, planner and base.

``registry()`` is the abstract binding: a small dictionary simulation for
``roar-verify run``, and the declared outcomes the explorer branches on.
``robot_registry()`` binds the same primitives to the pymunk reference robot
(``roar-verify simulate``, scenarios ``clear`` and ``lidar_dropout``): the
cloud is a lidar scan, ``fuse`` adds it to an occupancy grid, ``astar``
plans on the floor plan and the scan, ``follow`` drives the path with a
pure-pursuit controller, ``odom`` reads wheel odometry. Each outcome's
``covers`` says which robot results it stands for (``roar-verify conform``).

The outcomes with fixed values are written for the request
``locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0``:
``mk_point`` and ``odom`` answer that goal.
"""

import math

from roar_formal.robot.activity import Activity, Read, Sleep, failed, ok
from roar_formal.robot.robot import FollowPath, Handle, Plan
from roar_formal.roar.functional import Outcome, Registry

GOAL = {"x": 3.0, "y": 4.0}


def _near_goal(r, tol=0.1):
    v = r.value
    return r.ok and isinstance(v, dict) and math.hypot(float(v["x"]) - GOAL["x"], float(v["y"]) - GOAL["y"]) < tol


OUTCOMES = {
    "grab": [Outcome("cloud", True)],
    "lidar_ok": [Outcome("up", True), Outcome("down", False)],
    "sonar_ok": [Outcome("up", True), Outcome("down", False)],
    "fuse": [Outcome("fused", True, result=1,
                     covers=lambda r: r.ok and isinstance(r.value, int) and r.value >= 1)],
    "mk_point": [Outcome("point", True, result=dict(GOAL))],
    "distance": [Outcome("there", True, result=0.0, covers=lambda r: r.ok and float(r.value) < 0.1),
                 Outcome("far", True, result=5.0, covers=lambda r: r.ok and float(r.value) >= 0.1)],
    "astar": [Outcome("path", True), Outcome("no_path", False)],
    "straight": [Outcome("line", True)],
    "follow": [Outcome("following", True), Outcome("stuck", False)],
    # a reading at the goal, or anywhere else (the wait polls again)
    "odom": [Outcome("at_goal", True, result=dict(GOAL), covers=_near_goal),
             Outcome("en_route", True, result={"x": 0.0, "y": 0.0}, covers=lambda r: r.ok and not _near_goal(r))],
}


def registry() -> Registry:
    reg = Registry()
    robot = {"x": 0.0, "y": 0.0, "path": None}

    def mk_point(x, y):
        return {"x": x, "y": y}

    def distance(a, b):
        ax, ay = (a["x"], a["y"]) if isinstance(a, dict) else a
        bx, by = (b["x"], b["y"]) if isinstance(b, dict) else b
        return math.hypot(float(ax) - float(bx), float(ay) - float(by))

    def astar(version, goal):
        return ("astar", version, goal["x"], goal["y"])

    def straight(goal):
        return ("straight", goal["x"], goal["y"])

    def follow(traj):
        robot["path"] = (float(traj[-2]), float(traj[-1]))
        return True

    def odom():
        # the base moves 1 m along the path at each reading, and stops on the goal
        if robot["path"] is not None:
            gx, gy = robot["path"]
            dx, dy = gx - robot["x"], gy - robot["y"]
            d = math.hypot(dx, dy)
            if d <= 1.0:
                robot["x"], robot["y"] = gx, gy
            else:
                robot["x"] += dx / d
                robot["y"] += dy / d
        return {"x": round(robot["x"], 6), "y": round(robot["y"], 6)}

    reg.register("grab", lambda: object(), outcomes=OUTCOMES["grab"])
    reg.register("lidar_ok", lambda: True, outcomes=OUTCOMES["lidar_ok"])
    reg.register("sonar_ok", lambda: True, outcomes=OUTCOMES["sonar_ok"])
    reg.register("fuse", lambda cloud, version: version + 1, outcomes=OUTCOMES["fuse"])
    reg.register("mk_point", mk_point, outcomes=OUTCOMES["mk_point"])
    reg.register("distance", distance, outcomes=OUTCOMES["distance"])
    reg.register("astar", astar, outcomes=OUTCOMES["astar"])
    reg.register("straight", straight, outcomes=OUTCOMES["straight"])
    reg.register("follow", follow, outcomes=OUTCOMES["follow"])
    reg.register("odom", odom, outcomes=OUTCOMES["odom"])
    return reg


class Grab(Activity):
    """The next lidar scan, as a cloud (world points placed with the odometry pose)."""

    name = "grab"
    timeout = 1.0

    def start(self, robot):
        self.seen = robot.scans
        return None

    def tick(self, robot):
        if robot.scans > self.seen:
            return ok(Handle("cloud", (robot.last_scan_pose, list(robot.last_scan))), "scanned",
                      points=sum(1 for _a, rng in robot.last_scan if rng is not None))
        return None

    def on_timeout(self, robot):
        return failed("no_scan")


class Fuse(Activity):
    """Add a cloud to the robot's occupancy grid; the map's new version after ``seconds`` of work."""

    name = "fuse"

    def __init__(self, cloud, version, seconds=0.2):
        self.cloud = cloud.payload if isinstance(cloud, Handle) else None
        self.version = int(version)
        self.seconds = seconds
        self.until = 0.0

    def start(self, robot):
        if self.cloud is None:
            return failed("not_a_cloud")
        self.until = robot.time + self.seconds - 1e-9
        return None

    def tick(self, robot):
        if robot.time < self.until:
            return None
        pose, scan = self.cloud
        robot.map.update(pose, scan, robot.world.lidar.range)
        return ok(self.version + 1, "fused")


def robot_registry() -> Registry:
    reg = Registry()

    def distance(a, b):
        return math.hypot(float(a["x"]) - float(b["x"]), float(a["y"]) - float(b["y"]))

    def straight(goal):
        def read(robot):
            x, y, _ = robot.world.base.odometry
            path = [(x, y), (float(goal["x"]), float(goal["y"]))]
            robot.plans.append((round(robot.time, 3), "straight", path))
            return Handle("trajectory", path)
        return Read(read, "straight")

    def follow(traj):
        return FollowPath(traj.payload if isinstance(traj, Handle) else None, timeout=60.0)

    reg.register("grab", lambda: Grab(), outcomes=OUTCOMES["grab"])
    # a health check: did a scan arrive within two lidar periods (it waits one)
    reg.register("lidar_ok", lambda: Sleep(0.1, "lidar_up", name="lidar_ok"), outcomes=OUTCOMES["lidar_ok"])
    # the robot has no sonar: the lidar's front sector stands in for it
    reg.register("sonar_ok", lambda: Sleep(0.1, "front_clear", name="sonar_ok"), outcomes=OUTCOMES["sonar_ok"])
    reg.register("fuse", lambda cloud, version: Fuse(cloud, version), outcomes=OUTCOMES["fuse"])
    reg.register("mk_point", lambda x, y: {"x": float(x), "y": float(y)}, outcomes=OUTCOMES["mk_point"])
    reg.register("distance", distance, outcomes=OUTCOMES["distance"])
    reg.register("astar", lambda version, goal: Plan((goal["x"], goal["y"]), seconds=0.3, label="astar",
                                                     handle=True), outcomes=OUTCOMES["astar"])
    reg.register("straight", straight, outcomes=OUTCOMES["straight"])
    reg.register("follow", follow, outcomes=OUTCOMES["follow"])
    reg.register("odom", lambda: Sleep(0.05, "odometry_xy", name="odom"), outcomes=OUTCOMES["odom"])
    return reg
