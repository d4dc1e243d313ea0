"""Scenario files: the world a reference-robot run happens in (TOML).

A scenario gives the room (walls, obstacles, doors, loose objects, floor
patches), the robot, an optional pan-tilt unit and the fault points a run
may turn on. Lengths are metres, times seconds, angles degrees in the file;
angles the simulation uses directly are stored in radians under names
without a ``_deg`` suffix. Every mistake is a :class:`RoarError` at the
line and column of the offending key or value, saying what was expected.
"""

from __future__ import annotations

import bisect
import hashlib
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from ..errors import Pos, RoarError
from ..errors import did_you_mean as errors_did_you_mean

Point = tuple[float, float]
Rect = tuple[float, float, float, float]

FAULT_KINDS = ("door", "lidar_dropout", "friction", "ptu_cable", "grip_force", "odometry_bias")
DOOR_STATES = ("open", "closed")
MAX_DT = 0.05
NAME = r"[A-Za-z_][A-Za-z0-9_-]*"
NAME_RULE = "letters, digits, '_' or '-', starting with a letter or '_'"


# ---------------------------------------------------------------- data classes


@dataclass(frozen=True)
class DoorChange:
    """At ``time`` the door becomes open (``open`` true) or closed."""

    time: float
    open: bool


@dataclass(frozen=True)
class Wall:
    start: Point
    end: Point
    thickness: float = 0.1


@dataclass(frozen=True)
class Shape:
    """A box (centre x, y, size w x h, rotated by ``angle`` radians) or a circle (centre x, y, radius r)."""

    kind: str  # "box" | "circle"
    x: float
    y: float
    w: float = 0.0
    h: float = 0.0
    r: float = 0.0
    angle: float = 0.0


@dataclass(frozen=True)
class Door:
    name: str
    start: Point
    end: Point
    thickness: float = 0.1
    open: bool = True
    schedule: tuple[DoorChange, ...] = ()


@dataclass(frozen=True)
class LooseObject:
    """A dynamic object; ``friction`` is used against other shapes and against the floor."""

    name: str
    shape: Shape
    mass: float = 0.5
    friction: float = 0.6


@dataclass(frozen=True)
class Patch:
    """A floor area with its own wheel-floor friction coefficient."""

    area: Rect
    mu: float


@dataclass(frozen=True)
class Lidar:
    rays: int = 90
    fov_deg: float = 360.0
    range: float = 8.0
    noise: float = 0.01
    period: float = 0.1


@dataclass(frozen=True)
class Gripper:
    reach: float = 0.15
    width: float = 0.12
    grip_force: float = 30.0


@dataclass(frozen=True)
class Robot:
    """The differential-drive base. ``size`` (length, width) makes the chassis a box instead of a circle."""

    start: tuple[float, float, float] = (1.0, 1.0, 0.0)  # x, y, heading in radians
    radius: float = 0.25
    size: Optional[Point] = None
    mass: float = 20.0
    wheel_base: float = 0.4
    wheel_radius: float = 0.05
    max_wheel_speed: float = 20.0
    max_torque: float = 4.0
    floor_mu: float = 0.8
    odometry_noise: float = 0.01
    lidar: Lidar = field(default_factory=Lidar)
    gripper: Optional[Gripper] = None

    @property
    def half_length(self) -> float:
        """Distance from the centre to the front of the chassis."""
        return self.size[0] / 2 if self.size else self.radius

    @property
    def bounding_radius(self) -> float:
        return math.hypot(self.size[0] / 2, self.size[1] / 2) if self.size else self.radius


@dataclass(frozen=True)
class Ptu:
    position: Point
    min_deg: float = -170.0
    max_deg: float = 170.0
    max_rate_deg: float = 90.0
    max_torque: float = 2.0


@dataclass(frozen=True)
class Fault:
    """A fault point; only the fields of its ``kind`` are set."""

    name: str
    kind: str
    description: str = ""
    probability: float = 0.5
    door: Optional[str] = None                         # door
    schedule: tuple[DoorChange, ...] = ()               # door
    start: Optional[float] = None                       # lidar_dropout: from
    until: Optional[float] = None                       # lidar_dropout
    area: Optional[Rect] = None                         # friction
    mu: Optional[float] = None                          # friction
    max_deg: Optional[float] = None                     # ptu_cable
    force: Optional[float] = None                       # grip_force
    scale: Optional[float] = None                       # odometry_bias


