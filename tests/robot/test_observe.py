"""Conditions on the robot's state (roar_formal.robot.observe): syntax, types, observables, errors, an oracle."""

from __future__ import annotations

import functools
import re
import math
import pickle

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from roar_formal.errors import RoarError
from roar_formal.robot.observe import OBSERVABLES, RobotCondition, check_condition, parse_condition
from roar_formal.robot.robot import Robot
from roar_formal.robot.scenario import load_scenario
from repo import ROOT

SCENARIOS = ROOT / "models" / "scenarios"


@functools.cache
def scenario(name: str):
    return load_scenario(SCENARIOS / f"{name}.toml")


def robot(name: str, **kw) -> Robot:
    return Robot(scenario(name), **kw)


def steps(r: Robot, n: int) -> None:
    for _ in range(n):
        r.step()


def holds(text: str, r: Robot) -> bool:
    return parse_condition(text).holds(r)


def error(text: str, *where, scen=None) -> RoarError:
    """The RoarError parsing (and, with ``scen``, checking) ``text`` raises."""
    with pytest.raises(RoarError) as info:
        cond = parse_condition(text, *where)
        if scen is not None:
            check_condition(cond, scenario(scen))
    return info.value


@functools.cache
def _clear_robot() -> Robot:
    return robot("clear")


# ---------------------------------------------------------------- parsing and precedence


@pytest.mark.parametrize("text, value", [
    ("true", True),
    ("false", False),
    ("true || false && false", True),          # && binds tighter than ||
    ("(true || false) && false", False),
    ("!false && false", False),                # ! binds tighter than &&
    ("!(false && false)", True),
    ("true || false => false", False),         # => is loosest
    ("true || (false => false)", True),
    ("false => false => false", True),         # => groups to the right
    ("(false => false) => false", False),
    ("true => false", False),
    ("2 + 3 * 4 == 14", True),
    ("(2 + 3) * 4 == 20", True),
    ("10 - 4 - 3 == 3", True),                 # - and / group to the left
    ("12 / 3 / 2 == 2", True),
    ("-2 * 3 == -6", True),
    ("- -2 == 2", True),
    ("1 - -1 == 2", True),
    ("1 + 1 == 2 && 2 * 2 == 4", True),        # comparisons bind tighter than &&
    ("!true == false", True),                  # (!true) == false
    ("(1 < 2) == true", True),
    ("1 <= 1 && 1 >= 1 && !(1 < 1) && !(1 > 1) && 1 != 2", True),
    ('"a" == "a" && "a" != "b"', True),
    ("0.5 + .5 == 1 && 1e2 == 100 && 2.5E-1 == 0.25", True),
    ("1 / 4 == 0.25", True),
    ("  true\n\t&& \n true ", True),
])
def test_constant_conditions(text, value):
    cond = parse_condition(text)
    assert isinstance(cond, RobotCondition)
    assert cond.text == text
    assert cond.holds(_clear_robot()) is value


def test_short_circuit():
    """The right side of &&, || and => is read only when needed (no division by zero here)."""
    r = _clear_robot()
    assert holds("false && 1 / (t - t) > 0", r) is False
    assert holds("true || 1 / (t - t) > 0", r) is True
    assert holds("false => 1 / (t - t) > 0", r) is True
    with pytest.raises(RoarError, match="division by zero"):
        holds("true && 1 / (t - t) > 0", r)


def test_observables_listed_and_documented():
    assert set(OBSERVABLES) == {"t", "x", "y", "heading", "speed", "contact", "bumps", "following", "lidar_up",
                                "gripper", "holding", "held", "pan", "pan_target", "door_open", "dist", "near",
                                "inside", "object_x", "object_y", "object_near"}
    assert all(isinstance(v, str) and v and "\n" not in v for v in OBSERVABLES.values())
    assert OBSERVABLES["near"].startswith('near("place", r):')
    cond = parse_condition('near("goal", 1) || x > 2 && near("start", 1) || contact')
    assert cond.observables == ("near", "x", "contact")


def test_pickles_and_compares():
    cond = parse_condition("x < 3 && !contact", "p.toml", 4, 7)
    again = pickle.loads(pickle.dumps(cond))
    assert again == cond and hash(again) == hash(cond)
    assert again.holds(_clear_robot()) is True
    assert str(cond.pos) == "p.toml:4:7"


# ---------------------------------------------------------------- the observables on real robots


