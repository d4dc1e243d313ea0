"""The public API: load a spec or a CLF model, run it, explore it, read the results.

One object per thing a user has in hand, so that a test needs one import
instead of the parser, the compiler, the runner, the job loader and a CLI
module::

    import roar_formal as rf

    spec = rf.load_spec("specs/pick.roar")            # SPEC.py next to it is its functional layer
    run = spec.run("cell::lifted == true", seed=3, faults=["close_jaws:1"])
    run.ok, run.outcome, run.final["gripper::busy"]
    print(run)                                         # the ROAR-level trace, as `roar-verify run` prints it

    res = spec.explore("cell::lifted == true", ["deadlock", "livelock"])
    res.verdict("deadlock").status                     # holds | violated | incomplete
    print(res.counterexample("livelock"))              # as `roar-verify check` prints it

Results print themselves as the command line prints them: a run like
``roar-verify run``, a counterexample like ``roar-verify check`` (the
check printer is the command line's own, so the two cannot drift apart).
Every mistake in the input is a :class:`~roar_formal.errors.RoarError` with
a location, as on the command line.
"""

from __future__ import annotations

import atexit
import hashlib
import re
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Optional, Sequence, Union

from ..errors import Pos, RoarError
from ..lines import Lines
from ..explore.search import Budget
from ..verify.jobs import SPEC_DEFAULTS as _SPEC_DEFAULTS

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..clf.program import Program
    from ..verify.results import JobResult
    from ..explore.properties import Verdict
    from ..roar import ast as a
    from ..roar.compile import CompiledModel
    from ..roar.functional import Registry
    from ..roar.run import Fault, RoarEvent, RunResult

__all__ = [
    "AgentSpec", "ClfModel", "ClfRun", "Counterexample", "Exploration", "RunReport", "Budget", "RoarError",
    "Job", "load", "load_spec", "load_clf", "load_job", "load_jobs", "is_model_path", "parse_faults", "as_budget",
    "write_html_report", "ROAR_PROPERTIES", "CLF_PROPERTIES", "SPEC_DEFAULTS", "Replay", "replay", "ScheduledFault",
]

PathLike = Union[str, Path]
FaultLike = Union[str, "Fault"]
BudgetLike = Union[Budget, Mapping[str, Any], None]

#: properties a job on a spec can check (docs/checking.md, "Jobs on a ROAR spec")
ROAR_PROPERTIES = ("deadlock", "livelock", "sequential-achievement", "exclusive-writes", "invariant",
                   "mission-completion", "mission-failure", "incompatible-tasks")
#: properties a job on a .clf model can check
CLF_PROPERTIES = ("deadlock", "livelock", "invariant")
#: what :meth:`AgentSpec.explore` checks when no property is named: what ``roar-verify check`` checks on a
#: spec (deadlock, mission-completion, mission-failure; docs/checking.md, "Jobs on a ROAR spec")
SPEC_DEFAULTS = tuple(_SPEC_DEFAULTS)


class ScheduledFault(str):
    """A ``--fault`` value drawn by a generated fault schedule (``strategies.fault_schedules``):
    it may name a call the run never makes, so by default a run lists it in
    ``RunReport.unused_faults`` instead of refusing it, as it refuses a fault written by hand."""

    __slots__ = ()


# ---------------------------------------------------------------------------- loading


def load(path: PathLike, *, functional: Optional[PathLike] = None) -> Union["AgentSpec", "ClfModel"]:
    """A ``.clf`` file as a :class:`ClfModel`; anything else (``.roar``, ``.ability``, a hyper folder)
    as an :class:`AgentSpec`."""
    p = Path(path)
    if p.suffix == ".clf":
        if functional is not None:
            raise RoarError(f"{p}: a .clf model has no functional layer; 'functional' is for agent specs")
        return load_clf(p)
    return load_spec(p, functional=functional)


def load_spec(path: PathLike, *, functional: Optional[PathLike] = None, hyper_compat: bool = False) -> "AgentSpec":
    """Parse and check an agent spec (static checks included); its functional-layer module is
    ``functional`` or found next to it as ``roar-verify run`` finds it."""
    from ..roar.functional import functional_module
    from ..roar.spec import load_spec as parse_spec
    p = Path(path)
    tree = parse_spec(p, hyper_compat=hyper_compat)
    module = functional_module(p, Path(functional) if functional is not None else None)
    return AgentSpec(tree, p, functional=module)


def load_clf(path: PathLike) -> "ClfModel":
    """Parse and type-check a CLF program (Celf's language)."""
    p = Path(path)
    if not p.is_file():
        raise RoarError(f"cannot read {p}: no such file")
    return ClfModel(p)


def as_budget(budget: BudgetLike) -> Budget:
    """A :class:`Budget` from a Budget, a mapping with its keys, or None (no bound)."""
    if budget is None:
        return Budget()
    if isinstance(budget, Budget):
        return budget
    keys = {"max_states", "max_seconds", "max_memory_mb"}
    if not isinstance(budget, Mapping):
        raise RoarError(f"budget is a mapping such as {{'max_states': 100000, 'max_seconds': 60}} or a Budget, "
                        f"not {budget!r}")
    unknown = set(budget) - keys
    if unknown:
        raise RoarError(f"unknown budget key {sorted(unknown)[0]!r}; expected one of: {', '.join(sorted(keys))}")
    return Budget(**dict(budget))


def listed(x) -> list:
    """A list argument given as one string (``faults="grip:1"``, ``properties="deadlock"``) as a
    list of that one item, rather than of its characters; any other iterable as a list."""
    return [x] if isinstance(x, (str, Path)) else list(x)


def parse_faults(faults: Iterable[FaultLike]) -> list["Fault"]:
    """``--fault`` values (``NAME``, ``NAME:K``, ``NAME=OUTCOME``) as faults; a malformed one is a
    :class:`RoarError` saying the expected form. Fault objects pass through; one string is one fault."""
    from ..roar.run import parse_fault
    out = [f if not isinstance(f, str) else parse_fault(f) for f in listed(faults)]
    # faults written by hand (strings) that say one thing twice, or two things of one call: refused
    # before the run (the run used one, then said the other matched no call)
    seen: dict = {}
    for raw, f in zip(listed(faults), out):
        if not isinstance(raw, str):
            continue
        key = (f.name, f.call)   # every call (None), or the K-th
        if key in seen:
            other = seen[key]
            what = "is given twice" if str(other) == str(f) else f"conflicts with --fault {other}"
            raise RoarError(f"--fault {f}: {what} (each call of {f.name} "
                            f"{'' if f.call is None else f'number {f.call} '}takes one fault)")
        seen[key] = f
    return out


# Specs and models given as text live in one temporary folder of the process: the explorer
# (like the command line) reads a model from a file, and a file also gives errors a name.
_SCRATCH: list[Path] = []


def scratch_folder() -> Path:
    if not _SCRATCH:
        d = Path(tempfile.mkdtemp(prefix="roar-formal-"))
        _SCRATCH.append(d)
        atexit.register(shutil.rmtree, d, True)
    return _SCRATCH[0]


def _scratch_path(text: str, name: str, suffix: str) -> Path:
    """Where a model given as text is written when a file is needed (named by its content)."""
    safe = re.sub(r"[^A-Za-z0-9_-]", "_", name) or "model"
    digest = hashlib.sha1(text.encode("utf-8")).hexdigest()[:12]
    return scratch_folder() / digest / f"{safe}{suffix}"


def _written(path: Path, text: str) -> Path:
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return path


def _caller_pos() -> Pos:
    """Where the user's code called in (the first frame outside roar_formal): the position
    given to patterns written in a test, so that a bad pattern is reported at its line."""
    f = sys._getframe(1)
    while f is not None and f.f_globals.get("__name__", "").startswith("roar_formal."):
        f = f.f_back
    if f is None:
        return Pos("<python>", 1, 1)
    return Pos(f.f_code.co_filename, f.f_lineno, 1)


def _from_command_line() -> bool:
    """Was this call made by ``roar-verify`` (whose options have no file to point at)?"""
    f = sys._getframe(1)
    while f is not None:
        if f.f_globals.get("__name__", "").startswith("roar_formal.cli"):
            return True
        f = f.f_back
    return False


def _written_at(pos: Pos, text: str) -> Pos:
    """Where the string literal ``text`` is written on the caller's line (inside its quotes, as
    patterns are located), or ``pos`` itself when the line does not show it."""
    import linecache
    line = linecache.getline(pos.file, pos.line)
    for quote in ('"', "'"):
        col = line.find(quote + text + quote)
        if col >= 0:
            return Pos(pos.file, pos.line, col + 2)
    return pos


def _triple_quoted(text: str) -> str:
    """``text`` as a Python literal that shows its lines (the backslash after the opening quotes
    keeps the first line out of the string)."""
    body = text.replace("\\", "\\\\").replace("'''", "\\'\\'\\'")
    return "'''\\\n" + body + "'''"


# ---------------------------------------------------------------------------- agent specs


