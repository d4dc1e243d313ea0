"""Loading a spec: parse it (:mod:`.parser`), then check it (:mod:`.checks`).

:func:`load_spec` is what the rest of the toolkit calls. The checked form of
each loaded spec is kept (for as long as the spec lives), so the compiler
consumes what the checks found instead of checking again.
"""

from __future__ import annotations

import weakref
from os import PathLike
from typing import Union

from . import ast as a
from .checks import CheckedSpec, check_spec
from .parser import read_spec

__all__ = ["load_spec", "checked_spec"]

_CHECKED: dict[int, CheckedSpec] = {}


def _remember(checked: CheckedSpec) -> CheckedSpec:
    key = id(checked.spec)
    if key not in _CHECKED:
        weakref.finalize(checked.spec, _CHECKED.pop, key, None)
    _CHECKED[key] = checked
    return checked


def load_spec(path: Union[str, PathLike], *, hyper_compat: bool = False, check: bool = True) -> a.Spec:
    """Load a spec (a ``.roar`` file, a ``.ability`` file, or a folder of ``.ability`` files). With
    ``check`` (the default) the static checks run and a
    :class:`~roar_formal.roar.checks.SpecCheckError` lists every problem; with ``hyper_compat``
    the spec's ``warnings`` include every expression that hyper's grammar reads differently."""
    spec = read_spec(path, hyper_compat=hyper_compat)
    if check:
        _remember(check_spec(spec))
    return spec


def checked_spec(spec: Union[a.Spec, CheckedSpec]) -> CheckedSpec:
    """The checked form of ``spec``: the one :func:`load_spec` made, or the checks run now
    (raising :class:`~roar_formal.roar.checks.SpecCheckError` on a spec with problems)."""
    if isinstance(spec, CheckedSpec):
        return spec
    got = _CHECKED.get(id(spec))
    if got is not None and got.spec is spec:
        return got
    return _remember(check_spec(spec))
