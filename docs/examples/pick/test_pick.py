"""Tests of pick.roar: a property-based test over fault schedules, and an exhaustive check."""

from pathlib import Path

from hypothesis import given, settings, strategies as st

from roar_formal import load_spec
from roar_formal.testing import assert_no_deadlock, assert_succeeds, fault_schedules

SPEC = load_spec(Path(__file__).with_name("pick.roar"))
REQUEST = "cell::lifted == true"


@settings(max_examples=50, deadline=None)
@given(faults=fault_schedules(SPEC, max_faults=2), seed=st.integers(0, 1000))
def test_the_part_is_lifted_despite_transient_faults(faults, seed):
    # every fault is one failing call (f:K); the next attempt of the recipe may succeed
    assert_succeeds(SPEC, REQUEST, seed=seed, faults=faults)


def test_no_deadlock(roar_load):
    assert_no_deadlock(roar_load("pick.roar"), REQUEST)