@dataclass(frozen=True)
class Scenario:
    name: str
    bounds: Rect
    description: str = ""
    dt: float = 0.01
    horizon: float = 120.0
    seed: int = 0
    places: dict[str, Point] = field(default_factory=dict)
    walls: tuple[Wall, ...] = ()
    obstacles: tuple[Shape, ...] = ()
    doors: tuple[Door, ...] = ()
    objects: tuple[LooseObject, ...] = ()
    patches: tuple[Patch, ...] = ()
    robot: Robot = field(default_factory=Robot)
    ptu: Optional[Ptu] = None
    faults: dict[str, Fault] = field(default_factory=dict)
    path: Optional[str] = None
    fingerprint: str = ""

    def __hash__(self) -> int:  # the dict fields are not hashable; the text identifies the scenario
        return hash((self.fingerprint, self.path))

    def fault_names(self) -> tuple[str, ...]:
        """The fault points in file order."""
        return tuple(self.faults)

    def place(self, name: str) -> Point:
        """A named place, or a RoarError naming the known ones."""
        if name not in self.places:
            raise RoarError(f"scenario '{self.name}' has no place '{name}'{did_you_mean(name, self.places)}; "
                            f"places: {', '.join(self.places) or 'none'}")
        return self.places[name]

    def door(self, name: str) -> Door:
        for d in self.doors:
            if d.name == name:
                return d
        raise RoarError(f"scenario '{self.name}' has no door '{name}'"
                        f"{did_you_mean(name, [d.name for d in self.doors])}")


# ---------------------------------------------------------------- entry points


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario file."""
    path = Path(path)
    from ..inputs import check_input_file
    check_input_file(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RoarError(f"cannot read scenario {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RoarError(f"cannot read scenario {path}: {exc}") from None
    return parse_scenario(text, str(path))


def parse_scenario(text: str, filename: str = "<scenario>") -> Scenario:
    """Check a scenario given as text; ``filename`` is used in error positions and kept as ``path``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        if m:
            pos = Pos(filename, int(m.group(1)), int(m.group(2)))
        else:  # "(at end of document)": point at the end of the last line
            lines = text.splitlines() or [""]
            pos = Pos(filename, len(lines), len(lines[-1]) + 1)
        raise RoarError(f"invalid TOML: {re.sub(r' [(]at (line|end of document).*', '', msg)}", pos) from None
    except (RecursionError, ValueError) as exc:   # nested too deeply; a number past the int-string limit
        from ..inputs import toml_limit_error
        raise toml_limit_error(exc, text, filename) from None
    where = _Locator(text, filename)
    return _read_scenario(_Table(data, (), "the scenario file", where), text, filename)


# ---------------------------------------------------------------- locating keys and values


