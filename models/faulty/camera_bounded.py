"""Functional layer of camera_bounded.roar: a snapshot may come out blurred; a frame grabbed
from the video stream always arrives."""

from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("snap", lambda: True, outcomes=[Outcome("sharp", True), Outcome("blurred", False)])
    reg.register("grab_frame", lambda: True, outcomes=[Outcome("frame", True)])
    return reg
