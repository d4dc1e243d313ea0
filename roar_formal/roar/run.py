"""Running a compiled ROAR model: a committed-choice run of the CLF engine, seen at the ROAR level.

The run is the engine's forward chaining on the compiled signature; nothing
here decides what the agents do. The one thing outside the signature is the
functional layer: a ``pending F Args D`` fact is a call of primitive F, and
the runner answers it (with the registry's Python callable, or with the
primitive's first declared outcome, or with a failure outcome when a
``--fault`` names the call), adding ``return V D`` or ``callfail D``.

Every CLF step is recorded; :func:`events_of` reads the ROAR-level events a
step means from the facts it consumed and produced (a request sent, a state
change of figure 2, tasks and recipes chosen, a primitive started or ended, a
variable written, an activation paused or resumed). So a ROAR event is always
one CLF step of the same run.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, Optional

from ..clf.forward import Run, enabled_steps
from ..clf.printer import show
from ..clf.terms import Const, Root, const, num_term, num_value, string_term, string_value
from ..errors import RoarError, did_you_mean
from ..trace.format import ROAR_EVENT_KINDS
from .compile import CRASH_RULES, CompiledModel, Crashes, num_lit

#: the clock's rule in a timed model (docs/semantics.md, Time): a run takes it when nothing else can happen
TICK_RULE = "tick"
from .functional import Outcome, Registry, misfit, type_table
from . import vocabulary as V
from .pretty import string_literal

__all__ = ["Fault", "RoarEvent", "RunResult", "run_model", "parse_fault", "value_of", "Values", "Narrator",
           "Resolver", "collect_result", "list_items", "format_value", "describe_ec", "CrashAt", "parse_crash",
           "crash_setup"]

FINAL = {"s_success": "success", "s_failure": "failure", "s_aborted": "aborted"}
STATE_NAMES = {"s_sent": "sent", "s_pending": "pending", "s_running": "running", "s_tempfail": "temporary failure",
               "s_paused": "paused", "s_success": "success", "s_failure": "failure", "s_aborted": "aborted"}


@dataclass(frozen=True)
class Fault:
    """``NAME`` (every call of primitive NAME fails), ``NAME:K`` (its K-th call fails) or
    ``NAME=OUTCOME`` (every call takes that declared outcome)."""

    name: str
    call: Optional[int] = None
    outcome: Optional[str] = None

    def __str__(self) -> str:
        return self.name + (f":{self.call}" if self.call else "") + (f"={self.outcome}" if self.outcome else "")


_FAULT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*(?:::[A-Za-z_][A-Za-z0-9_]*)?)(?::(\d+))?(?:=([A-Za-z_][A-Za-z0-9_]*))?$")


def parse_fault(text: str) -> Fault:
    m = _FAULT.match(text.strip())
    if not m or (m.group(2) is not None and int(m.group(2)) < 1):
        raise RoarError(f"--fault {text!r}: expected NAME, NAME:K (the K-th call, from 1) or NAME=OUTCOME, "
                        f"where NAME is a function ('f' or 'agent::f')")
    return Fault(m.group(1), int(m.group(2)) if m.group(2) else None, m.group(3))


@dataclass(frozen=True)
class CrashAt:
    """``AGENT@STEP`` (the agent crashes at that step of the run and comes back as soon as it can)
    or ``AGENT@STEP-BACK`` (and comes back at step BACK): docs/semantics.md, "Crashes".

    The crash takes place at the first step from STEP on at which the agent handles a request
    (the model's crash: down and idle, an agent differs from up in nothing a step could show
    before a request reaches it); the comeback at the first step from BACK (or from the crash)
    at which none of its tasks is committed any more."""

    agent: str
    step: int
    back: Optional[int] = None

    def __str__(self) -> str:
        return f"{self.agent}@{self.step}" + (f"-{self.back}" if self.back is not None else "")


_CRASH = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)@(\d+)(?:-(\d+))?$")


def parse_crash(text) -> CrashAt:
    """``AGENT@STEP`` or ``AGENT@STEP-BACK`` (steps of the run's trace, from 1; BACK after STEP)."""
    if isinstance(text, CrashAt):
        return text
    m = _CRASH.match(str(text).strip())
    if not m or int(m.group(2)) < 1 or (m.group(3) is not None and int(m.group(3)) <= int(m.group(2))):
        raise RoarError(f"--crash {text!r}: expected AGENT@STEP (the agent crashes at that step of the run and "
                        f"comes back as soon as it can) or AGENT@STEP-BACK (and comes back at step BACK, after "
                        f"STEP); steps count from 1")
    return CrashAt(m.group(1), int(m.group(2)), int(m.group(3)) if m.group(3) else None)


def crash_setup(crashes) -> Optional[Crashes]:
    """What the model of a run with these crashes is compiled with (``compile_spec(...,
    crashes=crash_setup(cs))``): every agent named armed from the start, as many crashes as given."""
    cs = [parse_crash(c) for c in crashes]
    if not cs:
        return None
    return Crashes(tuple(dict.fromkeys(c.agent for c in cs)), len(cs), True)


@dataclass
class RoarEvent:
    """One ROAR-level event, the meaning of CLF step ``step``."""

    step: int
    kind: str          # sent state tasks recipe recipe-end primitive-start primitive-end write pause resume
    agent: str
    text: str
    data: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in ROAR_EVENT_KINDS:   # (the trace format's vocabulary: readers refuse others)
            raise ValueError(f"a ROAR event of unknown kind {self.kind!r}")

    def as_json(self) -> dict:
        return {"kind": self.kind, "agent": self.agent, "text": self.text, **self.data}


@dataclass
class RunResult:
    model: CompiledModel
    steps: list          # [(rule, consumed, produced)] as printed facts
    events: list[RoarEvent]
    quiescent: bool
    outcome: str         # the request's final state (success, failure, ...) or "unfinished"
    error_context: list[str]
    final: dict[str, object]   # agent::var -> value (Python)
    requests: dict[str, str]   # label -> "agent: predicate"
    ctx: object = None
    external: dict = field(default_factory=dict)   # step -> (pending fact, answer): functional-layer steps

    @property
    def ok(self) -> bool:
        return self.outcome == "success"


# ------------------------------------------------------------------ values


def value_of(t) -> object:
    """A CLF value term as a Python value (numbers as int or Fraction)."""
    h = t.head.name if isinstance(t.head, Const) else None
    if h == "vnum":
        q = num_value(V.unwrap(t))
        return int(q) if q.denominator == 1 else q
    if h == "vbool":
        return V.unwrap(t).head.name == "tt"
    if h == "vstr":
        return string_value(V.unwrap(t))
    if h == "vrec":
        return tuple(value_of(x) for x in list_items(V.unwrap(t)))
    if h == "vopq":
        return ("opaque", int(num_value(V.unwrap(t))))
    if h in ("vnil", "vcons"):
        return [value_of(x) for x in list_items(t)]
    return show(t)


def list_items(t):
    out = []
    while isinstance(t.head, Const) and t.head.name == "vcons":
        c = V.cons(t)
        out.append(c.head)
        t = c.tail
    return out


class Values:
    """Python values to CLF terms (opaque values kept in a table, named by a number)."""

    def __init__(self, model: CompiledModel):
        self.model = model
        self.opaque: list = []

    def term(self, v, ty: Optional[str] = None):
        """The term of a value of the spec's type ``ty``. A value of an opaque type is a handle
        whatever Python object it is (a planner's tuple, a number): the spec cannot look into
        it, so the model's outcomes stand for it (a run's trace replays), and the functional
        layer gets the same object back."""
        if ty is not None and ty in self.model.opaques:
            return self._handle(v)
        if isinstance(v, bool):
            return const("vbool", const("tt" if v else "ff"))
        if isinstance(v, (int, Fraction)):
            return const("vnum", num_term(v))
        if isinstance(v, float):
            return const("vnum", num_term(Fraction(repr(v))))
        if isinstance(v, str):
            return const("vstr", string_term(v))
        if ty in self.model.structs:
            names = self.model.structs[ty]
            if isinstance(v, dict):
                vals = [v[n] for n in names]
            elif isinstance(v, (tuple, list)):
                vals = list(v)
            else:
                vals = [getattr(v, n) for n in names]
            return const("vrec", self.list([self.term(x) for x in vals]))
        if isinstance(v, (tuple, list)):
            return const("vrec", self.list([self.term(x) for x in v]))
        return self._handle(v)

    def _handle(self, v):
        self.opaque.append(v)
        return const("vopq", num_term(len(self.opaque)))

    def python(self, t, ty: Optional[str] = None):
        """The Python value of a term; a struct of a known type is a dict by field name."""
        if ty in self.model.structs and isinstance(t.head, Const) and t.head.name == "vrec":
            return {n: self.python(x, self.model.field_types.get(ty, {}).get(n))
                    for n, x in zip(self.model.structs[ty], list_items(V.unwrap(t)))}
        v = value_of(t)
        if isinstance(v, tuple) and len(v) == 2 and v[0] == "opaque" and 1 <= v[1] <= len(self.opaque):
            return self.opaque[v[1] - 1]
        return v

    @staticmethod
    def list(items):
        out = const("vnil")
        for x in reversed(items):
            out = const("vcons", x, out)
        return out


# ------------------------------------------------------------------ the functional layer


class Resolver:
    """Answers pending calls: faults first, then the registry's callable, then the declared outcomes."""

    def __init__(self, model: CompiledModel, registry: Optional[Registry], faults: list[Fault], values: Values):
        self.model = model
        self.registry = registry
        self.faults = faults
        self.values = values
        self.types = type_table(model.spec)   # (what a callable's result is checked against)
        self.calls: dict[str, int] = {}
        self.used: set[Fault] = set()

    def _matches(self, f: Fault, owner: Optional[str], name: str) -> bool:
        return f.name in (name, f"{owner}::{name}")

    def forced(self, fc: str):
        """Count this call of ``fc``; when a ``--fault`` names it, its forced answer
        (result term or None, description, writes), else None."""
        owner, name = self.model.functions[fc]
        rty = self.model.fn_types.get(fc)
        qual = f"{owner}::{name}" if owner else name
        n = self.calls[qual] = self.calls.get(qual, 0) + 1
        prim = self.registry.lookup(name, owner) if self.registry is not None else None
        outcomes = prim.outcomes if prim is not None else ()
        for f in self.faults:
            if self._matches(f, owner, name) and (f.call is None or f.call == n):
                self.used.add(f)
                if f.outcome is not None:
                    o = next((o for o in outcomes if o.name == f.outcome), None)
                    if o is None:
                        raise RoarError(f"--fault {f}: primitive '{qual}' has no outcome '{f.outcome}' "
                                        f"(its outcomes: {', '.join(o.name for o in outcomes) or 'none declared'})")
                else:
                    o = next((o for o in outcomes if not o.success), Outcome("failure", False))
                return self.outcome_term(o, rty), f"fault: {o.name}", o.writes
        return None

    def answer(self, fc: str, args: list):
        """(result term or None for a failure, outcome description, writes)."""
        forced = self.forced(fc)
        if forced is not None:
            return forced
        owner, name = self.model.functions[fc]
        rty = self.model.fn_types.get(fc)
        prim = self.registry.lookup(name, owner) if self.registry is not None else None
        outcomes = prim.outcomes if prim is not None else ()
        if prim is not None and prim.fn is not None:
            tys = self.model.fn_params.get(fc, [])
            py = [self.values.python(x, tys[i] if i < len(tys) else None) for i, x in enumerate(args)]
            try:
                v = prim(*py)
            except RoarError:
                raise
            except Exception as exc:  # a bug of the functional layer: the user's to fix, located
                raise primitive_error(self.model, fc, prim, py, exc) from None
            if rty is None or v is None and rty != "bool":
                return const("vunit"), "done", {}
            why = misfit(v, rty, self.types)
            if why is not None:
                raise primitive_result_error(self.model, fc, prim, py, v, rty, why)
            return self.values.term(v, rty), "returned", {}
        o = next((o for o in outcomes if o.success), outcomes[0] if outcomes else Outcome("success", True))
        return self.outcome_term(o, rty), o.name, o.writes

    def outcome_term(self, o: Outcome, rty: Optional[str]):
        if o.result is not None:
            return self.values.term(o.result, rty)
        if rty == "bool":
            return const("vbool", const("tt" if o.success else "ff"))
        if not o.success:
            return None
        return self.values.term(_default(rty, self.model), rty)


def primitive_error(model: CompiledModel, fc: str, prim, args: list, exc: BaseException) -> RoarError:
    """A primitive that raised: a located error naming it, its arguments and the Python
    exception (a primitive fails by returning false or by a declared outcome; an exception is a
    bug in the functional layer, never read as a failure to retry)."""
    owner, name = model.functions.get(fc, (None, prim.name))
    qual = f"{owner}::{name}" if owner else name
    sites = model.call_sites.get(fc, [])
    notes = [f"called as {name}({', '.join(map(repr, args))})"]
    if len(sites) > 1:
        notes.append("other calls: " + ", ".join(str(p) for p in sites[1:]))
    if isinstance(exc, TypeError) and "argument" in str(exc):
        notes.append(f"the spec calls it with {len(args)} argument(s); check the Python function's parameters")
    else:
        notes.append("a primitive reports a failure by returning false or through its declared outcomes; "
                     "an exception is a bug of the functional layer")
    said = f": {exc}" if str(exc) else " (with no message)"
    return RoarError(f"primitive '{qual}' raised {type(exc).__name__}{said}", sites[0] if sites else None, notes)


def primitive_result_error(model: CompiledModel, fc: str, prim, args: list, value, rty: str,
                           why: Optional[str] = None) -> RoarError:
    """A primitive that returned a value of another type than its declaration's: a located error
    (a bug of the functional layer; read as it is, the value would stop the recipe that reads it)."""
    owner, name = model.functions.get(fc, (None, prim.name))
    qual = f"{owner}::{name}" if owner else name
    sites = model.call_sites.get(fc, [])
    return RoarError(f"primitive '{qual}' returned {value!r}, but it is declared to return {rty}"
                     + (f": {why}" if why else ""), sites[0] if sites
                     else None, [f"called as {name}({', '.join(map(repr, args))})"])


def _default(rty, model):
    if rty in ("int", "double"):
        return 0
    if rty == "bool":
        return False
    if rty in ("string", "identifier"):
        return ""
    if rty in model.structs:
        fields = model.field_types.get(rty, {})
        return {f: _default(fields.get(f), model) for f in model.structs[rty]}
    if rty in model.opaques:
        return None   # no object: the functions it is passed to get None (an outcome's result is one)
    return 0


# ------------------------------------------------------------------ events


class Narrator:
    """Reads ROAR-level events from CLF steps."""

    def __init__(self, model: CompiledModel):
        self.m = model
        self.labels: dict = {}       # req param -> label
        self.req_info: dict = {}     # label -> (agent, text)
        self.req_cst: dict = {}      # label -> its constraint's constant (what its failure explains)
        self.calls: dict = {}        # dest -> (agent, function text)
        self.acts: dict = {}         # inst -> (agent, task, recipe)
        # the task tree (for TCA): which request each activation handles, each request's parent
        self.inst_req: dict = {}     # inst -> label of the request it handles
        self.inst_labels: dict = {}  # inst -> "I<n>"
        self.req_meta: dict = {}     # label -> {"parent", "rkind", "emitter", "site"}
        self.call_ids: dict = {}     # dest -> "C<n>"
        self.n_calls = 0

    def label(self, r) -> str:
        lab = self.labels.get(r)
        if lab is None:
            lab = f"R{len(self.labels)}"
            self.labels[r] = lab
        return lab

    def _name(self, t) -> str:
        return t.head.name if isinstance(t.head, Const) else show(t)

    def inst_label(self, inst) -> str:
        lab = self.inst_labels.get(inst)
        if lab is None:
            lab = f"I{len(self.inst_labels) + 1}"
            self.inst_labels[inst] = lab
        return lab

    def events(self, i: int, step) -> list[RoarEvent]:
        """The ROAR events CLF step number ``i`` means, in the order a reader expects them: the
        task tree's bookkeeping first (which request each new activation handles), then requests
        and their states, the task tree's changes, primitive calls and variable writes."""
        st = _StepFacts(i, step)
        self._note_activations(st)
        out: list[RoarEvent] = []
        for part in (self._crashes, self._requests_sent, self._state_changes, self._aborts, self._conflicts,
                     self._tasks_chosen, self._recipes, self._primitives, self._writes, self._pauses):
            out.extend(part(st))
        return out

    # the task tree (for TCA): which request each activation handles, each request's parent
    def _note_activations(self, st: "_StepFacts") -> None:
        for fam, decode in ((V.ACT, V.act), (V.CHK, V.chk)):
            for a in map(decode, st.made(fam)):
                if a.inst not in self.inst_req:
                    self.inst_req[a.inst] = self.label(a.request)

    def _requests_sent(self, st: "_StepFacts"):
        m = self.m
        for q in map(V.rq, st.made(V.RQ)):
            r = q.request
            new = r not in self.labels
            if new or self.labels[r] not in self.req_meta:
                lab = self.label(r)
                agent, text = m.csts.get(self._name(q.cst), ("?", "?"))
                agent = m.agents.get(self._name(q.agent), agent)
                self.req_info.setdefault(lab, (agent, text))
                self.req_cst.setdefault(lab, self._name(q.cst))
                kind = self._name(q.kind) if isinstance(q.kind.head, Const) else "?"
                emitter = q.emitter
                outside = isinstance(emitter.head, Const) and emitter.head.name == "itop"
                site = m.sites.get(site_of(m, st.rule))
                self.req_meta[lab] = {"parent": None if outside else self.inst_req.get(emitter),
                                      "rkind": {"k_make": "make", "k_ensure": "ensure"}.get(kind, "task"),
                                      "emitter": None if outside else self.inst_label(emitter),
                                      "site": site.const if site is not None and not outside else None}
                if new and kind in ("k_make", "k_ensure"):
                    sender = site.agent if site else "outside"
                    yield RoarEvent(st.i, "sent", sender, f"{kind[2:]} {lab} to {agent}: {text}",
                                    {"request": lab, **self.req_meta[lab]})

    def _state_changes(self, st: "_StepFacts"):
        old = {x.request: self._name(x.state) for x in map(V.rs, st.used(V.RS))}
        made = [V.rs(f) for f in st.made(V.RS)]
        for x in made:
            r, s = x.request, self._name(x.state)
            if old.get(r) != s:
                lab = self.label(r)
                agent, text = self.req_info.get(lab, ("?", "?"))
                if s == "s_sent" and r not in old:
                    continue
                prev = old.get(r)
                why = ""
                if s == "s_tempfail" and st.rule.startswith("ensure_broken"):
                    why = ": the ensured predicate stopped holding"
                elif s == "s_tempfail" and st.rule.startswith("ensure_unmet"):
                    why = ": its tasks ran but the ensured predicate does not hold"
                elif s == "s_failure" and st.rule.startswith("unavailable"):
                    why = f": {agent} is unavailable (it crashed)"
                elif s == "s_failure" and st.rule == "no_task" and prev == "s_pending":
                    why = self._no_task_why(lab, agent)   # (after a temporary failure, the error context says it)
                yield RoarEvent(st.i, "state", agent, f"{lab} {STATE_NAMES.get(prev, 'new') if prev else 'new'}"
                                f" -> {STATE_NAMES[s]}  ({text}){why}",
                                {"request": lab, "from": STATE_NAMES.get(prev), "to": STATE_NAMES[s],
                                 **self.req_meta.get(lab, {})})
        for x in map(V.rs, st.used(V.RS)):
            r = x.request
            if not any(y.request is r for y in made) and st.rule.startswith("aborted"):
                lab = self.label(r)
                agent, text = self.req_info.get(lab, ("?", "?"))
                was = STATE_NAMES.get(self._name(x.state))
                yield RoarEvent(st.i, "state", agent, f"{lab} {was} -> aborted  ({text})",
                                {"request": lab, "from": was, "to": "aborted", **self.req_meta.get(lab, {})})

    def _no_task_why(self, lab: str, agent: str) -> str:
        """Why no task could be chosen for a request (the logic layer's candidates, from the model)."""
        c = self.req_cst.get(lab) or (self.m.request_cst if lab == "R0" else None)
        cands = self.m.candidates.get(c) if c is not None else None
        if cands is None:
            return ""
        if not cands:
            return f": no task of {agent} establishes it"
        names = ", ".join(dict.fromkeys(t for _a, t in cands))
        return (f": none of its candidate tasks ({names}) can be chosen: a pre-condition does not hold and no "
                f"other task of {agent} establishes it")

    def _crashes(self, st: "_StepFacts"):
        """Crash faults (docs/semantics.md, Crashes): the crash plan, a crash, a comeback, an
        activation stopped by its agent's crash."""
        rule = st.rule
        if rule.startswith(("may_crash_a_", "never_crash_a_")):
            agent = rule.split("_crash_a_", 1)[1]
            may = rule.startswith("may")
            yield RoarEvent(st.i, "crash-plan", agent, f"{agent} {'may crash' if may else 'does not crash'} in this run",
                            {"may_crash": may})
            return
        if rule in CRASH_RULES:
            cep = next((V.cep(c) for c in st.made(V.CEP)), None)
            agent = self.m.agents.get(self._name(cep.agent), "?") if cep is not None else "?"
            if rule == "crash":
                yield RoarEvent(st.i, "crash", agent, f"{agent} crashed", {})
            else:
                again = " (it may crash again)" if rule == "back_armed" else ""
                yield RoarEvent(st.i, "back", agent, f"{agent} back{again}", {"may_crash": rule == "back_armed"})
            return
        if rule.startswith("crash_stop"):
            for a in map(V.act, st.made(V.ACT)):
                agent, _task, recipe = self.acts.get(a.inst, ("?", "?", "?"))
                lab = self.label(a.request)
                yield RoarEvent(st.i, "recipe-stop", agent, f"{lab}: recipe {recipe} stopped: {agent} crashed "
                                f"(no end block; the requests it holds are aborted)", {"request": lab, "recipe": recipe})

    def _aborts(self, st: "_StepFacts"):
        for a in map(V.abortreq, st.made(V.ABORTREQ)):
            lab = self.label(a.request)
            agent, text = self.req_info.get(lab, ("?", "?"))
            site = self.m.sites.get(site_of(self.m, st.rule))
            acts = st.used(V.ACT)
            who = site.agent if site else self.acts.get(V.act(acts[0]).inst if acts else None, ("?",))[0]
            yield RoarEvent(st.i, "abort", who, f"abort {lab} ({agent}: {text})", {"request": lab})

    def _conflicts(self, st: "_StepFacts"):
        rule = st.rule
        if rule == "concurrency_issue":
            for c in map(V.cres, st.made(V.CRES)):
                lab, held = self.label(c.request), self.label(c.at)
                agent, text = self.req_info.get(lab, ("?", "?"))
                yield RoarEvent(st.i, "conflict", agent, f"{lab} ({text}) conflicts with {held}, which holds "
                                f"the task it needs: asking the calling context of {held}",
                                {"request": lab, "holder": held})
        if rule.startswith(("ask_alternative_", "ask_tasks_", "ask_caller_")):   # compiled per recipe and constraint
            rule = rule[:rule.index("_", 4)]
        if rule in ("ask_alternative", "ask_tasks", "ask_caller", "no_alternative", "holder_aborted"):
            for c in map(V.cres, st.used(V.CRES)):
                lab, at = self.label(c.request), self.label(c.at)
                agent = self.req_info.get(at, ("?",))[0]
                verdict = {"ask_alternative": "has an alternative: it reconfigures",
                           "ask_tasks": "has no other recipe, but its request has another task set: it reconfigures",
                           "ask_caller": "has no alternative: asking its caller",
                           "no_alternative": "is a request from outside: the conflict cannot be resolved",
                           "holder_aborted": "was aborted: waiting for its tasks to be released"}[rule]
                yield RoarEvent(st.i, "calling-context", agent, f"for {lab}: the emitter of {at} {verdict}",
                                {"request": lab, "at": at})

    def _tasks_chosen(self, st: "_StepFacts"):
        if st.rule != "tasks_chosen":
            return
        for h in map(V.hs, st.made(V.HS)):
            chosen = V.unwrap(V.unwrap(h.phase))   # h_write (vsome Tasks)
            ts = [self.m.tasks[self._name(V.unwrap(x))][1] for x in list_items(chosen)]
            lab = self.label(h.request)
            agent = self.req_info.get(lab, ("?",))[0]
            yield RoarEvent(st.i, "tasks", agent, f"{lab}: tasks {' then '.join(ts)}", {"request": lab, "tasks": ts})

    def _recipes(self, st: "_StepFacts"):
        m = self.m
        old_insts = {V.act(g).inst for g in st.used(V.ACT)}
        for a in map(V.act, st.made(V.ACT)):
            if a.inst not in old_insts:
                agent, task, recipe = m.recipes[self._name(a.recipe)]
                self.acts[a.inst] = (agent, task, recipe)
                lab = self.label(a.request)
                yield RoarEvent(st.i, "recipe", agent, f"{lab}: task {task}, recipe {recipe}",
                                {"request": lab, "task": task, "recipe": recipe})
        for d in map(V.rdone, st.made(V.RDONE)):
            agent, task, recipe = m.recipes[self._name(d.recipe)]
            reason = _reason(d.reason, m)
            lab = self.label(d.request)
            yield RoarEvent(st.i, "recipe-end", agent, f"{lab}: recipe {recipe} " +
                            ("done" if reason == "ok" else f"ended: {reason}"),
                            {"request": lab, "recipe": recipe, "reason": reason})

    def _primitives(self, st: "_StepFacts"):
        m, rule = self.m, st.rule
        for p in map(V.pending, st.made(V.PENDING)):
            owner, name = m.functions[self._name(p.fn)]
            args = ", ".join(_show_value(x) for x in list_items(p.args))
            site = m.sites.get(site_of(m, rule))
            agent = site.agent if site else (owner or "?")
            self.calls[p.dest] = (agent, f"{name}({args})")
            self.n_calls += 1
            cid = self.call_ids[p.dest] = f"C{self.n_calls}"
            inst = next((a.inst for fam, decode in ((V.CTL, V.ctl), (V.CHK, V.chk)) for a in map(decode, st.used(fam))),
                        None)
            yield RoarEvent(st.i, "primitive-start", agent, f"{name}({args})",
                            {"function": name, "call": cid, "request": self.inst_req.get(inst)})
        for r in map(V.return_, st.used(V.RETURN)):
            if r.dest in self.calls:
                agent, call = self.calls.pop(r.dest)
                dropped = " (dropped: the recipe was stopped)" if rule == "drop_result" else ""
                yield RoarEvent(st.i, "primitive-end", agent, f"{call} = {_show_value(r.value)}{dropped}",
                                {"value": _show_value(r.value), "dropped": bool(dropped),
                                 "call": self.call_ids.get(r.dest)})
        for c in map(V.callfail, st.used(V.CALLFAIL)):
            if c.dest in self.calls:
                agent, call = self.calls.pop(c.dest)
                yield RoarEvent(st.i, "primitive-end", agent, f"{call} failed",
                                {"failed": True, "call": self.call_ids.get(c.dest)})
        # a call withdrawn: its pending fact consumed with no answer made (the recipe was stopped)
        answered = ({V.return_(g).dest for g in st.made(V.RETURN)}
                    | {V.callfail(g).dest for g in st.made(V.CALLFAIL)})
        for p in map(V.pending, st.used(V.PENDING)):
            d = p.dest
            if d in self.calls and d not in answered:
                agent, call = self.calls.pop(d)
                yield RoarEvent(st.i, "primitive-end", agent, f"{call} withdrawn (the recipe was stopped)",
                                {"withdrawn": True, "call": self.call_ids.get(d)})

    def _writes(self, st: "_StepFacts"):
        m = self.m
        before = {c.cell: c.value for c in map(V.contains, st.used(V.CONTAINS))}
        site = m.sites.get(site_of(m, st.rule))
        written = f"v_{site.agent}_{site.var}" if site is not None and site.kind == "set" else None
        for x in map(V.contains, st.made(V.CONTAINS)):
            c = x.cell
            if c in before and (before[c] is not x.value or self._name(c) == written):
                cell = self._name(c)
                if cell in m.cells:
                    agent, var = m.cells[cell]
                    yield RoarEvent(st.i, "write", agent, f"{agent}::{var} = {_show_value(x.value)}",
                                    {"var": f"{agent}::{var}", "value": _show_value(x.value)})

    # pause / resume of an activation (its pause state goes from go to paused or back)
    def _pauses(self, st: "_StepFacts"):
        before_z = {z.inst: self._name(z.pause) for z in map(V.rstat, st.used(V.RSTAT))}
        for z in map(V.rstat, st.made(V.RSTAT)):
            i_ = z.inst
            was, now = before_z.get(i_), self._name(z.pause)
            if was is None or (was == "go") == (now == "go") or st.rule.startswith(("kill", "crash_stop")):
                continue
            who = self.acts.get(i_, ("?", "?", "?"))
            kind = "resume" if now == "go" else "pause"
            yield RoarEvent(st.i, kind, who[0], f"recipe {who[2]} {'resumed' if kind == 'resume' else 'paused'}",
                            {"recipe": who[2]})


class _StepFacts:
    """One step's facts grouped by family: ``made`` (produced) and ``used`` (consumed)."""

    __slots__ = ("i", "rule", "_made", "_used")

    def __init__(self, i: int, step):
        self.i = i
        self.rule = step.rule
        self._made = _by_family(f for _mode, f in step.produced if type(f) is Root)
        self._used = _by_family(f for _m, f in step.consumed if type(f) is Root)

    def made(self, fam: str):
        return self._made.get(fam, ())

    def used(self, fam: str):
        return self._used.get(fam, ())


def _by_family(facts) -> dict:
    """Facts grouped by the name of their family (what each kind of event reads)."""
    out: dict = {}
    for f in facts:
        if isinstance(f.head, Const):
            out.setdefault(f.head.name, []).append(f)
    return out


def site_of(model: CompiledModel, rule: str) -> str:
    """The site const of a compiled statement rule ("" for a framework rule): the compiler's table."""
    return model.rule_sites.get(rule, "")


def _reason(t, m) -> str:
    h = t.head.name if isinstance(t.head, Const) else "?"
    if h == "k_ok":
        return "ok"
    if h == "k_abort":
        return "aborted"
    if h == "k_local":
        site = m.sites.get(V.unwrap(t).head.name)
        return f"local failure at {site.pos.line}:{site.pos.col} ({site.text})" if site else "local failure"
    if h == "k_cst":
        return f"constraint failed: {m.csts.get(V.k_cst(t).cst.head.name, ('?', '?'))[1]}"
    if h == "k_switch":
        return f"switched away from {m.csts.get(V.unwrap(t).head.name, ('?', '?'))[1]}"
    if h == "k_retask":
        task = m.tasks.get(V.unwrap(t).head.name)
        return f"switched to a task set without {task[1] if task else '?'}"
    if h == "k_crash":
        return "stopped: its agent crashed"
    return show(t)


def _show_value(t) -> str:
    return format_value(value_of(t))


def format_value(v) -> str:
    """A Python value as the spec language writes it (structs as (a, b))."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, Fraction):   # exact when it has a decimal form (1234.5678, not 1234.57)
        try:
            return num_lit(v)
        except RoarError:
            return repr(float(v))
    if isinstance(v, str):
        return string_literal(v)
    if isinstance(v, tuple) and len(v) == 2 and v[0] == "opaque":
        return f"<opaque {v[1]}>"
    if isinstance(v, (tuple, list)):
        return "(" + ", ".join(format_value(x) for x in v) + ")"
    return str(v)


def describe_ec(t, m: CompiledModel) -> list[str]:
    out = []
    for x in list_items(t):
        h = x.head.name
        if h == "vcst":
            out.append(f"constraint failed: {m.csts.get(V.unwrap(x).head.name, ('?', '?'))[1]}")
        elif h == "vviol":
            out.append(f"post-condition violated: {m.csts.get(V.unwrap(x).head.name, ('?', '?'))[1]}")
        elif h == "vbroke":
            out.append(f"ensured constraint stopped holding: {m.csts.get(V.unwrap(x).head.name, ('?', '?'))[1]}")
        elif h == "vtsk":
            agent, task = m.tasks.get(V.unwrap(x).head.name, ("?", "?"))
            out.append(f"task failed: {agent}::{task}")
        elif h == "vconf":
            agent, task = m.tasks.get(V.unwrap(x).head.name, ("?", "?"))
            out.append(f"concurrency: task {agent}::{task} is held by another constraint, and no agent of "
                       f"its calling context has an alternative")
        elif h == "vunavail":
            agent = m.agents.get(V.unwrap(x).head.name, "?")
            out.append(f"unavailable: agent {agent} crashed")
        elif h == "vsite":
            s = m.sites.get(V.unwrap(x).head.name)
            out.append(f"local failure: {s.agent}.{s.task}.{s.recipe} at {s.pos.line}:{s.pos.col}: {s.text}"
                       if s else "local failure")
        else:
            out.append(show(x))
    return out


# ------------------------------------------------------------------ the run


def run_model(model: CompiledModel, seed: int = 0, max_steps: int = 100_000, registry: Optional[Registry] = None,
              faults: Optional[list[Fault]] = None, fair: bool = False,
              on_event: Optional[Callable[[RoarEvent], None]] = None,
              on_state: Optional[Callable[[object], None]] = None, crashes=()) -> RunResult:
    """Run the model to quiescence (or ``max_steps`` CLF steps); the functional layer answers pending calls.

    ``on_event`` sees each ROAR event as it happens; ``on_state`` sees the CLF context after each
    step (for checking a state invariant along the run; it must not change it). ``crashes``
    (``CrashAt`` or ``"AGENT@STEP[-BACK]"``) need a model compiled with ``crash_setup(crashes)``:
    the scheduler never chooses a crash or a comeback; each is the compiled crash rule, taken at the
    step given (docs/semantics.md, "Crashes")."""
    prog = model.program()
    schedule = _CrashSchedule(model, prog, crashes) if crashes else None
    start = next(d for d in prog.sig.directives if hasattr(d, "start"))
    ctx = prog.start_context(start.start)
    values = Values(model)
    resolver = Resolver(model, registry, list(faults or ()), values)
    narrator = Narrator(model)
    steps: list = []
    events: list[RoarEvent] = []
    external: dict = {}   # step number -> (pending fact, answer fact): the functional layer's steps

    def record(step, _ctx):
        i = len(steps) + 1
        steps.append((step.rule, [show(f) for _m, f in step.consumed if type(f) is Root],
                      [show(f) for _m, f in step.produced if type(f) is Root]))
        for ev in narrator.events(i, step):
            events.append(ev)
            if on_event:
                on_event(ev)
        if on_state:
            on_state(_ctx)

    def fire_due() -> bool:
        """Take the crashes and comebacks due before the next step; True if one was taken."""
        fired = False
        while schedule is not None:
            choice = schedule.due(ctx, len(steps) + 1)
            if choice is None:
                return fired
            _nxt, st = prog.successor(ctx, choice)   # the rule's instance, applied to the run's context
            record(runner.external([f for _m, f in st.consumed], [f for _m, f in st.produced], rule=choice.rule),
                   ctx)
            fired = True
        return fired

    def on_step(step, _ctx):
        record(step, _ctx)
        fire_due()

    for _mode, f, _n in ctx.facts():
        if type(f) is Root and isinstance(f.head, Const) and f.head.name == V.RQ:
            narrator.label(V.rq(f).request)
            narrator.req_info["R0"] = (model.request_agent, model.csts[model.request_cst][1])
    templates = prog.templates
    if model.crashes:   # crashes and comebacks happen when --crash says, never by the scheduler's choice
        templates = [t for t in templates if t.name not in CRASH_RULES]
    # timed (docs/semantics.md, Time): time is slow in a run, as the functional layer is: the
    # clock advances only when nothing else can happen (no step, no call to answer)
    tick_tpl = [t for t in templates if t.name == TICK_RULE] if getattr(model, "tick_ms", None) else []
    if tick_tpl:
        templates = [t for t in templates if t.name != TICK_RULE]
    runner = Run(templates, ctx, seed=seed, fair=fair, prover=prog.prover(), on_step=on_step)
    fire_due()
    pending = Const("pending")
    quiescent = False
    while True:
        # the bound counts every step of the run: the engine's and the functional layer's answers
        # (the runner counts its own steps only, cumulatively)
        left = max_steps - len(steps) if max_steps else None
        if left is not None and left <= 0:
            quiescent = False
            break
        quiescent = runner.run(runner.steps + left if left is not None else None)
        if not quiescent:
            break
        bag = ctx.index.get(pending)
        calls = list(bag.items) if bag else []
        if not calls:
            if schedule is not None and schedule.at_rest(ctx) and fire_due():
                continue   # a comeback due later: nothing else can happen before it
            tick = next(iter(enabled_steps(tick_tpl, ctx, prog.prover())), None) if tick_tpl else None
            if tick is not None:
                if max_steps and len(steps) >= max_steps:
                    quiescent = False   # the clock could still advance: the step bound stopped the run
                    break
                _nxt, st = prog.successor(ctx, tick)   # the tick's instance, applied to the run's context
                on_step(runner.external([f for _m, f in st.consumed], [f for _m, f in st.produced],
                                        rule=TICK_RULE), ctx)
                continue
            break
        # answer the oldest call first (all pending calls were made while the rest waited)
        for f in calls:
            if max_steps and len(steps) >= max_steps:
                break
            p = V.pending(f)
            fc, args, d = p.fn.head.name, list_items(p.args), p.dest
            result, how, writes = resolver.answer(fc, args)
            ans = const(V.RETURN, result, d) if result is not None else const(V.CALLFAIL, d)
            eaten, made = [f], [ans]
            owner = model.functions[fc][0]
            for var, value in writes.items():   # an outcome's writes (declared, or forced by a fault)
                agent, _, name = var.rpartition("::")
                cell = f"v_{agent or owner}_{name}"
                old = next((g for g in cells_of(ctx, cell)), None)
                if old is not None:
                    eaten.append(old)
                    made.append(const(V.CONTAINS, V.contains(old).cell,
                                      values.term(value, model.cell_types.get(cell))))
            step = runner.external(eaten, made, rule="functional_layer")
            external[len(steps) + 1] = (f, ans)
            on_step(step, ctx)
        if max_steps and len(steps) >= max_steps:
            quiescent = False
            break
    unused = [f for f in resolver.faults if f not in resolver.used]
    if unused:
        names = ", ".join(str(f) for f in unused)
        raise RoarError(f"--fault {names}: no such call happened in this run (check the name and the call number)")
    if schedule is not None and quiescent:
        schedule.check_done(len(steps))
    res = collect_result(model, ctx, steps, events, quiescent, narrator)
    res.external = external
    return res


class _CrashSchedule:
    """The crashes of a run (``--crash``): which crash or comeback is due before a step."""

    def __init__(self, model: CompiledModel, prog, crashes):
        cs = [parse_crash(c) for c in crashes]
        cr = model.crashes
        if not cr or not cr.scheduled:
            raise RoarError("a run with crashes needs its model compiled with them: compile_spec(..., "
                            "crashes=crash_setup(crashes))")
        known = [ag.name for ag in model.spec.agents]
        for c in cs:
            if c.agent not in known:
                raise RoarError(f"--crash {c}: unknown agent {c.agent!r}{did_you_mean(c.agent, known)}; the spec's "
                                f"agents: {', '.join(known)}")
            if c.agent not in cr.agents:
                raise RoarError(f"--crash {c}: the model was compiled without crashes of {c.agent} "
                                f"(compile_spec(..., crashes=crash_setup(crashes)))")
        if len(cs) > cr.bound:
            raise RoarError(f"--crash: {len(cs)} crashes, but the model was compiled for {cr.bound}")
        self.queue: dict = {}
        for c in sorted(cs, key=lambda c: c.step):
            q = self.queue.setdefault(c.agent, [])
            if q and (q[-1].back or q[-1].step) >= c.step:
                raise RoarError(f"--crash {c}: {c.agent} is still down then (--crash {q[-1]})")
            q.append(c)
        self.down: dict = {}     # agent -> the crash it is down from
        self.done: list = []     # crashes taken
        self.tpl = {t.name: t for t in prog.templates if t.name in CRASH_RULES}
        self.prover = prog.prover()

    def _choice(self, rule: str, agent: str, ctx):
        a = f"a_{agent}"
        for ch in enabled_steps([self.tpl[rule]], ctx, self.prover):
            if any(V.head_name(f) == V.CEP and V.head_name(V.cep(f).agent) == a for _m, f in ch.consumed):
                return ch
        return None

    def due(self, ctx, step: int):
        for agent, q in self.queue.items():
            if agent in self.down:
                c = self.down[agent]
                if c.back is None or step >= c.back:
                    ch = self._choice("back_armed" if q else "back", agent, ctx)
                    if ch is not None:
                        del self.down[agent]
                        return ch
            elif q and step >= q[0].step:
                ch = self._choice("crash", agent, ctx)
                if ch is not None:
                    self.down[agent] = q.pop(0)
                    self.done.append(self.down[agent])
                    return ch
        return None

    def at_rest(self, ctx) -> bool:
        """The run is quiescent: a comeback due later is due now (nothing else would happen)."""
        moved = False
        for agent, c in list(self.down.items()):
            if c.back is not None:
                self.down[agent] = CrashAt(c.agent, c.step, None)
                moved = True
        return moved or bool(self.down)

    def check_done(self, last: int) -> None:
        left = [c for q in self.queue.values() for c in q]
        if left:
            c = left[0]
            raise RoarError(f"--crash {c}: {c.agent} handled no request from step {c.step} to the end of the run "
                            f"(step {last}), so it never crashed: a crash shows only in the requests an agent "
                            f"handles (docs/semantics.md, Crashes)")


def cells_of(ctx, cell: str):
    bag = ctx.index.get(Const(V.CONTAINS))
    for f in (bag.items if bag else ()):
        if V.contains(f).cell.head.name == cell:
            yield f


def outside_request_state(ctx) -> str:
    """How the outside world's request (R0: the one emitted by ``itop``) stands in ``ctx``: a
    state's name (success, failure, running, ...), or "unfinished" when it has none."""
    facts = [f for _m, f, _n in ctx.facts() if type(f) is Root and isinstance(f.head, Const)]
    top = {V.rq(f).request for f in facts if f.head.name == V.RQ and show(V.rq(f).emitter) == "itop"}
    for f in facts:
        if f.head.name == V.RS and V.rs(f).request in top:
            return STATE_NAMES.get(V.rs(f).state.head.name, "?")
    return "unfinished"


def collect_result(model, ctx, steps, events, quiescent, narrator) -> RunResult:
    outcome, ec = "unfinished", []
    final: dict = {}
    for mode, f, _n in ctx.facts():
        if type(f) is not Root or not isinstance(f.head, Const):
            continue
        h = f.head.name
        if h == V.RS:
            x = V.rs(f)
            if narrator.labels.get(x.request) == "R0":
                outcome = STATE_NAMES.get(x.state.head.name, "?")
        elif h == V.CONTAINS:
            c = V.contains(f)
            if c.cell.head.name in model.cells:
                agent, var = model.cells[c.cell.head.name]
                final[f"{agent}::{var}"] = value_of(c.value)
        elif h == V.ECF:
            e = V.ecf(f)
            if narrator.labels.get(e.request) == "R0":
                ec = describe_ec(e.ec, model)
    if outcome == "unfinished" and not steps:
        outcome = "unfinished"
    reqs = {lab: f"{a}: {t}" for lab, (a, t) in narrator.req_info.items()}
    return RunResult(model, steps, events, quiescent, outcome, ec, final, reqs, ctx)