def test_time_pose_and_places():
    r = robot("clear")
    assert holds("t == 0 && x == 1 && y == 3 && heading == 0 && speed == 0", r)
    assert holds('dist("goal") == 9.5 && near("start", 0.001) && !near("goal", 9)', r)
    assert holds("inside(0, 0, 2, 6) && inside(2, 6, 0, 0) && !inside(2, 0, 3, 6)", r)
    steps(r, 25)
    assert holds("t > 0.2499 && t < 0.2501", r)
    r.world.base.teleport(5.0, 2.0, 3 * math.pi / 4)
    assert holds("x == 5 && y == 2 && heading > 134.99 && heading < 135.01", r)
    r.world.base.teleport(5.0, 2.0, -math.pi / 2 - 2 * math.pi)   # wrapped into -180..180
    assert holds("heading > -90.01 && heading < -89.99", r)
    r.world.base.teleport(5.0, 2.0, math.pi)
    assert holds("heading == 180", r)


def test_speed_contact_and_bumps_against_a_wall():
    r = robot("clear")                   # starts at (1, 3) facing +x; the wall x = 0 is behind it
    assert holds("!contact && bumps == 0 && speed == 0", r)
    r.world.base.set_wheel_speeds(-10.0, -10.0)
    steps(r, 30)
    assert holds("speed > 0.1 && x < 1 && !contact", r)
    cond = parse_condition("!contact", "props.toml", 3, 12)
    for _ in range(300):
        r.step()
        if not cond.holds(r):
            break
    assert not cond.holds(r)
    assert holds("contact && bumps >= 1 && x < 0.35", r)
    assert cond.explain(r) == "contact = true"
    r.world.base.set_wheel_speeds(10.0, 10.0)
    steps(r, 100)
    assert holds("!contact && bumps >= 1 && x > 0.5", r)


def test_following():
    r = robot("clear")
    assert holds('following == "idle"', r)
    r.follow([(1.0, 3.0), (1.6, 3.0)])
    steps(r, 10)
    assert holds('following == "following" && following != "arrived"', r)
    for _ in range(800):
        r.step()
        if r.follow_state == "arrived":
            break
    assert holds('following == "arrived" && near("start", 0.7) && x > 1.4', r)


def test_lidar_up():
    r = robot("clear")
    assert holds("!lidar_up", r)                 # no scan yet at t = 0
    steps(r, 15)
    assert holds("lidar_up", r)
    r = robot("lidar_dropout", faults=["lidar_dropout"])
    steps(r, 50)
    assert holds("!lidar_up && t > 0.49", r)


def pick_up_the_cup(r: Robot, check=lambda: True) -> None:
    """Drive the jaws around the cup (the base's front at 1.25 m, 0.15 m of jaws) and close them."""
    r.world.base.set_wheel_speeds(4.0, 4.0)
    for _ in range(300):
        r.step()
        if r.world.base.pose[0] > 1.25:
            break
    r.world.base.stop()
    steps(r, 30)
    r.world.gripper.close()
    steps(r, 5)
    assert check()
    steps(r, 40)
    assert r.world.gripper.holding == "cup"


def test_gripper_holding_held_and_objects():
    r = robot("gripper")                          # the cup is 0.6 m ahead of the base
    assert holds('gripper == "open" && !holding && held == ""', r)
    assert holds('object_x("cup") == 1.6 && object_y("cup") == 2.5 && object_x("crate") == 3', r)
    assert holds('object_near("cup", "start", 0.61) && !object_near("cup", "table", 1)', r)
    pick_up_the_cup(r, check=lambda: holds('gripper == "open" && !holding', r))   # closing, not yet shut
    cond = parse_condition('gripper == "closed" && holding && held == "cup" && held != "crate"')
    assert cond.holds(r)
    assert cond.explain(r) == 'gripper = "closed", holding = true, held = "cup"'
    # carried: the cup moves with the base
    r.world.base.set_wheel_speeds(4.0, 4.0)
    steps(r, 100)
    assert holds('holding && object_x("cup") > 1.7 && object_near("cup", "start", 1.2)', r)
    r.world.gripper.open()
    steps(r, 1)
    assert holds('gripper == "open" && !holding && held == ""', r)


def test_pan_unit():
    r = robot("ptu_cable")
    assert holds("pan == 0 && pan_target == 0", r)
    r.world.ptu.command(30.0)
    steps(r, 10)
    assert holds("pan_target == 30 && pan > 0 && pan < 30", r)
    steps(r, 100)
    assert holds("pan_target - pan < 1 && pan - pan_target < 1", r)
    r = robot("ptu_cable", faults=["cable"])
    r.world.ptu.command(30.0)
    steps(r, 150)
    assert holds("pan_target == 30 && pan < 21", r)