class AgentSpec:
    """A checked agent spec and its functional layer: what ``roar-verify run``, ``check``,
    ``simulate`` and ``conform`` take as SPEC, as one object.

    Compiled models are cached per request, so a property test that runs one spec on
    many seeds or fault schedules compiles it once.
    """

    def __init__(self, tree: "a.Spec", path: Optional[Path] = None, *, functional: Optional[Path] = None,
                 text: Optional[str] = None, name: Optional[str] = None):
        self.ast = tree
        self.path = Path(path) if path is not None else None
        self.functional = Path(functional) if functional is not None else None
        self.text = text
        self.name = name or (str(self.path) if self.path is not None else "<spec>")
        self._compiled: dict[tuple[str, str], "CompiledModel"] = {}
        self._spare: Optional["Registry"] = None

    # -- construction -------------------------------------------------------------
    @classmethod
    def from_text(cls, text: str, *, name: str = "spec", functional: Optional[PathLike] = None) -> "AgentSpec":
        """A spec in the single-file layout given as text, parsed and checked. Positions name a
        scratch file, written when a file is needed (the explorer reads one)."""
        from ..roar.parser import parse_roar
        from ..roar.spec import checked_spec
        from ..roar.spec import load_spec as parse_spec
        path = _scratch_path(text, name, ".roar")
        tree = parse_roar(text, str(path))
        if any(ag.imports for ag in tree.agents):   # imports are loaded from files: go through one
            tree = parse_spec(_written(path, text))
        else:
            checked_spec(tree)   # checked once; the compiler reuses it
        return cls(tree, path, functional=Path(functional) if functional is not None else None, text=text,
                   name=f"<{name}>")

    def input_files(self) -> list[Path]:
        """Every file this spec was read from: its own, those it imports, its functional-layer
        module (outputs are refused these paths)."""
        from ..roar.sources import spec_files
        files = [Path(f) for f in spec_files(self.ast)]
        return files + [p for p in (self.path, self.functional) if p is not None and p.exists()]

    def __repr__(self) -> str:
        if self.text is not None:   # generated specs print as code that rebuilds them
            return f"AgentSpec.from_text({_triple_quoted(self.text)})"
        return f"<AgentSpec {self.name}: agents {', '.join(self.agents)}>"

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:  # hypothesis' and IPython's printer
        p.text(repr(self))

    # -- what it holds ----------------------------------------------------------------
    @property
    def agents(self) -> list[str]:
        return [ag.name for ag in self.ast.agents]

    def functions(self) -> list[tuple[str, str]]:
        """``(agent, function)`` for every function the agents export."""
        return [(ag.name, f.name) for ag in self.ast.agents for f in ag.functions]

    def registry(self) -> Optional["Registry"]:
        """A fresh registry of the functional layer (its ``registry()`` is called anew: each run
        gets its own simulation), or None when the spec has no module."""
        from ..roar.functional import load_registry
        return load_registry(self.functional)

    def compile(self, request: str, mode: str = "python", crashes: Any = None, time: Any = None,
                wait_timeout: Optional[int] = None, request_at: Optional[Pos] = None) -> "CompiledModel":
        """The compiled model of a request: ``mode`` "python" for runs (the registry's callables
        answer calls), "abstract" for exploration (declared outcomes are rules). ``crashes``: a
        ``roar.compile.Crashes``, or the ``--crash`` values of a run (docs/semantics.md, Crashes).
        ``time``: "untimed" (default) or "timed", with ``wait_timeout`` in ms (docs/semantics.md, Time).
        An error in the request is reported at ``request_at`` (where its text is written), by
        default at the caller's line when the text is written there."""
        from ..roar.compile import Crashes, compile_spec
        from ..roar.run import crash_setup
        if mode not in ("python", "abstract"):
            raise RoarError(f"compile mode must be 'python' or 'abstract', not {mode!r}")
        if crashes is not None and not isinstance(crashes, Crashes):
            crashes = crash_setup([crashes] if isinstance(crashes, str) else crashes)
        timing = _timing(time, wait_timeout)
        key = (request, mode, crashes or None, timing)
        model = self._compiled.get(key)
        if model is None:
            reg = self.registry()
            model = compile_spec(self.ast, request, registry=reg, functional=mode, crashes=crashes, time=timing,
                                 request_at=request_at or _request_at(request))
            from ..roar.compile import nothing_timed, timeout_unused
            why = nothing_timed(model) or timeout_unused(model)
            if why:
                raise RoarError(f"{self.name}: {why}")
            self._compiled[key] = model
            self._spare = reg   # unused by any run yet: the next run takes it (the module runs once)
        return model

    def _run_registry(self) -> Optional["Registry"]:
        """A registry no run has used: the one the last compile built, else a fresh one."""
        reg, self._spare = self._spare, None
        return reg if reg is not None else self.registry()

    # -- running -----------------------------------------------------------------------
    def run(self, request: str, *, seed: Optional[int] = None, faults: Iterable[FaultLike] = (), max_steps: int = 100_000,
            fair: bool = False, strict_faults: Optional[bool] = None, scenario: Optional[PathLike] = None,
            crashes: Iterable[Any] = (), time: Any = None, wait_timeout: Optional[int] = None) -> "RunReport":
        """Run the spec on ``request`` to quiescence, as ``roar-verify run`` does (or, with a
        ``scenario``, on the reference robot as ``roar-verify simulate`` does).

        ``faults`` are ``NAME``, ``NAME:K`` or ``NAME=OUTCOME`` (docs/spec-language.md, Faults);
        on the robot, scenario fault points too. A fault naming no function of the spec is an error
        before the run (with a did-you-mean). A fault that matched no call is an error, as on the
        command line (``--fault close_jaws:5: no such call happened in this run ...``), except a
        fault drawn by ``fault_schedules`` (a :class:`ScheduledFault`: a generated schedule may
        name calls a run never makes), which is listed in ``RunReport.unused_faults``.
        ``strict_faults=False`` lists every such fault there instead; ``strict_faults=True``
        refuses generated ones too.
        ``crashes`` are ``AGENT@STEP`` or ``AGENT@STEP-BACK`` (``--crash``; docs/semantics.md, Crashes).
        ``time="timed"`` models the periods of wait, assert and ensure, a wait giving up after
        ``wait_timeout`` ms (``--time``, ``--wait-timeout``; docs/semantics.md, Time).
        ``seed`` seeds the scheduler (default 0) and, on the robot, the noise (default: the
        scenario's ``seed``); the report says the seed used.
        """
        faults, crashes = listed(faults), listed(crashes)   # (one string is one fault, one crash)
        texts = [f if isinstance(f, str) else str(f) for f in faults]   # as given: a run prints them so
        try:
            return self._run(request, seed, faults, texts, crashes, max_steps, fair, strict_faults, scenario,
                             time, wait_timeout)
        except RoarError as exc:
            # a fault the spec cannot use (the command line's message): located where the test writes it
            if exc.pos is None and exc.message.startswith("--fault ") and not _from_command_line():
                name = exc.message[len("--fault "):].split(":", 1)[0].split(",", 1)[0]
                written = next((t for t in texts if t == name or t.startswith(name)), name)
                raise RoarError(exc.message, _written_at(_caller_pos(), written), exc.notes) from None
            raise

    def _run(self, request, seed, faults, texts, crashes, max_steps, fair, strict_faults, scenario, time,
             wait_timeout) -> "RunReport":
        from ..roar.run import parse_crash
        crashes = [parse_crash(c) for c in crashes]
        if scenario is not None:
            if crashes:
                raise RoarError("crashes (--crash) are for runs on the model; on the robot, faults are the "
                                "scenario's fault points")
            if _timing(time, wait_timeout):
                raise RoarError("the timed mode is for runs on the model; on the robot, time is the robot's "
                                "simulated time")
            return self._simulate(request, Path(scenario), seed, texts, max_steps, strict_faults)
        parsed = parse_faults(texts)
        wanted = list(dict.fromkeys(parsed))
        scheduled = {f for t, f in zip(texts, parsed) if isinstance(t, ScheduledFault)}
        seed = 0 if seed is None else seed
        model = self.compile(request, "python", crashes=crashes or None, time=time, wait_timeout=wait_timeout)
        _check_fault_names(wanted, self, model)
        res, unused = _run_tolerant(lambda fs: _run_model(model, seed, max_steps, self._run_registry(), fs, fair,
                                                          crashes), wanted, strict_faults, scheduled)
        return RunReport(self.name, request, seed, tuple(texts), res, max_steps,
                         tuple(str(f) for f in unused), functional=self.functional)

    def _simulate(self, request: str, scenario: Path, seed: Optional[int], faults: list[str], max_steps: int,
                  strict_faults: Optional[bool]) -> "RunReport":
        from ..roar.compile import compile_spec
        from ..robot.binding import load_robot_binding
        from ..robot.setup import split_faults
        from ..robot.scenario import load_scenario
        from ..robot.sim import simulate
        if self.text is not None and self.functional is None:
            raise RoarError("a spec given as text has no functional-layer module to bind to the robot")
        sc = load_scenario(scenario)
        if seed is None:   # the scenario's seed is the robot's default
            seed = sc.seed
        binding = load_robot_binding(self._file(), self.functional)
        model = compile_spec(self.ast, request, registry=binding.robot, functional="python",
                             request_at=_request_at(request))
        world, prims = split_faults(faults, sc, model)   # a name that is neither is refused there
        wanted = list(dict.fromkeys(prims))
        points = set(world)
        scheduled = {f for f in parse_faults(t for t in faults if isinstance(t, ScheduledFault) and t not in points)}
        sim_box: list = []
        fresh = [binding]   # the first run uses the binding loaded above; a second one gets its own robot layer

        def go(fs):
            b = fresh.pop() if fresh else load_robot_binding(self._file(), self.functional)
            sim = simulate(model, b.robot, sc, seed=seed, faults=world, prim_faults=fs, max_steps=max_steps)
            sim_box[:] = [sim]
            return sim.run

        res, unused = _run_tolerant(go, wanted, strict_faults, scheduled)
        return RunReport(self.name, request, seed, tuple(faults), res, max_steps,
                         tuple(str(f) for f in unused), robot=sim_box[0], scenario=sc, scenario_path=scenario,
                         functional=binding.path)

    # -- exploring ---------------------------------------------------------------------
    def explore(self, request: str, properties: Optional[Sequence[str]] = None, *,
                never: Sequence[str] = (), progress: Sequence[str] = (), sequence_recipes: Sequence[str] = (),
                kept: Union[bool, Sequence[str]] = False,
                budget: BudgetLike = None, reduction: bool = False, name: Optional[str] = None,
                crash: Sequence[str] = (), max_crashes: int = 1,
                incompatible: Sequence[Sequence[str]] = (), time: Any = None,
                wait_timeout: Optional[int] = None) -> "Exploration":
        """Explore every interleaving and every declared outcome of the functional layer, as a
        job on a spec does (docs/checking.md). Without ``properties``, what ``roar-verify check``
        checks on a spec: :data:`SPEC_DEFAULTS` (deadlock, mission-completion, mission-failure).
        ``never`` adds the ``invariant`` property; as in a job file's ``[invariant] never``, each is a
        predicate in the spec's terms (``"cell::rate == 5 && request R0 finished"``, docs/checking.md,
        "Properties in the spec's terms") or a CLF pattern (``"busy P * busy P"``);
        ``incompatible`` pairs of 'agent::task' names the ``incompatible-tasks`` property (no two
        live requests hold them at once; without pairs it checks those the spec makes incompatible).
        ``time="timed"`` (with ``wait_timeout`` in ms) explores the timed model (a job's ``time``).
        ``crash`` names agents that may crash and come back, at most ``max_crashes`` times in a
        run (a job's [faults] table; docs/semantics.md, Crashes). ``kept`` (sequential achievement, as a
        property file's ``[sequential-achievement] kept``): True, or the 'agent.task.recipe' names
        whose achieved sub-goals must still hold when a later one of their block is achieved and
        when the recipe ends."""
        from ..roar.compile import Crashes
        from ..verify.jobs import Job, PropertySpec
        # marked "(a default property)" as check marks them, unless never or incompatible add one that is not
        defaulted = properties is None and not never and not incompatible
        properties = SPEC_DEFAULTS if properties is None else listed(properties)
        progress, sequence_recipes = listed(progress), listed(sequence_recipes)
        wanted = list(properties) + (["incompatible-tasks"] if incompatible and "incompatible-tasks" not in properties
                                     else [])
        props = _properties(wanted, never, ROAR_PROPERTIES)
        spec_path = self._file()
        ps = PropertySpec(check=props, sequence_recipes=list(sequence_recipes), defaulted=defaulted)
        pos = _caller_pos()
        ps.never, ps.spec_never = split_never(never, pos)
        ps.progress, ps.spec_progress = split_progress(progress, pos)
        for pair in incompatible:
            if isinstance(pair, str) or len(pair) != 2 or not all(isinstance(x, str) and "::" in x for x in pair):
                raise RoarError(f"incompatible is a list of pairs of tasks named 'agent::task', not {pair!r}", pos)
            ps.incompatible_pairs.append(((pair[0], pos), (pair[1], pos)))
        for r in sequence_recipes:
            if not isinstance(r, str) or r.count(".") != 2:
                raise RoarError(f"sequence_recipes are named 'agent.task.recipe', not {r!r}", pos)
        if isinstance(kept, bool):
            ps.sequence_kept = kept
        else:
            kept = listed(kept)
            for r in kept:
                if not isinstance(r, str) or r.count(".") != 2 or not all(r.split(".")):
                    raise RoarError(f"kept is True or a list of recipes named 'agent.task.recipe', not {r!r}", pos)
                ps.sequence_at.setdefault(r, pos)
            ps.sequence_kept = list(kept)
        job = Job(path=spec_path, name=name or _job_name(self.name, request), model=None, props=ps,
                  budget=as_budget(budget), reduction=reduction, spec=spec_path, request=request,
                  functional=self.functional)
        job.request_at = _request_at(request)
        job.crashes = Crashes(tuple([crash] if isinstance(crash, str) else crash), max_crashes) if crash else None
        job.time = _timing(time, wait_timeout)
        return _explore(job)

    def explore_on_robot(self, request: str, scenario: PathLike,
                         properties: Sequence[str] = ("deadlock", "livelock"), *,
                         faults: Union[Sequence[str], dict] = (), on: Sequence[str] = (), seed: Optional[int] = None,
                         quantise: Any = None, robot_never: Sequence[str] = (), robot_always: Sequence[str] = (),
                         never: Sequence[str] = (), progress: Sequence[str] = (), budget: BudgetLike = None,
                         compare: bool = False, name: Optional[str] = None) -> "Exploration":
        """Explore with the reference robot as the functional layer (docs/robot.md, robot-backed
        checking): every interleaving, every order of starting pending calls, and every choice of
        the fault points ``faults`` (a list: armed at any call; a dict: fault point -> the
        primitives at whose calls it may be armed). ``quantise`` is ``"exact"``, a dict
        (position, heading, speed, clock, memory) or an ``Abstraction``; ``robot_never`` /
        ``robot_always`` are conditions on the robot state (``"contact"``) checked at every tick.
        ``seed`` is the robot's (default: the scenario's ``seed``)."""
        from ..verify.jobs import Job, PropertySpec, RobotSetup
        from ..robot.explore import Abstraction
        allowed = ROAR_PROPERTIES + ("robot-invariant",)
        properties, on, progress = listed(properties), listed(on), listed(progress)
        robot_never, robot_always = listed(robot_never), listed(robot_always)
        if not isinstance(faults, dict):
            faults = listed(faults)
        props = _properties([p for p in properties if p != "robot-invariant"], never, allowed)
        pos = _caller_pos()
        if robot_never or robot_always:
            props.append("robot-invariant")
        ps = PropertySpec(check=props)
        ps.progress, ps.spec_progress = split_progress(progress, _caller_pos())
        ps.never, ps.spec_never = split_never(never, pos)
        ps.robot_never = [(c, pos) for c in robot_never]
        ps.robot_always = [(c, pos) for c in robot_always]
        if isinstance(quantise, str):
            if quantise != "exact":
                raise RoarError(f"quantise is 'exact', a dict or an Abstraction, not {quantise!r}", pos)
            quantise = Abstraction(exact=True)
        elif isinstance(quantise, dict):
            try:
                quantise = Abstraction(**quantise)
            except TypeError as exc:
                raise RoarError(f"quantise: {exc}; keys: position, heading, speed, clock, memory", pos) from None
        if isinstance(faults, dict):
            fault_at = {n: None if at is None else frozenset([at] if isinstance(at, str) else at)
                        for n, at in faults.items()}
        else:
            fault_at = {n: None for n in ([faults] if isinstance(faults, str) else faults)}
        setup = RobotSetup(scenario=Path(scenario).resolve(), seed=seed, faults=fault_at, on=tuple(on),
                           quantise=quantise, compare=compare, pos=pos)
        spec_path = self._file()
        job = Job(path=spec_path, name=name or _job_name(self.name, request), model=None, props=ps,
                  budget=as_budget(budget), spec=spec_path, request=request, functional=self.functional,
                  robot=setup)
        job.request_at = _request_at(request)
        return _explore(job)

    def _file(self) -> Path:
        if self.path is None:
            raise RoarError(f"{self.name}: a spec built from a tree has no file to explore; use AgentSpec.from_text")
        return _written(self.path, self.text) if self.text is not None else self.path

    # -- on the robot --------------------------------------------------------------------
    def conform(self, request: str, scenario: PathLike, *, runs: int = 3, seed: Optional[int] = None, faults: Sequence[str] = (),
                random_faults: bool = True, max_steps: int = 200_000, on_run: Optional[Any] = None) -> Any:
        """``roar-verify conform``: seeded robot runs, each result classified into a declared outcome
        and each run replayed on the model; returns the robot's ``ConformReport`` (``.sound``,
        ``.lines()``, ``.as_json()``). ``faults`` are scenario fault points always on (the others are
        drawn at random unless ``random_faults`` is false); ``on_run(k, summary)`` is called after
        run ``k`` (from 0). Run ``k`` has seed ``seed + k``, ``seed`` by default the scenario's."""
        from ..roar.compile import compile_spec
        from ..robot.binding import load_robot_binding
        from ..robot.setup import split_faults
        from ..robot.conform import conform
        from ..robot.scenario import load_scenario
        if runs < 1:
            raise RoarError(f"runs must be at least 1, not {runs}")
        sc = load_scenario(Path(scenario))
        binding = load_robot_binding(self._file(), self.functional)
        model = compile_spec(self.ast, request, registry=binding.robot, functional="python",
                             request_at=_request_at(request))
        world, prims = split_faults(listed(faults), sc, model)
        if prims:
            raise RoarError("conform draws the scenario's fault points; primitive faults "
                            f"({', '.join(map(str, prims))}) are not allowed here")
        return conform(self.ast, request, model, binding, sc, runs=runs, seed=sc.seed if seed is None else seed,
                       always=world,
                       random_faults=random_faults, max_steps=max_steps, spec_name=self.name, on_run=on_run)


