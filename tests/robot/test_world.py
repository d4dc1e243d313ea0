"""The physical world: drive, walls, slip, pan unit, gripper, lidar, doors, determinism and snapshots."""

from __future__ import annotations

import math
import pickle

import pytest

from roar_formal.errors import RoarError
from roar_formal.robot.scenario import load_scenario, parse_scenario
from roar_formal.robot.world import World
from repo import ROOT

SCENARIOS = ROOT / "models" / "scenarios"

ROOM = """
name = "room"
bounds = [0, 0, 12, 6]
[[wall]]
from = [0, 0]
to = [12, 0]
[[wall]]
from = [12, 0]
to = [12, 6]
[[wall]]
from = [12, 6]
to = [0, 6]
[[wall]]
from = [0, 6]
to = [0, 0]
"""


def room(extra: str = "", **kwargs) -> World:
    return World(parse_scenario(ROOM + extra, "room.toml"), **kwargs)


# the physics tests build their own scenarios, so that editing the examples cannot break them
SLIP = """
[robot]
start = [0.8, 3, 0]
[faults.slip]
kind = "friction"
area = [4, 0, 5, 6]
mu = 0.05
[[patch]]
area = [6, 0, 7, 6]
mu = 0.6
"""

DOOR = """
[[wall]]
from = [6, 0]
to = [6, 2.4]
[[wall]]
from = [6, 3.6]
to = [6, 6]
[[door]]
name = "d1"
from = [6, 2.4]
to = [6, 3.6]
[robot]
start = [1.5, 3, 0]
[faults.door_closes]
kind = "door"
door = "d1"
schedule = [[4.0, "closed"], [14.0, "open"]]
[faults.door_stays_closed]
kind = "door"
door = "d1"
schedule = [[4.0, "closed"]]
"""

GRIPPER = """
[[object]]
name = "cup"
circle = [1.6, 2.5, 0.04]
mass = 0.3
[[object]]
name = "crate"
box = [3.0, 1.2, 0.1, 0.1]
mass = 2.0
[robot]
start = [1.0, 2.5, 0]
[robot.gripper]
[faults.weak_grip]
kind = "grip_force"
force = 1.0
"""


def scenario(name: str):
    return load_scenario(SCENARIOS / f"{name}.toml")


def drive_until(world: World, done, limit_s: float = 30.0) -> None:
    for _ in range(round(limit_s / world.dt)):
        if done():
            return
        world.step()
    raise AssertionError("the condition never came true")


# ---------------------------------------------------------------- the base


def test_equal_wheel_speeds_drive_straight_at_wheel_speed_times_radius():
    w = room("[robot]\nstart = [1, 3, 0]\n")
    w.base.set_wheel_speeds(10, 10)
    w.run_for(1.0)
    v, omega = w.base.velocity
    assert v == pytest.approx(0.5, rel=0.1)
    assert abs(omega) < 1e-3
    x, y, theta = w.base.pose
    # 1 s at 0.5 m/s from x = 1, less the short acceleration at the start
    assert x == pytest.approx(1.5, abs=0.08) and x < 1.5
    assert y == pytest.approx(3.0, abs=0.01) and theta == pytest.approx(0.0, abs=0.01)
    assert w.base.wheel_speeds == pytest.approx((10, 10), rel=0.01)
    assert w.time == pytest.approx(1.0) and w.steps == 100


def test_wheel_speed_commands_are_clamped():
    w = room()
    w.base.set_wheel_speeds(100, -100)
    assert w.base.target == [20.0, -20.0]


def test_opposite_wheel_speeds_turn_on_the_spot():
    w = room("[robot]\nstart = [6, 3, 0]\n")
    w.base.set_wheel_speeds(-10, 10)
    w.run_for(1.0)
    v, omega = w.base.velocity
    assert abs(v) < 1e-3
    assert omega == pytest.approx(0.5 * 2 / 0.4, rel=0.1)  # rim speed 0.5 m/s on a 0.4 m wheel base
    x, y, _ = w.base.pose
    assert math.hypot(x - 6, y - 3) < 0.005


