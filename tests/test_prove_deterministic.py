"""``roar-verify prove`` prints the same countermodels on every run (a fixed Z3 seed, model searches
bounded by Z3's step count rather than the clock)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

REFUTED = ["desc_nesting_needs_induction", "seq_ach_goals", "seq_ach_goal_second"]


def _prove() -> str:
    env = {**os.environ, "NO_COLOR": "1", "COLUMNS": "200"}
    r = subprocess.run([sys.executable, "-m", "roar_formal", "prove", *REFUTED], capture_output=True, text=True,
                       env=env, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_prove_prints_the_same_countermodels_on_every_run():
    first, second = _prove(), _prove()
    # the time column is the only thing allowed to differ
    mask = lambda text: re.sub(r"│ \d+\.\d+ +│", "│ TIME │", text)   # noqa: E731
    assert mask(first) == mask(second)
    for name in REFUTED:
        assert f"countermodel for {name} at t = " in first
    assert first.count("countermodel for") == len(REFUTED)


def test_model_searches_are_bounded_by_steps_not_by_the_clock():
    from roar_formal.tca import prover
    assert prover.READABLE_RLIMIT > 0 and prover.MODEL_RLIMIT > 0
    # the clock is a safety net far above the step bounds: it must not decide which model is found
    assert prover.READABLE_TIMEOUT_MS >= 30_000 and prover.MODEL_TIMEOUT_MS >= 30_000
    assert all("random_seed" in p for p in prover.PORTFOLIO)
