"""The functional layer of div_call_pre.roar: ready(n) is n > 1."""
from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("ready", lambda n: n > 1, outcomes=[Outcome("yes", True, result=True)])
    return reg