class _Locator:
    """Where each key and each value of a (valid) TOML text starts.

    Paths are tuples of keys and list indices, with arrays of tables indexed
    in order: ``("wall", 1, "from", 0)`` is the x of the second wall's
    ``from``. tomllib gives no positions, so the text is scanned once.
    """

    _BARE = re.compile(r"[A-Za-z0-9_-]+")

    def __init__(self, text: str, filename: str):
        self.text = text
        self.filename = filename
        self.line_starts = [0] + [m.end() for m in re.finditer(r"\n", text)]
        self.keys: dict[tuple, int] = {}
        self.values: dict[tuple, int] = {}
        self.i = 0
        try:
            self._scan()
        except (IndexError, ValueError):  # the text parsed, so this is a scanner gap: positions get coarser
            pass

    def key(self, path: tuple) -> Pos:
        """Position of the key at ``path`` (or of the nearest enclosing key or table)."""
        return self._pos(path, self.keys, self.values)

    def value(self, path: tuple) -> Pos:
        """Position of the value at ``path`` (or of its key, or the nearest enclosing one)."""
        return self._pos(path, self.values, self.keys)

    def _pos(self, path: tuple, first: dict, second: dict) -> Pos:
        while True:
            for table in (first, second):
                if path in table:
                    return self._at(table[path])
            if not path:
                return Pos(self.filename, 1, 1)
            path = path[:-1]

    def _at(self, index: int) -> Pos:
        line = bisect.bisect_right(self.line_starts, index)
        return Pos(self.filename, line, index - self.line_starts[line - 1] + 1)

    # the scanner proper: it trusts the text to be valid TOML

    def _scan(self) -> None:
        text = self.text
        table: tuple = ()
        array_counts: dict[tuple, int] = {}
        while True:
            self._skip(newlines=True)
            if self.i >= len(text):
                return
            if text[self.i] == "[":
                double = text.startswith("[[", self.i)
                start = self.i
                self.i += 2 if double else 1
                names = self._key_parts()
                table = ()
                for n, name in enumerate(names):
                    table += (name,)
                    last = n == len(names) - 1
                    if last and double:
                        array_counts[table] = array_counts.get(table, -1) + 1
                    if table in array_counts:
                        table += (array_counts[table],)
                self.keys.setdefault(table, start)
                self.i = text.index("]]" if double else "]", self.i) + (2 if double else 1)
            else:
                self._key_value(table)

    def _key_value(self, table: tuple) -> None:
        start = self.i
        path = table + tuple(self._key_parts())
        self.keys.setdefault(path, start)
        self._skip()
        self.i += 1  # '='
        self._skip()
        self._value(path)

    def _key_parts(self) -> list[str]:
        parts = []
        while True:
            self._skip()
            c = self.text[self.i]
            if c in "\"'":
                parts.append(self._string())
            else:
                m = self._BARE.match(self.text, self.i)
                parts.append(m.group())
                self.i = m.end()
            self._skip()
            if self.text[self.i] != ".":
                return parts
            self.i += 1

    def _value(self, path: tuple) -> None:
        text = self.text
        self.values.setdefault(path, self.i)
        c = text[self.i]
        if c == "[":
            self.i += 1
            index = 0
            while True:
                self._skip(newlines=True)
                if text[self.i] == "]":
                    self.i += 1
                    return
                if text[self.i] == ",":
                    self.i += 1
                    continue
                self._value(path + (index,))
                index += 1
        elif c == "{":
            self.i += 1
            while True:
                self._skip()
                if text[self.i] == "}":
                    self.i += 1
                    return
                if text[self.i] == ",":
                    self.i += 1
                    continue
                self._key_value(path)
        elif c in "\"'":
            self._string()
        else:
            m = re.compile(r"[^,\]}\n#]*").match(text, self.i)
            self.i = m.end()

    def _string(self) -> str:
        text = self.text
        quote = text[self.i]
        if text.startswith(quote * 3, self.i):
            end = text.index(quote * 3, self.i + 3)
            while text.startswith(quote, end + 3):  # up to two quotes may end the content
                end += 1
            self.i = end + 3
            return ""
        j = self.i + 1
        while text[j] != quote:
            j += 2 if quote == '"' and text[j] == "\\" else 1
        raw = text[self.i + 1:j]
        self.i = j + 1
        if quote == '"' and "\\" in raw:
            try:
                return tomllib.loads(f"k = \"{raw}\"")["k"]
            except tomllib.TOMLDecodeError:
                return raw
        return raw

    def _skip(self, newlines: bool = False) -> None:
        """Skip blanks and comments (and line ends when ``newlines``)."""
        text = self.text
        while self.i < len(text):
            c = text[self.i]
            if c in " \t\r" or (newlines and c == "\n"):
                self.i += 1
            elif c == "#":
                end = text.find("\n", self.i)
                self.i = len(text) if end < 0 else end
            else:
                return


# ---------------------------------------------------------------- checked reading


def did_you_mean(name: str, candidates) -> str:
    """A hint naming the closest candidate to a misspelt name (empty when none is close)."""
    return errors_did_you_mean(name, sorted(set(candidates)))


