"""``prove``, ``tca-check`` and ``tca-simulate`` through typer's test runner."""

from __future__ import annotations

from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from roar_formal.errors import RoarError
from roar_formal.cli.tca import register
from repo import ROOT

TRACES = Path(__file__).parent / "traces"
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


def test_prove_lists_obligations(app):
    result = run(app, "prove", "--list")
    assert result.exit_code == 0
    for name in ("seq_ach", "seq_ach_goals", "desc_nesting_step", "consistency"):
        assert name in result.output


def test_prove_named_theorems_with_their_axioms(app):
    result = run(app, "prove", "seq_ach", "seq_ach_goals", "--deps")
    assert result.exit_code == 0, result.output
    assert "proved" in result.output and "refuted" in result.output
    assert "l_desc_nesting" in result.output  # the uses column
    assert "countermodel for seq_ach_goals" in result.output and "m3" in result.output
    # what a refutation shows is said before the table
    assert "seq_ach_goals is refuted, its claim does not follow from the axioms" in " ".join(result.output.split())


def test_prove_an_unknown_name_is_a_user_error(app):
    result = run(app, "prove", "no_such_theorem")
    assert isinstance(result.exception, RoarError) and "no_such_theorem" in str(result.exception)


def test_prove_a_model(app):
    result = run(app, "prove", "--model", AMBLER, "ambler-walking:at_most_one_step_ahead",
                 "ambler-walking:at_least_one_step_ahead")
    assert result.exit_code == 0, result.output
    assert "necessary: yes" in result.output


def test_prove_exits_nonzero_when_an_expectation_fails(app, tmp_path):
    text = AMBLER.read_text().replace('holds = "end(leg) < start(next)"', 'holds = "end(body) < start(next)"')
    model = tmp_path / "wrong.toml"
    model.write_text(text)
    result = run(app, "prove", "--model", model, "ambler-walking:next_plan_waits_for_leg")
    assert result.exit_code == 1
    assert "did not come out as expected" in result.output


def test_check_a_good_trace(app):
    result = run(app, "tca-check", TRACES / "seq_ach_ok.jsonl")
    assert result.exit_code == 0 and "no violations" in result.output


def test_check_a_bad_trace(app):
    result = run(app, "tca-check", TRACES / "seq_ach_violated.jsonl")
    assert result.exit_code == 1
    assert "seq_ach" in result.output and "drive_b" in result.output and "starts at 4.5" in result.output


def test_check_malformed_input_raises_a_located_error(app):
    result = run(app, "tca-check", TRACES / "malformed_json.jsonl")
    assert isinstance(result.exception, RoarError) and result.exception.pos.line == 3


def test_simulate_then_check(app, tmp_path):
    out = tmp_path / "walk.jsonl"
    result = run(app, "tca-simulate", AMBLER, "--size", "arcs=1", "--size", "steps=3", "--seed", "4", "--out", out)
    assert result.exit_code == 0, result.output
    assert run(app, "tca-check", out).exit_code == 0
    bad = run(app, "tca-simulate", AMBLER, "--size", "legs=2")
    assert isinstance(bad.exception, RoarError)


def test_registered_in_roar_verify():
    from roar_formal import cli

    names = {c.name for c in cli.app.registered_commands}
    assert {"prove", "tca-check", "tca-simulate"} <= names


def test_a_misspelt_obligation_gets_a_suggestion(capsys):
    from roar_formal.cli import main
    try:
        main(["prove", "seq_ahc"])
        code = 0
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and "no obligation named seq_ahc (did you mean 'seq_ach'?)" in err


def test_prove_with_a_model_and_named_obligations_says_which_claims_it_left_out(app):
    result = run(app, "prove", "--model", AMBLER, "seq_ach", "ambler-walking:steps_in_order")
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "note: 5 claim(s) of --model not run" in text and "steps_in_order" in text.split("TCA proof")[1]
    assert "note:" not in " ".join(run(app, "prove", "--model", AMBLER, "seq_ach", *[
        f"ambler-walking:{c}" for c in ("at_most_one_step_ahead", "next_plan_waits_for_leg", "steps_in_order",
                                        "never_plans_during_body_move", "arcs_not_planned_ahead",
                                        "at_least_one_step_ahead")]).output.split())
