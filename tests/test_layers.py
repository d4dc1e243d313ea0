"""The package's layers point one way (docs/architecture.md).

Every import in ``roar_formal`` (at module level or inside a function) goes to
its own package or to one below it, in this order:

    errors, lines  <  inputs  <  clf  <  trace  <  tca, explore  <  roar  <  robot
        <  verify  <  testing  <  cli  <  fuzz

``errors`` and ``lines``, and ``tca`` and ``explore``, share a level and do not import each other; only
``cli`` imports typer and rich; no module imports a private name (``_x``) of
another module. The graph is read from the source with ``ast``, so an import
hidden in a function counts as much as one at the top.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "roar_formal"

RANK = {"errors": 0, "lines": 0, "inputs": 1, "outputs": 1, "clf": 2, "trace": 3, "tca": 4, "explore": 4, "roar": 5,
        "robot": 6, "verify": 7, "testing": 8, "cli": 9, "fuzz": 10}
TERMINAL = ("typer", "rich", "click")


def _unit(parts: tuple[str, ...]) -> str:
    """The layer unit of a module path inside roar_formal: its package, or its own name at the top."""
    return parts[0].removesuffix(".py")


def _imports():
    """(file, line, importing unit, imported module (absolute), names) for every import of the package."""
    for f in sorted(ROOT.rglob("*.py")):
        rel = f.relative_to(ROOT).parts
        if rel in (("__init__.py",), ("__main__.py",)):   # the package's front door re-exports the API
            continue
        unit = _unit(rel)
        pkg = ["roar_formal", *rel[:-1]]
        tree = ast.parse(f.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg[: len(pkg) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                yield f, node.lineno, unit, target, [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                for a in node.names:
                    yield f, node.lineno, unit, a.name, []


IMPORTS = list(_imports())


def test_the_graph_is_read():
    """The test sees the package's imports (an empty graph would pass everything)."""
    units = {u for _f, _l, u, _t, _n in IMPORTS}
    assert units >= set(RANK) - {"errors", "lines"}
    assert sum(1 for _f, _l, _u, t, _n in IMPORTS if t.startswith("roar_formal.")) > 300


def test_every_unit_has_a_layer():
    units = {_unit(f.relative_to(ROOT).parts) for f in ROOT.rglob("*.py")} - {"__init__", "__main__"}
    assert units <= set(RANK), f"give these a layer in RANK and docs/architecture.md: {units - set(RANK)}"


def test_no_package_imports_one_above_it():
    bad = []
    for f, line, unit, target, names in IMPORTS:
        if not target.startswith("roar_formal."):
            continue
        parts = target.split(".")[1:]
        # `from roar_formal import lines` names a unit in `names`
        dest = parts[0] if parts else None
        dests = [dest] if dest else [n for n in names]
        for d in dests:
            if d == unit or d not in RANK:
                continue
            if RANK[d] >= RANK[unit]:
                bad.append(f"{f.relative_to(ROOT.parent)}:{line}: {unit} imports {target or d} ({d} is "
                           f"{'above' if RANK[d] > RANK[unit] else 'beside'} {unit})")
    assert not bad, "\n".join(bad)


def test_only_the_command_line_imports_terminal_libraries():
    bad = [f"{f.relative_to(ROOT.parent)}:{line}: {target}" for f, line, unit, target, _n in IMPORTS
           if target.split(".")[0] in TERMINAL and unit != "cli"]
    assert not bad, "\n".join(bad)


def test_no_module_imports_a_private_name_of_another():
    bad = []
    for f, line, _unit, target, names in IMPORTS:
        if not target.startswith("roar_formal"):
            continue
        for n in names:
            if n.startswith("_") and not n.startswith("__"):
                bad.append(f"{f.relative_to(ROOT.parent)}:{line}: imports {n} from {target}")
        if any(p.startswith("_") and not p.startswith("__") for p in target.split(".")):
            bad.append(f"{f.relative_to(ROOT.parent)}:{line}: imports the private module {target}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("source, expected", [
    ("from ..cli import main\n", "above"),
    ("from ..tca.check import check_trace\n", "beside"),
])
def test_the_checker_sees_a_bad_import(tmp_path, monkeypatch, source, expected):
    """The check itself can fail: an upward and a sideways import planted in a copy are reported."""
    fake = tmp_path / "roar_formal" / "explore"
    fake.mkdir(parents=True)
    (fake / "planted.py").write_text(source)
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path / "roar_formal")
    planted = list(_imports())
    monkeypatch.setattr(sys.modules[__name__], "IMPORTS", planted)
    with pytest.raises(AssertionError, match=expected):
        test_no_package_imports_one_above_it()


def test_the_front_ends_meet_the_explorer_through_its_protocol():
    """The explorer knows models only as `TransitionSystem`s; every front end's system is one."""
    import inspect

    from roar_formal.explore.system import ClfSystem, TransitionSystem
    from roar_formal.roar.explore import RoarSystem
    from roar_formal.robot.explore import RobotSystem
    wanted = [n for n, v in vars(TransitionSystem).items() if inspect.isfunction(v) and not n.startswith("_")]
    assert set(wanted) == {"initial", "key", "successors", "reduced_successors", "describe", "describe_step"}
    for cls in (ClfSystem, RoarSystem, RobotSystem):
        assert [n for n in wanted if not callable(getattr(cls, n, None))] == [], cls.__name__


def _module_graph():
    """Module -> the package's modules it imports (at the top or in a function), by dotted name."""
    import networkx as nx
    modules = {}
    for f in ROOT.rglob("*.py"):
        name = ".".join(("roar_formal", *f.relative_to(ROOT).with_suffix("").parts))
        modules[name.removesuffix(".__init__")] = f
    g = nx.DiGraph()
    for f, _line, _unit, target, names in IMPORTS:
        src = ".".join(("roar_formal", *f.relative_to(ROOT).with_suffix("").parts)).removesuffix(".__init__")
        for dest in [target, *(f"{target}.{n}" for n in names)]:
            if dest in modules and dest != src and not modules[dest].name == "__init__.py":
                g.add_edge(src, dest)
    return g


def test_no_module_imports_one_that_imports_it_back():
    """Within a package too, imports point one way: an import hidden in a function does not make a
    cycle of modules acceptable (the verify runners and the engine's matcher had some)."""
    import networkx as nx
    g = _module_graph()
    assert g.number_of_edges() > 300
    cycles = sorted(nx.simple_cycles(g), key=len)
    assert not cycles, "\n".join(" -> ".join(c + [c[0]]) for c in cycles[:10])


def test_the_cycle_check_sees_a_cycle():
    import networkx as nx
    g = _module_graph()
    g.add_edge("roar_formal.clf.terms", "roar_formal.clf.printer")   # the import terms.py used to make
    assert list(nx.simple_cycles(g))
