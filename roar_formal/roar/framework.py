"""The ROAR framework signature (``framework.clf``, package data) and programs built on it.

A compiled agent spec is CLF declarations added to the framework, so that the
semantics a run or the explorer sees is the CLF signature itself. The
framework is parsed and elaborated once per process (:func:`framework_signature`);
each spec's declarations extend a copy of it, one item at a time as Celf checks
a file.
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources

from ..clf.parser import parse_program
from ..clf.program import Program
from ..clf.signature import Signature, elaborate, elaborate_steps


@lru_cache(maxsize=1)
def framework_text() -> str:
    return resources.files(__package__).joinpath("framework.clf").read_text(encoding="utf-8")


@lru_cache(maxsize=1)
def framework_signature() -> Signature:
    """The framework, elaborated once (never changed: programs extend copies of it)."""
    return elaborate(parse_program(framework_text(), "<framework>"))


def extend_signature(base: Signature, text: str, file: str = "<compiled spec>") -> Signature:
    """A copy of ``base`` extended with ``text`` (declarations and directives), checked one item
    at a time; positions in errors refer to ``text`` alone. ``base`` is not changed."""
    sig = Signature(dict(base.consts), list(base.directives), dict(base.modes), dict(base.implicit_modes), file)
    for _ in elaborate_steps(parse_program(text, file), sig):
        pass
    return sig


def extend_framework(text: str, file: str = "<compiled spec>") -> Signature:
    """The framework's signature extended with ``text``."""
    return extend_signature(framework_signature(), text, file)


def with_framework(text: str, file: str = "<compiled spec>") -> Program:
    """A program made of the framework followed by ``text`` (declarations and directives)."""
    return Program(extend_framework(text, file))