def test_driving_into_a_wall_stops_at_the_wall():
    w = room("[robot]\nstart = [10, 3, 0]\n")
    assert not w.base.bumped and w.base.bump_count == 0
    w.base.set_wheel_speeds(20, 20)
    w.run_for(4.0)
    x, y, _ = w.base.pose
    face = 12 - 0.05  # the wall is 0.1 thick
    assert face - 0.25 - 0.01 < x <= face - 0.25 + 0.002  # at the wall, not through it
    assert w.base.bumped and w.base.bump_count == 1
    assert abs(w.base.velocity[0]) < 1e-3
    assert w.base.stuck
    # the wheels spin on the floor, so dead reckoning runs away from the truth
    assert w.base.odometry[0] - x > 1.0
    w.base.set_wheel_speeds(-10, -10)
    w.run_for(1.0)
    assert not w.base.bumped and not w.base.stuck and w.base.bump_count == 1


def test_slippery_patch_makes_the_odometry_over_read():
    s = parse_scenario(ROOM + SLIP)
    readings = {}
    for faults in ((), ("slip",)):
        w = World(s, faults=faults)
        w.base.set_wheel_speeds(4, 4)
        drive_until(w, lambda: w.base.pose[0] >= 4.05)
        w.base.reset_odometry()
        x0 = w.base.pose[0]
        w.base.set_wheel_speeds(20, 20)
        w.run_for(0.6)
        readings[faults] = (w.base.pose[0] - x0, w.base.odometry[0] - x0)
    true_dry, odo_dry = readings[()]
    true_wet, odo_wet = readings[("slip",)]
    assert odo_dry == pytest.approx(true_dry, rel=0.05)
    assert odo_wet > 1.5 * true_wet  # the wheels spun
    assert true_wet < 0.6 * true_dry
    assert World(s, faults=["slip"]).patch_mu(4.5, 1.0) == 0.05
    assert World(s).patch_mu(4.5, 1.0) == 0.8 and World(s).patch_mu(6.5, 1.0) == 0.6


def test_odometry_follows_the_truth_on_a_good_floor_and_resets():
    w = room("[robot]\nstart = [2, 3, 0]\n")
    w.base.set_wheel_speeds(8, 10)
    w.run_for(3.0)
    (x, y, th), (ox, oy, oth) = w.base.pose, w.base.odometry
    assert math.hypot(x - ox, y - oy) < 0.05 and abs(th - oth) < 0.05
    w.base.reset_odometry((0.0, 0.0, 7.0))
    assert w.base.odometry == (0.0, 0.0, pytest.approx(7.0 - 2 * math.pi))
    w.base.reset_odometry()
    assert w.base.odometry == w.base.pose


def test_odometry_bias_fault_scales_the_left_encoder():
    s = parse_scenario(ROOM + "[robot]\nstart = [2, 3, 0]\nodometry_noise = 0.0\n"
                       "[faults.bias]\nkind = \"odometry_bias\"\nscale = 1.1\n")
    plain, biased = World(s), World(s, faults=["bias"])
    for w in (plain, biased):
        w.base.set_wheel_speeds(10, 10)
        w.run_for(2.0)
    assert plain.base.pose == biased.base.pose
    assert abs(plain.base.odometry[2]) < 1e-9
    assert biased.base.odometry[2] < -0.1  # the left wheel seems to have gone further: a right turn


# ---------------------------------------------------------------- the pan unit


PTU = """
[ptu]
position = [6, 3]
max_rate_deg = 90.0
[faults.cable]
kind = "ptu_cable"
max_deg = 60.0
"""


def test_ptu_reaches_its_target_at_its_rate_limit():
    w = room(PTU)
    assert w.ptu.angle_deg == 0 and w.ptu.at_target()
    w.ptu.command(90)
    w.run_for(0.5)
    assert w.ptu.rate_deg == pytest.approx(90, rel=0.02) and w.ptu.angle_deg == pytest.approx(45, abs=3)
    assert not w.ptu.at_target()
    w.run_for(0.7)
    assert w.ptu.at_target() and w.ptu.target_deg == 90
    w.ptu.command(500)
    assert w.ptu.target_deg == 170  # the unit's own limit


