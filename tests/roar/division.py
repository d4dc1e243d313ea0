"""What the division-by-zero tests share (test_division_decisions.py, test_division_more.py):
a case is (spec file in data/, request, the run's error context, the edits that make its twin
with a non-zero divisor, the twin's final values). Each case is checked three ways: the run ends
with the located division, the explorer finds the failure and no deadlock, and the twin
behaves as before (run and explorer)."""

from __future__ import annotations

from pathlib import Path

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.functional import load_registry
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from roar_formal.testing import load

DATA = Path(__file__).parent / "data"


def run_spec(path: Path, request: str, seed: int = 0):
    """A run with the spec's Python functional layer (its .py next to it), if it has one."""
    py = path.with_suffix(".py")
    reg = (lambda: load_registry(py)) if py.exists() else (lambda: None)
    model = compile_spec(load_spec(path), request, registry=reg(), functional="python")
    return run_model(model, seed=seed, max_steps=500, registry=reg())


def twin(name: str, edits, tmp_path: Path) -> Path:
    """The spec ``name`` with ``edits`` (old, new) made, written with its functional layer."""
    text = (DATA / name).read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    out = tmp_path / name
    out.write_text(text)
    py = (DATA / name).with_suffix(".py")
    if py.exists():
        (tmp_path / py.name).write_text(py.read_text())
    return out


def check_run(case) -> None:
    name, request, ec, _edits, _values = case
    res = run_spec(DATA / name, request)
    assert res.quiescent and res.outcome == "failure"
    assert res.error_context == ec


def check_explorer(case) -> None:
    name, request, _ec, _edits, _values = case
    ex = load(DATA / name).explore(request, properties=["deadlock", "mission-failure"])
    assert ex.verdicts["deadlock"].status == "holds"            # a rule that never fired: a deadlock
    assert ex.verdicts["mission-failure"].status == "violated"  # the located failure


def check_twin(case, tmp_path: Path) -> None:
    name, request, _ec, edits, values = case
    path = twin(name, edits, tmp_path)
    res = run_spec(path, request)
    assert res.outcome == "success" and res.error_context == []
    assert {k: res.final[k] for k in values} == values
    ex = load(path).explore(request, properties=["deadlock", "mission-failure"])
    assert ex.verdicts["deadlock"].status == "holds"
    assert ex.verdicts["mission-failure"].status == "holds"