def _run_model(model: "CompiledModel", seed: int, max_steps: int, registry: Optional["Registry"], faults: list,
               fair: bool, crashes: list = ()) -> "RunResult":
    from ..roar.run import run_model
    return run_model(model, seed=seed, max_steps=max_steps, registry=registry, faults=faults, fair=fair,
                     crashes=crashes)


_UNUSED = re.compile(r"^--fault (.*): no such call happened in this run")


def _run_tolerant(go, faults: list, strict: Optional[bool], scheduled: Iterable["Fault"] = ()):
    """Run with ``faults``. A fault that matched no call is an error (the command line's) with
    ``strict``; without (False), it is dropped (the run is the same without it: it never changed
    an answer) and returned as unused; by default (None) only the ``scheduled`` ones (drawn by a
    generated schedule) are dropped so, and any other one is the error."""
    try:
        return go(faults), []
    except RoarError as exc:
        m = _UNUSED.match(exc.message)
        if strict or m is None:
            raise
        names = set(m.group(1).split(", "))
        unused = [f for f in faults if str(f) in names]
        if not unused:
            raise
        if strict is None:
            keep = set(scheduled)
            given = [f for f in unused if f not in keep]
            if given:
                raise RoarError(_UNUSED_MESSAGE.format(names=", ".join(str(f) for f in given))) from None
        return go([f for f in faults if f not in unused]), unused


