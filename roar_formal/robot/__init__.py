"""The pymunk reference robot and specs run on it (docs/robot.md).

Data flows one way: a scenario file (``scenario``) builds a ``world`` (pymunk
physics: base, lidar, pan unit, gripper, doors, objects); ``robot`` adds the
functional layer's own state (maps, plans, the path follower) and runs the
``activity`` objects primitives start; ``planning`` has the algorithms
(occupancy grid, A*, pure pursuit). A spec's module binds its primitives to
activities (``binding``); ``sim`` runs the spec on the CLF engine in lockstep
with the robot; ``conform`` checks robot runs against the model the explorer
checks; ``onrobot`` drives a counterexample on the robot; ``report`` and
``draw`` write traces and pictures; ``commands`` is the command line.
"""
