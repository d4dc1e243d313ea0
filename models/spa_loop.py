"""Functional layer of spa_loop.roar: a simulated lidar, planner and base.

``registry()`` builds a fresh simulation for each run. Each primitive also
declares its abstract outcomes, which the explorer branches on instead of
calling it.
"""

from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    state = {"scans": 0, "target": None, "pos": 0}

    def scan_stamp():
        # one scan arrives, then the lidar keeps reporting it
        state["scans"] = 1
        return state["scans"]

    def compute_plan(goal):
        return True

    def track(goal):
        state["target"] = goal
        return True

    def odometry():
        # the base moves one unit towards the tracked target at each reading
        t = state["target"]
        if t is not None and state["pos"] != t:
            state["pos"] += 1 if t > state["pos"] else -1
        return state["pos"]

    reg.register("scan_stamp", scan_stamp, outcomes=[Outcome("new_scan", True, result=1),
                                                     Outcome("no_scan", True, result=0)])
    reg.register("compute_plan", compute_plan, outcomes=[Outcome("planned", True), Outcome("no_path", False)])
    reg.register("track", track, outcomes=[Outcome("tracking", True), Outcome("lost", False)])
    reg.register("odometry", odometry, outcomes=[Outcome("at_goal", True, result=7),
                                                 Outcome("moving", True, result=3)])
    return reg
