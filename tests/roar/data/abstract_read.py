"""The functional layer of abstract_read.roar: the read of loco::pos, abstracted for exploration
(no callable): at the goal, short of it, or the localisation fails."""
from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("loco::pos", outcomes=[Outcome("at_goal", True, {"pos": 5}), Outcome("short", True, {"pos": 3}),
                                        Outcome("lost", False)])
    return reg
