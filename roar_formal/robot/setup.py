"""Everything a robot run needs, from what a user names: spec, request, scenario, faults."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from ..errors import RoarError, did_you_mean
from ..roar.compile import compile_spec
from ..roar.spec import load_spec
from ..roar.run import parse_fault
from .binding import load_robot_binding
from .scenario import load_scenario

__all__ = ["split_faults", "prepare"]


def split_faults(names: list[str], scenario, model=None) -> tuple[list[str], list]:
    """``--fault`` values: scenario fault points (``door_closes``) and primitive faults (``compute_path:1``)."""
    world, prims = [], []
    known = set(scenario.fault_names())
    functions = set()
    if model is not None:
        for owner, name in model.functions.values():
            functions |= {name, f"{owner}::{name}"} if owner else {name}
    for n in names:
        if n in known:
            world.append(n)
            continue
        try:
            f = parse_fault(n)
        except RoarError:
            f = None
        if f is None or (model is not None and f.name not in functions):
            name = f.name if f is not None else n
            hint = did_you_mean(name, sorted(known | functions))
            raise RoarError(f"--fault {n!r}{hint}: not a fault point of scenario '{scenario.name}' "
                            f"({', '.join(sorted(known)) or 'it has none'}) nor a primitive fault "
                            f"(NAME, NAME:K or NAME=OUTCOME, NAME a function the spec calls)")
        prims.append(f)
    return world, prims


def prepare(spec: Path, request: str, scenario: Path, functional: Optional[Path] = None):
    """(spec AST, compiled model in run mode, robot binding, scenario): everything a robot run needs."""
    sc = load_scenario(scenario)
    spec_ast = load_spec(spec)
    binding = load_robot_binding(spec, functional)
    model = compile_spec(spec_ast, request, registry=binding.robot, functional="python")
    return spec_ast, model, binding, sc
