"""The functional layer of div_call_start.roar: half(n) is n / 2 (an integer)."""
from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("half", lambda n: n // 2, outcomes=[Outcome("two", True, result=2)])
    return reg
