"""Verification jobs (``checker/*.toml``) and property files (``properties/*.toml``).

A job names a model, a start state, the property files that say what must
hold, search bounds and the expected verdict of each property. Paths in a
job are relative to the job file. Every mistake in a file is reported with
the file (and, where TOML gives it, the line and column) and what was
expected.
"""

from __future__ import annotations

import json
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

from ..errors import ErrorList, Pos, RoarError, collecting, did_you_mean
from ..explore.search import Budget

PROPERTIES = ("deadlock", "livelock", "sequential-achievement", "exclusive-writes", "invariant", "robot-invariant",
              "mission-completion", "mission-failure", "incompatible-tasks")
#: properties that read ROAR events or state: only for jobs on a spec
ROAR_PROPERTIES = ("sequential-achievement", "exclusive-writes", "mission-completion", "mission-failure",
                   "incompatible-tasks")
#: what a job on a spec checks when nothing names a property (docs/checking.md)
SPEC_DEFAULTS = ["deadlock", "mission-completion", "mission-failure"]
STATUSES = ("holds", "violated")


@dataclass
class PropertySpec:
    """What must hold, read from one or more property files."""

    check: list[str] = field(default_factory=list)
    progress: list[str] = field(default_factory=list)
    fairness: str = "first-argument"
    strong: bool = False   # livelock under strong fairness ([livelock] strength = "strong")
    accept: Optional[str] = None  # a positive CLF type: quiescent states matching it are final
    accept_at: Optional[Pos] = None  # where its text starts (inside the quotes)
    sources: list[str] = field(default_factory=list)
    fairness_given: bool = False
    never: list[tuple[str, Pos]] = field(default_factory=list)   # invariant: patterns no reachable state matches
    sequence_recipes: list[str] = field(default_factory=list)   # agent.task.recipe; empty: every recipe
    sequence_at: dict = field(default_factory=dict)   # a recipe name of recipes or kept -> where it is written
    # [sequential-achievement] kept: True (every recipe) or the agent.task.recipe names whose achieved
    # sub-goals must still hold when a later one is achieved and when the recipe ends; False: none
    sequence_kept: Any = False
    robot_never: list[tuple[str, Pos]] = field(default_factory=list)    # robot-invariant: conditions never true
    robot_always: list[tuple[str, Pos]] = field(default_factory=list)   # robot-invariant: conditions always true
    # in the spec's terms (roar/props.py Formula objects): jobs on a spec only
    spec_never: list = field(default_factory=list)      # invariant: predicates no reachable state satisfies
    spec_always: list = field(default_factory=list)     # invariant: predicates every reachable state satisfies
    spec_progress: list = field(default_factory=list)   # livelock: a step into a state where one holds is progress
    temporal: dict = field(default_factory=dict)        # [temporal] name -> Formula (always/eventually/leads-to)
    temporal_strong: set = field(default_factory=set)   # [temporal] names decided under strong fairness
    defaulted: bool = False                             # nothing named a property: the spec defaults are checked
    # [incompatible-tasks] pairs: ((text, Pos), (text, Pos)) of 'agent::task' names declared incompatible;
    # empty: the pairs the spec's post-conditions make incompatible
    incompatible_pairs: list = field(default_factory=list)
    progress_at: dict = field(default_factory=dict)     # a [livelock] progress rule name -> where it is written

    @property
    def spec_terms(self) -> bool:
        """Does any property read the spec's terms (predicates, temporal formulas)?"""
        return bool(self.spec_never or self.spec_always or self.spec_progress or self.temporal)


@dataclass
class RobotSetup:
    """A robot-backed job's [robot] table: the scenario and what the search may choose."""

    scenario: Path
    seed: Optional[int] = None                     # None: the scenario's own seed
    faults: dict = field(default_factory=dict)   # fault point -> frozenset of primitive names, or None (any call)
    on: tuple = ()                                 # fault points on from the start (the scenario's timeline)
    quantise: Any = None                           # roar_formal.robot.explore.Abstraction
    compare: bool = True                           # also check the abstract model and set the verdicts side by side
    pos: Optional[Pos] = None                      # where the table starts (errors about faults point here)


@dataclass
class Job:
    path: Path
    name: str
    model: Optional[Path]
    start: int = 1
    props: PropertySpec = field(default_factory=PropertySpec)
    expect: dict[str, str] = field(default_factory=dict)
    budget: Budget = field(default_factory=Budget)
    backend: str = "auto"
    search: str = "bfs"
    canonical: bool = True
    reduction: bool = False  # partial-order reduction (general backend, every property)
    visited: str = "exact"   # "hash": hash compaction, "bitstate": bitstate hashing (bug-hunting modes: a "holds" is no proof)
    bits: int = 1 << 27      # visited = "bitstate": bits in the array ([bitstate] bits)
    swarm_runs: int = 8             # search = "swarm": how many randomized depth-first searches
    swarm_states: int = 10_000      # ... and the states each may visit
    spec: Optional[Path] = None        # a ROAR spec (instead of a .clf model)
    request: Optional[str] = None      # the request the spec is run on
    request_at: Optional[Pos] = None   # where its text is written (errors inside it are reported there)
    start_at: Optional[Pos] = None     # where 'start' is written
    backend_at: Optional[Pos] = None   # where 'backend' is written (None: the default)
    functional: Optional[Path] = None  # the functional-layer module (outcomes of the primitives)
    robot: Optional[RobotSetup] = None  # robot-backed: the reference robot is the functional layer
    crashes: Any = None                 # [faults]: roar.compile.Crashes, the agents that may crash (None: none)
    cluster: Any = None                 # [cluster] (search = "distributed", or a swarm on a cluster): verify.cluster.ClusterSetup
    time: Any = None                    # time / [time]: roar.compile.Timing (None: untimed; docs/semantics.md, Time)
    symmetry: bool = False              # symmetry reduction (explore/symmetry.py; docs/checking.md, Symmetry reduction)
    symmetry_at: Optional[Pos] = None   # where the job file turns it on (None: --symmetry, or off)

    @property
    def is_roar(self) -> bool:
        return self.spec is not None