def test_door_open():
    r = robot("door", faults=["door_closes"])
    cond = parse_condition('door_open("d1")')
    assert cond.holds(r)
    r.world.run_for(4.05)
    assert not cond.holds(r)
    assert cond.explain(r) == 'door_open("d1") = false'
    r.world.run_for(10.0)
    assert cond.holds(r)


def test_explain_lists_each_read_once_in_order():
    r = robot("door")
    cond = parse_condition('near("goal", 1) || x > 2 && x < 3 || dist("goal") < t')
    assert cond.explain(r) == 'dist("goal") = 8.5, x = 1.5, t = 0'
    cond = parse_condition("inside(0, 0, 1, 1) || bumps > 0")
    assert cond.explain(r) == "x = 1.5, y = 3, bumps = 0"


# ---------------------------------------------------------------- errors


def test_syntax_errors_are_located_inside_the_string():
    e = error("x < 1 && ?", "props.toml", 7, 12)
    assert str(e.pos) == "props.toml:7:21" and "illegal character '?'" in e.message
    e = error("x < 1 &&\n   y >", "props.toml", 7, 12)
    assert str(e.pos) == "props.toml:8:7" and "unexpected end of the condition; expected an expression" in e.message
    e = error("x < y < 3")
    assert str(e.pos) == "<condition>:1:7" and "comparisons do not chain" in e.message
    assert "'=='" in error("x = 3").message
    assert "'=>'" in error("contact -> x > 1").message
    assert "'&&'" in error("contact and x > 1").message
    assert "'&&'" in error("contact & holding").message
    assert "'||'" in error("contact | holding").message
    assert "'!'" in error("not contact").message
    assert "not closed" in error("(x < 3").message
    assert "no open '('" in error("x < 3)").message
    assert "unterminated string" in error('held == "cup').message
    assert "double quotes" in error("held == 'cup'").message
    assert "empty condition" in error("   ").message
    assert "too large" in error("x < 1e999").message
    assert "division by zero" in error("x / 0 > 1").message
    assert "nested more than" in error("!" * 300 + "true").message
    assert parse_condition("(" * 300 + "true" + ")" * 300).holds(_clear_robot())   # parentheses alone nest nothing


def test_unknown_names_suggest():
    e = error("!contcat", "p.toml", 2, 5)
    assert str(e.pos) == "p.toml:2:6"
    assert "unknown name 'contcat' (did you mean 'contact'?)" in e.message
    assert "did you mean 'heading'" in error("headng > 3").message
    assert "unknown function 'dst' (did you mean 'dist'?)" in error('dst("goal") < 1').message
    assert "write 'true'" in error("True").message
    assert "is a function" in error("dist < 1").message
    assert "is not a function" in error("x() < 1").message
    assert 'never "walking"' in error('following == "walking"').message
    assert "did you mean 'closed'" in error('"close" == gripper').message


def test_type_errors():
    e = error("x + 1", "p.toml", 1, 30)
    assert str(e.pos) == "p.toml:1:30" and "must be true or false" in e.message
    e = error("x + contact > 1", "p.toml", 1, 30)
    assert str(e.pos) == "p.toml:1:32" and "'+' works on numbers, and 'contact' is a truth value" in e.message
    assert "'&&' combines conditions" in error("x && contact").message
    assert "compares values of one type" in error("x == true").message
    assert "compares numbers" in error('held < "b"').message
    assert "'!' negates a condition" in error("!x").message
    assert "'-' negates a number" in error("-contact").message
    assert "takes 2 arguments" in error('near("goal") ').message
    assert "is a number (the radius in m)" in error('near("goal", true)').message
    e = error('dist(goal) < 1', "p.toml", 1, 1)
    assert str(e.pos) == "p.toml:1:6" and 'in quotes' in e.message and 'write "goal" in quotes' in e.message
    assert "in quotes" in error('object_near("cup", 3, 1)').message