#: the command line's message for faults that matched no call (roar/run.py's run_model)
_UNUSED_MESSAGE = "--fault {names}: no such call happened in this run (check the name and the call number)"


def _check_fault_names(faults: Sequence["Fault"], spec: "AgentSpec", model: "CompiledModel") -> None:
    """A fault naming no function of the spec (``f`` or ``agent::f``) cannot match a call: refused
    before the run, with the closest name."""
    from ..errors import did_you_mean
    known: dict[str, None] = {}
    pairs = list(spec.functions()) + [(o, n) for o, n in model.functions.values()]
    for owner, name in pairs:
        known[name] = None
        if owner:
            known[f"{owner}::{name}"] = None
    for f in faults:
        if f.name in known:
            continue
        names = sorted({n for _o, n in pairs})
        what = f"its functions: {', '.join(names)}" if names else "it calls no function"
        raise RoarError(f"--fault {f}: the spec has no function '{f.name}'{did_you_mean(f.name, known)}; {what} "
                        "(checked before the run)")


def _job_name(spec_name: str, request: str) -> str:
    """The spec's file stem: it names the counterexample traces (``pick.deadlock.jsonl``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", Path(spec_name.strip("<>")).stem) or "spec"


def _timing(time: Any, wait_timeout: Optional[int]):
    """A ``roar.compile.Timing`` from the API's ``time`` ("untimed", "timed" or a Timing) and
    ``wait_timeout`` (ms), checked; None when untimed."""
    from ..roar.compile import Timing, timing_of
    if time is None and wait_timeout is None:
        return None
    if wait_timeout is not None:
        if time is None:   # untimed (the default): a timeout alone does not choose the timed mode
            raise RoarError("wait_timeout needs the timed mode (time = \"timed\", --time timed): "
                            "an untimed wait never times out")
        if isinstance(time, Timing):
            if time.wait_timeout is not None and time.wait_timeout != wait_timeout:
                raise RoarError(f"wait_timeout given twice: {time.wait_timeout} ms in the Timing and "
                                f"{wait_timeout!r} ms; give it once")
            time = Timing(time.mode, wait_timeout, time.where)
        else:
            time = Timing(time, wait_timeout)
    return timing_of(time)


def _properties(properties: Sequence[str], never: Sequence[str], allowed: tuple) -> list[str]:
    if isinstance(properties, str):
        properties = [properties]
    out: list[str] = []
    for p in properties:
        if p not in allowed:
            from ..errors import did_you_mean
            raise RoarError(f"unknown property {p!r}{did_you_mean(str(p), allowed)}; expected one of: "
                            f"{', '.join(allowed)}", _written_at(_caller_pos(), str(p)))
        if p not in out:
            out.append(p)
    if never and "invariant" not in out:
        out.append("invariant")
    if "invariant" in out and not never:
        raise RoarError("property 'invariant' needs patterns: never=[\"...\"]", _caller_pos())
    if not out:
        raise RoarError("nothing to check: name at least one property", _caller_pos())
    return out


def _split_terms(items: Sequence[str], pos: Pos, what: str, example: str) -> tuple[list, list]:
    """``items`` read as a job file reads them: the predicates in the spec's terms (parsed
    ``Formula``s), and the others (CLF patterns or rule names, as given); ``what`` names the
    argument and ``example`` what else it takes, for the error on an item that is neither."""
    from ..roar.props import looks_like_spec, parse_formula
    if isinstance(items, str):
        items = [items]
    other: list = []
    spec: list = []
    for p in items:
        if not isinstance(p, str) or not p.strip():
            raise RoarError(f"{what} is a list of predicates in the spec's terms or of {example}, not {p!r}", pos)
        if looks_like_spec(p):
            spec.append(parse_formula(p, _string_pos(pos, p), temporal=False))
        else:
            other.append(p)
    return other, spec


def split_never(never: Sequence[str], pos: Pos) -> tuple[list, list]:
    """``never`` of an exploration of a spec (or of a stateful machine), read as a job file reads
    ``[invariant] never``: CLF patterns (``(text, pos)``) and predicates in the spec's terms."""
    clf, spec = _split_terms(never, pos, "never", 'CLF patterns such as "busy P * busy P"')
    return [(p, _string_pos(pos, p)) for p in clf], spec


def split_progress(progress: Sequence[str], pos: Pos) -> tuple[list, list]:
    """``progress`` of an exploration, read as a job file reads ``[livelock] progress``: rule names
    (globs) and predicates in the spec's terms (a step into a state where one holds is progress)."""
    return _split_terms(progress, pos, "progress", "rule names")


def _string_pos(pos: Pos, text: str) -> Pos:
    """Where ``text`` starts on the caller's line (inside its quotes), so that an error inside a
    predicate points at its column; the line's start if it is not there."""
    import linecache
    col = linecache.getline(str(pos.file), pos.line).find(text)
    return Pos(pos.file, pos.line, col + 1) if col >= 0 else pos


def variable_value(model: "CompiledModel", state, var: str, where: str) -> object:
    """The value of the spec variable ``agent::var`` in a state of its compiled model (numbers as
    int or Fraction); ``where`` names the spec in errors."""
    from ..clf.terms import Const
    from ..roar import vocabulary as V
    from ..roar.run import value_of
    agent, _, name = var.partition("::")
    cell = f"v_{agent}_{name}"
    if not name or cell not in model.cells:
        raise RoarError(f"no variable {var!r} in {where} (write 'agent::var')")
    bag = state.index.get(Const(V.CONTAINS)) if hasattr(state, "index") else None
    items = bag.items if bag else [f for _m, f, _n in state.facts() if getattr(f.head, "name", None) == V.CONTAINS]
    for c in map(V.contains, items):
        if c.cell.head.name == cell:
            return value_of(c.value)
    raise RoarError(f"{var} holds no value in this state")


def _request_at(request) -> Optional[Pos]:
    """Where a request given as text is written in the caller's code (its line, the column inside
    the quotes when the text is on that line), so that an error in it is reported there."""
    if not isinstance(request, str):
        return None
    pos = _caller_pos()
    at = _string_pos(pos, request)
    return at if at is not pos else None


def _explore(job) -> "Exploration":
    from ..verify.check import run_job
    return Exploration(run_job(job))


#: the style of each verdict status, where the command line shows it
STATUS_STYLE = {"holds": "green", "violated": "red", "incomplete": "yellow"}


def _verdict_line(prop: str, v: "Verdict") -> Lines:
    return Lines().add(f"  {prop}: ", (v.status, STATUS_STYLE.get(v.status, "")), f" — {v.message}", wrap=True)


# ---------------------------------------------------------------------------- job files


class Job:
    """A verification job (docs/checking.md): a job file (``*.toml``), or a model or spec named
    directly with its properties, as ``roar-verify check`` takes them. :meth:`run` explores it.
    ``budget`` is the job's :class:`Budget` (its ``[bounds]``), which may be changed before running."""

    def __init__(self, job: Any):
        self.job = job    # the verify.jobs.Job

    @property
    def name(self) -> str:
        return self.job.name

    @property
    def path(self) -> Path:
        return self.job.path

    @property
    def budget(self) -> Budget:
        return self.job.budget

    @property
    def expect(self) -> dict[str, str]:
        """property -> expected status (the job's ``[expect]``)."""
        return self.job.expect

    @property
    def properties(self) -> list[str]:
        return list(self.job.props.check)

    def run(self, progress: Optional[Any] = None) -> Exploration:
        """Explore: the verdicts and counterexamples. ``progress(stats)`` is called now and then with
        ``states``, ``transitions``, ``states_per_s``, ``frontier``, ``memory_mb``."""
        from ..verify.check import run_job
        return Exploration(run_job(self.job, progress))

    def __repr__(self) -> str:
        return f"<Job {self.name} ({self.path}): {', '.join(self.properties)}>"


