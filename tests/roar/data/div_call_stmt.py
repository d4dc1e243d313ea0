"""The functional layer of div_call_stmt.roar: twice(n) is 2 * n."""
from roar_formal.roar.functional import Outcome, Registry


def registry() -> Registry:
    reg = Registry()
    reg.register("twice", lambda n: 2 * n, outcomes=[Outcome("ten", True, result=10)])
    return reg
