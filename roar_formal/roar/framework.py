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
from typing import Optional, Sequence, Union

from ..clf.parser import parse_program
from ..clf.program import Program
from ..clf.signature import Signature, elaborate, extend_signature


@lru_cache(maxsize=1)
def framework_text() -> str:
    return resources.files(__package__).joinpath("framework.clf").read_text(encoding="utf-8")


@lru_cache(maxsize=1)
def framework_signature() -> Signature:
    """The framework, elaborated once (never changed: programs extend copies of it)."""
    return elaborate(parse_program(framework_text(), "<framework>"))


def extend_framework(items: Union[str, Sequence], file: str = "<compiled spec>",
                     failed: Optional[list] = None) -> Signature:
    """The framework's signature extended with ``items`` (trees or text)."""
    return extend_signature(framework_signature(), items, file, failed)


def with_framework(items: Union[str, Sequence], file: str = "<compiled spec>") -> Program:
    """A program made of the framework followed by ``items`` (declarations and directives)."""
    return Program(extend_framework(items, file))


@lru_cache(maxsize=None)
def parsed_part(text: str, file: str) -> tuple:
    """A fixed part of the framework added only to some models (crashes, time), parsed once per
    process: its items, to extend a model with."""
    return parse_program(text, file).items