def _load_toml(path: Path) -> dict:
    from ..inputs import check_input_file
    check_input_file(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RoarError(f"cannot read {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RoarError(f"cannot read {path}: {exc}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        pos = Pos(str(path), int(m.group(1)), int(m.group(2))) if m else Pos(str(path), 1, 1)
        brief = re.sub(r" \(at line .*", "", msg)
        raise RoarError(f"invalid TOML: {brief}", pos) from None
    except (RecursionError, ValueError) as exc:   # nested too deeply; a number past the int-string limit
        from ..inputs import toml_limit_error
        raise toml_limit_error(exc, text, str(path)) from None


#: the keys and tables of a property file (docs/checking.md)
PROPERTY_KEYS = {"description", "check", "livelock", "deadlock", "sequential-achievement", "invariant",
                 "robot-invariant", "temporal", "incompatible-tasks"}


#: the keys of a job's [bounds] table
BOUND_KEYS = ("max_states", "max_seconds", "max_memory_mb")


def _expect_keys(d: dict, allowed: set, where: str, path: Path) -> None:
    for k in d:
        if k not in allowed:
            hint = ""
            if where == "a job file" and k in PROPERTY_KEYS:
                hint = (f" ('{k}' belongs in a property file, which the job names with properties = "
                        f"[\"file.toml\"]" + ("; this file looks like one: a folder of jobs should not hold it"
                                               if "check" in d else "") + ")")
            if not hint:
                hint = did_you_mean(str(k), sorted(allowed))
                near = did_you_mean(str(k), BOUND_KEYS) if not hint and where == "a job file" else ""
                if k in BOUND_KEYS and where == "a job file":
                    hint = f" ('{k}' is a bound: it goes in a [bounds] table)"
                elif near:   # " (did you mean 'max_states'?)" with where it goes
                    hint = near[:-1] + "; the bounds go in a [bounds] table)"
            raise RoarError(f"unknown key '{k}' in {where}{hint}; expected one of: {', '.join(sorted(allowed))}",
                            Pos(str(path), _line_of(path, k), 1))


def _line_of(path: Path, key: str) -> int:
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError:
        return 1
    for n, line in enumerate(lines, 1):
        if re.match(rf"\s*\[*\s*{re.escape(key)}\s*[=\]]", line):
            return n
    for n, line in enumerate(lines, 1):   # a key inside an inline table: { key = ... }
        if re.search(rf"[{{,]\s*{re.escape(key)}\s*=", line):
            return n
    return 1


def _typed(d: dict, key: str, ty, path: Path, what: str) -> Any:
    v = d[key]
    if ty is int and isinstance(v, bool) or not isinstance(v, ty):
        tn = {int: "an integer", str: "a string", list: "a list", bool: "true or false",
              float: "a number", dict: "a table"}.get(ty, str(ty))
        raise RoarError(f"'{key}' in {what} must be {tn}, not {_toml_value(v)}", Pos(str(path), _line_of(path, key), 1))
    if isinstance(v, str) and "\0" in v:   # no path, name or formula holds a NUL character
        raise RoarError(f"'{key}' in {what} holds a NUL character (\\u0000)", Pos(str(path), _line_of(path, key), 1))
    return v


#: the smallest memory budget a job may set: the Python process alone takes about this much
MIN_MEMORY_MB = 16
#: the largest value any bound may take (beyond it a bound bounds nothing)
MAX_BOUND = 10 ** 12


def _value_pos(path: Path, key: str) -> Pos:
    """Where ``key = value`` puts its value (line and column), for errors about the value."""
    line = _line_of(path, key)
    try:
        text = path.read_text(encoding="utf-8").splitlines()[line - 1]
        m = re.match(rf"(\s*{re.escape(key)}\s*=\s*)", text) or re.match(rf"(.*[{{,]\s*{re.escape(key)}\s*=\s*)", text)
        if m:
            return Pos(str(path), line, len(m.group(1)) + 1)
        col = text.find(key)
        return Pos(str(path), line, col + 1 if col >= 0 else 1)
    except (OSError, IndexError):
        return Pos(str(path), line, 1)


def _bound(b: dict, key: str, path: Path, expected: str, low: float, integer: bool):
    """One search bound: a finite number, at least ``low`` (above it when ``low`` is 0)."""
    if key not in b:
        return None
    v = b[key]
    ok = not isinstance(v, bool) and isinstance(v, int if integer else (int, float))
    if ok:
        ok = math.isfinite(v) and (v > 0 if low == 0 else v >= low) and v <= MAX_BOUND
    if not ok:
        shown = ("true" if v else "false") if isinstance(v, bool) else json.dumps(v) if isinstance(v, str) \
            else repr(v) if isinstance(v, (int, float)) else f"a {type(v).__name__}"
        raise RoarError(f"[bounds] {key} must be {expected} (at most {MAX_BOUND:,}), not {shown}",
                        _value_pos(path, key))
    return float(v) if not integer else v


def load_properties(path: Path, into: Optional[PropertySpec] = None) -> PropertySpec:
    spec = into or PropertySpec()
    d = _load_toml(path)
    from ..roar.props import looks_like_spec, parse_formula
    _expect_keys(d, PROPERTY_KEYS, "a property file", path)
    if "check" in d:
        for p in _typed(d, "check", list, path, "a property file"):
            if p not in PROPERTIES:
                raise RoarError(f"unknown property '{p}'{did_you_mean(str(p), PROPERTIES)}; expected one of: "
                                f"{', '.join(PROPERTIES)}", _string_pos(path, "check", str(p)))
            if p not in spec.check:
                spec.check.append(p)
    if "livelock" in d:
        ll = _typed(d, "livelock", dict, path, "a property file")
        _expect_keys(ll, {"progress", "fairness", "strength"}, "[livelock]", path)
        if "progress" in ll:
            for x in _typed(ll, "progress", list, path, "[livelock]"):
                if isinstance(x, str) and looks_like_spec(x):
                    spec.spec_progress.append(parse_formula(x, _string_pos(path, "progress", x), temporal=False))
                else:
                    spec.progress.append(str(x))
                    spec.progress_at.setdefault(str(x), _string_pos(path, "progress", str(x)))
        if "fairness" in ll:
            f = _typed(ll, "fairness", str, path, "[livelock]")
            if f not in ("first-argument", "rule", "none"):
                raise RoarError(f"fairness must be 'first-argument', 'rule' or 'none', not '{f}'",
                                Pos(str(path), _line_of(path, "fairness"), 1))
            spec.fairness = f
            spec.fairness_given = True
        if "strength" in ll:
            st = _typed(ll, "strength", str, path, "[livelock]")
            if st not in ("weak", "strong"):
                raise RoarError(f"strength must be 'weak' (a process enabled all along a cycle moves on it) or "
                                f"'strong' (a process enabled infinitely often moves infinitely often), not '{st}'",
                                _value_pos(path, "strength"))
            spec.strong = st == "strong"
        if "livelock" not in spec.check:   # a [livelock] table says how to check it: so it is checked
            spec.check.append("livelock")
    if "sequential-achievement" in d:
        sa = _typed(d, "sequential-achievement", dict, path, "a property file")
        _expect_keys(sa, {"recipes", "kept"}, "[sequential-achievement]", path)
        if "recipes" in sa:
            for r in _typed(sa, "recipes", list, path, "[sequential-achievement]"):
                if not isinstance(r, str) or r.count(".") != 2:
                    raise RoarError(f"[sequential-achievement] recipes are named 'agent.task.recipe', not {r!r}",
                                    Pos(str(path), _line_of(path, "recipes"), 1))
                spec.sequence_recipes.append(r)
                spec.sequence_at.setdefault(r, _string_pos(path, "recipes", r))
        if "kept" in sa:
            _sequence_kept(sa["kept"], spec, path)
        if "sequential-achievement" not in spec.check:   # the table says how to check it: so it is checked
            spec.check.append("sequential-achievement")
    if "incompatible-tasks" in d:
        it = _typed(d, "incompatible-tasks", dict, path, "a property file")
        _expect_keys(it, {"pairs"}, "[incompatible-tasks]", path)
        if "pairs" in it:
            _incompatible_pairs(it["pairs"], spec, path)
        if "incompatible-tasks" not in spec.check:   # the table says how to check it: so it is checked
            spec.check.append("incompatible-tasks")
    if "invariant" in d:
        inv = _typed(d, "invariant", dict, path, "a property file")
        _expect_keys(inv, {"never", "always"}, "[invariant]", path)
        pats = _typed(inv, "never", list, path, "[invariant]") if "never" in inv else []
        for pat in pats:
            if not isinstance(pat, str) or not pat.strip():
                raise RoarError("[invariant] never is a list of predicates in the spec's terms such as "
                                "\"arm::holding == true && gripper::closed == false\" (jobs on a spec) or of CLF "
                                "patterns such as \"busy P * busy P\"", Pos(str(path), _line_of(path, "never"), 1))
            if looks_like_spec(pat):
                spec.spec_never.append(parse_formula(pat, _string_pos(path, "never", pat), temporal=False))
            else:
                spec.never.append((pat, _string_pos(path, "never", pat)))
        alw = _typed(inv, "always", list, path, "[invariant]") if "always" in inv else []
        for pat in alw:
            if not isinstance(pat, str) or not pat.strip():
                raise RoarError("[invariant] always is a list of predicates in the spec's terms such as "
                                "\"ptu::heading != 0\"", Pos(str(path), _line_of(path, "always"), 1))
            spec.spec_always.append(parse_formula(pat, _string_pos(path, "always", pat), temporal=False))
        if (pats or alw) and "invariant" not in spec.check:
            spec.check.append("invariant")
    if "robot-invariant" in d:
        ri = _typed(d, "robot-invariant", dict, path, "a property file")
        _expect_keys(ri, {"never", "always"}, "[robot-invariant]", path)
        for key, into in (("never", spec.robot_never), ("always", spec.robot_always)):
            conds = _typed(ri, key, list, path, "[robot-invariant]") if key in ri else []
            for k, text in enumerate(conds):
                if not isinstance(text, str) or not text.strip():
                    raise RoarError(f"[robot-invariant] {key} is a list of conditions on the robot such as "
                                    "\"contact\" (docs/robot.md)", Pos(str(path), _line_of(path, key), 1))
                into.append((text, _string_pos(path, key, text)))
        if (spec.robot_never or spec.robot_always) and "robot-invariant" not in spec.check:
            spec.check.append("robot-invariant")
    if "temporal" in d:
        tm = _typed(d, "temporal", dict, path, "a property file")
        for name, text in tm.items():
            where = Pos(str(path), _line_of(path, name), 1)
            if name in PROPERTIES or not re.fullmatch(r"[a-z][a-z0-9-]*", name):
                raise RoarError(f"[temporal] '{name}': a property is named with lower-case letters, digits and '-', "
                                f"and not like a built-in property ({', '.join(PROPERTIES)})", where)
            if isinstance(text, dict):   # name = { formula = "...", fairness = "strong" }
                _expect_keys(text, {"formula", "fairness"}, f"[temporal] {name}", path)
                fairness = text.get("fairness", "weak")
                if fairness not in ("weak", "strong"):
                    raise RoarError(f"[temporal] {name}: fairness must be 'weak' (an agent enabled all along a "
                                    f"cycle moves on it) or 'strong' (an agent enabled infinitely often moves "
                                    f"infinitely often), not {fairness!r}", _value_pos(path, "fairness"))
                if fairness == "strong":
                    spec.temporal_strong.add(name)
                text = text.get("formula")
            if not isinstance(text, str) or not text.strip():
                raise RoarError(f"[temporal] {name} is a formula such as \"always P\", \"eventually P\" or "
                                f"\"P leads-to Q\" (docs/checking.md), or a table {{ formula = \"...\", "
                                f"fairness = \"strong\" }}", where)
            spec.temporal[name] = parse_formula(text, _string_pos(path, name, text))
            if name in spec.temporal_strong and spec.temporal[name].form in ("always", "state"):
                raise RoarError(f"[temporal] {name}: fairness applies to 'eventually' and 'leads-to' (it says "
                                f"which cycles count); {text!r} is decided on states alone, so fairness = "
                                f"\"strong\" would change nothing", _value_pos(path, "fairness"))
            if name not in spec.check:
                spec.check.append(name)
    if "deadlock" in d:
        dl = _typed(d, "deadlock", dict, path, "a property file")
        _expect_keys(dl, {"accept"}, "[deadlock]", path)
        if "accept" in dl:
            spec.accept = _typed(dl, "accept", str, path, "[deadlock]")
            spec.accept_at = _string_pos(path, "accept", spec.accept)
    spec.sources.append(str(path))
    return spec


def _sequence_kept(v, spec: PropertySpec, path: Path) -> None:
    """``kept = true`` (every recipe) or ``kept = ["agent.task.recipe", ...]``: an achieved
    sub-goal must still hold when a later one of its block is achieved and when its recipe ends."""
    what = ("[sequential-achievement] kept is true (every recipe), false, or a list of recipes named "
            "'agent.task.recipe' whose achieved sub-goals must not be undone")
    if isinstance(v, bool):
        if v:
            spec.sequence_kept = True
        return
    if not isinstance(v, list):
        shown = json.dumps(v) if isinstance(v, (str, int, float)) else "a table" if isinstance(v, dict) \
            else f"a {type(v).__name__}"
        raise RoarError(f"{what}, not {shown}", _value_pos(path, "kept"))
    names = []
    for r in v:
        if not isinstance(r, str) or r.count(".") != 2 or not all(r.split(".")) or "\0" in r:
            at = _string_pos(path, "kept", r) if isinstance(r, str) else _value_pos(path, "kept")
            shown = json.dumps(r) if isinstance(r, (str, int, float, bool)) else f"a {type(r).__name__}"
            raise RoarError(f"{what}, not {shown}", at)
        names.append(r)
        spec.sequence_at.setdefault(r, _string_pos(path, "kept", r))
    if spec.sequence_kept is not True:
        spec.sequence_kept = list(spec.sequence_kept or []) + [r for r in names
                                                               if r not in (spec.sequence_kept or [])]


def _incompatible_pairs(v, spec: PropertySpec, path: Path) -> None:
    """``pairs = [["gripper::grasp", "gripper::release"], ...]``: tasks the user declares must never
    be held by two live requests at once (the names are checked against the spec when it is bound)."""
    what = ("[incompatible-tasks] pairs is a list of pairs of tasks named 'agent::task', such as "
            "[[\"gripper::grasp\", \"gripper::release\"]]")
    if not isinstance(v, list) or not v:
        shown = "an empty list" if v == [] else json.dumps(v) if isinstance(v, (str, int, float, bool)) \
            else "a table" if isinstance(v, dict) else f"a {type(v).__name__}"
        raise RoarError(f"{what}, not {shown}", _value_pos(path, "pairs"))
    for pair in v:
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
            shown = json.dumps(pair) if isinstance(pair, (str, int, float, bool, list)) else "a table"
            raise RoarError(f"{what}, not {shown}", _value_pos(path, "pairs"))
        named = []
        for x in pair:
            at = _string_pos(path, "pairs", x)
            agent, sep, task = x.partition("::")
            if not sep or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", agent) or \
                    not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", task):
                raise RoarError(f"a task is named 'agent::task', not {json.dumps(x)}", at)
            named.append((x, at))
        spec.incompatible_pairs.append(tuple(named))


def _string_pos(path: Path, key: str, text: str) -> Pos:
    """Where a string value of ``key`` starts (inside its quotes), for errors inside the string."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError:
        return Pos(str(path), 1, 1)
    start = _line_of(path, key) - 1
    for n in range(start, len(lines)):
        for quote in ('"', "'"):
            col = lines[n].find(quote + text)
            if col >= 0:
                return Pos(str(path), n + 1, col + 2)
    return Pos(str(path), start + 1, 1)


def _robot_setup(d: dict, path: Path, base: Path) -> RobotSetup:
    """``robot = "scenario.toml"`` or a [robot] table (docs/robot.md, robot-backed checking)."""
    from ..robot.explore import Abstraction
    raw = d["robot"]
    where = Pos(str(path), _line_of(path, "robot"), 1)
    if isinstance(raw, str):
        raw = {"scenario": raw}
    if not isinstance(raw, dict):
        raise RoarError("'robot' is a scenario file (robot = \"scenario.toml\") or a [robot] table", where)
    _expect_keys(raw, {"scenario", "seed", "faults", "on", "quantise", "compare"}, "[robot]", path)
    if "scenario" not in raw:
        raise RoarError("[robot] needs 'scenario = \"path/to/scenario.toml\"'", where)
    setup = RobotSetup(scenario=(base / _typed(raw, "scenario", str, path, "[robot]")).resolve(), pos=where)
    if "seed" in raw:
        setup.seed = _typed(raw, "seed", int, path, "[robot]")
    if "compare" in raw:
        setup.compare = _typed(raw, "compare", bool, path, "[robot]")
    if "on" in raw:
        on = _typed(raw, "on", list, path, "[robot]")
        if not all(isinstance(x, str) for x in on):
            raise RoarError("[robot] on is a list of fault point names", _value_pos(path, "on"))
        setup.on = tuple(on)
    if "faults" in raw:
        f = raw["faults"]
        if isinstance(f, list) and all(isinstance(x, str) for x in f):
            setup.faults = {x: None for x in f}
        elif isinstance(f, dict):
            for name, prims in f.items():
                if prims == "any":
                    setup.faults[name] = None
                elif isinstance(prims, list) and prims and all(isinstance(x, str) for x in prims):
                    setup.faults[name] = frozenset(prims)
                else:
                    raise RoarError(f"[robot.faults] {name} is \"any\" or a list of the primitives at whose calls "
                                    f"it may be armed, not {prims!r}", _value_pos(path, name))
        else:
            raise RoarError("[robot] faults is a list of fault point names, or a table naming for each the "
                            "primitives at whose calls it may be armed", _value_pos(path, "faults"))
    q = raw.get("quantise", {})
    if q == "exact":
        setup.quantise = Abstraction(exact=True)
    elif isinstance(q, dict):
        _expect_keys(q, {"position", "heading", "speed", "clock", "memory"}, "[robot.quantise]", path)
        vals = {}
        for k in ("position", "heading", "speed", "clock"):
            if k in q:
                v = q[k]
                lowest = 0.0 if k == "clock" else None
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or \
                        (v < 0 if lowest == 0.0 else v <= 0):
                    raise RoarError(f"[robot.quantise] {k} must be a {'non-negative' if k == 'clock' else 'positive'} "
                                    f"number, not {_toml_value(v)}", _value_pos(path, k))
                vals[k] = float(v)
        if "memory" in q:
            vals["memory"] = _typed(q, "memory", bool, path, "[robot.quantise]")
        setup.quantise = Abstraction(**vals)
    else:
        raise RoarError("[robot] quantise is \"exact\" or a table: position (m), heading (degrees), speed (m/s), "
                        "clock (s, 0: not compared), memory (true/false)", _value_pos(path, "quantise"))
    return setup


#: the largest number of crashes a job may ask for in one run (each one multiplies the states)
MAX_CRASHES = 100


def _faults_setup(d: dict, path: Path):
    """The [faults] table (docs/checking.md): ``crash = ["agent", ...]`` names the agents that may
    crash and come back, ``max_crashes`` how many crashes a run may hold in all (default 1). The
    names are checked against the spec when it is compiled, at their place in this file."""
    from ..roar.compile import Crashes
    f = _typed(d, "faults", dict, path, "a job file")
    _expect_keys(f, {"crash", "max_crashes"}, "[faults]", path)
    names: list = []
    where: list = []
    if "crash" in f:
        raw = f["crash"]
        if not isinstance(raw, list) or not all(isinstance(x, str) and x and "\0" not in x for x in raw):
            raise RoarError("[faults] crash is a list of agent names, such as crash = [\"ptu\"]",
                            _value_pos(path, "crash"))
        for x in raw:
            if x in names:
                raise RoarError(f"[faults] crash names agent {x!r} twice", _name_pos(path, "crash", x, 2))
            names.append(x)
            where.append(_name_pos(path, "crash", x))
    bound = 1
    if "max_crashes" in f:
        v = f["max_crashes"]
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_CRASHES:
            shown = ("true" if v else "false") if isinstance(v, bool) else json.dumps(v) if isinstance(v, str) \
                else repr(v) if isinstance(v, (int, float)) else f"a {type(v).__name__}"
            raise RoarError(f"[faults] max_crashes is the number of crashes a run may hold, a whole number from 1 "
                            f"to {MAX_CRASHES}, not {shown}", _value_pos(path, "max_crashes"))
        bound = v
        if not names:
            raise RoarError("[faults] max_crashes without crash: name the agents that may crash "
                            "(crash = [\"agent\"])", _value_pos(path, "max_crashes"))
    return Crashes(tuple(names), bound, False, tuple(where)) if names else None


def _time_setup(d: dict, path: Path):
    """``time = "untimed" | "timed"``, or a ``[time]`` table: ``mode`` (default "timed") and
    ``wait_timeout`` (ms; a wait with a period gives up after that long). docs/checking.md;
    the semantics is docs/semantics.md, "Time". None when untimed."""
    from ..roar.compile import TIME_MODES, Timing
    v = d["time"]
    shown = lambda x: ("true" if x else "false") if isinstance(x, bool) else json.dumps(x) \
        if isinstance(x, str) else repr(x) if isinstance(x, (int, float)) else f"a {type(x).__name__}"
    modes = " or ".join(f'"{m}"' for m in TIME_MODES)
    timeout, tpos = None, None
    if isinstance(v, dict):
        _expect_keys(v, {"mode", "wait_timeout"}, "[time]", path)
        mode = v.get("mode", "timed")
        mpos = _value_pos(path, "mode") if "mode" in v else Pos(str(path), _line_of(path, "time"), 1)
        what = "[time] mode"
        if "wait_timeout" in v:
            timeout, tpos = v["wait_timeout"], _value_pos(path, "wait_timeout")
            if isinstance(timeout, bool) or not isinstance(timeout, int) or not 1 <= timeout <= MAX_BOUND:
                raise RoarError(f"[time] wait_timeout is a whole number of milliseconds, at least 1 (a wait with a "
                                f"period gives up after that long), not {shown(timeout)}", tpos)
    else:
        mode, mpos, what = v, _value_pos(path, "time"), "time"
    if not isinstance(mode, str) or mode not in TIME_MODES:
        raise RoarError(f"{what} is {modes} (or a [time] table), not {shown(mode)}", mpos)
    if timeout is not None and mode != "timed":
        raise RoarError("[time] wait_timeout needs mode = \"timed\": an untimed wait never times out", tpos)
    timing = Timing(mode, timeout, (mpos, tpos))
    return timing if timing else None


def _name_pos(path: Path, key: str, name: str, nth: int = 1) -> Pos:
    """Where the ``nth`` string ``"name"`` (quotes included, so that "pt" is not found in "ptu")
    of the value of ``key`` starts, inside its quotes."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError:
        return Pos(str(path), 1, 1)
    start = _line_of(path, key) - 1
    seen = 0
    for n in range(start, len(lines)):
        for m in re.finditer(r'"((?:[^"\\]|\\.)*)"|\'([^\']*)\'', lines[n]):
            if name in (m.group(1), m.group(2)):
                seen += 1
                if seen == nth:
                    return Pos(str(path), n + 1, m.start() + 2)
    return _value_pos(path, key)


def _named_file(base: Path, name: str, job: Path, key: str, what: str) -> Path:
    """The file a job names under ``key``, resolved against the job's folder; one that does not
    exist is an error at the job file's line and column that name it."""
    p = (base / name).resolve()
    if not p.exists():
        raise RoarError(f"{key} = \"{name}\": no such {what} ({p})", _string_pos(job, key, name))
    return p


def _toml_value(v) -> str:
    """A value as TOML writes it (in messages about what a file holds)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (int, float)):
        return repr(v)
    return f"a {'table' if isinstance(v, dict) else 'list' if isinstance(v, list) else type(v).__name__}"


def _in_order(errors: list[RoarError], path: Path) -> RoarError:
    """The errors found in a job file as one, the job file's first in the order of its lines."""
    flat = ErrorList(errors).errors
    flat.sort(key=lambda e: (e.pos is None or e.pos.file != str(path), e.pos.file if e.pos else "",
                             e.pos.line if e.pos else 0, e.pos.col if e.pos else 0))
    return flat[0] if len(flat) == 1 else ErrorList(flat)


def load_job(path: str | Path) -> Job:
    """A job file read and checked. The checks of its keys and tables that do not depend on each
    other all run, and their errors are reported together (:class:`ErrorList`); the checks that
    combine them run once those pass."""
    path = Path(path)
    d = _load_toml(path)
    errs: list[RoarError] = []
    with collecting(errs):
        _expect_keys(d, {"name", "model", "spec", "request", "functional", "start", "properties", "backend", "search",
                         "canonical", "reduction", "visited", "swarm", "bitstate", "bounds", "expect", "robot", "faults",
                         "time", "symmetry",
                         "cluster"},
                     "a job file", path)
    base = path.parent
    job: Optional[Job] = None
    with collecting(errs):
        if "spec" in d:
            if "model" in d:
                raise RoarError("a job names either 'model' (a .clf program) or 'spec' (a ROAR spec), not both",
                                Pos(str(path), _line_of(path, "model"), 1))
            if "request" not in d:
                raise RoarError("a job on a spec needs 'request = \"agent::var == value ...\"'",
                                Pos(str(path), _line_of(path, "spec"), 1))
            spec = _named_file(base, _typed(d, "spec", str, path, "a job file"), path, "spec", "spec")
            job = Job(path=path, name=str(d.get("name", path.stem)), model=None, spec=spec,
                      request=_typed(d, "request", str, path, "a job file"))
            job.request_at = _string_pos(path, "request", job.request)
            if "functional" in d:
                job.functional = _named_file(base, _typed(d, "functional", str, path, "a job file"), path, "functional",
                                             "functional-layer module")
            if "robot" in d:
                job.robot = _robot_setup(d, path, base)
            if "faults" in d:
                job.crashes = _faults_setup(d, path)
                if job.crashes and job.robot is not None:
                    raise RoarError("[faults] crash is for a job on the model; on the robot, faults are the "
                                    "scenario's fault points ([robot] faults)", Pos(str(path), _line_of(path, "faults"), 1))
            if "time" in d:
                job.time = _time_setup(d, path)
                if job.time and job.robot is not None:
                    raise RoarError("the timed mode is for a job on the model; on the robot, time is the robot's "
                                    "simulated time", job.time.where[0])
        else:
            if "robot" in d:
                raise RoarError("'robot' belongs to a job on a spec ('spec = ...'): the robot is the functional layer "
                                "a spec calls", Pos(str(path), _line_of(path, "robot"), 1))
            if "model" not in d:
                raise RoarError("a job needs 'model = \"path/to/model.clf\"' or 'spec = \"path/to/spec.roar\"' "
                                "with a 'request'", Pos(str(path), 1, 1))
            for k in ("request", "functional", "faults", "time"):
                if k in d:
                    raise RoarError(f"'{k}' belongs to a job on a spec ('spec = ...'), not on a .clf model",
                                    Pos(str(path), _line_of(path, k), 1))
            model = _named_file(base, _typed(d, "model", str, path, "a job file"), path, "model", "model")
            job = Job(path=path, name=str(d.get("name", path.stem)), model=model)
    if job is None:
        raise _in_order(errs, path)
    bad: set[str] = set()   # keys whose values were refused: the checks that read them are skipped
    with collecting(errs):
        if "start" in d:
            job.start = _typed(d, "start", int, path, "a job file")
            job.start_at = Pos(str(path), _line_of(path, "start"), 1)
            if job.start < 1:
                raise RoarError("'start' counts #exec and #trace directives from 1", Pos(str(path), _line_of(path, "start"), 1))
    with collecting(errs):
        bad.add("properties")
        props = d.get("properties", [])
        if isinstance(props, str):
            props = [props]
        if not isinstance(props, list):
            raise RoarError("'properties' must be a path or a list of paths", Pos(str(path), _line_of(path, "properties"), 1))
        for p in props:
            if not isinstance(p, str) or "\0" in p:
                raise RoarError(f"'properties' must be a path or a list of paths, not a list holding {p!r}"[:300],
                                Pos(str(path), _line_of(path, "properties"), 1))
            _named_file(base, p, path, "properties", "property file")
            # (read as the job names it: its errors then point at the file as the job's do, relative
            # when the job was named relative)
            load_properties(Path(os.path.normpath(base / p)), job.props)
        bad.discard("properties")
    for key, allowed in (("backend", ("auto", "ground", "general")), ("search", ("bfs", "dfs", "swarm", "distributed")),
                         ("visited", ("exact", "hash", "bitstate"))):
        with collecting(errs):
            if key in d:
                bad.add(key)
                v = _typed(d, key, str, path, "a job file")
                if v not in allowed:
                    raise RoarError(f"'{key}' must be one of {', '.join(allowed)}, not '{v}'",
                                    Pos(str(path), _line_of(path, key), 1))
                setattr(job, key, v)
                if key == "backend":
                    job.backend_at = _value_pos(path, key)
                bad.discard(key)
    with collecting(errs):
        if job.backend == "ground" and "spec" in d:
            raise RoarError("backend = \"ground\" runs plain CLF models (model = FILE.clf) that make no fresh names; "
                            "a compiled spec makes them (its requests, activations and calls), so a spec job runs on "
                            "the general backend: drop the line (or write \"auto\")", _value_pos(path, "backend"))
    with collecting(errs):
        if job.visited in ("hash", "bitstate") and job.backend == "ground":
            raise RoarError(f"visited = \"{job.visited}\" is a mode of the general backend (the ground backend keeps "
                            "its states compact and exact already): drop one of them",
                            Pos(str(path), _line_of(path, "visited"), 1))
    with collecting(errs):
        if "bitstate" in d:
            bt = _typed(d, "bitstate", dict, path, "a job file")
            _expect_keys(bt, {"bits"}, "[bitstate]", path)
            if job.visited != "bitstate" and "visited" not in bad:
                raise RoarError("a [bitstate] table needs visited = \"bitstate\"", Pos(str(path), _line_of(path, "bitstate"), 1))
            if "bits" in bt:
                v = bt["bits"]
                if isinstance(v, bool) or not isinstance(v, int) or not 1024 <= v <= 1 << 40:
                    raise RoarError(f"[bitstate] bits is the size of the bit array, a whole number from 1,024 to 2^40, "
                                    f"not {_toml_value(v)}"[:300], _value_pos(path, "bits"))
                job.bits = v
    with collecting(errs):
        if "swarm" in d:
            sw = _typed(d, "swarm", dict, path, "a job file")
            _expect_keys(sw, {"runs", "max_states"}, "[swarm]", path)
            if job.search != "swarm" and "search" not in bad:
                raise RoarError("a [swarm] table needs search = \"swarm\"", Pos(str(path), _line_of(path, "swarm"), 1))
            for key, attr in (("runs", "swarm_runs"), ("max_states", "swarm_states")):
                if key in sw:
                    v = sw[key]
                    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                        raise RoarError(f"[swarm] {key} must be a whole number, at least 1, not {_toml_value(v)}"[:300],
                                        _value_pos(path, key))
                    setattr(job, attr, v)
    with collecting(errs):
        if ("cluster" in d or job.search == "distributed") and "search" not in bad:
            job.cluster = _cluster_setup(d, path, job)
    with collecting(errs):
        if "canonical" in d:
            job.canonical = _typed(d, "canonical", bool, path, "a job file")
    with collecting(errs):
        if "reduction" in d:
            job.reduction = _typed(d, "reduction", bool, path, "a job file")
    with collecting(errs):
        if "symmetry" in d:
            v = d["symmetry"]
            if not isinstance(v, bool):
                raise RoarError(f"'symmetry' in a job file must be true or false, not {_toml_value(v)}"[:300],
                                _value_pos(path, "symmetry"))
            job.symmetry = v
            job.symmetry_at = _value_pos(path, "symmetry") if v else None
    with collecting(errs):
        if "bounds" in d:
            b = _typed(d, "bounds", dict, path, "a job file")
            with collecting(errs):
                _expect_keys(b, set(BOUND_KEYS), "[bounds]", path)
            got = {}
            for key, what, least, integer in (
                    ("max_states", "a whole number of states, at least 1", 1, True),
                    ("max_seconds", "a number of seconds above 0", 0, False),
                    ("max_memory_mb", f"a whole number of MiB, at least {MIN_MEMORY_MB}", MIN_MEMORY_MB, True)):
                with collecting(errs):
                    got[key] = _bound(b, key, path, what, least, integer=integer)
            if len(got) == 3:
                job.budget = Budget(**got)
    from_expect: dict[str, Pos] = {}   # properties only [expect] names -> its line (errors point there)

    def at(prop: str, what: str) -> tuple[str, Pos]:
        """An error about ``prop``: at the [expect] line that alone asks for it, else the job's start."""
        if prop in from_expect:
            return (f"[expect] {prop}: the job's properties do not check it, and [expect] adds it; {what}",
                    from_expect[prop])
        return what, Pos(str(path), 1, 1)
    with collecting(errs):
        if "expect" in d:
            e = _typed(d, "expect", dict, path, "a job file")
            if "properties" not in bad:   # (a property file that failed defines no names to expect)
                with collecting(errs):
                    _expect_keys(e, set(PROPERTIES) | set(job.props.temporal), "[expect]", path)
            for k, v in e.items():
                if v not in STATUSES:
                    errs.append(RoarError(f"expected verdict of '{k}' must be 'holds' or 'violated', not "
                                          f"{_toml_value(v)}",
                                          Pos(str(path), _line_of(path, k), 1)))
                    continue
                job.expect[k] = v
                if k not in job.props.check:
                    job.props.check.append(k)
                    from_expect[k] = Pos(str(path), _line_of(path, k), 1)
    if errs:
        raise _in_order(errs, path)
    if job.is_roar and not job.props.check:   # nothing names a property: the defaults of a spec
        job.props.check = list(SPEC_DEFAULTS)
        job.props.defaulted = True
    if not job.is_roar and job.props.spec_terms:
        f = (job.props.spec_never + job.props.spec_always + job.props.spec_progress +
             list(job.props.temporal.values()))[0]
        raise RoarError(f"property {f.text!r} is written in the spec's terms: it needs a job on a spec "
                        "('spec = ...'); on a .clf model write CLF patterns ([invariant] never) and rule names "
                        "([livelock] progress)", f.pos or Pos(str(path), 1, 1))
    if not job.is_roar:
        for p in job.props.check:
            if p in ROAR_PROPERTIES:
                raise RoarError(*at(p, f"property '{p}' reads ROAR events: it needs a job on a spec ('spec = ...')"))
    if "robot-invariant" in job.props.check and job.robot is None:
        raise RoarError(*at("robot-invariant", "property 'robot-invariant' reads the robot's state: it needs a "
                                               "robot-backed job ('robot = \"scenario.toml\"')"))
    if "robot-invariant" in job.props.check and not (job.props.robot_never or job.props.robot_always):
        raise RoarError(*at("robot-invariant", "property 'robot-invariant' needs conditions: [robot-invariant] "
                                               "never = [\"...\"] or always = [\"...\"] in a property file"))
    if "invariant" in job.props.check and not (job.props.never or job.props.spec_never or job.props.spec_always):
        raise RoarError(*at("invariant", "property 'invariant' needs patterns: [invariant] never = [\"...\"] in a "
                                         "property file (on a spec, predicates in the spec's terms: never = "
                                         "[\"...\"] or always = [\"...\"])"))
    if "livelock" in job.props.check and not job.is_roar and not job.props.progress:
        raise RoarError(*at("livelock", "property 'livelock' on a .clf model needs its progress rules: [livelock] "
                                        "progress = [\"rule\", ...] in a property file (without them every cycle "
                                        "is a livelock)"))
    if not job.props.check:
        raise RoarError("the job checks nothing: name properties in 'check' of a property file or in [expect]",
                        Pos(str(path), 1, 1))
    if job.cluster is not None:   # search = "distributed", or a swarm on a cluster
        for bad, why in ((job.robot is not None, "robot-backed jobs (their states pair a model state with the robot's)"),
                         (job.reduction, "partial-order reduction (its cycle proviso reads the whole visited set)"),
                         (job.backend == "ground", "the ground backend (it searches in one process)")):
            if bad:
                what = "search = \"distributed\"" if job.search == "distributed" else "a swarm on a cluster"
                raise RoarError(f"{what} is not available for {why}", Pos(str(path), _line_of(path, "search"), 1))
    if job.search == "swarm" and job.robot is not None:
        raise RoarError("search = \"swarm\" is not available for robot-backed jobs: use bfs or dfs",
                        Pos(str(path), _line_of(path, "search"), 1))
    if job.visited in ("hash", "bitstate") and job.robot is not None:
        raise RoarError(f"visited = \"{job.visited}\" is not available for robot-backed jobs (their states pair a "
                        "model state with the robot's): remove it", Pos(str(path), _line_of(path, "visited"), 1))
    if job.visited == "bitstate":
        _bitstate_refusals(job, path)
    if job.symmetry:
        symmetry_refusals(job)
    return job


#: properties symmetry reduction does not decide: they read cycles, where weak fairness per
#: process is judged on the quotient's edges, whose processes are renamed from state to state
SYMMETRY_CYCLE_PROPERTIES = ("livelock", "mission-completion")


def symmetry_refusals(job: Job) -> None:
    """What symmetry reduction cannot do, refused before the search (at the job file's
    ``symmetry`` line, or naming --symmetry): properties read on cycles (livelock, fair cycles),
    and the modes it is not combined with. Properties that name one of the agents
    it permutes are refused once the symmetries are known (verify/check.py)."""
    where = job.symmetry_at
    opt = "symmetry = true" if where is not None else "--symmetry"
    cycles = [p for p in job.props.check if p in SYMMETRY_CYCLE_PROPERTIES]
    cycles += [n for n, f in job.props.temporal.items() if n in job.props.check and f.form in ("eventually", "leads-to")]
    if cycles:
        extra = (" (a default property of a spec: name the properties to check, e.g. --property "
                 "deadlock,mission-failure or [expect] deadlock)") if job.props.defaulted else ""
        raise RoarError(f"{opt}: {', '.join(cycles)} read{'s' if len(cycles) == 1 else ''} the cycles of the state "
                        f"graph under weak fairness per process, which symmetry reduction does not keep (a cycle of "
                        f"the quotient renames the processes from state to state){extra}: check "
                        f"{'it' if len(cycles) == 1 else 'them'} without symmetry", where)
    for bad, why in ((job.reduction, "partial-order reduction"),
                     (not job.canonical, "canonical = false (its least key over a state's images is read on "
                                         "canonical keys)"),
                     (job.robot is not None, "robot-backed jobs"),
                     (job.backend == "ground", "the ground backend (symmetry reduction runs on the general one)"),
                     (job.search in ("swarm", "distributed"), f"search = \"{job.search}\""),
                     ("sequential-achievement" in job.props.check,
                      "sequential-achievement (its monitor names statement sites of particular agents)")):
        if bad:
            raise RoarError(f"{opt} is not available with {why}", where)


def cycle_properties(job: Job) -> list[str]:
    """The properties of the job read on the cycles of the state graph (fair cycles)."""
    cycles = [p for p in job.props.check if p in ("livelock", "mission-completion")]
    return cycles + [n for n, f in job.props.temporal.items()
                     if n in job.props.check and f.form in ("eventually", "leads-to")]


def _bitstate_refusals(job: Job, path: Optional[Path], cli: bool = False) -> None:
    """What a bitstate search cannot decide: it keeps the discovery tree and counts the other
    transitions without their targets, so properties read on cycles or on every step are out.
    ``cli``: asked for by --visited (the errors name the options, not a job file's lines)."""
    where = None if cli or path is None else Pos(str(path), _line_of(path, "visited"), 1)
    mode, hash_mode = ("--visited bitstate", "--visited hash") if cli else ('visited = "bitstate"', 'visited = "hash"')
    cycles = cycle_properties(job)
    if cycles:
        extra = ((" (a default property of a spec: name the properties to check, e.g. --property "
                  "deadlock,mission-failure)") if cli else
                 " (a default property of a spec: name the properties to check, e.g. [expect] deadlock)") \
            if job.props.defaulted else ""
        raise RoarError(f"{mode} decides properties read on states; {', '.join(cycles)} "
                        f"need{'s' if len(cycles) == 1 else ''} the cycles of the graph, which a bitstate search "
                        f"does not record{extra}: use {hash_mode}", where)
    if any(f.events for f in job.props.spec_never):
        raise RoarError(f"{mode} does not record every step, so invariants over events "
                        f"(primitive ... starts, constraint sent to ...) cannot be checked: use {hash_mode}",
                        where)
    for bad, why in ((job.reduction, "partial-order reduction (its cycle proviso reads the visited set)"),
                     (job.search in ("swarm", "distributed"), f"search = \"{job.search}\"")):
        if bad:
            raise RoarError(f"{mode} is not available with {why}", where)


def apply_search_options(job: Job, search: Optional[str], visited: Optional[str]) -> None:
    """``check --search`` / ``--visited``: a job's search and visited set from the command line
    (every job named), refused as a job file's would be, the errors naming the options."""
    if search is not None:
        if search not in ("bfs", "dfs", "swarm"):
            raise RoarError(f"--search {search}: expected bfs, dfs or swarm (a distributed search needs a job file "
                            "with search = \"distributed\" and its [cluster] table)")
        if search == "swarm" and job.robot is not None:
            raise RoarError(f"--search swarm: {job.name} is robot-backed, and a swarm is not available for "
                            "robot-backed jobs")
        if search in ("bfs", "dfs"):
            job.cluster = None   # a job file's cluster served its distributed search or its swarm
        job.search = search
    if visited is not None:
        if visited not in ("exact", "hash", "bitstate"):
            raise RoarError(f"--visited {visited}: expected exact, hash or bitstate")
        if visited != "exact":
            if job.backend == "ground":
                raise RoarError(f"--visited {visited}: {job.name} asks for the ground backend, which keeps its "
                                "states compact and exact already")
            if job.robot is not None:
                raise RoarError(f"--visited {visited}: {job.name} is robot-backed (its states pair a model state "
                                "with the robot's)")
        job.visited = visited
    if job.visited == "bitstate" and (visited is not None or search is not None):
        _bitstate_refusals(job, None, cli=True)


#: a scheduler address: scheme://host:port
ADDRESS = re.compile(r"(tcp|tls|ws|wss|ucx|inproc)://[^\s/:]+(:\d{1,5})?")
#: the most local worker processes a job may ask for
MAX_WORKERS = 256


@dataclass
class ClusterSetup:
    """A job's [cluster] table."""

    workers: int = 2                    # a local cluster of this many worker processes
    address: Optional[str] = None       # or a running cluster's scheduler
    batch: int = 1_000                  # frontier states each worker expands per exchange
    connect_seconds: float = 30.0       # how long to wait for the scheduler and its first worker
    pos: Optional[Pos] = None           # where the table (or the search key) is, for errors at run time
    address_pos: Optional[Pos] = None

    def describe(self, n: int) -> str:
        return f"{n} worker{'s' if n != 1 else ''}" + (f" at {self.address}" if self.address else "")



def _cluster_setup(d: dict, path: Path, job: Job):
    """The [cluster] table (docs/checking.md, "Running on a cluster"): ``workers = N`` (a local
    cluster of N processes, default 2) or ``address = "tcp://host:port"`` (a running scheduler),
    and ``batch`` (frontier states each worker expands per exchange)."""
    where = Pos(str(path), _line_of(path, "cluster" if "cluster" in d else "search"), 1)
    setup = ClusterSetup(pos=where)
    if "cluster" not in d:
        return setup
    c = _typed(d, "cluster", dict, path, "a job file")
    _expect_keys(c, {"workers", "address", "batch", "connect_seconds"}, "[cluster]", path)
    if job.search not in ("distributed", "swarm"):
        raise RoarError("a [cluster] table needs search = \"distributed\" (or \"swarm\": its searches run as "
                        "tasks on the cluster)", where)
    if "workers" in c and "address" in c:
        raise RoarError("[cluster] names either workers (a local cluster started for the job) or address (a "
                        "running cluster), not both", _value_pos(path, "address"))

    def shown(v) -> str:
        return ("true" if v else "false") if isinstance(v, bool) else json.dumps(v) if isinstance(v, str) \
            else repr(v) if isinstance(v, (int, float)) else f"a {type(v).__name__}"

    for key, low, high, what in (("workers", 1, MAX_WORKERS, "worker processes"),
                                 ("batch", 1, MAX_BOUND, "frontier states each worker expands per exchange")):
        if key in c:
            v = c[key]
            if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= high:
                raise RoarError(f"[cluster] {key} is the number of {what}, a whole number from {low} to "
                                f"{high:,}, not {shown(v)}"[:300], _value_pos(path, key))
            setattr(setup, key, v)
    if "connect_seconds" in c:
        v = c["connect_seconds"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= 3600:
            raise RoarError(f"[cluster] connect_seconds is how long to wait for the scheduler, a number of seconds "
                            f"above 0 and at most 3600, not {shown(v)}"[:300], _value_pos(path, "connect_seconds"))
        setup.connect_seconds = float(v)
    if "address" in c:
        v = c["address"]
        setup.address_pos = _value_pos(path, "address")
        if not isinstance(v, str) or not ADDRESS.fullmatch(v):
            raise RoarError(f"[cluster] address is a Dask scheduler's address such as \"tcp://10.0.0.5:8786\", "
                            f"not {shown(v)}"[:300], setup.address_pos)
        setup.address = v
    return setup


def is_model_path(p: Path) -> bool:
    """Is ``p`` a model or spec to check directly (not a job file or a folder of them)?"""
    p = Path(p)
    if p.is_dir():
        return any(p.glob("*.ability")) and not any(p.glob("*.toml"))
    return p.suffix in (".clf", ".roar", ".ability")


#: the time bound of a check of a model or spec named on the command line, with no job file
COMMAND_LINE_SECONDS = 600.0


def job_for_model(path: Path, request: Optional[str] = None, properties: Optional[list[str]] = None,
                  property_files: Sequence[str | Path] = ()) -> Job:
    """A job without a job file: ``check MODEL.clf`` or ``check SPEC --request ...`` with the
    properties named (``properties``), else those the ``property_files`` check, else the
    defaults (deadlock; for a spec, deadlock, mission-completion and mission-failure), and no
    expectation (so any violation is an error). The property files say how to check what they
    name (livelock progress, invariants, temporal formulas), as a job file's would."""
    path = Path(path)
    spec = path.suffix != ".clf"
    if spec and not request:
        raise RoarError(f"{path}: checking a spec needs the request to enforce: --request "
                        f"'agent::var == value [where ...]'")
    if not spec and request:
        raise RoarError(f"{path}: --request is for a ROAR spec, not a .clf program")
    if not path.exists():
        raise RoarError(f"{path}: no such file or folder")
    given = PropertySpec()
    for f in property_files:
        f = Path(f)
        if not f.is_file():
            raise RoarError(f"--properties {f}: no such file")
        load_properties(f, given)
    if not spec and given.spec_terms:
        f = (given.spec_never + given.spec_always + given.spec_progress + list(given.temporal.values()))[0]
        raise RoarError(f"property {f.text!r} is written in the spec's terms: it needs a ROAR spec; on a .clf "
                        "model write CLF patterns ([invariant] never) and rule names ([livelock] progress)",
                        f.pos)
    wanted = properties or given.check or (list(SPEC_DEFAULTS) if spec else ["deadlock"])
    allowed = (PROPERTIES if spec else tuple(p for p in PROPERTIES if p not in ROAR_PROPERTIES)) + tuple(given.temporal)
    where = "--property" if properties else "--properties"
    for p in wanted:
        if p not in allowed:
            raise RoarError(f"{where} {p}{did_you_mean(p, allowed)}: expected one of {', '.join(allowed)}"
                            + ("" if spec else " (the others read ROAR events: check a spec)"))
        if p == "robot-invariant":
            raise RoarError(f"{where} robot-invariant needs a scenario and its conditions: write them in a "
                            "robot-backed job (docs/robot.md)")
        if p == "invariant" and not (given.never or given.spec_never or given.spec_always):
            raise RoarError(f"{where} invariant needs its patterns: [invariant] never = [\"...\"] (or, on a "
                            "spec, always = [\"...\"]) in a property file, named with --properties FILE "
                            "(docs/checking.md)")
        if p == "livelock" and not spec and not given.progress:
            raise RoarError(f"{where} livelock on a .clf program needs its progress rules: [livelock] progress "
                            "= [\"rule\"] in a property file, named with --properties FILE (docs/checking.md)")
    job = Job(path=path, name=path.stem if path.suffix else path.name, model=None if spec else path.resolve())
    # no job file gives a bound: a default one, so that a large state space ends with "incomplete"
    # and the budget named instead of running for hours (--max-states, --max-seconds override it)
    job.budget.max_seconds = COMMAND_LINE_SECONDS
    if spec:
        job.spec = path.resolve()
        job.request = request
        job.request_at = Pos("--request", 1, 1)
    given.check = list(dict.fromkeys(wanted))
    given.sources = [str(f) for f in property_files] + ["command line"]
    given.defaulted = not properties and not property_files
    job.props = given
    return job


def find_jobs(paths: list[str | Path]) -> list[Path]:
    """Job files named directly or found (``*.toml``) in the given folders, sorted."""
    out: list[Path] = []
    for p in paths:
        p = Path(p)
        if p.is_dir():
            out += sorted(q for q in p.glob("*.toml"))
        elif p.exists():
            out.append(p)
        else:
            raise RoarError(f"no such job file or folder: {p}")
    if not out:
        raise RoarError("no job files (*.toml) found in " + ", ".join(str(p) for p in paths))
    return out