def is_model_path(path: PathLike) -> bool:
    """Is ``path`` a model or spec to check directly (a ``.clf``, ``.roar``, ``.ability`` file or a
    hyper folder), not a job file or a folder of them?"""
    from ..verify.jobs import is_model_path as model_path
    return model_path(Path(path))


def load_job(path: PathLike) -> Job:
    """A job file, read and checked (every mistake located)."""
    from ..verify.jobs import load_job as read_job
    return Job(read_job(Path(path)))


def load_jobs(paths: Sequence[PathLike], *, request: Optional[str] = None,
              properties: Sequence[str] = (), time: Any = None, wait_timeout: Optional[int] = None,
              functional: Optional[PathLike] = None, property_files: Sequence[PathLike] = ()) -> list[Job]:
    """What ``roar-verify check PATH...`` checks: job files, the job files of folders (sorted), and
    models or specs named directly (checked for ``properties``, a spec on ``request`` with the
    functional layer ``functional`` or the module next to it, explored untimed or, with
    ``time="timed"``, timed; ``property_files`` say how to check them, as a job's would). Every
    job is read and checked before any runs."""
    from ..verify.jobs import find_jobs, job_for_model
    from ..verify.jobs import load_job as read_job
    ps = [Path(p) for p in paths]
    models = [p for p in ps if is_model_path(p)]
    files = find_jobs([p for p in ps if not is_model_path(p)]) if len(models) < len(ps) else []
    if property_files and not models:
        raise RoarError("--properties is for a model or spec named on the command line; a job file names its "
                        "own (properties = [\"file.toml\"])")
    direct = [job_for_model(p, request, list(properties), property_files) for p in models]
    if wait_timeout is not None and not direct:
        raise RoarError("--wait-timeout is for a spec named on the command line; a job file says its own "
                        "([time] wait_timeout)")
    if functional is not None:
        specs = [j for j in direct if j.is_roar]
        if not specs:
            raise RoarError("--functional is for a spec named on the command line; a job file says its own "
                            "(functional = \"module.py\")")
        fn = Path(functional)
        if not fn.is_file():
            raise RoarError(f"--functional {fn}: no such file")
        for j in specs:
            j.functional = fn.resolve()
    timing = _timing(time, wait_timeout)
    if timing:
        if not direct:
            raise RoarError("--time is for a spec named on the command line; a job file says its own "
                            "(time = \"timed\")")
        for j in direct:
            if not j.is_roar:
                raise RoarError(f"{j.path}: --time is for a ROAR spec; a .clf program has no periods")
            j.time = timing
    return [Job(read_job(f)) for f in files] + [Job(j) for j in direct]


def write_html_report(folder: PathLike, explorations: Sequence[Exploration], inputs: Sequence[PathLike] = ()) -> Path:
    """An HTML report of explorations (``roar-verify check --html``): the summary, each verdict and
    counterexample, its chart and its trace; the path of its ``index.html``. A file in ``inputs`` is
    never overwritten."""
    from ..verify.html import write_html_report as write_html
    return write_html(Path(folder), [e.result for e in explorations], [e.as_json() for e in explorations],
                      tuple(inputs))


# ---------------------------------------------------------------------------- runs


@dataclass
class RunReport:
    """One run of a spec on a request: its outcome, ROAR-level events and final values.

    ``str(report)`` is what ``roar-verify run`` prints (``simulate`` on the robot); the command
    line prints :meth:`lines`, the same document with its styles.
    """

    spec: str
    request: str
    seed: int
    faults: tuple[str, ...]              # as given (``--fault`` values, scenario fault points on the robot)
    result: "RunResult"
    max_steps: int
    unused_faults: tuple[str, ...] = ()
    robot: Any = None        # the robot's SimResult, for a run on a scenario
    scenario: Any = None     # its Scenario
    scenario_path: Optional[Path] = None
    functional: Optional[Path] = None    # the functional-layer module the run used (named in its trace)

    @property
    def outcome(self) -> str:
        """The request's final state: success, failure, running, paused, ... ("unfinished" at the start)."""
        return self.result.outcome

    @property
    def ok(self) -> bool:
        return self.result.ok

    @property
    def quiescent(self) -> bool:
        return self.result.quiescent

    @property
    def events(self) -> list["RoarEvent"]:
        return self.result.events

    @property
    def final(self) -> dict[str, object]:
        """Every variable's final value, keyed ``agent::var``."""
        return self.result.final

    @property
    def error_context(self) -> list[str]:
        return self.result.error_context

    @property
    def clf_steps(self) -> int:
        return len(self.result.steps)

    # -- printing: the command line prints these lines ---------------------------------
    def header_lines(self) -> Lines:
        """The first line: spec, request (and scenario), faults, seed."""
        faults = f", faults {', '.join(self.faults)}" if self.faults else ""
        if self.robot is not None:
            return Lines().add(f"{self.spec}: request {self.request} on scenario {self.scenario.name}, "
                               f"seed {self.seed}{faults}")
        return Lines().add((self.spec, "bold"), ": request ", (self.request, "cyan"), f"{faults}, seed {self.seed}",
                           wrap=True)

    def event_lines(self, verbose: bool = False) -> Lines:
        """The step table of ``trace.render`` (with time and pose on the robot); ``verbose`` adds
        each event's CLF rule."""
        from ..trace.render import event_lines, event_rows
        if self.robot is not None:
            res = self.robot
            return event_lines(event_rows(res.events, res.times, res.poses, [st.rule for st in res.run.steps.raw]),
                               verbose=verbose)
        return event_lines(event_rows(self.events, rules=[s[0] for s in self.result.steps]), verbose=verbose)

    def end_lines(self) -> Lines:
        """How the run ended, its error context, and warnings (unused faults; on the robot, results
        no declared outcome covers)."""
        out = Lines()
        style = "green" if self.ok else "red"
        if self.robot is not None:
            res = self.robot
            end = {"quiescent": "quiescent", "horizon": f"horizon of {self.scenario.horizon:g} s reached",
                   "max-steps": f"stopped after {self.max_steps} CLF steps",
                   "zero-time loop": "stopped: the agents kept stepping without the robot's time advancing, "
                                     "a loop that calls no primitive taking time"}.get(res.end, res.end)
            x, y, th = res.robot.world.base.pose
            out.add((f"request {res.outcome}", style),
                    f" at t = {res.robot.time:.2f} s after {len(res.run.steps)} CLF steps ({end}); "
                    f"robot at ({x:.2f}, {y:.2f}), heading {th * 57.29577951308232:.0f}°")
            for e in self.error_context:
                out.add(f"  error context: {e}")
            for line in _unsuccessful_calls(res.calls):
                out.add(line, wrap=True)
            for c in res.uncovered():
                out.add(f"  warning: call {c.n} {c.function}({', '.join(map(str, c.args))}) at t = {c.t_end:.2f} s "
                        f"returned {c.result.as_json()}, which no declared outcome covers", style="yellow")
        else:
            end = ("quiescent" if self.quiescent else
                   f"stopped at the bound of {self.max_steps} steps, the functional layer's answers included")
            out.add((f"request {self.outcome}", style), f" after {self.clf_steps} CLF steps ({end})", wrap=True)
            if not self.quiescent:   # a run stops where a bound says, not where the system does
                out.add("  one run cannot tell whether this goes on forever: `roar-verify check` on the same spec "
                        "and request decides it for every run (mission-completion, and livelock with a progress "
                        "property), with a lasso when it can", wrap=True)
            for line in self.error_context:
                out.add(f"  error context: {line}", wrap=True)
            if self.outcome == "failure" and not self.error_context:   # (as the explorer says it)
                from ..roar.props import NO_TASK
                out.add(f"  error context: {NO_TASK}", wrap=True)
        if self.unused_faults:
            out.add(f"  faults that matched no call: {', '.join(self.unused_faults)}", style="yellow")
        return out

    def lines(self, verbose: bool = False) -> Lines:
        """The whole run as the command line prints it."""
        return self.header_lines().extend(self.event_lines(verbose)).extend(self.end_lines())

    def format(self, verbose: bool = False) -> str:
        """The run as the command line prints it, as plain text."""
        return self.lines(verbose).text()

    def __str__(self) -> str:
        return self.format()

    def __repr__(self) -> str:   # short: pytest shows it under a failed `assert run.ok, run`
        return f"<run of {self.request!r}: {self.outcome} after {self.clf_steps} CLF steps>"

    def value(self, var: str) -> object:
        """The final value of ``agent::var``."""
        if var not in self.final:
            raise RoarError(f"no variable {var!r}; the variables are: {', '.join(sorted(self.final))}")
        return self.final[var]

    def as_json(self) -> dict:
        """The run as ``roar-verify run --json`` (``simulate --json`` on the robot) prints it."""
        if self.robot is not None:
            res = self.robot
            x, y, th = res.robot.world.base.pose
            return {"spec": self.spec, "scenario": str(self.scenario_path), "request": self.request,
                    "seed": self.seed, "faults": list(self.faults), "outcome": res.outcome, "end": res.end,
                    "time": round(res.robot.time, 4), "pose": [x, y, th], "clf_steps": len(res.run.steps),
                    "error_context": res.run.error_context, "calls": [c.as_json() for c in res.calls],
                    "uncovered": [c.n for c in res.uncovered()],
                    "events": [dict(step=e.step, time=round(res.times[e.step - 1], 4), **e.as_json())
                               for e in res.events]}
        from ..roar.traces import jsonable
        return {"spec": self.spec, "request": self.request, "seed": self.seed, "faults": list(self.faults),
                "outcome": self.outcome, "quiescent": self.quiescent, "clf_steps": self.clf_steps,
                "error_context": self.error_context, "final": {k: jsonable(v) for k, v in self.final.items()},
                "events": [dict(step=e.step, **e.as_json()) for e in self.events]}

    # -- files ----------------------------------------------------------------------------
    def save_trace(self, path: PathLike) -> Path:
        """Write the run as a JSON Lines trace (the format of ``roar-verify run --trace``,
        ``simulate --trace`` on the robot): ``roar-verify replay`` reads it."""
        from ..roar.traces import write_run_trace
        p = Path(path)
        if self.robot is not None:
            from ..roar.sources import spec_files
            from ..robot.report import write_robot_trace
            write_robot_trace(p, self.robot, self.spec, self.request, str(self.scenario_path),
                              spec_files(self.result.model.spec))
        else:
            write_run_trace(p, self.result, self.spec, self.request, self.seed, list(self.faults), self.functional)
        return p

    def save_chart(self, png: Optional[PathLike] = None, svg: Optional[PathLike] = None) -> list[Path]:
        """Draw the run's message sequence chart into the PNG and SVG files asked for; the paths
        written. (On the robot, :meth:`save_picture` draws the map and the trajectory.)"""
        from ..verify.pictures import write_chart
        from ..verify.report import run_report
        return write_chart(run_report(self.result), f"{Path(self.spec).name}: request {self.request}: {self.outcome}",
                           f"the run of {self.request}", None if png is None else Path(png),
                           None if svg is None else Path(svg))

    def save_task_tree(self, path: PathLike) -> Path:
        """Write the run's task tree (goals, commands, sequential-achievement constraints) as DOT."""
        from ..roar.traces import run_records
        from ..tca.roar_runs import task_tree_events
        from ..tca.tree_dot import task_tree_dot
        from ..trace.format import write_atomic
        header, records = run_records(self.result, self.spec, self.request, self.seed, list(self.faults),
                                      self.functional)
        p = Path(path)
        write_atomic(p, task_tree_dot(task_tree_events(header, records),
                                      f"{Path(self.spec).name}: request {self.request}: {self.outcome}"))
        return p

    def save_picture(self, path: PathLike) -> Path:
        """On the robot: draw the map, the planned paths and the trajectory (PNG)."""
        if self.robot is None:
            raise RoarError("a picture of the robot needs a run on a scenario (run(..., scenario=...))")
        from ..robot.report import draw_sim
        draw_sim(Path(path), self.robot)
        return Path(path)


