"""Functional layer of ordered_pick.roar and ordered_pick_fixed.roar: the jaw and the
spindle always work, so the only fault left to find is the order of the sub-goals."""

from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("press", lambda: True, outcomes=[Outcome("pressed", True)])
    reg.register("spin", lambda: True, outcomes=[Outcome("spun", True)])
    return reg
