"""Functional layer of conflict.roar: the pan-tilt unit's motors (always reach the heading)."""

from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("turn_to", lambda heading: True, outcomes=[Outcome("turned", True), Outcome("blocked", False)])
    return reg