def test_ptu_cable_fault_stops_the_pan_at_60_degrees():
    w = World(parse_scenario(ROOM + PTU), faults=["cable"])
    w.ptu.command(90)
    w.run_for(2.0)
    assert w.ptu.angle_deg == pytest.approx(60, abs=1)
    assert not w.ptu.at_target() and abs(w.ptu.rate_deg) < 1
    w.ptu.command(-30)
    w.run_for(2.0)
    assert w.ptu.at_target()


def test_ptu_cable_example_stops_short_of_90_degrees():
    s = scenario("ptu_cable")
    w = World(s, faults=["cable"])
    w.ptu.command(90)
    w.run_for(2.0)
    assert w.ptu.angle_deg == pytest.approx(s.faults["cable"].max_deg, abs=1) and not w.ptu.at_target()


# ---------------------------------------------------------------- the gripper


def test_gripper_holds_a_light_object_and_carries_it():
    w = room(GRIPPER)
    g = w.gripper
    w.base.set_wheel_speeds(6, 6)
    drive_until(w, lambda: w.base.pose[0] >= 1.6 - 0.25 - 0.09)
    w.base.stop()
    w.run_for(0.3)
    g.close()
    assert g.busy and not g.closed
    w.run_for(0.2)
    assert g.holding is None
    w.run_for(0.2)
    assert g.closed and not g.busy and g.holding == "cup"
    w.base.set_wheel_speeds(10, 10)
    w.run_for(1.0)
    w.base.set_wheel_speeds(-5, 5)
    w.run_for(1.0)
    w.base.stop()
    w.run_for(0.5)
    assert g.holding == "cup" and g.drops == 0
    x, y, theta = w.base.pose
    cup = w.objects["cup"].position
    ahead = (x + 0.32 * math.cos(theta), y + 0.32 * math.sin(theta))
    assert math.hypot(cup.x - ahead[0], cup.y - ahead[1]) < 0.06
    g.open()
    assert g.holding is None and not g.closed and g.busy
    w.base.set_wheel_speeds(-5, -5)
    w.run_for(1.0)
    assert math.hypot(w.objects["cup"].position.x - cup.x, w.objects["cup"].position.y - cup.y) < 0.01


def test_gripper_closing_on_nothing_holds_nothing():
    w = room(GRIPPER)
    w.gripper.close()
    w.run_for(0.5)
    assert w.gripper.closed and w.gripper.holding is None


@pytest.mark.parametrize("faults,kept", [((), True), (("weak_grip",), False)])
def test_weak_grip_loses_a_heavy_object_when_the_base_accelerates(faults, kept):
    w = room(GRIPPER, faults=faults)
    w.place_object("crate", 1.0 + 0.25 + 0.07, 2.5)  # between the jaws
    w.gripper.close()
    w.run_for(0.4)
    assert w.gripper.holding == "crate"
    w.base.set_wheel_speeds(20, 20)
    w.run_for(0.5)
    assert (w.gripper.holding == "crate") is kept
    assert w.gripper.drops == (0 if kept else 1)


# ---------------------------------------------------------------- the lidar


def test_lidar_measures_the_walls_and_ignores_the_robot():
    w = room("[robot]\nstart = [3, 3, 90]\n[robot.lidar]\nrays = 4\nrange = 8\n")
    scan = w.lidar.scan()
    assert [a for a, _ in scan] == pytest.approx([-math.pi, -math.pi / 2, 0, math.pi / 2])
    ranges = dict((round(math.degrees(a)), r) for a, r in scan)
    # heading north: behind is south (3 m), right is east (9 m, out of range), ahead north (3 m), left west (3 m)
    assert ranges[-180] == pytest.approx(2.95, abs=0.05)
    assert ranges[-90] is None
    assert ranges[0] == pytest.approx(2.95, abs=0.05)
    assert ranges[90] == pytest.approx(2.95, abs=0.05)
    assert w.lidar.period == 0.1


def test_lidar_dropout_window():
    dropout = '[faults.blind]\nkind = "lidar_dropout"\nfrom = 0.0\nuntil = 5.0\n'
    w = room(dropout, faults=["blind"])
    assert w.lidar.scan() == [] and w.lidar.dropped_out
    w.run_for(4.99)
    assert w.lidar.scan() == []
    w.run_for(0.01)
    assert len(w.lidar.scan()) == 90
    assert len(room(dropout).lidar.scan()) == 90


