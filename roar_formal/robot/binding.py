"""Binding a spec's primitives to the robot: the functional-layer module's ``robot_registry()``.

A spec's functional-layer module (``SPEC.py`` next to a ``.roar`` file)
defines ``registry()``, the abstract binding that the explorer's outcomes
come from, and, to run on the reference robot, ``robot_registry()``: the same
primitive names with the same declared outcomes, whose callables return
robot activities. The outcomes must agree: the explorer branches on the
abstract registry's outcomes, and robot results are classified into the robot
registry's, so a difference would compare two different abstractions.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ..errors import RoarError
from ..roar.functional import Registry, find_module, import_module, module_candidates

__all__ = ["RobotBinding", "load_robot_binding", "functional_module_of"]


@dataclass
class RobotBinding:
    path: Path
    abstract: Optional[Registry]    # registry(), when the module has one
    robot: Registry                 # robot_registry()


def functional_module_of(spec: Path, given: Optional[Path] = None) -> Path:
    """``--functional FILE``, else the module next to the spec (roar.functional.find_module); an error if none."""
    found = find_module(spec, given)
    if found is None:
        looked = ", ".join(str(c) for c in module_candidates(spec))
        raise RoarError(f"{spec}: no functional-layer module found (looked for {looked}); pass --functional FILE")
    return found


def load_robot_binding(spec: Path, given: Optional[Path] = None) -> RobotBinding:
    """Import the spec's functional-layer module (the user named the spec: this is the one code we run)."""
    path = functional_module_of(spec, given)
    mod = import_module(path)
    make_robot = getattr(mod, "robot_registry", None)
    if not callable(make_robot):
        raise RoarError(f"{path}: defines no robot_registry(): the spec's primitives are not bound to the robot "
                        f"(see docs/robot.md, 'Binding a spec to the robot')")
    robot = _call(path, make_robot, "robot_registry")
    abstract = _call(path, mod.registry, "registry") if callable(getattr(mod, "registry", None)) else None
    if abstract is not None:
        _same_outcomes(path, abstract, robot)
    return RobotBinding(path, abstract, robot)


def _call(path: Path, fn, what: str) -> Registry:
    try:
        reg = fn()
    except RoarError:
        raise
    except Exception as exc:
        raise RoarError(f"{path}: {what}() failed: {type(exc).__name__}: {exc}") from None
    if not isinstance(reg, Registry):
        raise RoarError(f"{path}: {what}() must return a roar_formal.roar.functional.Registry")
    return reg


def _same_outcomes(path: Path, abstract: Registry, robot: Registry) -> None:
    problems = []
    for name in robot.names():
        if name == "now":
            continue
        a = abstract.get(name)
        r = robot[name]
        if a is None:
            problems.append(f"'{name}' is bound to the robot but not in registry()")
        elif [(o.name, o.success) for o in a.outcomes] != [(o.name, o.success) for o in r.outcomes]:
            problems.append(f"'{name}': registry() declares outcomes "
                            f"{', '.join(o.name for o in a.outcomes)} but robot_registry() declares "
                            f"{', '.join(o.name for o in r.outcomes)}")
    if problems:
        raise RoarError(f"{path}: the robot binding and the abstract registry disagree", None, problems)
