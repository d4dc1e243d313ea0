"""The functional-layer binding: Python callables behind a spec's functions.

A spec declares functions (``double distance(point, point);``) and variables
whose reads run a task (``int pos = get_pos();``) but not how the robot
computes them. A :class:`Registry` maps those names to :class:`Primitive`
objects: a Python callable (for simulated runs) and the abstract outcomes the
explorer enumerates instead of calling it (success or failure, and which
variables each outcome may change, to which values)::

    reg = Registry()

    @reg.register("compute_plan", outcomes=[Outcome("planned", True), Outcome("no_path", False)])
    def compute_plan(goal): ...

    reg.register("demo_loco::pos", outcomes=[Outcome("read", True, {"pos": 5})])  # exploration only

    binding = reg.resolve(spec)   # every function the spec uses must be bound

Names are ``f`` (any agent's function f) or ``agent::f`` (that agent's f,
which wins over a plain ``f``); a task-initialised variable is bound as
``agent::var``. :meth:`Registry.resolve` reports every unbound use, at the
position of the spec that uses it, in one :class:`BindingError`.
"""

from __future__ import annotations

from fractions import Fraction

import inspect
import re
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Optional

from ..errors import ErrorList, Pos, RoarError
from . import ast as a

__all__ = ["Outcome", "Primitive", "Registry", "Binding", "BindingError", "SUCCESS", "FAILURE",
           "DEFAULT_OUTCOMES", "find_module", "module_candidates", "import_module"]


@dataclass(frozen=True)
class Outcome:
    """One abstract result of a primitive: its name, whether it succeeds, what it returns and writes.

    ``writes`` maps variable names (``var`` of the agent that owns the
    primitive, or ``agent::var``) to the value the outcome leaves there.
    """

    name: str
    success: bool = True
    writes: dict[str, object] = field(default_factory=dict, hash=False)
    #: the value the call returns in this outcome (None: true/false by ``success`` for a
    #: bool function, the type's default value otherwise)
    result: object = field(default=None, hash=False)
    #: which concrete results of the robot this outcome stands for: a predicate over a
    #: :class:`roar_formal.robot.activity.CallResult` (None: the results whose success
    #: is ``success`` and, when ``result`` is given, whose value equals it)
    covers: Optional[Callable[[object], bool]] = field(default=None, compare=False, hash=False, repr=False)


SUCCESS = Outcome("success", True)
FAILURE = Outcome("failure", False)
#: outcomes of a primitive registered without any: it may succeed or fail, and writes nothing
DEFAULT_OUTCOMES = (SUCCESS, FAILURE)


@dataclass(frozen=True)
class Primitive:
    """A function (or task-initialised variable) of the functional layer."""

    name: str
    fn: Optional[Callable] = field(default=None, compare=False)
    outcomes: tuple[Outcome, ...] = DEFAULT_OUTCOMES
    #: an assumption about the functional layer for exploration: the failing outcomes happen at
    #: most this many times in a run (None: any number of times)
    max_failures: Optional[int] = None
    #: an assumption for exploration: the successful outcomes are fair (a call retried forever
    #: succeeds at last), decided under strong fairness (each has its own fairness group)
    fair: bool = False
    #: where it was registered (the caller of Registry.register), for located errors
    where: Optional[Pos] = field(default=None, compare=False)

    def __call__(self, *args):
        if self.fn is None:
            raise RoarError(f"primitive '{self.name}' has no Python implementation "
                            f"(it was registered for exploration only)")
        return self.fn(*args)

    def outcome(self, name: str) -> Outcome:
        for o in self.outcomes:
            if o.name == name:
                return o
        raise KeyError(f"primitive '{self.name}' has no outcome '{name}'")


class BindingError(ErrorList):
    """Problems binding a spec to a registry: the first as message, the others as notes; all in ``errors``."""


@dataclass(frozen=True)
class Binding:
    """A spec's functions and task-initialised variables, resolved to primitives.

    ``functions`` is keyed ``agent::f`` (``f`` alone for builtins such as
    ``now``); ``variables`` is keyed ``agent::var`` and holds only the
    task-initialised variables that the registry binds (the others are
    computed by their task's recipes).
    """

    functions: dict[str, Primitive]
    variables: dict[str, Primitive]

    def function(self, owner: Optional[str], name: str) -> Primitive:
        return self.functions[f"{owner}::{name}" if owner else name]


