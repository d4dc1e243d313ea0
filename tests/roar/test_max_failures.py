"""A bound on a primitive's failures (``Registry.register(..., max_failures=k)``): an assumption
about the functional layer ("the gripper slips at most twice") under which a recipe retried on
failure is no longer a livelock."""

from __future__ import annotations

import shutil

import pytest

from roar_formal.clf.terms import Const, Root
from roar_formal.errors import RoarError
from roar_formal.roar.functional import Outcome, Registry
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import job_for_model
from repo import ROOT

MODULE = """from roar_formal.roar.functional import Outcome, Registry

def registry():
    reg = Registry()
    reg.register("grip", lambda: True, outcomes=[Outcome("closed", True), Outcome("slipped", False)]{extra})
    return reg
"""


def _explore(tmp_path, extra: str):
    spec = tmp_path / "grip.roar"
    shutil.copy(ROOT / "models" / "faulty" / "retry_forever.roar", spec)
    (tmp_path / "grip.py").write_text(MODULE.format(extra=extra))
    return run_job(job_for_model(spec, "hand::holding == true", ["deadlock", "livelock"]))


def _budgets(res) -> set:
    out = set()
    for sid in range(res.graph.n_states):
        for _m, f, _n in res.roar[2].states[sid].facts():
            if type(f) is Root and isinstance(f.head, Const) and f.head.name == "fails_left":
                n, t = 0, f.args[1]
                while t.head.name == "s":
                    n, t = n + 1, t.args[0]
                out.add(n)
    return out


def test_unbounded_failures_are_a_livelock(tmp_path):
    res = _explore(tmp_path, "")
    assert res.verdicts["livelock"].status == "violated"
    assert _budgets(res) == set()


@pytest.mark.parametrize("k", [0, 1, 2])
def test_at_most_k_failures_end_every_run(tmp_path, k):
    res = _explore(tmp_path, f", max_failures={k}")
    assert res.graph.complete
    assert res.verdicts["livelock"].status == "holds", res.verdicts["livelock"].message
    assert res.verdicts["deadlock"].status == "holds"
    # every budget from k down to 0 is reached (k failures happen on some run), none other
    assert _budgets(res) == set(range(k + 1))


def test_a_bound_must_be_a_count_with_a_success_to_fall_back_on():
    reg = Registry()
    for bad in (-1, 1.5, True):
        with pytest.raises(RoarError, match="max_failures must be a whole number"):
            reg.register("f", lambda: True, max_failures=bad)
    with pytest.raises(RoarError, match="needs a successful outcome"):
        reg.register("g", lambda: True, outcomes=[Outcome("broken", False)], max_failures=1)


# ------------------------------------------------------------------ fair outcomes

def _livelock(tmp_path, extra: str, strength: str):
    from roar_formal.verify.jobs import load_job
    spec = tmp_path / "grip.roar"
    shutil.copy(ROOT / "models" / "faulty" / "retry_forever.roar", spec)
    (tmp_path / "grip.py").write_text(MODULE.format(extra=extra))
    (tmp_path / "p.toml").write_text(f'check = ["livelock"]\n[livelock]\nprogress = ["request R0 finished"]\n'
                                     f'strength = "{strength}"\n')
    (tmp_path / "job.toml").write_text('name = "grip"\nspec = "grip.roar"\nrequest = "hand::holding == true"\n'
                                       'properties = ["p.toml"]\n')
    return run_job(load_job(tmp_path / "job.toml")).verdicts["livelock"]


@pytest.mark.parametrize("fair,strength,status", [
    (False, "weak", "violated"), (False, "strong", "violated"),    # the hand itself keeps moving: no help
    (True, "weak", "violated"),                                     # success is possible only now and then
    (True, "strong", "holds"),                                      # ... and under strong fairness it is taken
])
def test_a_fair_outcome_ends_a_retry_loop_under_strong_fairness(tmp_path, fair, strength, status):
    v = _livelock(tmp_path, ", fair=True" if fair else "", strength)
    assert v.status == status, v.message
    if status == "holds":
        assert "strongly unfair" in v.message


def test_fair_needs_a_successful_outcome():
    with pytest.raises(RoarError, match="fair needs a successful outcome"):
        Registry().register("g", lambda: True, outcomes=[Outcome("broken", False)], fair=True)


def test_registration_errors_point_at_the_users_call_and_fair_is_a_bool(tmp_path):
    for extra, message in ((", fair='yes'", "fair must be True or False, not 'yes'"),
                           (", max_failures=-2", "max_failures must be a whole number >= 0, not -2")):
        with pytest.raises(RoarError, match=message) as e:
            _explore(tmp_path, extra)
        # the line of the register call in the user's module (grip.py line 5)
        assert e.value.pos is not None and e.value.pos.file.endswith("grip.py") and e.value.pos.line == 5


def test_an_assumption_about_a_primitive_the_spec_never_calls_is_refused_at_its_registration(tmp_path):
    spec = tmp_path / "grip.roar"
    shutil.copy(ROOT / "models" / "faulty" / "retry_forever.roar", spec)
    (tmp_path / "grip.py").write_text(MODULE.format(extra="") + "\n\ndef _unused():\n    pass\n")
    text = MODULE.format(extra="").replace("    return reg",
                                           "    reg.register('gripp', lambda: True, max_failures=1)\n    return reg")
    (tmp_path / "grip.py").write_text(text)
    with pytest.raises(RoarError, match=r"primitive 'gripp' is registered with max_failures=1, but no function") as e:
        run_job(job_for_model(spec, "hand::holding == true", ["deadlock"]))
    assert e.value.pos.file.endswith("grip.py") and e.value.pos.line == 6
    # without an assumption an extra primitive is fine (a module may serve several specs)
    (tmp_path / "grip.py").write_text(text.replace(", max_failures=1", ""))
    assert run_job(job_for_model(spec, "hand::holding == true", ["deadlock"])).verdicts["deadlock"].status == "holds"