# ---------------------------------------------------------------------------- exploration


class Counterexample:
    """A counterexample of one property: a path to a bad state, or a lasso (livelock)."""

    def __init__(self, exploration: "Exploration", prop: str):
        self.exploration = exploration
        self.prop = prop
        self.verdict = exploration.verdicts[prop]
        assert self.verdict.counterexample is not None
        self._cx = self.verdict.counterexample

    @property
    def kind(self) -> str:
        """'path' or 'lasso'."""
        return self._cx.kind

    def __len__(self) -> int:
        return self._cx.length()

    @property
    def steps(self) -> list[dict]:
        """The steps as trace records (rule, consumed, produced, group, event, loop)."""
        from ..verify.results import counterexample_steps
        r = self.exploration.result
        return counterexample_steps(r.graph, self.verdict, r)

    @property
    def events(self) -> Optional[list[list["RoarEvent"]]]:
        """For a spec, the ROAR events of each step (None for a .clf model)."""
        from ..verify.results import roar_events
        return roar_events(self.exploration.result, self.verdict)

    @property
    def trace(self) -> Optional[Path]:
        """Where the counterexample was saved (:meth:`save`), if it was."""
        return getattr(self.exploration.result, "saved", {}).get(self.prop)

    def save(self, folder: PathLike) -> Path:
        """Write the replayable trace (``roar-verify replay``) into ``folder``; its path is printed with it."""
        from ..verify.results import save_counterexample
        r = self.exploration.result
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        path = save_counterexample(r, self.prop, folder)
        saved = dict(getattr(r, "saved", {}) or {})
        saved[self.prop] = path
        r.saved = saved
        return path

    def lines(self, verbose: bool = False) -> Lines:
        """The verdict line and the counterexample, as ``roar-verify check`` prints them (styled);
        ``verbose`` adds the facts each step consumed and produced."""
        from ..verify.report import counterexample_lines
        out = _verdict_line(self.prop, self.verdict)
        return out.extend(counterexample_lines(self.exploration.result, self.prop, verbose))

    def format(self, verbose: bool = False) -> str:
        """The verdict line and the counterexample, as ``roar-verify check`` prints them."""
        return self.lines(verbose).text()

    def __str__(self) -> str:
        return self.format()

    def __repr__(self) -> str:
        return f"<{self.prop} counterexample: {self.kind} of {len(self)} steps>"


def _unsuccessful_calls(calls: list) -> list[str]:
    """The robot calls that failed, a line per function and status (how many,
    and the last one with why it ended so, when the robot says): a spec that waits for a
    primitive the robot keeps refusing shows why in its run, not only as a false in the table."""
    groups: dict = {}
    for c in calls:
        if c.result is not None and c.result.failed:   # (a read that answers false did not fail)
            groups.setdefault((c.agent, c.function, c.result.status), []).append(c)
    if not groups:
        return []
    out = ["  calls that did not succeed on the robot:"]
    for (agent, fn, status), cs in groups.items():
        last = cs[-1]
        d = last.result.detail
        name = fn if "::" in fn else f"{agent}::{fn}"
        why = ""
        if d.get("why") == "obstacle ahead":
            why = (f": the safety stop saw an obstacle at ({d.get('ox', float('nan')):.2f}, "
                   f"{d.get('oy', float('nan')):.2f}) on the path ahead and waited {d.get('waited', 0):.1f} s")
        elif d.get("why") == "no progress":
            why = f": the base made no progress for {d.get('waited', 0):.1f} s (pushing against something?)"
        times = f"{len(cs)} times, the last" if len(cs) > 1 else "once,"
        out.append(f"    {name} {status}: {times} at t = {last.t_end:.2f} s{why}")
    return out