def _caller() -> Optional[Pos]:
    """Where the user's code called into this module (the first frame outside it)."""
    import sys
    f = sys._getframe(1)
    while f is not None and f.f_code.co_filename == __file__:
        f = f.f_back
    return Pos(f.f_code.co_filename, f.f_lineno, 1) if f is not None else None


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(::[A-Za-z_][A-Za-z0-9_]*)?")


class Registry:
    """Names of functions and task-initialised variables -> :class:`Primitive`."""

    def __init__(self, builtins: bool = True):
        self._prims: dict[str, Primitive] = {}
        if builtins:
            start = time.monotonic()
            self.register("now", lambda: int((time.monotonic() - start) * 1000),
                          outcomes=[Outcome("now", True)])

    # -- registration --------------------------------------------------------
    def register(self, name: str, fn: Optional[Callable] = None,
                 outcomes: Optional[Iterable[Outcome]] = None, *, replace: bool = False,
                 max_failures: Optional[int] = None, fair: bool = False):
        """Bind ``name`` to ``fn`` with its abstract ``outcomes`` (default: success or failure).

        ``max_failures`` bounds how many times, in one explored run, the primitive's failing
        outcomes may happen (an assumption about the functional layer: "the gripper fails at
        most twice"); past it only its successful outcomes remain. ``fair`` says a call retried
        forever succeeds at last: each successful outcome is its own fairness group, so under
        strong fairness (``[livelock] strength = "strong"``, or a temporal property's
        ``fairness = "strong"``) a run on which it is possible infinitely often takes it.

        Without ``fn`` the name is bound for exploration only, and the call
        returns a decorator that supplies the callable::

            @registry.register("distance", outcomes=[...])
            def distance(p, q): ...
        """
        where = _caller()

        def bad(msg: str) -> RoarError:
            return RoarError(msg, where)
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise bad(f"cannot register {name!r}: a primitive is named 'f' or 'agent::f'")
        if name in self._prims and not replace:
            raise bad(f"'{name}' is already registered (pass replace=True to rebind it)")
        outs = tuple(outcomes) if outcomes is not None else DEFAULT_OUTCOMES
        if not outs:
            raise bad(f"primitive '{name}' needs at least one outcome")
        seen = set()
        for o in outs:
            if not isinstance(o, Outcome):
                raise bad(f"primitive '{name}': {o!r} is not an Outcome")
            if o.name in seen:
                raise bad(f"primitive '{name}' has two outcomes named '{o.name}'")
            seen.add(o.name)
            for var in o.writes:
                if not isinstance(var, str) or not _NAME.fullmatch(var):
                    raise bad(f"outcome '{o.name}' of '{name}' writes {var!r}: "
                              f"a variable is named 'var' or 'agent::var'")
        if max_failures is not None and (not isinstance(max_failures, int) or isinstance(max_failures, bool)
                                         or max_failures < 0):
            raise bad(f"primitive '{name}': max_failures must be a whole number >= 0, not {max_failures!r}")
        if not isinstance(fair, bool):
            raise bad(f"primitive '{name}': fair must be True or False, not {fair!r}")
        if fair and all(not o.success for o in outs):
            raise bad(f"primitive '{name}': fair needs a successful outcome")
        if max_failures is not None and all(not o.success for o in outs):
            raise bad(f"primitive '{name}': max_failures needs a successful outcome to fall back on")
        if fn is not None and not callable(fn):
            raise bad(f"cannot register '{name}': {fn!r} is not callable")
        self._prims[name] = Primitive(name, fn, outs, max_failures, fair, where)

        def decorate(f: Callable) -> Callable:
            self._prims[name] = Primitive(name, f, outs, max_failures, fair, where)
            return f

        return decorate if fn is None else fn

    # -- lookup ----------------------------------------------------------------
    def __contains__(self, name: str) -> bool:
        return name in self._prims

    def __getitem__(self, name: str) -> Primitive:
        return self._prims[name]

    def get(self, name: str) -> Optional[Primitive]:
        return self._prims.get(name)

    def names(self) -> list[str]:
        return sorted(self._prims)

    def lookup(self, name: str, owner: Optional[str] = None) -> Optional[Primitive]:
        """``owner::name`` if registered, else ``name``."""
        if owner is not None and f"{owner}::{name}" in self._prims:
            return self._prims[f"{owner}::{name}"]
        return self._prims.get(name)

    def call(self, name: str, *args, owner: Optional[str] = None):
        p = self.lookup(name, owner)
        if p is None:
            raise RoarError(f"no primitive '{name}' is registered")
        return p(*args)

    # -- resolution ----------------------------------------------------------
    def assumption_errors(self, spec: a.Spec) -> list[RoarError]:
        """An assumption (``max_failures``, ``fair``) about a primitive that nothing in the spec
        calls would silently apply to nothing (a misspelt name): one located error each."""
        used = set()
        for ag in spec.agents:
            for _where, node in _executable(ag):
                for call in a.calls(node):
                    for owner, _decl in spec.resolve_function(ag, call) or [(None, None)]:
                        prim = self.lookup(call.name, owner)
                        if prim is not None:
                            used.add(prim.name)
            for var in ag.task_initialised():
                used.add(f"{ag.name}::{var}")
        errors = []
        for prim in self._prims.values():
            if prim.name not in used and (prim.max_failures is not None or prim.fair):
                what = " and ".join(x for x in (f"max_failures={prim.max_failures}" if prim.max_failures is not
                                                None else "", "fair=True" if prim.fair else "") if x)
                errors.append(RoarError(
                    f"primitive '{prim.name}' is registered with {what}, but no function the spec calls and "
                    f"no task-initialised variable has that name, so the assumption would apply to nothing; "
                    f"check the name ('f' or 'agent::f')", prim.where))
        return errors

    def resolve(self, spec: a.Spec) -> Binding:
        """Bind every function the spec calls; raise :class:`BindingError` listing each unbound use.

        Calls in rules are not bound (the logic layer reasons about them
        symbolically). Registered callables are checked against the declared
        number of parameters, and outcome writes against the spec's variables.
        """
        errors: list[RoarError] = []
        functions: dict[str, Primitive] = {}
        variables: dict[str, Primitive] = {}
        checked: set[str] = set()
        types = type_table(spec)   # (what outcomes' results and writes are checked against)
        for ag in spec.agents:
            for where, node in _executable(ag):
                for call in a.calls(node):
                    if where == "init" and ag.reading_task(node) is not None:
                        continue
                    found = spec.resolve_function(ag, call)
                    if len(found) != 1:
                        if not found and call.name in a.BUILTINS and call.agent is None:
                            owner, decl = None, None
                        else:
                            continue  # unknown or ambiguous: check_spec reports it
                    else:
                        owner, decl = found[0]
                    key = f"{owner}::{call.name}" if owner else call.name
                    prim = self.lookup(call.name, owner)
                    if prim is None:
                        by = f" (declared by agent '{owner}')" if owner else ""
                        errors.append(RoarError(
                            f"function '{call.qualified}'{by} has no binding in the functional-layer "
                            f"registry; register it as '{call.name}'" + (f" or '{key}'" if owner else ""),
                            call.pos))
                        continue
                    functions[key] = prim
                    if key not in checked:
                        checked.add(key)
                        errors += _check_primitive(spec, prim, owner, decl, types)
            for var, _task in ag.task_initialised().items():
                prim = self._prims.get(f"{ag.name}::{var}")
                if prim is not None:
                    variables[f"{ag.name}::{var}"] = prim
                    errors += _check_writes(spec, prim, ag.name, ag.var(var).pos, types)
        errors += self.assumption_errors(spec)
        if errors:
            seen, unique = set(), []
            for e in sorted(errors, key=_ekey):
                if (e.pos, e.message) not in seen:
                    seen.add((e.pos, e.message))
                    unique.append(e)
            raise BindingError(unique)
        return Binding(functions, variables)


