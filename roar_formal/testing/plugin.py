"""The pytest plugin of roar-formal (registered through the ``pytest11`` entry point).

It gives a test suite that keeps agent specs next to its tests:

* the fixture ``roar_load(path, functional=None)``: a spec (``.roar``, ``.ability``,
  hyper folder) or a ``.clf`` model, the path relative to the test file's folder;
* the fixtures ``roar_budget`` (this test's exploration budget) and
  ``roar_traces`` (the folder where counterexample traces are written);
* the marker ``@pytest.mark.roar_budget(max_states=..., max_seconds=...,
  max_memory_mb=...)``, and the options ``--roar-budget`` (the default
  budget of every test) and ``--roar-traces DIR``;
* the assertion helpers of :mod:`roar_formal.testing` pick the budget and
  the trace folder of the running test, so their failure message ends with
  the path of a replayable trace.

Nothing heavy is imported until a test asks for it: the plugin loads in
every pytest run of an environment where roar-formal is installed.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Callable, Iterator, Optional

import pytest

from ..errors import RoarError

_BUDGET_KEYS = {"states": "max_states", "max_states": "max_states", "seconds": "max_seconds",
                "max_seconds": "max_seconds", "memory": "max_memory_mb", "max_memory_mb": "max_memory_mb"}
_TRACES_KEY = pytest.StashKey[Path]()
_DEFAULT_KEY = pytest.StashKey[dict]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("roar-formal", "roar-formal: tests of agent specs and CLF models")
    group.addoption("--roar-budget", action="store", default=None, metavar="BUDGET",
                    help="default exploration budget of every test: 'states=N,seconds=S,memory=MB' "
                         "(any of them; a bare number is states). A test's roar_budget marker wins.")
    group.addoption("--roar-traces", action="store", default=None, metavar="DIR",
                    help="folder for counterexample traces (default: roar-traces in pytest's temporary folder)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "roar_budget(max_states=None, max_seconds=None, max_memory_mb=None): "
                                       "the exploration budget of this test's roar-formal assertions")
    text = config.getoption("--roar-budget", default=None)
    try:
        config.stash[_DEFAULT_KEY] = parse_budget(text) if text else {}
    except ValueError as exc:
        raise pytest.UsageError(f"--roar-budget {text!r}: {exc}") from None


def parse_budget(text: str) -> dict:
    """``states=50000,seconds=30,memory=2000`` (or ``50000``) as Budget keyword arguments."""
    out: dict = {}
    for part in [p.strip() for p in re.split(r"[,\s]+", text.strip()) if p.strip()]:
        key, sep, value = part.partition("=")
        if not sep:
            key, value = "states", part
        name = _BUDGET_KEYS.get(key.strip())
        if name is None:
            raise ValueError(f"unknown key {key!r}; expected states, seconds or memory")
        try:
            number = float(value) if name == "max_seconds" else int(value.replace("_", ""))
        except ValueError:
            raise ValueError(f"{key} must be a number, not {value!r}") from None
        if number <= 0:
            raise ValueError(f"{key} must be above 0, not {value}")
        out[name] = number
    if not out:
        raise ValueError("expected states=N, seconds=S or memory=MB")
    return out


def _marker_budget(item: pytest.Item) -> dict:
    """The budget of the test's ``roar_budget`` markers (the closest wins); a malformed one fails the test."""
    out: dict = {}
    for mark in reversed(list(item.iter_markers("roar_budget"))):
        if mark.args:
            pytest.fail(f"roar_budget takes keywords: max_states=..., max_seconds=..., max_memory_mb=..., "
                        f"not {mark.args!r}", pytrace=False)
        for k, v in mark.kwargs.items():
            if k not in ("max_states", "max_seconds", "max_memory_mb"):
                pytest.fail(f"roar_budget has no key {k!r}; expected max_states, max_seconds or max_memory_mb",
                            pytrace=False)
            whole = k != "max_seconds"
            if isinstance(v, bool) or not isinstance(v, int if whole else (int, float)) or v <= 0:
                pytest.fail(f"roar_budget({k}={v!r}): expected a {'whole ' if whole else ''}number above 0",
                            pytrace=False)
            out[k] = v
    return out


def _budget_kwargs(item: pytest.Item) -> dict:
    """--roar-budget, overridden key by key by the test's marker."""
    return {**item.config.stash.get(_DEFAULT_KEY, {}), **_marker_budget(item)}


def _traces(config: pytest.Config) -> Path:
    if _TRACES_KEY not in config.stash:
        given = config.getoption("--roar-traces", default=None)
        if given:
            folder = Path(given)
        else:
            factory = getattr(config, "_tmp_path_factory", None)
            folder = factory.getbasetemp() / "roar-traces" if factory is not None else Path("roar-traces")
        config.stash[_TRACES_KEY] = folder.resolve()
    return config.stash[_TRACES_KEY]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    """Run the test with its budget and trace folder as the assertion helpers' settings."""
    from .session import PLUGIN
    token = PLUGIN.set((_budget_kwargs(item), lambda: _traces(item.config)))
    try:
        yield
    finally:
        PLUGIN.reset(token)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    """A test that fails with a :class:`RoarError` (a mistake in a spec, a request, a fault, a
    property: the message says where) is shown from the test's own frames: the library's
    frames under it are cut, so the located message is what the reader sees, not forty lines
    of roar_formal internals (``--full-trace`` shows them)."""
    excinfo = call.excinfo
    if excinfo is not None and excinfo.errisinstance(RoarError) and not item.config.getoption("fulltrace", False):
        package = str(Path(__file__).resolve().parents[1])
        frames = []
        tb = excinfo.value.__traceback__
        while tb is not None:
            frames.append(tb)
            tb = tb.tb_next
        kept = [f for f in frames if not f.tb_frame.f_code.co_filename.startswith(package)]
        if kept and len(kept) < len(frames):
            # (pytest prints the exception's own traceback: relink it past the library's frames)
            for a, b in zip(kept, kept[1:]):
                a.tb_next = b
            kept[-1].tb_next = None
            excinfo.value.__traceback__ = kept[0]
            excinfo.traceback = excinfo.traceback.filter(lambda entry: not str(entry.path).startswith(package))
    yield


@pytest.fixture
def roar_budget(request: pytest.FixtureRequest):
    """The exploration budget of this test (marker, else --roar-budget, else the default)."""
    from dataclasses import replace
    from .assertions import DEFAULT_BUDGET
    return replace(DEFAULT_BUDGET, **_budget_kwargs(request.node))


@pytest.fixture(scope="session")
def roar_traces(pytestconfig: pytest.Config) -> Path:
    """The folder where the helpers write counterexample traces."""
    folder = _traces(pytestconfig)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@pytest.fixture(scope="module")
def roar_load(request: pytest.FixtureRequest) -> Callable[..., Any]:
    """``roar_load(path, functional=None)``: a spec or a .clf model, relative to the test file's folder."""
    from .api import load
    base = Path(request.path).parent
    cache: dict = {}

    def load_relative(path: str, functional: Optional[str] = None):
        p = Path(path)
        p = p if p.is_absolute() else base / p
        f = None if functional is None else (Path(functional) if Path(functional).is_absolute()
                                             else base / functional)
        key = (p, f)
        if key not in cache:
            cache[key] = load(p, functional=f)
        return cache[key]

    return load_relative