def _show(value: Any) -> str:
    """A value as the user wrote it (TOML spelling for booleans), shortened."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = f'"{value}"'
    elif isinstance(value, dict):
        text = "a table"
    elif isinstance(value, list):
        text = "[" + ", ".join(_show(v) for v in value) + "]"
    else:
        text = repr(value)
    return text if len(text) <= 50 else text[:47] + "..."


def _is_number(v: Any) -> bool:
    """A finite int or float that fits a float (TOML integers are unbounded; booleans are not numbers)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    return math.isfinite(v) if isinstance(v, float) else abs(v) <= 1e300


class _Table:
    """A TOML table being read: typed getters that fail at the right line and column."""

    def __init__(self, data: dict, path: tuple, what: str, where: _Locator):
        self.data = data
        self.path = path
        self.what = what
        self.where = where

    def error(self, message: str, key: Optional[str] = None, *more: Any, at_key: bool = False) -> RoarError:
        if key is None:
            return RoarError(message, self.where.key(self.path))
        path = self.path + (key,) + more
        return RoarError(message, self.where.key(path) if at_key else self.where.value(path))

    def check_keys(self, allowed, hint: str = "") -> None:
        for key in self.data:
            if key not in allowed:
                raise self.error(f"unknown key '{key}' in {self.what}{did_you_mean(key, allowed)}; "
                                 f"expected {hint or 'one of: ' + ', '.join(allowed)}", key, at_key=True)

    def has(self, key: str) -> bool:
        return key in self.data

    def require(self, key: str) -> None:
        if key not in self.data:
            raise self.error(f"{self.what} needs '{key}'")

    def number(self, key: str, default: Optional[float] = None, low: Optional[float] = None,
               high: Optional[float] = None, low_open: bool = False) -> float:
        """A number (an integer is fine, a boolean is not) within [low, high] (or (low, high] with low_open)."""
        if key not in self.data:
            if default is None:
                self.require(key)
            return default
        v = self.data[key]
        if not _is_number(v):
            raise self.error(f"'{key}' in {self.what} must be a number, not {_show(v)}", key)
        self._in_range(key, v, low, high, low_open)
        return float(v)

    def _in_range(self, key: str, v: float, low, high, low_open: bool, *more: Any) -> None:
        too_low = low is not None and (v <= low if low_open else v < low)
        too_high = high is not None and v > high
        if too_low or too_high:
            parts = []
            if low is not None:
                parts.append(f"{'>' if low_open else '>='} {low:g}")
            if high is not None:
                parts.append(f"<= {high:g}")
            raise self.error(f"'{key}' in {self.what} must be {' and '.join(parts)}, not {_show(v)}", key, *more)

    def integer(self, key: str, default: int, low: Optional[int] = None, high: Optional[int] = None) -> int:
        if key not in self.data:
            return default
        v = self.data[key]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.error(f"'{key}' in {self.what} must be an integer, not {_show(v)}", key)
        self._in_range(key, v, low, high, False)
        return v

    def string(self, key: str, default: Optional[str] = None) -> str:
        if key not in self.data:
            if default is None:
                self.require(key)
            return default
        v = self.data[key]
        if not isinstance(v, str):
            raise self.error(f"'{key}' in {self.what} must be a string, not {_show(v)}", key)
        return v

    def name(self, key: str = "name") -> str:
        v = self.string(key)
        if not re.fullmatch(NAME, v):
            raise self.error(f"'{key}' in {self.what} must be a name ({NAME_RULE}), not {_show(v)}", key)
        return v

    def boolean(self, key: str, default: bool) -> bool:
        if key not in self.data:
            return default
        v = self.data[key]
        if not isinstance(v, bool):
            raise self.error(f"'{key}' in {self.what} must be true or false, not {_show(v)}", key)
        return v

    def numbers(self, key: str, shape: str, default: Optional[tuple] = None) -> tuple[float, ...]:
        """A list of numbers laid out as ``shape`` (e.g. "[x, y]")."""
        if key not in self.data:
            if default is None:
                self.require(key)
            return default
        v = self.data[key]
        count = shape.count(",") + 1
        if not isinstance(v, list) or len(v) != count:
            raise self.error(f"'{key}' in {self.what} must be a list of {count} numbers {shape}, not {_show(v)}",
                             key)
        for i, item in enumerate(v):
            if not _is_number(item):
                raise self.error(f"'{key}' in {self.what} must be a list of {count} numbers {shape}; "
                                 f"item {i + 1} is {_show(item)}", key, i)
        return tuple(float(x) for x in v)

    def rect(self, key: str) -> Rect:
        x0, y0, x1, y1 = self.numbers(key, "[x0, y0, x1, y1]")
        if not (x0 < x1 and y0 < y1):
            raise self.error(f"'{key}' in {self.what} must have x0 < x1 and y0 < y1, not {_show(self.data[key])}",
                             key)
        return (x0, y0, x1, y1)

    def table(self, key: str, what: str) -> Optional["_Table"]:
        if key not in self.data:
            return None
        v = self.data[key]
        if not isinstance(v, dict):
            raise self.error(f"'{key}' must be a table ([{'.'.join(map(str, self.path + (key,)))}]), "
                             f"not {_show(v)}", key)
        return _Table(v, self.path + (key,), what, self.where)

    def tables(self, key: str) -> list["_Table"]:
        """An array of tables ([[key]] sections)."""
        if key not in self.data:
            return []
        v = self.data[key]
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            raise self.error(f"'{key}' must be written as [[{key}]] sections, not {_show(v)}", key)
        return [_Table(t, self.path + (key, i), f"[[{key}]] #{i + 1}", self.where) for i, t in enumerate(v)]