def module_candidates(spec_path) -> list:
    """Where a spec's functional-layer module may be: ``SPEC.py`` next to a ``.roar`` file,
    ``functional.py`` inside (or ``NAME.py`` next to) a hyper folder, ``functional.py`` next to an
    ``.ability`` file."""
    from pathlib import Path
    spec_path = Path(spec_path)
    if spec_path.is_dir():
        return [spec_path / "functional.py", spec_path.with_suffix(".py")]
    out = [spec_path.with_suffix(".py")]
    if spec_path.suffix == ".ability":
        out.append(spec_path.parent / "functional.py")
    return out


def find_module(spec_path, given=None):
    """The functional-layer module of a spec: ``given`` (``--functional FILE``), else the first of
    :func:`module_candidates` that exists, else None."""
    from pathlib import Path
    if given is not None:
        if not Path(given).is_file():
            raise RoarError(f"{given}: no such functional-layer module")
        return Path(given)
    return next((c for c in module_candidates(spec_path) if c.is_file()), None)


def import_module(path):
    """Import a functional-layer module from its file (the one Python a spec named on the command
    line brings); a module that fails to import is the user's error, with the file named."""
    import importlib.util
    from pathlib import Path
    path = Path(path)
    spec = importlib.util.spec_from_file_location(f"roar_functional_{abs(hash(str(path.resolve())))}", path)
    if spec is None or spec.loader is None:
        raise RoarError(f"{path}: cannot be imported as a Python module")
    import sys
    mod = importlib.util.module_from_spec(spec)
    # registered under its name, so that objects of its classes (a robot activity under way) pickle
    # with a robot snapshot and unpickle in this process
    sys.modules[spec.name] = mod
    try:
        spec.loader.exec_module(mod)
    except SyntaxError as exc:   # located in the module: file, line, column
        sys.modules.pop(spec.name, None)
        raise RoarError(f"the functional-layer module is not valid Python: {exc.msg}",
                        Pos(str(path), exc.lineno or 1, exc.offset or 1)) from None
    except Exception as exc:
        sys.modules.pop(spec.name, None)
        where = _module_line(exc, path)
        raise RoarError(f"importing the functional-layer module failed: {type(exc).__name__}: {exc}",
                        where or Pos(str(path), 1, 1)) from None
    return mod


