"""The ROAR framework signature (``framework.clf``, package data) and programs built on it.

A compiled agent spec is CLF text appended to the framework, so that the
semantics a run or the explorer sees is the CLF signature itself.
"""

from __future__ import annotations

from functools import lru_cache
from importlib import resources

from ..clf.program import Program


@lru_cache(maxsize=1)
def framework_text() -> str:
    return resources.files(__package__).joinpath("framework.clf").read_text(encoding="utf-8")


def with_framework(text: str, file: str = "<compiled spec>") -> Program:
    """A program made of the framework followed by ``text`` (declarations and directives).

    Line numbers in errors refer to the combined text; the framework comes first.
    """
    return Program.from_text(framework_text() + "\n" + text, file)