def test_narrow_field_of_view_spans_its_edges():
    w = room("[robot.lidar]\nrays = 5\nfov = 90\n")
    assert [a for a, _ in w.lidar.scan()] == pytest.approx([math.radians(d) for d in (-45, -22.5, 0, 22.5, 45)])


# ---------------------------------------------------------------- doors and geometry


def test_door_fault_closes_and_reopens_the_door():
    s = parse_scenario(ROOM + DOOR)
    w = World(s, faults=["door_closes"])
    east = lambda: dict((round(math.degrees(a)), r) for a, r in w.lidar.scan())[0]  # noqa: E731
    w.base.teleport(5.0, 3.0)
    assert w.door_open("d1") and not w.occupied(6.0, 3.0)
    assert east() == pytest.approx(6.95, abs=0.05)  # through the doorway to the far wall
    w.run_for(4.0)
    assert not w.door_open("d1") and w.occupied(6.0, 3.0)
    assert east() == pytest.approx(0.95, abs=0.05)
    w.run_for(10.0)
    assert w.door_open("d1")
    plain = World(s)
    plain.run_for(20)
    assert plain.door_open("d1")
    stays = World(s, faults=["door_stays_closed"])
    stays.run_for(80)
    assert not stays.door_open("d1")
    with pytest.raises(RoarError, match="no door 'd2'"):
        w.door_open("d2")


def test_door_does_not_close_on_the_robot_and_blocks_it_when_closed():
    w = room(DOOR, faults=["door_stays_closed"])
    w.base.teleport(6.0, 3.0)
    w.run_for(5.0)
    assert w.door_open("d1")  # the robot stands in the doorway
    w.base.set_wheel_speeds(-10, -10)
    w.run_for(1.5)
    assert not w.door_open("d1")
    w.base.set_wheel_speeds(10, 10)
    w.run_for(3.0)
    assert w.base.bumped and w.base.pose[0] < 6.0 - 0.05 - 0.25 + 0.002


def test_geometry_is_plain_data():
    g = room(SLIP, faults=["slip"]).geometry()
    assert set(g) == {"bounds", "walls", "boxes", "circles", "doors", "patches", "objects", "robot", "ptu"}
    assert g["patches"] == [(6.0, 0.0, 7.0, 6.0, 0.6), (4.0, 0.0, 5.0, 6.0, 0.05)] and g["ptu"] is None
    assert g["robot"]["x"] == 0.8 and g["robot"]["radius"] == 0.25
    assert room(SLIP).geometry()["patches"] == [(6.0, 0.0, 7.0, 6.0, 0.6)]
    g = room(DOOR, faults=["door_closes"]).geometry()
    assert g["doors"] == [{"name": "d1", "from": (6.0, 2.4), "to": (6.0, 3.6), "thickness": 0.1, "open": True}]
    assert len(g["walls"]) == 6 and g["bounds"] == (0.0, 0.0, 12.0, 6.0)
    g = room(GRIPPER).geometry()
    assert {o["name"]: o["kind"] for o in g["objects"]} == {"cup": "circle", "crate": "box"}
    assert room(PTU).geometry()["ptu"]["x"] == 6.0
    pickle.dumps(g)


def test_occupied_sees_statics_not_the_robot():
    w = room("[[obstacle]]\nbox = [4, 1, 1.2, 0.8]\n[[obstacle]]\ncircle = [5.5, 4.6, 0.3]\n"
             "[robot]\nstart = [1, 3, 0]\n")
    assert w.occupied(4.0, 1.0)       # a box
    assert w.occupied(5.5, 4.6)       # a circle
    assert w.occupied(0.0, 3.0)       # a wall
    assert not w.occupied(1.0, 3.0)   # the robot
    assert not w.occupied(6.0, 3.0)


# ---------------------------------------------------------------- faults, determinism, snapshots


def test_unknown_or_clashing_faults_are_errors():
    with pytest.raises(RoarError, match=r"no fault point 'door_close'.*did you mean 'door_closes'.*door_stays_closed"):
        room(DOOR, faults=["door_close"])
    with pytest.raises(RoarError, match="both replace the schedule of door 'd1'"):
        room(DOOR, faults=["door_closes", "door_stays_closed"])
    assert room(DOOR, faults="door_closes").faults == {"door_closes"}