def _module_line(exc: BaseException, path) -> Optional[Pos]:
    """The line of the module where an exception raised while importing it came from, if any."""
    from pathlib import Path
    target = str(Path(path).resolve())
    tb, found = exc.__traceback__, None
    while tb is not None:
        if str(Path(tb.tb_frame.f_code.co_filename).resolve()) == target:
            found = Pos(str(path), tb.tb_lineno, 1)
        tb = tb.tb_next
    return found


def _ekey(e: RoarError):
    p = e.pos or Pos("", 0, 0)
    return (p.file, p.line, p.col, e.message)


def _executable(ag: a.Agent):
    """The parts of an agent that run (and so call the functional layer): not its rules."""
    for v in ag.vars:
        if v.init is not None:
            yield "init", v
    for t in ag.tasks:
        for e in t.pre + t.post:
            yield "cond", e
        for r in t.recipes:
            yield "recipe", r


def _check_primitive(spec: a.Spec, prim: Primitive, owner: Optional[str],
                     decl: Optional[a.Function], types: dict) -> list[RoarError]:
    errors: list[RoarError] = []
    if decl is not None and prim.fn is not None:
        span = _arity(prim.fn)
        k = len(decl.params)
        if span is not None and not (span[0] <= k and (span[1] is None or k <= span[1])):
            low, high = span
            takes = str(low) if low == high else f"{low} to {high}"
            errors.append(RoarError(
                f"the callable bound to '{prim.name}' takes {takes} argument{'s' if high != 1 else ''}, "
                f"but agent '{owner}' declares '{decl.name}' with {k}", decl.pos))
    if decl is not None:
        ty = resolve_type(spec, owner, decl.result)
        for o in prim.outcomes:
            why = misfit(o.result, ty, types) if o.result is not None else None
            if why is not None:
                errors.append(RoarError(
                    f"outcome '{o.name}' of primitive '{prim.name}' returns {o.result!r}, but "
                    f"'{decl.name}' is declared to return {decl.result}: {why}", decl.pos))
    if owner is not None:
        errors += _check_writes(spec, prim, owner, decl.pos if decl else None, types)
    return errors


def _check_writes(spec: a.Spec, prim: Primitive, owner: str, pos: Optional[Pos], types: dict) -> list[RoarError]:
    errors = []
    for o in prim.outcomes:
        for var, value in o.writes.items():
            agent, _, name = var.rpartition("::")
            agent = agent or owner
            ag = spec.agent(agent)
            if ag is None or ag.var(name) is None:
                errors.append(RoarError(
                    f"outcome '{o.name}' of primitive '{prim.name}' writes '{var}', which is not a "
                    f"variable of agent '{agent}'", pos))
                continue
            tref = ag.var(name).type
            why = misfit(value, resolve_type(spec, agent, tref), types)
            if why is not None:
                errors.append(RoarError(
                    f"outcome '{o.name}' of primitive '{prim.name}' writes {value!r} to '{var}', which is "
                    f"{tref}: {why}", pos))
    return errors


def resolve_type(spec: a.Spec, agent: Optional[str], t: a.TypeRef) -> Optional[str]:
    """A type as written in ``agent``'s scope, qualified (``agent::T``) unless it is a base type;
    None when it names no declared type (the static checks say so)."""
    if t.agent is not None:
        return f"{t.agent}::{t.name}"
    if t.name in a.BASE_TYPES:
        return t.name
    ag = spec.agent(agent) if agent else None
    if ag is not None and ag.type_decl(t.name) is not None:
        return f"{ag.name}::{t.name}"
    owners = [b.name for b in spec.agents if b.type_decl(t.name) is not None]
    return f"{owners[0]}::{t.name}" if len(owners) == 1 else None