# ---------------------------------------------------------------- the scenario


TOP_KEYS = ("name", "description", "dt", "horizon", "seed", "bounds", "places", "wall", "obstacle", "door",
            "object", "patch", "robot", "ptu", "faults")


def _read_scenario(top: _Table, text: str, filename: str) -> Scenario:
    top.check_keys(TOP_KEYS)
    name = top.name("name")
    dt = top.number("dt", 0.01, 0.0, MAX_DT, low_open=True)
    horizon = top.number("horizon", 120.0, 0.0, low_open=True)
    bounds = top.rect("bounds")
    x0, y0, x1, y1 = bounds
    if max(x1 - x0, y1 - y0) > MAX_EXTENT or max(map(abs, bounds)) > MAX_COORD:
        raise top.error(f"'bounds' spans {x1 - x0:g} m by {y1 - y0:g} m: a world is at most {MAX_EXTENT:g} m on a side "
                        f"(its occupancy grid has a cell every 0.1 m), within {MAX_COORD:g} m of the origin", "bounds")
    inside = _Inside(bounds)

    places: dict[str, Point] = {}
    place_table = top.table("places", "[places]")
    if place_table:
        for key in place_table.data:
            if not re.fullmatch(NAME, key):
                raise place_table.error(f"place names are names ({NAME_RULE}), not '{key}'", key, at_key=True)
            p = place_table.numbers(key, "[x, y]")
            inside.check(place_table, key, p, f"place '{key}'")
            places[key] = p

    walls = []
    for t in top.tables("wall"):
        t.check_keys(("from", "to", "thickness"))
        start, end = t.numbers("from", "[x, y]"), t.numbers("to", "[x, y]")
        if start == end:
            raise t.error(f"{t.what}: 'from' and 'to' are the same point", "to")
        inside.check(t, "from", start, f"{t.what}: 'from'")
        inside.check(t, "to", end, f"{t.what}: 'to'")
        walls.append(Wall(start, end, t.number("thickness", 0.1, 0.0, low_open=True)))

    obstacles = []
    for t in _checked(top.tables("obstacle"), ("box", "circle", "angle")):
        shape = _shape(t, "obstacle")
        inside.check(t, shape.kind, (shape.x, shape.y), f"{t.what}")
        obstacles.append(shape)
    obstacles = tuple(obstacles)

    doors = []
    for t in top.tables("door"):
        t.check_keys(("name", "from", "to", "thickness", "open", "schedule"))
        door_name = t.name()
        if any(d.name == door_name for d in doors):
            raise t.error(f"a door named '{door_name}' is already declared", "name")
        start, end = t.numbers("from", "[x, y]"), t.numbers("to", "[x, y]")
        if start == end:
            raise t.error(f"{t.what}: 'from' and 'to' are the same point", "to")
        inside.check(t, "from", start, f"door '{door_name}': 'from'")
        inside.check(t, "to", end, f"door '{door_name}': 'to'")
        doors.append(Door(door_name, start, end, t.number("thickness", 0.1, 0.0, low_open=True),
                          t.boolean("open", True), _schedule(t, horizon)))

    objects = []
    for t in _checked(top.tables("object"), ("name", "box", "circle", "angle", "mass", "friction")):
        obj_name = t.name()
        if any(o.name == obj_name for o in objects):
            raise t.error(f"an object named '{obj_name}' is already declared", "name")
        shape = _shape(t, "object")
        inside.check(t, shape.kind, (shape.x, shape.y), f"object '{obj_name}'")
        objects.append(LooseObject(obj_name, shape, t.number("mass", 0.5, 0.0, low_open=True),
                                   t.number("friction", 0.6, 0.0)))

    patches = []
    for t in top.tables("patch"):
        t.check_keys(("area", "mu"))
        area = t.rect("area")
        inside.check(t, "area", (area[0], area[1]), f"{t.what}: the area's corner")
        inside.check(t, "area", (area[2], area[3]), f"{t.what}: the area's corner")
        patches.append(Patch(area, t.number("mu", None, 0.0)))

    robot = _robot(top.table("robot", "[robot]"), inside)
    ptu = _ptu(top.table("ptu", "[ptu]"), inside)
    faults = _faults(top.table("faults", "[faults]"), doors, robot, ptu, horizon)

    return Scenario(
        name=name, bounds=bounds, description=top.string("description", ""), dt=dt, horizon=horizon,
        seed=top.integer("seed", 0), places=places, walls=tuple(walls), obstacles=obstacles, doors=tuple(doors),
        objects=tuple(objects), patches=tuple(patches), robot=robot, ptu=ptu, faults=faults,
        path=None if filename.startswith("<") else filename,
        fingerprint=hashlib.sha256(text.encode("utf-8")).hexdigest())