def test_checked_against_a_scenario():
    e = error('near("gaol", 1)', "p.toml", 3, 10, scen="door")
    assert str(e.pos) == "p.toml:3:15"
    assert "scenario 'door' has no place 'gaol' (did you mean 'goal'?)" in e.message
    assert "no door 'd11' (did you mean 'd1'?)" in error('door_open("d11")', scen="door").message
    assert "no door 'd2'; doors: d1" in error('door_open("d2")', scen="door").message
    assert "no object 'cpu' (did you mean 'cup'?)" in error('object_x("cpu") > 1', scen="gripper").message
    assert "no place 'tabel'" in error('object_near("cup", "tabel", 1)', scen="gripper").message
    assert "has none" in error("!holding", scen="clear").message
    assert "has none" in error('gripper == "open"', scen="door").message
    assert "pan unit" in error("pan < 30", scen="clear").message
    assert "no object 'mug'" in error('held == "mug"', scen="gripper").message
    for text, name in [('near("goal", 1) && door_open("d1")', "door"), ('held == "cup" || held == ""', "gripper"),
                       ("pan < pan_target", "ptu_cable"), ("!contact && speed < 1", "clear")]:
        check_condition(parse_condition(text), scenario(name))
    # the location may be given again when checking
    cond = parse_condition('dist("nowhere") < 1')
    with pytest.raises(RoarError) as info:
        check_condition(cond, scenario("door"), "q.toml", 9, 3)
    assert str(info.value.pos) == "q.toml:9:8"


def test_errors_while_evaluating_are_located():
    r = robot("clear")
    with pytest.raises(RoarError, match="has no gripper") as info:
        parse_condition("  holding", "p.toml", 2, 4).holds(r)
    assert str(info.value.pos) == "p.toml:2:6"
    with pytest.raises(RoarError, match="no pan unit"):
        holds("pan > 1", r)
    with pytest.raises(RoarError, match="no place 'table'"):
        holds('near("table", 1)', r)
    with pytest.raises(RoarError, match="no door 'd1'"):
        holds('door_open("d1")', r)
    with pytest.raises(RoarError, match="no object 'cup'"):
        holds('object_y("cup") > 1', r)
    assert "<" in parse_condition('dist("table") < 1 || x > 0').explain(r)   # explain does not raise


_PIECES = ["x", "t", "contact", "dist", "(", ")", '"goal"', '"', ",", "&&", "||", "=>", "!", "==", "<", "-",
           "*", "/", "1", "0.5", "e", ".", " ", "\n", "true", "=", "&", "?", "near", "'", "\\", "é"]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(_PIECES), max_size=12))
def test_any_text_is_a_condition_or_a_roar_error(pieces):
    text = "".join(pieces)
    try:
        cond = parse_condition(text, "f.toml", 3, 4)
    except RoarError as e:
        assert e.pos is not None and e.pos.file == "f.toml" and e.pos.line >= 3
        return
    try:
        assert isinstance(cond.holds(_clear_robot()), bool)
    except RoarError as e:
        assert e.pos is not None


# ---------------------------------------------------------------- an oracle: random well-typed conditions

# trees: ("num", v) ("str", s) ("bool", b) ("obs", name) ("call", name, args) ("not", e) ("neg", e)
# ("bin", op, left, right); written out with as few parentheses as the precedence allows


class Names:
    """What the generator may name for one robot."""

    def __init__(self, name, places, objects, doors, gripper, ptu):
        self.name, self.places, self.objects, self.doors = name, places, objects, doors
        self.gripper, self.ptu = gripper, ptu


WORLDS = {
    "gripper": Names("gripper", ["start", "table", "shelf"], ["cup", "crate"], [], True, False),
    "door": Names("door", ["start", "door_west", "goal"], [], ["d1"], False, False),
    "ptu_cable": Names("ptu_cable", ["start"], [], [], False, True),
}


@functools.cache
def oracle_robot(name: str) -> Robot:
    if name == "gripper":                          # holding the cup and turning
        r = robot("gripper")
        pick_up_the_cup(r)
        r.world.base.set_wheel_speeds(2.0, 4.0)
        steps(r, 60)
    elif name == "door":                           # following a plan, the door closed
        r = robot("door", faults=["door_closes"])
        r.follow([(1.5, 3.0), (3.0, 3.0), (3.0, 4.0)])
        steps(r, 420)
    else:                                          # the pan on its way to 45 degrees
        r = robot("ptu_cable")
        r.world.ptu.command(45.0)
        r.world.base.set_wheel_speeds(3.0, -3.0)
        steps(r, 30)
    return r


