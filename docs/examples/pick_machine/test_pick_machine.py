"""A stateful test of pick.roar: hypothesis drives the model one ROAR event at a time."""

from pathlib import Path

from hypothesis import settings
from hypothesis.stateful import invariant

from roar_formal.testing import RoarMachine, load_spec

HERE = Path(__file__).parent


class PickMachine(RoarMachine):
    spec = load_spec(HERE.parent / "pick" / "pick.roar")
    request = "cell::lifted == true"

    @invariant()
    def the_gripper_is_free_once_all_is_done(self):
        if self.quiescent:
            assert self.value("gripper::busy") is False, "the gripper is still busy when all is done"


TestPick = PickMachine.TestCase
TestPick.settings = settings(TestPick.settings, max_examples=50)
