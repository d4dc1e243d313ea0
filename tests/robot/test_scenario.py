"""Scenario files: the examples load, defaults and units are right, every mistake is located and explained."""

from __future__ import annotations

import math

import pytest

from roar_formal.errors import RoarError
from roar_formal.robot.scenario import FAULT_KINDS, load_scenario, parse_scenario

from repo import ROOT

SCENARIOS = ROOT / "models" / "scenarios"
HEAD = 'name = "t"\nbounds = [0, 0, 10, 5]\n'


def error_of(text: str) -> RoarError:
    with pytest.raises(RoarError) as info:
        parse_scenario(text, "t.toml")
    return info.value


@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.toml")), ids=lambda p: p.stem)
def test_example_scenarios_load(path):
    s = load_scenario(path)
    assert s.name == path.stem
    assert s.path == str(path)
    assert len(s.fingerprint) == 64
    for name, (x, y) in s.places.items():
        assert s.bounds[0] <= x <= s.bounds[2] and s.bounds[1] <= y <= s.bounds[3], name


def test_example_fault_points():
    expected = {"clear": (), "door": ("door_closes", "door_stays_closed"), "lidar_dropout": ("lidar_dropout",),
                "slip": ("slip",), "ptu_cable": ("cable",), "gripper": ("weak_grip",)}
    for name, faults in expected.items():
        assert load_scenario(SCENARIOS / f"{name}.toml").fault_names() == faults
    door = load_scenario(SCENARIOS / "door.toml")
    assert door.horizon == 90.0 and "goal" in door.places and door.door("d1").open
    closes = door.faults["door_closes"]
    assert [(c.time, c.open) for c in closes.schedule] == [(4.0, False), (14.0, True)]
    assert [(c.time, c.open) for c in door.faults["door_stays_closed"].schedule] == [(4.0, False)]
    grip = load_scenario(SCENARIOS / "gripper.toml")
    assert {"table", "shelf"} <= set(grip.places) and {o.name for o in grip.objects} == {"cup", "crate"}


def test_defaults_of_a_minimal_scenario():
    s = parse_scenario(HEAD)
    assert (s.dt, s.horizon, s.seed, s.description) == (0.01, 120.0, 0, "")
    assert s.path is None and s.faults == {} and s.ptu is None
    r = s.robot
    assert (r.radius, r.mass, r.wheel_base, r.wheel_radius) == (0.25, 20.0, 0.4, 0.05)
    assert (r.max_wheel_speed, r.max_torque, r.floor_mu, r.odometry_noise) == (20.0, 4.0, 0.8, 0.01)
    assert (r.lidar.rays, r.lidar.fov_deg, r.lidar.range, r.lidar.noise, r.lidar.period) == (90, 360.0, 8.0, 0.01, 0.1)
    assert r.gripper is None
    assert r.start == (1.0, 2.5, 0.0)


def test_units_and_kinds():
    s = parse_scenario(HEAD + """
[[obstacle]]
box = [2, 2, 1, 0.5]
angle = 90

[[obstacle]]
circle = [5, 2, 0.3]

[[object]]
name = "cup"
circle = [3, 3, 0.05]

[robot]
start = [1, 1, 180]
size = [0.5, 0.4]

[robot.gripper]

[ptu]
position = [4, 4]

[faults.drop]
kind = "lidar_dropout"
from = 1
until = 2

[faults.cable]
kind = "ptu_cable"
max_deg = 60

[faults.weak]
kind = "grip_force"
force = 2

[faults.bias]
kind = "odometry_bias"
scale = 1.05
probability = 0.1

[faults.spill]
kind = "friction"
area = [1, 1, 2, 2]
mu = 0.05
""", "units.toml")
    assert s.obstacles[0].angle == pytest.approx(math.pi / 2) and s.obstacles[1].kind == "circle"
    assert s.robot.start[2] == pytest.approx(math.pi) and s.robot.size == (0.5, 0.4)
    assert s.robot.gripper.grip_force == 30.0 and s.ptu.max_rate_deg == 90.0
    assert s.objects[0].mass == 0.5
    assert s.fault_names() == ("drop", "cable", "weak", "bias", "spill")
    assert (s.faults["drop"].start, s.faults["drop"].until) == (1.0, 2.0)
    assert s.faults["bias"].probability == 0.1 and s.faults["spill"].area == (1.0, 1.0, 2.0, 2.0)
    assert set(FAULT_KINDS) == {f.kind for f in s.faults.values()} | {"door"}


def test_fingerprint_follows_the_text():
    a, b = parse_scenario(HEAD), parse_scenario(HEAD + "# a comment\n")
    assert a.fingerprint != b.fingerprint and a.fingerprint == parse_scenario(HEAD).fingerprint
    assert hash(a) == hash(parse_scenario(HEAD))