class Exploration:
    """The result of exploring a model: a verdict per property, statistics, counterexamples."""

    def __init__(self, result: "JobResult"):
        self.result = result

    @property
    def name(self) -> str:
        return self.result.job.name

    @property
    def title(self) -> str:
        """What was explored: ``SPEC, request R`` or ``MODEL.clf`` (with its start when not the first)."""
        job = self.result.job
        if job.is_roar:
            return f"{job.spec}, request {job.request}"
        return str(job.model) + (f", start {job.start}" if job.start != 1 else "")

    @property
    def verdicts(self) -> dict[str, "Verdict"]:
        return self.result.verdicts

    def verdict(self, prop: str) -> "Verdict":
        if prop not in self.verdicts:
            raise RoarError(f"property {prop!r} was not checked; checked: {', '.join(self.verdicts)}")
        return self.verdicts[prop]

    def status(self, prop: str) -> str:
        """holds, violated or incomplete."""
        return self.verdict(prop).status

    def holds(self, prop: str) -> bool:
        return self.verdict(prop).status == "holds"

    def violated(self, prop: str) -> bool:
        return self.verdict(prop).status == "violated"

    def counterexample(self, prop: str) -> Optional[Counterexample]:
        return Counterexample(self, prop) if self.verdict(prop).counterexample is not None else None

    @property
    def states(self) -> int:
        return self.result.graph.n_states

    @property
    def transitions(self) -> int:
        g = self.result.graph
        return g.n_edges + g.n_unrecorded   # a bitstate search counts some without recording them

    @property
    def complete(self) -> bool:
        """The whole reachable state space was explored."""
        return bool(self.result.graph.complete)

    @property
    def seconds(self) -> float:
        return self.result.seconds

    @property
    def backend(self) -> str:
        return self.result.backend

    @property
    def memory_mb(self) -> float:
        return self.result.memory_mb

    @property
    def ok(self) -> bool:
        """Every verdict as the job expects (with no expectation: no violation)."""
        return self.result.ok

    @property
    def incomplete(self) -> list[str]:
        """Properties the job expects nothing of whose search ran out of budget: no verdict."""
        return self.result.incomplete

    @property
    def unexpected(self) -> list[str]:
        """Why the job fails: verdicts other than the expected ones, violations nothing was expected of."""
        return self.result.unexpected

    def expected(self, prop: str) -> Optional[str]:
        """The verdict the job expects of ``prop`` (its ``[expect]``), or None."""
        return self.result.job.expect.get(prop)

    @property
    def robot(self) -> Any:
        """For a robot-backed exploration, its robot run (``describe()``, ``comparison``); else None."""
        return getattr(self.result, "robot", None)

    def save_counterexamples(self, folder: PathLike) -> dict[str, Path]:
        """Save every counterexample's trace into ``folder``; property -> path."""
        out = {}
        for p in self.verdicts:
            cx = self.counterexample(p)
            if cx is not None:
                out[p] = cx.save(folder)
        self.result.saved = out
        return out

    def save_pictures(self, png: Optional[PathLike] = None, svg: Optional[PathLike] = None,
                      dot: Optional[PathLike] = None, inputs: Sequence[PathLike] = ()) -> dict[str, list]:
        """A message sequence chart (PNG, SVG) and the state graph (DOT) of each counterexample, one
        file per property in each folder given; property -> paths (and notes saying why a DOT file
        was not written). A file in ``inputs`` is never overwritten."""
        from ..verify.pictures import write_pictures
        pics = write_pictures(self.result, None if png is None else Path(png), None if svg is None else Path(svg),
                              None if dot is None else Path(dot), tuple(inputs)) if (png or svg or dot) else {}
        self.result.pictures = pics
        return pics

    def as_json(self) -> dict:
        """The job as ``roar-verify check --json`` prints it (one element of its list)."""
        from ..verify.results import counterexample_steps
        from ..verify.report import counterexample_report
        r = self.result
        out = {"job": r.job.name, "file": str(r.job.path),
               "model": str(r.job.model if not r.job.is_roar else r.job.spec),
               # as the text's first word: "ok" only when every verdict is there and as expected
               "ok": r.ok and not self.incomplete,
               "result": "unexpected" if not r.ok else "incomplete" if self.incomplete else "ok",
               "backend": r.backend, "reduction": getattr(r, "reduction", "off"), "states": r.graph.n_states,
               "transitions": r.graph.n_edges + r.graph.n_unrecorded, "complete": bool(r.graph.complete),
               "incomplete": list(self.incomplete),
               # every "holds" a proof: an exact visited set, every reachable state explored
               # (a swarm's graph is complete only when one of its searches covered the whole space)
               "exhaustive": bool(r.graph.complete) and r.job.visited == "exact",
               "visited": r.job.visited, "seconds": round(r.seconds, 4),
               # what makes the job fail, as the text says it: verdicts other than expected, and
               # violations nothing expected (a command-line check expects every property to hold)
               "memory_mb": round(r.memory_mb, 1), "mismatches": r.unexpected, "verdicts": {}}
        robot = self.robot
        if robot is not None:
            out["robot"] = {"setup": robot.describe(), "abstraction": robot.abstraction.as_json(),
                            "horizon_states": robot.horizon_states, **robot.tree.stats(),
                            "comparison": [{"property": p, "abstract": av, "robot": rv, "why": why}
                                           for p, av, rv, why in robot.comparison]}
        for p, v in r.verdicts.items():
            d = {"status": v.status, "message": v.message, "expected": r.job.expect.get(p)}
            if "visited" in v.details:   # hash compaction, bitstate: what the verdict is worth
                for k in ("visited", "omission_probability", "expected_omissions", "bits", "unrecorded_transitions"):
                    if k in v.details:
                        d[k] = v.details[k]
            for k in ("reduced_expansions", "steps_left_out"):   # what a partial-order reduction left out
                if k in v.details:
                    d[k] = v.details[k]
            if v.counterexample is not None:
                d["counterexample"] = {"shape": v.counterexample.kind, "steps": counterexample_steps(r.graph, v, r),
                                       "report": counterexample_report(r, p)}
                saved = getattr(r, "saved", {}).get(p)
                if saved:
                    d["trace"] = str(saved)
                pics = getattr(r, "pictures", {}).get(p)
                if pics:
                    d["pictures"] = [str(x) for x in pics if not isinstance(x, str)]
                    d["picture_notes"] = [x for x in pics if isinstance(x, str)]
            out["verdicts"][p] = d
        return out

    def _stats(self) -> str:
        # a swarm that found nothing: its statistics are its last search's; the verdicts say the total
        total = max((v.details.get("swarm_states", 0) for v in self.verdicts.values()), default=0)
        last = " in the last search" if total > self.states else ""
        return (f"({self.states:,} states{last}, {self.transitions:,} transitions, {self.seconds:.2f} s, "
                f"backend {self.backend})")

    def verdict_lines(self, verbose: bool = False, unexpected: bool = True) -> Lines:
        """Each verdict with its counterexample (and, robot-backed, the abstract model's verdicts
        beside the robot's; with ``unexpected``, then why the job fails)."""
        out = Lines()
        robot = self.robot
        if robot is not None:   # the abstraction is part of every robot-backed verdict: say it
            out.add(f"  robot: {robot.describe()}")
        for p, v in self.verdicts.items():
            cx = self.counterexample(p)
            out.extend(cx.lines(verbose) if cx is not None else _verdict_line(p, v))
        if robot is not None and robot.comparison:
            out.add("  abstract model vs robot:", wrap=True)
            for p, verdict_a, verdict_r, why in robot.comparison:
                out.add(f"    {p}: abstract {verdict_a}, robot {verdict_r} — {why}")
        for m in (self.result.unexpected if unexpected else ()):
            out.add(f"  {m}", style="red", wrap=True)
        return out

    def lines(self, verbose: bool = False) -> Lines:
        """The job as ``roar-verify check`` prints it: ``ok`` (or ``UNEXPECTED``), the job's name
        and statistics, then :meth:`verdict_lines`."""
        # (a job with no violation whose search ran out of budget is not "ok": it has no verdict)
        head = ("UNEXPECTED", "red") if not self.ok else ("incomplete", "yellow") if self.incomplete else ("ok", "green")
        out = Lines().add(head, " ", (self.name, "bold"), f"  {self._stats()}", wrap=True)
        return out.extend(self.verdict_lines(verbose))

    def format(self, verbose: bool = False) -> str:
        """Statistics, then each verdict with its counterexample, as ``roar-verify check`` prints a
        job; the first line names what was explored (``str(exploration)``)."""
        job = self.result.job
        what = f"{self.name}: request {job.request}" if job.is_roar else self.name
        return Lines().add(f"{what}  {self._stats()}").extend(self.verdict_lines(verbose, unexpected=False)).text()

    def __str__(self) -> str:
        return self.format()

    def __repr__(self) -> str:
        vs = ", ".join(f"{p} {v.status}" for p, v in self.verdicts.items())
        return f"<exploration of {self.name}: {vs}; {self.states:,} states>"


# ---------------------------------------------------------------------------- CLF models