def drive(world: World, start: int, end: int) -> list:
    """A fixed command pattern; the observations every 25 ticks."""
    seen = []
    for tick in range(start, end):
        phase = tick // 50
        world.base.set_wheel_speeds(10 + (phase % 3) * 3, 10 - (phase % 2) * 4)
        if world.ptu:
            world.ptu.command(60 if phase % 2 else -60)
        world.step()
        if tick % 25 == 0:
            seen.append((world.base.pose, world.base.odometry, tuple(world.lidar.scan()), world.base.bump_count))
    return seen


def test_same_seed_and_faults_give_the_same_run():
    s = parse_scenario(ROOM + DOOR)
    first = drive(World(s, faults=["door_closes"]), 0, 500)
    assert drive(World(s, faults=["door_closes"]), 0, 500) == first
    other = drive(World(s, seed=5, faults=["door_closes"]), 0, 500)
    assert other[-1][1] != first[-1][1]  # odometry noise differs
    assert World(s).seed == s.seed == 0


@pytest.mark.parametrize("extra,faults", [(DOOR, ["door_closes"]), (PTU, ["cable"]), (GRIPPER, [])],
                         ids=["door", "ptu", "gripper"])
def test_snapshot_and_restore_continue_bit_for_bit(extra, faults):
    s = parse_scenario(ROOM + extra)
    straight = World(s, faults=faults)
    whole = drive(straight, 0, 500)
    w = World(s, faults=faults)
    head = drive(w, 0, 200)
    data = w.snapshot()
    restored = World.restore(data)
    assert restored.steps == 200 and restored.faults == frozenset(faults)
    assert head + drive(w, 200, 500) == whole
    assert head + drive(restored, 200, 500) == whole


def test_snapshot_while_pressing_a_wall_and_holding_an_object():
    w = room(GRIPPER)
    w.base.set_wheel_speeds(6, 6)
    drive_until(w, lambda: w.base.pose[0] >= 1.26)
    w.base.stop()
    w.gripper.close()
    w.run_for(0.4)
    assert w.gripper.holding == "cup"
    w.base.set_wheel_speeds(12, 12)
    w.run_for(18.0)  # into the east wall, cup and all
    assert w.base.bumped
    copy = World.restore(w.snapshot())
    for world in (w, copy):
        world.base.set_wheel_speeds(-12, 12)
        world.run_for(1.5)
    assert copy.base.pose == w.base.pose and copy.base.odometry == w.base.odometry
    assert copy.gripper.holding == w.gripper.holding and copy.base.bump_count == w.base.bump_count
    assert tuple(copy.objects["cup"].position) == tuple(w.objects["cup"].position)


def test_restore_rejects_what_is_not_a_world():
    with pytest.raises(RoarError, match="cannot restore"):
        World.restore(b"not a pickle")
    with pytest.raises(RoarError, match="not a world snapshot"):
        World.restore(pickle.dumps({"a": 1}))


def test_fast_rays_agree_with_pymunks_public_query(monkeypatch):
    import roar_formal.robot.world as world_module

    w = room("[[obstacle]]\nbox = [4, 3, 1, 1]\nangle = 30\n[[obstacle]]\ncircle = [2, 5, 0.4]\n"
             "[robot]\nstart = [2, 2.5, 20]\n[robot.lidar]\nrays = 180\nrange = 5\n")
    fast = w.lidar._cast(2.0, 2.5, 0.3)
    monkeypatch.setattr(world_module, "_RAW_RAYS", False)
    assert w.lidar._cast(2.0, 2.5, 0.3) == fast
    assert any(a is None for a in fast) and any(a is not None for a in fast)


def test_devices_pickle_with_their_world():
    import copy

    w = room(GRIPPER)
    w.base.set_wheel_speeds(5, 6)
    w.run_for(0.5)
    base = pickle.loads(pickle.dumps(w.base))
    assert base.pose == w.base.pose and base.world.steps == 50
    twin = copy.deepcopy(w)
    twin.run_for(0.5)
    w.run_for(0.5)
    assert twin.base.pose == w.base.pose and twin.base.odometry == w.base.odometry
