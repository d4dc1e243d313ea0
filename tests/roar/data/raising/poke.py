"""A functional layer with a bug: poke raises (tests/roar/test_primitive_errors.py)."""
from roar_formal.roar.functional import Registry


def registry():
    reg = Registry()

    @reg.register("poke")
    def poke(n):
        if n == 3:
            raise ValueError("sensor unplugged")
        return True
    return reg