@dataclass
class ClfRun:
    """A committed-choice run of a CLF program from one of its ``#exec`` start states."""

    rules: list[str]              # the rule of each step
    quiescent: bool
    state: list[str]              # the final context, one hypothesis a line
    seed: Optional[int] = 0

    @property
    def steps(self) -> int:
        return len(self.rules)

    def format(self) -> str:
        lines = [f"{i:>5}. {r}" for i, r in enumerate(self.rules, 1)]
        end = "quiescent" if self.quiescent else "stopped at the step bound"
        lines.append(f"{self.steps} steps ({end}); final state: {'; '.join(self.state)}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.format()


# ---------------------------------------------------------------------------- replay


def replay(trace: PathLike, model: Optional[PathLike] = None, *, functional: Optional[PathLike] = None,
           force: bool = False, _from_cli: bool = False) -> "Replay":
    """Replay a trace (a counterexample from :meth:`Exploration.save_counterexamples` or
    ``check``, or a run's trace) step by step on ``model`` (a spec or a ``.clf`` program: the
    trace's own is never opened), as ``roar-verify replay`` does. A step the model cannot take, or a
    trace of another version of the spec (unless ``force``), is a :class:`RoarError`."""
    from ..clf.query import with_big_stack
    from ..trace.format import read_trace
    from ..verify.replay import replay_trace
    if isinstance(model, (AgentSpec, ClfModel)):   # a loaded spec or program: its file
        if functional is None and isinstance(model, AgentSpec):
            functional = model.functional
        model = model._file() if isinstance(model, AgentSpec) else model.path
    if model is None and not _from_cli:
        from ..verify.replay import need_model
        raise need_model(trace, read_trace(trace)[0], "name it: replay(trace, model), with a ROAR spec (whose "
                         "functional-layer module next to it is used) or a .clf file")
    header, records = read_trace(trace)
    from ..robot.report import TRACE_KIND
    if header.get("kind") == TRACE_KIND and model is not None:
        return _replay_robot_run(Path(trace), header, records, model, functional, force)
    rep = with_big_stack(lambda: replay_trace(trace, model, functional=functional, force=force))
    return Replay(Path(trace), rep)


def _replay_robot_run(trace: Path, header: dict, records: list, model, functional, force: bool) -> "RobotReplay":
    """A robot run's trace on the abstract model, as ``roar-verify replay TRACE --model SPEC``."""
    from ..clf.query import with_big_stack
    from ..robot.conform import replay_robot_trace
    rp, confirmed, why = with_big_stack(lambda: replay_robot_trace(trace, header, records, model, functional, force))
    if not rp.ok:
        raise RoarError(f"{trace}: the robot's run is not a run of the model of {model}", None,
                        rp.divergence.lines())
    return RobotReplay(trace, rp.steps, list(rp.outcomes), confirmed, why)


@dataclass
class RobotReplay:
    """A robot run's trace replayed on the abstract model: every step a step of the model, each
    functional-layer answer in a declared outcome (``outcomes``: (step, function, outcome)), and
    whether the request ends as the trace records (``confirmed``; None when it records nothing)."""

    trace: Path
    steps: int
    outcomes: list = field(repr=False)
    confirmed: Optional[bool] = None
    confirmation: str = ""


@dataclass
class Replay:
    """A trace replayed on a model and read back in the model's terms: ROAR events and variable
    changes per step for a spec, the per-agent state after any step, and whether the end shows
    again what the trace claims (``confirmed``: True, False, or None when replay cannot re-decide
    the claim)."""

    trace: Path
    _rep: Any

    @property
    def steps(self) -> int:
        return len(self._rep.steps)

    @property
    def confirmed(self) -> Optional[bool]:
        return self._rep.confirmed

    @property
    def confirmation(self) -> str:
        return self._rep.confirmation

    @property
    def notes(self) -> list[str]:
        return list(self._rep.result.notes)

    @property
    def cycle_closes(self) -> bool:
        return bool(self._rep.result.cycle_closes)

    @property
    def claim(self) -> str:
        """What the trace says it shows: its property, or its kind."""
        return self._rep.header.get("property") or self._rep.header.get("kind") or "trace"

    @property
    def is_spec(self) -> bool:
        return self._rep.compiled is not None

    def state(self, i: int) -> dict:
        """The state after step ``i`` (0: the start): per agent for a spec, ``{"facts": [...]}`` otherwise."""
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i <= self.steps:
            raise IndexError(f"state {i!r}: this replay has states 0 (the start) to {self.steps}")
        return self._rep.state_table(i)

    def step_lines(self, i: int, verbose: bool = False, always: bool = False) -> Lines:
        """Step ``i`` (from 1): its ROAR events and variable changes (its CLF rule with
        ``verbose``; ``always``: a line even for a step with nothing to show)."""
        from ..verify.report import replay_step_lines
        return replay_step_lines(self._rep, i, verbose, always=always)

    def state_lines(self, i: int, agent: Optional[str] = None) -> Lines:
        """The state after step ``i`` (0: the start), as a table per agent (one agent's row if named)."""
        from ..verify.report import replay_state_lines
        return replay_state_lines(self._rep, i, agent) if agent else replay_state_lines(self._rep, i)

    def body_lines(self, verbose: bool = False, states: bool = False) -> Lines:
        """Notes, every step (with the state after each when ``states``), the final state, and
        the line that says every step was a step of the model."""
        out = Lines()
        for note in self.notes:
            out.add(f"note: {note}", style="yellow")
        if states or verbose:
            for i in range(1, self.steps + 1):
                out.extend(self.step_lines(i, verbose))
                if states:
                    out.extend(self.state_lines(i))
        else:   # repeated blocks of steps folded, as the run's step table folds them
            from ..trace.render import Repeat, folded
            shown = [(i, lines) for i in range(1, self.steps + 1) for lines in [self.step_lines(i)] if lines.text()]
            for item in folded(shown, key=lambda il: re.sub(r"(?m)^\s*\d+\.", "", il[1].text()),
                               step=lambda il: il[0]):
                if isinstance(item, Repeat):
                    out.add((f"        {item.text('step')}", "dim"))
                else:
                    out.extend(item[1])
        if self.is_spec and not states:
            out.extend(self.state_lines(self.steps))
        return out.extend(self.replayed_lines())

    def replayed_lines(self) -> Lines:
        n = self.steps
        tail = " and the cycle closes" if self.cycle_closes else ""
        return Lines().add(f"replayed {n} step{'s' if n != 1 else ''}{tail}: every step is a step of the model",
                           style="green")

    def confirmation_lines(self) -> Lines:
        """Whether the end of the replay shows again what the trace claims."""
        if self.confirmed is False:
            return Lines().add(f"NOT CONFIRMED: {self.confirmation}", style="red")
        from ..verify.replay import NOTHING_CLAIMED
        if self.confirmed is None and self.confirmation == NOTHING_CLAIMED:
            return Lines()   # a trace that claims nothing: the replayed line has said it all
        return Lines().add(("confirmed: " if self.confirmed else "") + self.confirmation,
                           style="green" if self.confirmed else "")

    def lines(self, verbose: bool = False, states: bool = False) -> Lines:
        """As ``roar-verify replay`` prints it (without pictures)."""
        return self.body_lines(verbose, states).extend(self.confirmation_lines())

    def format(self, verbose: bool = False) -> str:
        """The replay as ``roar-verify replay`` prints it, as plain text."""
        return self.lines(verbose).text()

    def __str__(self) -> str:
        return self.format()

    def save_chart(self, png: Optional[PathLike] = None, svg: Optional[PathLike] = None) -> list[Path]:
        """Draw the replay's message sequence chart into the PNG and SVG files asked for."""
        from ..verify.pictures import write_chart
        from ..verify.report import replay_report
        return write_chart(replay_report(self._rep), f"{self.trace.name}: replay of the {self.claim} "
                           f"({self.steps} steps)", f"the trace {self.trace}",
                           None if png is None else Path(png), None if svg is None else Path(svg))


class ClfModel:
    """A CLF program (Celf's language) with its ``#exec`` start states."""

    def __init__(self, path: Path, *, text: Optional[str] = None, start: Optional[int] = 1,
                 name: Optional[str] = None):
        self.path = Path(path)
        self.text = text
        self._start = start
        self.name = name or str(self.path)
        self._program: Optional["Program"] = None

    @classmethod
    def from_text(cls, text: str, *, name: str = "model", start: Optional[int] = None,
                  check: bool = True) -> "ClfModel":
        """A program given as text; ``start`` defaults to its last ``#exec``. With ``check`` it is
        type-checked now (a bad program is an error here, not at first use); the strategies,
        whose programs are well-typed by construction, leave that to first use. The text is
        written to a scratch file when the explorer needs one."""
        m = cls(_scratch_path(text, name, ".clf"), text=text, start=start, name=f"<{name}>")
        if check:
            m.program
        return m

    @property
    def start(self) -> int:
        """The ``#exec`` runs and explorations start from (counted from 1)."""
        if self._start is None:
            self._start = max(1, self.starts)
        return self._start

    @start.setter
    def start(self, k: int) -> None:
        self._start = k

    def __repr__(self) -> str:
        if self.text is not None:
            return f"ClfModel.from_text({_triple_quoted(self.text)})"
        return f"<ClfModel {self.name}>"

    def _repr_pretty_(self, p: Any, cycle: bool) -> None:
        p.text(repr(self))

    @property
    def program(self) -> "Program":
        if self._program is None:
            from ..clf.program import Program
            self._program = (Program.from_text(self.text, str(self.path)) if self.text is not None
                             else Program.from_file(self.path))
        return self._program

    @property
    def starts(self) -> int:
        """How many ``#exec`` directives (start states) the program has."""
        from ..clf.signature import ExecDirective
        return sum(1 for d in self.program.sig.directives if isinstance(d, ExecDirective))

    def start_context(self, start: Optional[int] = None):
        """A fresh context of start state ``start`` (counted from 1, as in a job's ``start``)."""
        from ..clf.signature import ExecDirective
        k = start if start is not None else self.start
        execs = [d for d in self.program.sig.directives if isinstance(d, ExecDirective)]
        if not 1 <= k <= len(execs):
            raise RoarError(f"{self.name}: start {k} but the program has {len(execs)} #exec or #trace directive(s)")
        return self.program.start_context(execs[k - 1].start)

    def run(self, *, start: Optional[int] = None, seed: Optional[int] = 0, max_steps: int = 100_000,
            fair: bool = False) -> ClfRun:
        """Committed choice from a start state to quiescence (or ``max_steps``)."""
        from ..clf.query import show_context, with_big_stack
        ctx = self.start_context(start)
        rules: list[str] = []

        def go():
            return self.program.run(ctx, max_steps=max_steps, seed=seed, fair=fair,
                                    on_step=lambda step, _c: rules.append(step.rule))

        _n, quiescent = with_big_stack(go)
        return ClfRun(rules, quiescent, show_context(ctx), seed)

    def explore(self, properties: Sequence[str] = ("deadlock",), *, start: Optional[int] = None,
                progress: Sequence[str] = (), fairness: str = "first-argument", accept: Optional[str] = None,
                never: Sequence[str] = (), budget: BudgetLike = None, backend: str = "auto",
                reduction: bool = False, name: Optional[str] = None) -> Exploration:
        """Explore every interleaving from a start state (docs/checking.md)."""
        from ..verify.jobs import Job, PropertySpec
        props = _properties(properties, never, CLF_PROPERTIES)
        from ..roar.props import looks_like_spec
        for p in [never] if isinstance(never, str) else never:
            if isinstance(p, str) and looks_like_spec(p):
                raise RoarError(f"never pattern {p!r} is written in the spec's terms: it needs an agent spec "
                                "(AgentSpec.explore); on a .clf model write CLF patterns such as "
                                "\"busy P * busy P\"", _caller_pos())
        if fairness not in ("first-argument", "rule", "none"):
            raise RoarError(f"fairness must be 'first-argument', 'rule' or 'none', not {fairness!r}", _caller_pos())
        if backend not in ("auto", "ground", "general"):
            raise RoarError(f"backend must be 'auto', 'ground' or 'general', not {backend!r}", _caller_pos())
        pos = _caller_pos()
        ps = PropertySpec(check=props, progress=list(progress), fairness=fairness, accept=accept,
                          never=[(p, _string_pos(pos, p)) for p in never], sources=[str(pos.file)] if accept else [])
        path = _written(self.path, self.text) if self.text is not None else self.path
        job = Job(path=path, name=name or Path(self.name.strip("<>")).stem, model=path,
                  start=start if start is not None else self.start, props=ps, budget=as_budget(budget),
                  backend=backend, reduction=reduction)
        return _explore(job)
