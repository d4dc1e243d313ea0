"""The functional layer of div_start.roar: count() is 6."""
from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("count", lambda: 6, outcomes=[Outcome("six", True, result=6)])
    return reg
