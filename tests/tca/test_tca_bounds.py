"""Bounded resources in the TCA commands: the difference-constraint solver behind
``tca-check`` (linear memory on a 4,000-message trace), numbers a trace may hold,
``tca-simulate --size`` and the unrolled tree's size, and an atomic ``--out``."""

from __future__ import annotations

import os
import random
import subprocess
import sys
from fractions import Fraction

import pytest
import typer
import z3
from typer.testing import CliRunner

from roar_formal.errors import RoarError
from roar_formal.tca.check import MAX_CORES, check_trace
from roar_formal.cli.tca import MAX_SIZE, register
from roar_formal.tca.difference import Atom, DifferenceSystem, NotDifference, ZERO, atoms
from roar_formal.tca.model import load_model
from roar_formal.tca.trace_events import parse_events
from roar_formal.tca.unroll import MAX_MESSAGES, unroll

from repo import ROOT
from trace_shapes import deep_chain
AMBLER = ROOT / "models" / "ambler" / "ambler.toml"


@pytest.fixture(scope="module")
def app():
    app = typer.Typer()
    register(app)

    @app.callback()
    def root() -> None:
        """Test app."""

    return app


def run(app, *args):
    return CliRunner().invoke(app, list(map(str, args)), terminal_width=200)


# ------------------------------------------------------------------ the difference solver


def test_atoms_of_the_residual_shapes():
    x, y = z3.Reals("x y")
    assert atoms(x <= y) == [Atom("x", "y", Fraction(0), False)]
    assert atoms(z3.RealVal("3/2") > x) == [Atom("x", ZERO, Fraction(3, 2), True)]
    assert atoms(z3.BoolVal(True) == (x <= y + 2)) == [Atom("x", "y", Fraction(2), False)]
    assert atoms(z3.Not(x < y)) == [Atom("y", "x", Fraction(0), False)]
    assert sorted(atoms(x == 5), key=str) == sorted([Atom("x", ZERO, Fraction(5), False),
                                                    Atom(ZERO, "x", Fraction(-5), False)], key=str)
    assert len(atoms(z3.And(x <= y, y < 4))) == 2
    for outside in (z3.Or(x < y, y < x), x * y <= 1, x + y <= 1, z3.Not(x == y)):
        with pytest.raises(NotDifference):
            atoms(outside)


def _z3_sat(system_atoms: list[tuple[str, Atom]], keep: set) -> bool:
    s = z3.Solver()
    v = {}

    def term(name):
        if name == ZERO:
            return z3.RealVal(0)
        return v.setdefault(name, z3.Real(name))

    for label, a in system_atoms:
        if label in keep:
            d = term(a.x) - term(a.y)
            s.add(d < a.c if a.strict else d <= a.c)
    return s.check() == z3.sat


@pytest.mark.parametrize("seed", range(40))
def test_conflicts_agree_with_z3_and_are_minimal(seed):
    rng = random.Random(seed)
    names = [ZERO] + [f"v{i}" for i in range(rng.randint(2, 7))]
    labelled = []
    ds = DifferenceSystem()
    for i in range(rng.randint(3, 14)):
        x, y = rng.sample(names, 2)
        a = Atom(x, y, Fraction(rng.randint(-6, 6), rng.choice([1, 2, 3])), rng.random() < 0.4)
        labelled.append((f"l{i}", a))
        ds.add(f"l{i}", [a])
    live = {label for label, _ in labelled}
    for _ in range(5):
        core = ds.conflict()
        assert (core is None) == _z3_sat(labelled, live)
        if core is None:
            break
        assert core <= live and not _z3_sat(labelled, core)
        for label in core:  # minimal: without any one of its labels the rest is satisfiable
            assert _z3_sat(labelled, core - {label})
        drop = min(core)
        ds.drop(drop)
        live.discard(drop)


def test_long_conflicts_are_found_and_reported_up_to_the_limit(tmp_path):
    path = tmp_path / "deep.jsonl"
    path.write_text(deep_chain(300, 40, seed=3))
    report = check_trace(path)
    together = [v for v in report.violations if v.source == "axioms together"]
    assert len(together) == MAX_CORES
    assert max(len(v.messages) for v in together) > 20  # conflicts along the chain
    assert all("cannot all hold together" in v.explanation for v in together)


