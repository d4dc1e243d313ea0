"""The functional layer of pre_call.roar: in a run, ready, in range below 10, a full battery."""
from roar_formal.roar.functional import Outcome, Registry

CALLS = []


def registry() -> Registry:
    reg = Registry()

    def ready():
        CALLS.append("ready")
        return True

    def in_range(goal):
        CALLS.append(f"in_range({goal})")
        return goal < 10

    def battery():
        CALLS.append("battery")
        return 80

    reg.register("ready", ready, outcomes=[Outcome("yes", True), Outcome("no", False)])
    reg.register("in_range", in_range, outcomes=[Outcome("inside", True)])
    reg.register("battery", battery, outcomes=[Outcome("full", True, result=80), Outcome("low", True, result=5),
                                               Outcome("dead", False)])
    return reg