def test_missing_file():
    with pytest.raises(RoarError, match="no such file"):
        load_scenario(SCENARIOS / "nope.toml")


MALFORMED = [
    # (text after HEAD, line, column, words the message must contain)
    ('dt = 0.1\n', 3, 6, "'dt' in the scenario file must be > 0 and <= 0.05, not 0.1"),
    ('dt = true\n', 3, 6, "must be a number, not true"),
    ('horizn = 5\n', 3, 1, "unknown key 'horizn' in the scenario file (did you mean 'horizon'?)"),
    ('[[wall]]\nfrom = [0, 0]\nto = [1, 2, 3]\n', 5, 6, "'to' in [[wall]] #1 must be a list of 2 numbers [x, y]"),
    ('[[wall]]\nfrom = [0, 0]\nto = [1, 1]\n\n[[wall]]\nfrom = [0, 0]\nto = [1, "x"]\n', 9, 10,
     'item 2 is "x"'),
    ('[[door]]\nname = "d1"\nfrom = [1, 1]\nto = [1, 2]\nschedule = [[5.0, "closed"], [3.0, "open"]]\n', 7, 31,
     "schedule times in [[door]] #1 must increase: 3 comes after 5"),
    ('[[door]]\nname = "d1"\nfrom = [1, 1]\nto = [1, 2]\nschedule = [\n  [5.0, "closed"],\n  [7.0, "shut"],\n]\n',
     9, 3, 'a list of [time, "open" or "closed"] pairs; item 2 is [7.0, "shut"]'),
    ('[[door]]\nname = "d1"\nfrom = [1, 1]\nto = [1, 2]\nschedule = [[200.0, "closed"]]\n', 7, 14,
     "schedule time 200 in [[door]] #1 is outside [0, horizon = 120]"),
    ('[[door]]\nname = "d1"\nfrom = [1, 1]\nto = [1, 2]\n\n[faults.f]\nkind = "door"\ndoor = "d2"\n'
     'schedule = []\n', 10, 8, "fault 'f' names door 'd2', which is not declared"),
    ('[robot]\nstart = [20.0, 1.0, 0.0]\n', 4, 9, "the robot's start at (20, 1) lies outside the bounds"),
    ('[robot.lidar]\nrays = 90\nfov = 400\n', 5, 7, "'fov' in [robot.lidar] must be > 0 and <= 360, not 400"),
    ('[robot]\nmass = 20\n[robot.lidar]\nrange = 8\n  noise = -1\n', 7, 11,
     "'noise' in [robot.lidar] must be >= 0, not -1"),
    ('[faults.x]\nkind = "lidar_dropout"\nfrom = 2.0\nuntil = 6.0\nmu = 0.1\n', 7, 1,
     "unknown key 'mu' in [faults.x]; expected for a 'lidar_dropout' fault one of"),
    ('[faults.x]\nkind = "frictoin"\n', 4, 8, "unknown fault kind 'frictoin' (did you mean 'friction'?)"),
    ('[faults.x]\ndescription = "no kind"\n', 3, 1, "[faults.x] needs 'kind'"),
    ('[[obstacle]]\nbox = [1, 1, 1, 1]\ncircle = [1, 1, 1]\n', 5, 1, "a box or a circle, not both"),
    ('[[obstacle]]\ncircle = [1, 1, -1]\n', 4, 17, "the radius in 'circle' of [[obstacle]] #1 must be > 0"),
    ('[[object]]\nname = "cup"\ncircle = [1, 1, 0.1]\n[[object]]\nname = "cup"\ncircle = [2, 1, 0.1]\n', 7, 8,
     "an object named 'cup' is already declared"),
    ('[places]\ngoal = [1, 2]\nbad = [20, 2]\n', 5, 7, "place 'bad' at (20, 2) lies outside the bounds"),
    ('[faults.c]\nkind = "ptu_cable"\nmax_deg = 60\n', 4, 8, "the scenario has no [ptu]"),
    ('[faults.g]\nkind = "grip_force"\nforce = 2\n', 4, 8, "the robot has no [robot.gripper]"),
    ('wall = 3\n', 3, 8, "'wall' must be written as [[wall]] sections, not 3"),
    ('seed = 1.5\n', 3, 8, "'seed' in the scenario file must be an integer, not 1.5"),
    ('robot.lidar.rays = 0\n', 3, 20, "'rays' in [robot.lidar] must be >= 1 and <= 3600, not 0"),
    ('[ptu]\nposition = [1, 1]\nmin_deg = 10\nmax_deg = -10\n', 6, 11, "'min_deg' (10) must be below 'max_deg' (-10)"),
    ('[[patch]]\narea = [0, 0, 1, 1]\n', 3, 1, "[[patch]] #1 needs 'mu'"),
    ('[[door]]\nname = "d 1"\nfrom = [1, 1]\nto = [1, 2]\n', 4, 8, "must be a name"),
    ('description = """\nmulti [x] = 3\nline"""\n[[wall]]\nfrom = [0, 0]\nto = [0, 0]\n', 8, 6,
     "[[wall]] #1: 'from' and 'to' are the same point"),
    ('[robot]\nradius = 0.3\nsize = [0.5, 0.4]\n', 5, 1,
     "takes 'radius' (a round chassis) or 'size' (a box), not both"),
    ('[faults.f]\nkind = "friction"\narea = [2, 2, 1, 1]\nmu = 0.1\n', 5, 8, "must have x0 < x1 and y0 < y1"),
    ('[faults.f]\nkind = "lidar_dropout"\nfrom = 5\nuntil = 2\n', 6, 9, "'until' (2) must be after 'from' (5)"),
    ('[faults.f]\nkind = "odometry_bias"\nscale = 1.0\nprobability = 1.5\n', 6, 15,
     "'probability' in [faults.f] must be >= 0 and <= 1, not 1.5"),
    ('[robot]\nmass = "heavy"\n', 4, 8, "'mass' in [robot] must be a number, not \"heavy\""),
    ('[robot]\nlidar = { rays = 10, range = [\n 8] }\n', 4, 30, "'range' in [robot.lidar] must be a number, not [8]"),
]