@pytest.mark.parametrize("shape", ["deep-chain", "ambler"])
def test_tca_check_on_1000_messages(tmp_path, shape):
    """Before the difference solver, the deep chain took 200 s and 616 MB at 2,000 messages
    (quadratic: the SMT solver minimised cores as long as the chain). The 4,000-message peak
    memory (target: far within 2 GB) is measured by bench/b5_tca.py, in a fresh process."""
    path = tmp_path / f"{shape}.jsonl"
    if shape == "deep-chain":
        path.write_text(deep_chain(1000, 50))
    else:
        result = subprocess.run([sys.executable, "-m", "roar_formal.cli", "tca-simulate", str(AMBLER),
                                 "--size", "arcs=2", "--size", "steps=125", "--out", str(path)],
                                capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, result.stderr
    report = check_trace(path)
    assert len(report.tree.messages) >= 1000
    if shape == "ambler":
        assert report.ok, [v.explanation for v in report.violations]
    else:
        assert len(report.violations) >= MAX_CORES


# ------------------------------------------------------------------ numbers in traces


@pytest.mark.parametrize("number", ["1e999999999", "-1e999999999", "1e20", "1e-40", "123456789012345678901234",
                                    "0." + "0" * 50 + "1"])
def test_huge_or_tiny_times_are_refused_at_their_column(number):
    line = '{"event": "constraint_sent", "time": ' + number + ', "msg": "m", "kind": "goal"}'
    with pytest.raises(RoarError) as e:
        parse_events([line], "t.jsonl")
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == ("t.jsonl", 1, line.index('"time"') + 1)
    assert "at most 30 decimal places" in e.value.message


def test_an_integer_of_thousands_of_digits_is_refused():
    with pytest.raises(RoarError) as e:
        parse_events(['{"event": "started", "msg": "m", "time": ' + "9" * 5000 + "}"], "t.jsonl")
    assert "5000 digits" in e.value.message and e.value.pos.line == 1


def test_reasonable_times_are_read_exactly():
    (ev,) = parse_events(['{"event": "constraint_sent", "time": 1.25e3, "msg": "m", "kind": "goal"}'])
    assert ev.time == Fraction(1250)
    events = parse_events(['{"event": "constraint_sent", "time": 0, "msg": "m", "kind": "goal"}',
                           '{"event": "started", "time": 0.500000000000000000000000000000000000, "msg": "m"}',
                           '{"event": "ended", "time": 1700000000123456789, "msg": "m"}'])
    assert events[1].time == Fraction(1, 2) and events[2].time == 1700000000123456789


def test_an_80_byte_trace_with_a_huge_exponent_does_not_hang(tmp_path):
    path = tmp_path / "huge.jsonl"
    path.write_text('{"event": "constraint_sent", "time": 1e999999999, "msg": "m", "kind": "goal"}\n')
    assert path.stat().st_size <= 80
    result = subprocess.run([sys.executable, "-m", "roar_formal.cli", "tca-check", str(path)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert f"{path}:1:30: expected field 'time'" in result.stderr.replace("\n", "")
    assert "Traceback" not in result.stderr


# ------------------------------------------------------------------ tca-simulate sizes and --out


@pytest.mark.parametrize("value", [str(MAX_SIZE + 1), "9" * 5000, "0", "-3", "x", "1e3", "٣"])
def test_simulate_sizes_are_bounded(app, value):
    result = run(app, "tca-simulate", AMBLER, "--size", f"steps={value}")
    assert isinstance(result.exception, RoarError), result.output
    assert f"N from 1 to {MAX_SIZE:,}" in result.exception.message


def test_the_unrolled_tree_is_bounded_before_it_takes_memory(app):
    result = run(app, "tca-simulate", AMBLER, "--size", "arcs=1000", "--size", "steps=1000")
    assert isinstance(result.exception, RoarError)
    assert f"more than {MAX_MESSAGES:,} messages" in result.exception.message
    with pytest.raises(RoarError):
        unroll(load_model(AMBLER), {"arcs": 10, "steps": 10}, max_messages=100)
    assert len(unroll(load_model(AMBLER), {"arcs": 10, "steps": 10}).nodes) > 100


def test_a_failed_simulate_keeps_the_previous_output(app, tmp_path, monkeypatch):
    out = tmp_path / "walk.jsonl"
    ok = run(app, "tca-simulate", AMBLER, "--size", "arcs=1", "--size", "steps=2", "--out", out)
    assert ok.exit_code == 0, ok.output
    before = out.read_text()
    # bad input: nothing is written
    bad = run(app, "tca-simulate", AMBLER, "--size", "steps=0", "--out", out)
    assert isinstance(bad.exception, RoarError) and out.read_text() == before
    # the write itself fails half-way (disk full): the previous trace is whole, no temporary file stays

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    failed = run(app, "tca-simulate", AMBLER, "--size", "arcs=2", "--size", "steps=3", "--out", out)
    assert isinstance(failed.exception, RoarError) and "No space left" in failed.exception.message
    assert out.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.jsonl"]
