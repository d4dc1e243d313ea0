"""The functional layer of init_call.roar: level() answers 3 in a run; three declared outcomes."""
from roar_formal.roar.functional import Outcome, Registry

CALLS = []


def registry() -> Registry:
    reg = Registry()

    def level():
        CALLS.append("level")
        return 3

    reg.register("level", level, outcomes=[Outcome("low", True, result=1), Outcome("high", True, result=3),
                                           Outcome("broken", False)])
    return reg