@pytest.mark.parametrize("text,line,col,words", MALFORMED, ids=[m[3][:40] for m in MALFORMED])
def test_malformed_scenarios_are_located(text, line, col, words):
    e = error_of(HEAD + text)
    assert e.pos is not None and e.pos.file == "t.toml"
    assert (e.pos.line, e.pos.col) == (line, col), e.format()
    assert words in e.message, e.message


def test_missing_required_keys():
    e = error_of('bounds = [0, 0, 1, 1]\n')
    assert e.message == "the scenario file needs 'name'" and (e.pos.line, e.pos.col) == (1, 1)
    e = error_of('name = "t"\n\n[[wall]]\nfrom = [0, 0]\n')
    assert "needs 'bounds'" in e.message


def test_toml_syntax_errors_are_located():
    e = error_of('name = "t"\nbounds = [0, 0, 10, 5\n')
    assert e.message.startswith("invalid TOML") and e.pos.line == 2
    e = error_of('name = "t"\nbounds = [0, 0, 10, 5]\ndt = = 3\n')
    assert e.message.startswith("invalid TOML") and (e.pos.line, e.pos.col) == (3, 6)
    e = error_of('name = "t"\nname = "u"\n')
    assert e.message.startswith("invalid TOML") and e.pos.line == 2


def test_positions_survive_tricky_toml():
    """Strings holding brackets and '#', comments, quoted keys and multi-line arrays do not confuse the locator."""
    text = HEAD + '''description = "a [[wall]] # not a table"
# [[door]] in a comment
[places]
"goal" = [1, 1] # [x, y]
'home' = [2, 2]

[[wall]]   # the first wall
from = [0, 0]
to = [
  1,   # x
  1,
]

[[wall]]
from = [ 0 , 0 ]
to = [ 2 , "y" ]
'''
    e = error_of(text)
    assert (e.pos.line, e.pos.col) == (18, 12) and "[[wall]] #2" in e.message
    s = parse_scenario(text.replace('"y"', "2"))
    assert s.places == {"goal": (1.0, 1.0), "home": (2.0, 2.0)}


def test_unknown_names_in_lookups():
    s = load_scenario(SCENARIOS / "door.toml")
    with pytest.raises(RoarError, match="did you mean 'goal'"):
        s.place("gaol")
    with pytest.raises(RoarError, match="no door 'd2'"):
        s.door("d2")


@pytest.mark.parametrize("old,new,msg", [
    ("to = [0.0, 0.0]", "to = [18446744073709551615, 0.0]",
     "'to' at (1.84467e+19, 0) lies outside the bounds [0, 0, 12, 6]"),
    ("bounds = [0.0, 0.0, 12.0, 6.0]", "bounds = [0.0, 0.0, 18446744073709551615, 6.0]",
     "a world is at most 200 m on a side"),
    ("box = [4.0, 1.0, 1.2, 0.8]", "box = [40.0, 1.0, 1.2, 0.8]", "lies outside the bounds"),
])
def test_a_world_too_large_or_a_wall_outside_it_is_a_located_error(tmp_path, old, new, msg):
    """Found by fuzzing: a wall 1.8e19 m long made `simulate` hang, huge bounds crashed the grid."""
    src = (ROOT / "models" / "scenarios" / "lidar_dropout.toml").read_text()
    assert old in src
    path = tmp_path / "s.toml"
    path.write_text(src.replace(old, new, 1))
    with pytest.raises(RoarError) as info:
        load_scenario(path)
    assert msg in info.value.message and info.value.pos.file == str(path) and info.value.pos.line > 1