#: the largest world: its planning grid (a cell every 0.1 m) stays a few million cells
MAX_EXTENT = 200.0
#: the farthest a world's bounds may lie from the origin (floats lose centimetres beyond)
MAX_COORD = 1.0e6


class _Inside:
    """Checks that points lie within the world bounds."""

    def __init__(self, bounds: Rect):
        self.bounds = bounds

    def check(self, t: _Table, key: str, p: tuple, what: str) -> None:
        x0, y0, x1, y1 = self.bounds
        if not (x0 <= p[0] <= x1 and y0 <= p[1] <= y1):
            raise t.error(f"{what} at ({p[0]:g}, {p[1]:g}) lies outside the bounds "
                          f"[{x0:g}, {y0:g}, {x1:g}, {y1:g}]", key)


def _checked(tables: list[_Table], allowed) -> list[_Table]:
    for t in tables:
        t.check_keys(allowed)
    return tables


def _shape(t: _Table, what: str) -> Shape:
    """The box or circle of an [[obstacle]] or [[object]]."""
    if t.has("box") and t.has("circle"):
        raise t.error(f"{t.what} is a box or a circle, not both: drop 'box' or 'circle'", "circle", at_key=True)
    if not t.has("box") and not t.has("circle"):
        raise t.error(f"{t.what} needs 'box = [cx, cy, w, h]' or 'circle = [cx, cy, r]'")
    if t.has("circle"):
        if t.has("angle"):
            raise t.error(f"'angle' in {t.what} applies to boxes only", "angle", at_key=True)
        x, y, r = t.numbers("circle", "[cx, cy, r]")
        if r <= 0:
            raise t.error(f"the radius in 'circle' of {t.what} must be > 0, not {r:g}", "circle", 2)
        return Shape("circle", x, y, r=r)
    x, y, w, h = t.numbers("box", "[cx, cy, w, h]")
    for i, v in ((2, w), (3, h)):
        if v <= 0:
            raise t.error(f"the {'width' if i == 2 else 'height'} in 'box' of {t.what} must be > 0, not {v:g}",
                          "box", i)
    return Shape("box", x, y, w=w, h=h, angle=math.radians(t.number("angle", 0.0)))