def numbers(w: Names):
    lit = st.builds(lambda v: ("num", v), st.sampled_from([0, 1, 2, 3, 10, 0.5, 2.5, 0.25, 45]))
    obs = ["t", "x", "y", "heading", "speed", "bumps"] + (["pan", "pan_target"] if w.ptu else [])
    calls = [st.builds(lambda p: ("call", "dist", [("str", p)]), st.sampled_from(w.places))]
    if w.objects:
        calls.append(st.builds(lambda f, o: ("call", f, [("str", o)]), st.sampled_from(["object_x", "object_y"]),
                               st.sampled_from(w.objects)))
    return st.one_of(lit, st.sampled_from(obs).map(lambda n: ("obs", n)), *calls)


def strings(w: Names):
    """(observable, literal of its domain) pairs and other well-typed string comparisons."""
    domains = {"following": ["idle", "following", "waiting", "arrived", "blocked"]}
    if w.gripper:
        domains["gripper"] = ["open", "closed"]
        domains["held"] = [""] + w.objects
    obs = st.sampled_from(sorted(domains))
    with_literal = obs.flatmap(lambda n: st.sampled_from(domains[n]).map(lambda s: (("obs", n), ("str", s))))
    two_obs = st.tuples(obs.map(lambda n: ("obs", n)), obs.map(lambda n: ("obs", n)))
    two_lit = st.tuples(*[st.sampled_from(["a", "", "idle"]).map(lambda s: ("str", s))] * 2)
    pair = st.one_of(with_literal, two_obs, two_lit)
    return st.tuples(pair, st.booleans(), st.sampled_from(["==", "!="])).map(
        lambda p: ("bin", p[2], *(p[0][::-1] if p[1] else p[0])))


@functools.cache
def conditions(w: Names):
    bool_obs = ["contact", "lidar_up"] + (["holding"] if w.gripper else [])

    def num_expr(leaf):
        return st.recursive(leaf, lambda sub: st.one_of(
            st.builds(lambda op, a, b: ("bin", op, a, b), st.sampled_from("+-*/"), sub, sub),
            st.builds(lambda a: ("neg", a), sub)), max_leaves=4)

    nums = num_expr(numbers(w))
    base = [st.booleans().map(lambda b: ("bool", b)), st.sampled_from(bool_obs).map(lambda n: ("obs", n)),
            st.builds(lambda op, a, b: ("bin", op, a, b), st.sampled_from(["<", "<=", ">", ">=", "==", "!="]),
                      nums, nums),
            strings(w),
            st.builds(lambda p, r: ("call", "near", [("str", p), r]), st.sampled_from(w.places), nums),
            st.builds(lambda *c: ("call", "inside", list(c)), nums, nums, nums, nums)]
    if w.doors:
        base.append(st.sampled_from(w.doors).map(lambda d: ("call", "door_open", [("str", d)])))
    if w.objects:
        base.append(st.builds(lambda o, p, r: ("call", "object_near", [("str", o), ("str", p), r]),
                              st.sampled_from(w.objects), st.sampled_from(w.places), nums))
    return st.recursive(st.one_of(*base), lambda sub: st.one_of(
        st.builds(lambda op, a, b: ("bin", op, a, b), st.sampled_from(["&&", "||", "=>", "==", "!="]), sub, sub),
        st.builds(lambda a: ("not", a), sub)), max_leaves=6)


_LEVEL = {"=>": 0, "||": 1, "&&": 2, "==": 3, "!=": 3, "<": 3, "<=": 3, ">": 3, ">=": 3, "+": 4, "-": 4,
          "*": 5, "/": 5}


def level(tree) -> int:
    if tree[0] == "bin":
        return _LEVEL[tree[1]]
    return 6 if tree[0] in ("not", "neg") else 7


def write(tree, need: int = 0) -> str:
    """The tree as text, parenthesised only where the precedence needs it."""
    kind = tree[0]
    if kind == "num":
        text = repr(tree[1])
    elif kind == "str":
        text = f'"{tree[1]}"'
    elif kind == "bool":
        text = "true" if tree[1] else "false"
    elif kind == "obs":
        text = tree[1]
    elif kind == "call":
        text = f"{tree[1]}({', '.join(write(a) for a in tree[2])})"
    elif kind in ("not", "neg"):
        text = ("!" if kind == "not" else "-") + write(tree[1], 6)
    else:
        op, p = tree[1], _LEVEL[tree[1]]
        if op == "=>":       # right-associative
            left, right = write(tree[2], p + 1), write(tree[3], p)
        elif p == 3:         # comparisons do not chain
            left, right = write(tree[2], p + 1), write(tree[3], p + 1)
        else:                # left-associative
            left, right = write(tree[2], p), write(tree[3], p + 1)
        text = f"{left} {op} {right}"
    return f"({text})" if level(tree) < need else text