def type_table(spec: a.Spec) -> dict:
    """The declared types of a spec, by qualified name: ("struct", [(field, its type), ...]),
    ("new", its base type) or ("opaque",)."""
    out: dict = {}
    for ag in spec.agents:
        for td in ag.types:
            q = f"{ag.name}::{td.name}"
            if isinstance(td, a.StructType):
                out[q] = ("struct", [(f.name, resolve_type(spec, ag.name, f.type)) for f in td.fields])
            elif isinstance(td, a.NewType):
                out[q] = ("new", resolve_type(spec, ag.name, td.base))
            else:
                out[q] = ("opaque",)
    return out


def misfit(value, ty: Optional[str], table: dict) -> Optional[str]:
    """Why a Python value cannot stand for a value of the spec's type ``ty`` (qualified, see
    :func:`type_table`), or None when it can: a base type's Python type, a struct's fields (a dict
    by field name, a tuple or list in field order, or an object with those attributes) each
    fitting its type, a newtype's base; an opaque type takes any object."""
    if ty is None:
        return None
    if ty in _PY_TYPES:
        return None if value_fits(value, ty) else f"expected {_PY_TYPES[ty]}"
    kind = table.get(ty)
    if kind is None or kind[0] == "opaque":
        return None
    if kind[0] == "new":
        return misfit(value, kind[1], table)
    fields = kind[1]
    names = [f for f, _t in fields]
    if isinstance(value, dict):
        missing = [n for n in names if n not in value]
        extra = [str(k) for k in value if k not in names]
        if missing or extra:
            return (f"a struct {ty} has the fields {', '.join(names)}"
                    + (f"; missing: {', '.join(missing)}" if missing else "")
                    + (f"; not a field: {', '.join(extra)}" if extra else ""))
        items = [value[n] for n in names]
    elif isinstance(value, (tuple, list)):
        if len(value) != len(names):
            return f"a struct {ty} has {len(names)} fields ({', '.join(names)}), not {len(value)}"
        items = list(value)
    elif any(not hasattr(value, n) for n in names) or isinstance(value, (bool, int, float, str, Fraction)):
        return f"expected a struct {ty}: a dict with the fields {', '.join(names)}"
    else:
        items = [getattr(value, n) for n in names]
    for (n, fty), v in zip(fields, items):
        why = misfit(v, fty, table)
        if why is not None:
            return f"field '{n}': {why}"
    return None


#: the spec's base types a Python value is checked against (others, structs and newtypes, are not)
_PY_TYPES = {"bool": "true or false (a Python bool)", "int": "a whole number (a Python int)",
             "double": "a number (a Python int or float)", "string": "a Python str"}


def value_fits(value, ty: Optional[str]) -> bool:
    """May a Python value stand for a value of the spec's type ``ty``? Only base types are judged
    (a struct, a newtype or an opaque type: yes)."""
    if ty == "bool":
        return isinstance(value, bool)
    if ty == "int":
        return isinstance(value, int) and not isinstance(value, bool) or (
            isinstance(value, Fraction) and value.denominator == 1)
    if ty == "double":
        return isinstance(value, (int, float, Fraction)) and not isinstance(value, bool)
    if ty == "string":
        return isinstance(value, str)
    return True


def _arity(fn: Callable) -> Optional[tuple[int, Optional[int]]]:
    """(fewest, most) positional arguments ``fn`` accepts (most None: any number); None if unknown."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    low, high = 0, 0
    for p in sig.parameters.values():
        if p.kind == p.VAR_POSITIONAL:
            return (low, None)
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
            high += 1
            if p.default is p.empty:
                low += 1
    return (low, high)


def functional_module(spec_path, given=None):
    """The functional-layer module of a spec (``--functional FILE`` or the one next to it), or None."""
    return find_module(spec_path, given)


def load_registry(path) -> Optional["Registry"]:
    """Import a functional-layer module and build its registry (``registry()``, or ``REGISTRY``)."""
    if path is None:
        return None
    mod = import_module(path)
    make = getattr(mod, "registry", None)
    if callable(make):
        try:
            reg = make()
        except RoarError:
            raise
        except Exception as exc:
            raise RoarError(f"{path}: registry() failed: {type(exc).__name__}: {exc}") from None
    else:
        reg = getattr(mod, "REGISTRY", None)
    if not isinstance(reg, Registry):
        raise RoarError(f"{path}: a functional-layer module defines registry() returning a Registry "
                        f"(roar_formal.roar.functional.Registry)")
    return reg