def _schedule(t: _Table, horizon: float) -> tuple[DoorChange, ...]:
    """A door schedule: [[time, "open"|"closed"], ...] with increasing times within the horizon."""
    if not t.has("schedule"):
        return ()
    v = t.data["schedule"]
    shape = 'a list of [time, "open" or "closed"] pairs'
    if not isinstance(v, list):
        raise t.error(f"'schedule' in {t.what} must be {shape}, not {_show(v)}", "schedule")
    changes: list[DoorChange] = []
    for i, item in enumerate(v):
        if not (isinstance(item, list) and len(item) == 2 and _is_number(item[0])
                and isinstance(item[1], str) and item[1] in DOOR_STATES):
            raise t.error(f"'schedule' in {t.what} must be {shape}; item {i + 1} is {_show(item)}", "schedule", i)
        time = float(item[0])
        if not 0 <= time <= horizon:
            raise t.error(f"schedule time {time:g} in {t.what} is outside [0, horizon = {horizon:g}]",
                          "schedule", i, 0)
        if changes and time <= changes[-1].time:
            raise t.error(f"schedule times in {t.what} must increase: {time:g} comes after {changes[-1].time:g}",
                          "schedule", i, 0)
        changes.append(DoorChange(time, item[1] == "open"))
    return tuple(changes)


ROBOT_KEYS = ("start", "radius", "size", "mass", "wheel_base", "wheel_radius", "max_wheel_speed", "max_torque",
              "floor_mu", "odometry_noise", "lidar", "gripper")


def _robot(t: Optional[_Table], inside: _Inside) -> Robot:
    x0, y0, x1, y1 = inside.bounds
    default_start = (x0 + min(1.0, (x1 - x0) / 2), (y0 + y1) / 2, 0.0)
    if t is None:
        return Robot(start=default_start)
    t.check_keys(ROBOT_KEYS)
    x, y, heading = t.numbers("start", "[x, y, heading_deg]", default_start)
    inside.check(t, "start", (x, y), "the robot's start")
    if t.has("radius") and t.has("size"):
        raise t.error("[robot] takes 'radius' (a round chassis) or 'size' (a box), not both", "size", at_key=True)
    size = None
    if t.has("size"):
        size = t.numbers("size", "[length, width]")
        if min(size) <= 0:
            raise t.error(f"'size' in [robot] must be positive, not {_show(t.data['size'])}", "size")
    lidar_table = t.table("lidar", "[robot.lidar]")
    lidar = Lidar()
    if lidar_table:
        lt = lidar_table
        lt.check_keys(("rays", "fov", "range", "noise", "period"))
        lidar = Lidar(rays=lt.integer("rays", 90, 1, 3600), fov_deg=lt.number("fov", 360.0, 0.0, 360.0, True),
                      range=lt.number("range", 8.0, 0.0, low_open=True), noise=lt.number("noise", 0.01, 0.0),
                      period=lt.number("period", 0.1, 0.0, low_open=True))
    gripper = None
    grip_table = t.table("gripper", "[robot.gripper]")
    if grip_table:
        g = grip_table
        g.check_keys(("reach", "width", "grip_force"))
        gripper = Gripper(reach=g.number("reach", 0.15, 0.0, low_open=True),
                          width=g.number("width", 0.12, 0.0, low_open=True),
                          grip_force=g.number("grip_force", 30.0, 0.0, low_open=True))
    return Robot(
        start=(x, y, math.radians(heading)), radius=t.number("radius", 0.25, 0.0, low_open=True), size=size,
        mass=t.number("mass", 20.0, 0.0, low_open=True),
        wheel_base=t.number("wheel_base", 0.4, 0.0, low_open=True),
        wheel_radius=t.number("wheel_radius", 0.05, 0.0, low_open=True),
        max_wheel_speed=t.number("max_wheel_speed", 20.0, 0.0, low_open=True),
        max_torque=t.number("max_torque", 4.0, 0.0, low_open=True),
        floor_mu=t.number("floor_mu", 0.8, 0.0), odometry_noise=t.number("odometry_noise", 0.01, 0.0, 1.0),
        lidar=lidar, gripper=gripper)