def read(r: Robot, name: str):
    """The observables, read off the robot by their definitions."""
    w = r.world
    x, y, theta = w.base.pose
    vx, vy = w.base.body.velocity
    g, ptu = w.gripper, w.ptu
    return {
        "t": w.steps * w.dt, "x": x, "y": y, "heading": math.degrees(theta), "speed": math.sqrt(vx * vx + vy * vy),
        "contact": w.base.bumped, "bumps": w.base.bump_count, "following": r.follow_state,
        "lidar_up": r.time - r.last_scan_time <= 2 * w.lidar.period + 1e-9,
        "gripper": (("closed" if g.closed else "open") if g else None),
        "holding": (g.holding is not None if g else None), "held": ((g.holding or "") if g else None),
        "pan": ptu.angle_deg if ptu else None, "pan_target": ptu.target_deg if ptu else None,
    }[name]


def evaluate(tree, r: Robot):
    kind = tree[0]
    if kind in ("num", "str", "bool"):
        return tree[1]
    if kind == "obs":
        return read(r, tree[1])
    if kind == "not":
        return not evaluate(tree[1], r)
    if kind == "neg":
        return -evaluate(tree[1], r)
    if kind == "call":
        name, args = tree[1], tree[2]
        bx, by, _ = r.world.base.pose
        if name == "door_open":
            return r.world.door_open(args[0][1])
        if name in ("dist", "near"):
            px, py = r.scenario.places[args[0][1]]
            d = math.dist((bx, by), (px, py))
            return d if name == "dist" else d <= evaluate(args[1], r)
        if name == "inside":
            x0, y0, x1, y1 = (evaluate(a, r) for a in args)
            return min(x0, x1) <= bx <= max(x0, x1) and min(y0, y1) <= by <= max(y0, y1)
        ox, oy = r.world.objects[args[0][1]].position
        if name == "object_x":
            return ox
        if name == "object_y":
            return oy
        px, py = r.scenario.places[args[1][1]]
        return math.dist((ox, oy), (px, py)) <= evaluate(args[2], r)
    op = tree[1]
    a = evaluate(tree[2], r)
    if op == "&&":
        return a and evaluate(tree[3], r)
    if op == "||":
        return a or evaluate(tree[3], r)
    if op == "=>":
        return (not a) or evaluate(tree[3], r)
    b = evaluate(tree[3], r)
    return {"==": lambda: a == b, "!=": lambda: a != b, "<": lambda: a < b, "<=": lambda: a <= b,
            ">": lambda: a > b, ">=": lambda: a >= b, "+": lambda: a + b, "-": lambda: a - b,
            "*": lambda: a * b, "/": lambda: a / b}[op]()


def divides_by_literal_zero(tree) -> bool:
    if tree[0] == "bin" and tree[1] == "/" and tree[3] == ("num", 0):
        return True
    children = tree[2] if tree[0] == "call" else tree[1:] if tree[0] in ("not", "neg") else \
        tree[2:] if tree[0] == "bin" else []
    return any(divides_by_literal_zero(c) for c in children)


@pytest.mark.parametrize("name", sorted(WORLDS))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_conditions_agree_with_an_independent_evaluation(name, data):
    w = WORLDS[name]
    r = oracle_robot(name)
    tree = data.draw(conditions(w))
    text = write(tree)
    if divides_by_literal_zero(tree):
        with pytest.raises(RoarError, match="division by zero"):
            parse_condition(text)
        return
    cond = parse_condition(text, "gen.toml", 1, 1)
    check_condition(cond, scenario(name))
    try:
        want = evaluate(tree, r)
    except ZeroDivisionError:
        with pytest.raises(RoarError, match="division by zero"):
            cond.holds(r)
        return
    assert cond.holds(r) is bool(want), text
    assert isinstance(cond.explain(r), str)


def test_the_docs_section_is_true():
    doc = (SCENARIOS.parents[1] / "docs" / "robot.md").read_text(encoding="utf-8")
    section = doc.split("## Conditions on the robot state\n", 1)[1].split("\n## ", 1)[0]
    examples = section.split("```\n", 2)[1].strip().splitlines()
    assert len(examples) == 3
    for text in examples:
        check_condition(parse_condition(text), scenario("gripper"))
    table = {name for row in section.splitlines() if row.startswith("| `")
             for name in re.findall(r"`([a-z_]+)[`(]", row.split("|")[1])}
    assert table == set(OBSERVABLES)