def _ptu(t: Optional[_Table], inside: _Inside) -> Optional[Ptu]:
    if t is None:
        return None
    t.check_keys(("position", "min_deg", "max_deg", "max_rate_deg", "max_torque"))
    position = t.numbers("position", "[x, y]")
    inside.check(t, "position", position, "the ptu")
    low = t.number("min_deg", -170.0, -360.0, 360.0)
    high = t.number("max_deg", 170.0, -360.0, 360.0)
    if not low < high:
        raise t.error(f"'min_deg' ({low:g}) must be below 'max_deg' ({high:g}) in [ptu]", "max_deg")
    return Ptu(position, low, high, t.number("max_rate_deg", 90.0, 0.0, low_open=True),
               t.number("max_torque", 2.0, 0.0, low_open=True))


FAULT_COMMON = ("kind", "description", "probability")
FAULT_KEYS = {
    "door": ("door", "schedule"),
    "lidar_dropout": ("from", "until"),
    "friction": ("area", "mu"),
    "ptu_cable": ("max_deg",),
    "grip_force": ("force",),
    "odometry_bias": ("scale",),
}


def _faults(t: Optional[_Table], doors: list[Door], robot: Robot, ptu: Optional[Ptu],
            horizon: float) -> dict[str, Fault]:
    if t is None:
        return {}
    faults: dict[str, Fault] = {}
    for fault_name in t.data:
        f = t.table(fault_name, f"[faults.{fault_name}]")
        if f is None or not re.fullmatch(NAME, fault_name):
            raise t.error(f"fault names are names ({NAME_RULE}), not '{fault_name}'",
                          fault_name, at_key=True)
        f.require("kind")
        kind = f.string("kind")
        if kind not in FAULT_KINDS:
            raise f.error(f"unknown fault kind '{kind}'{did_you_mean(kind, FAULT_KINDS)}; expected one of: "
                          f"{', '.join(FAULT_KINDS)}", "kind")
        f.check_keys(FAULT_COMMON + FAULT_KEYS[kind],
                     f"for a '{kind}' fault one of: {', '.join(FAULT_COMMON + FAULT_KEYS[kind])}")
        common = dict(name=fault_name, kind=kind, description=f.string("description", ""),
                      probability=f.number("probability", 0.5, 0.0, 1.0))
        if kind == "door":
            door = f.string("door")
            names = [d.name for d in doors]
            if door not in names:
                raise f.error(f"fault '{fault_name}' names door '{door}', which is not declared"
                              f"{did_you_mean(door, names)}; doors: {', '.join(names) or 'none'}", "door")
            f.require("schedule")
            faults[fault_name] = Fault(**common, door=door, schedule=_schedule(f, horizon))
        elif kind == "lidar_dropout":
            start = f.number("from", None, 0.0)
            until = f.number("until", None, 0.0)
            if not start < until:
                raise f.error(f"'until' ({until:g}) must be after 'from' ({start:g}) in [faults.{fault_name}]",
                              "until")
            faults[fault_name] = Fault(**common, start=start, until=until)
        elif kind == "friction":
            faults[fault_name] = Fault(**common, area=f.rect("area"), mu=f.number("mu", None, 0.0))
        elif kind == "ptu_cable":
            if ptu is None:
                raise f.error(f"fault '{fault_name}' is a ptu_cable fault but the scenario has no [ptu]", "kind")
            faults[fault_name] = Fault(**common, max_deg=f.number("max_deg", None, 0.0, 360.0, True))
        elif kind == "grip_force":
            if robot.gripper is None:
                raise f.error(f"fault '{fault_name}' is a grip_force fault but the robot has no [robot.gripper]",
                              "kind")
            faults[fault_name] = Fault(**common, force=f.number("force", None, 0.0, low_open=True))
        else:
            faults[fault_name] = Fault(**common, scale=f.number("scale", None, 0.0, low_open=True))
    return faults
