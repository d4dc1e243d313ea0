"""The framework's vocabulary: the facts and terms of ``framework.clf`` by name, with named arguments.

Code that reads the states and steps of a compiled model decodes facts here,
never by argument position: ``rq(f).emitter``, not ``f.args[3]``. Each record
is a ``NamedTuple`` whose fields are the family's arguments in the order the
framework declares them (implicit arguments first; the framework's families
have none), named as the framework's comments name them, and whose ``sorts``
are the declared types of those arguments. ``tests/roar/test_vocabulary.py``
checks every record against the elaborated framework signature, so a change
of the framework that adds, removes or moves an argument fails there.

Decoders are on the explorer's hot path (per state and per step): a decoder
builds its record straight from the term's argument tuple, with no checks.
"""

from __future__ import annotations

from typing import NamedTuple, Optional

from ..clf.terms import Const, Root

__all__ = [
    # family and constructor names
    "CONTAINS", "RQ", "RS", "ECF", "HS", "MASK", "ABORTREQ", "CRES", "ACT", "CHK", "CTL", "RSTAT", "OWNS",
    "RDONE", "PENDING", "RETURN", "CALLFAIL", "CEP", "MON_IN", "MON_CMD", "MON_B", "MON_PLAN", "MON_GOT",
    "MON_UNDONE", "MTAG_SITE", "MTAG_TASK", "MTAG_END", "RB_RUN", "RB_SLEEP",
    "REQUEST_FAMILIES", "INSTANCE_FAMILIES", "EXPLORER_FAMILIES", "EXPLORER_TERMS", "FACTS", "TERMS", "WRAPPERS",
    # records
    "Contains", "Rq", "Rs", "Ecf", "Hs", "Mask", "Abortreq", "Cres", "Act", "Chk", "Ctl", "Rstat", "Owns",
    "Rdone", "Pending", "Return", "Callfail", "Cep", "MonIn", "MonCmd", "MonB", "MonPlan", "MonGot",
    "MonUndone", "TagSite", "TagTask", "RbRun", "RbSleep",
    "Cons", "VPair", "MCall", "CCons", "KCst",
    # decoders
    "contains", "rq", "rs", "ecf", "hs", "mask", "abortreq", "cres", "act", "chk", "ctl", "rstat", "owns",
    "rdone", "pending", "return_", "callfail", "cep", "mon_in", "mon_cmd", "mon_b", "mon_plan", "mon_got",
    "mon_undone", "tag_site", "tag_task", "rb_run", "rb_sleep",
    "cons", "vpair", "m_call", "ccons", "k_cst", "unwrap", "decode", "head_name", "subject",
]

_new = tuple.__new__

# ------------------------------------------------------------------ family names

CONTAINS = "contains"
RQ = "rq"
RS = "rs"
ECF = "ecf"
HS = "hs"
MASK = "mask"
ABORTREQ = "abortreq"
CRES = "cres"
ACT = "act"
CHK = "chk"
CTL = "ctl"
RSTAT = "rstat"
OWNS = "owns"
RDONE = "rdone"
PENDING = "pending"
RETURN = "return"
CALLFAIL = "callfail"
CEP = "cep"
#: the sequential-achievement monitor's facts (roar/explore.py adds them; not declared in the framework)
MON_IN = "mon_in"
MON_CMD = "mon_cmd"
MON_B = "mon_b"
MON_PLAN = "mon_plan"
MON_GOT = "mon_got"
MON_UNDONE = "mon_undone"
#: the monitor's subtree tags (terms, the second argument of mon_in / mon_cmd, the argument of mon_b)
MTAG_SITE = "mtag_site"
MTAG_TASK = "mtag_task"
MTAG_END = "mtag_end"     # (a constant: the B of a mon_undone when the recipe ended)
#: the robot-backed explorer's marks (robot/explore.py adds them; not declared in the framework)
RB_RUN = "rb_run"
RB_SLEEP = "rb_sleep"

#: families whose first argument is the request they are about (see :func:`subject`)
REQUEST_FAMILIES = frozenset({"hs", "rs", "rq", "wrq", "tfn", "abortreq", "cres", "ppz", "rdone", "ecf", "cfail",
                              "tfe"})
#: families whose first argument is the recipe activation they are about (see :func:`subject`)
INSTANCE_FAMILIES = frozenset({"ctl", "rstat", "alive", "ending", "kill", "fin", "act", "chk", "owns"})


# ------------------------------------------------------------------ facts (framework.clf)


class Contains(NamedTuple):
    """``contains C V``: cell C holds V."""
    cell: object
    value: object
    sorts = ("dest", "val")


class Rq(NamedTuple):
    """``rq R Agent Constraint Emitter Kind``: request R of a constraint at an agent, emitted by an
    activation (``itop`` for the outside world, ``irel`` once released), of kind make, ensure or task run."""
    request: object
    agent: object
    cst: object
    emitter: object
    kind: object
    sorts = ("req", "agent", "cst", "inst", "kind")


class Rs(NamedTuple):
    """``rs R State``: the state of request R (figure 2)."""
    request: object
    state: object
    sorts = ("req", "rstate")


class Ecf(NamedTuple):
    """``ecf R ErrorContext``: the error context of a failed request."""
    request: object
    ec: object
    sorts = ("req", "val")


class Hs(NamedTuple):
    """``hs R Phase EC Failed Plan Where``: the handler of a request at its agent: phase, error
    context, failed tasks, plan, where values."""
    request: object
    phase: object
    ec: object
    failed: object
    plan: object
    where: object
    sorts = ("req", "phase", "val", "val", "val", "val")


class Mask(NamedTuple):
    """``mask Agent Entries``: the tasks committed to live requests (``vpair (vtsk T) (vreq R)``)."""
    agent: object
    entries: object
    sorts = ("agent", "val")


class Abortreq(NamedTuple):
    """``abortreq R``: request R is to be aborted."""
    request: object
    sorts = ("req",)


class Cres(NamedTuple):
    """``cres R At``: the calling-context search for R, at request At of the calling context."""
    request: object
    at: object
    sorts = ("req", "req")


class Act(NamedTuple):
    """``act I Request Task Recipe OwnedCount``: recipe activation I handles a request."""
    inst: object
    request: object
    task: object
    recipe: object
    owned: object
    sorts = ("inst", "req", "task", "recipe", "nat")


class Chk(NamedTuple):
    """``chk I Request Recipe Failed``: activation I checks a recipe's pre-conditions."""
    inst: object
    request: object
    recipe: object
    failed: object
    sorts = ("inst", "req", "recipe", "number")


class Ctl(NamedTuple):
    """``ctl I Mode Code Locals``: the control of activation I: its mode, the code left, its locals."""
    inst: object
    mode: object
    code: object
    locals: object
    sorts = ("inst", "mode", "code", "val")


class Rstat(NamedTuple):
    """``rstat I Pause``: the pause state of activation I (``go`` or ``pz N B``)."""
    inst: object
    pause: object
    sorts = ("inst", "pzs")


class Owns(NamedTuple):
    """``owns I R Forwarded``: activation I holds request R; tt: a pause was forwarded to it."""
    inst: object
    request: object
    forwarded: object
    sorts = ("inst", "req", "bool")


class Rdone(NamedTuple):
    """``rdone R Recipe Reason``: the recipe handling R ended, for a reason."""
    request: object
    recipe: object
    reason: object
    sorts = ("req", "recipe", "reason")


class Pending(NamedTuple):
    """``pending F Args D``: a call of function F with a list of arguments, answered at D."""
    fn: object
    args: object
    dest: object
    sorts = ("fn", "val", "dest")


class Return(NamedTuple):
    """``return V D``: value V delivered at D (a primitive's answer, among others)."""
    value: object
    dest: object
    sorts = ("val", "dest")


class Callfail(NamedTuple):
    """``callfail D``: the call answered at D failed."""
    dest: object
    sorts = ("dest",)


class Cep(NamedTuple):
    """``cep Agent Epoch``: an agent that may crash, and its epoch (a sentinel task ``t_epN``: N
    crashes and comebacks so far; down when N is odd). Only in models compiled with crashes."""
    agent: object
    epoch: object
    sorts = ("agent", "task")


# ------------------------------------------------------------------ facts the explorers add


class MonIn(NamedTuple):
    """``mon_in R Pair``: request R is in the subtree tagged Pair (an ``mtag_site`` or ``mtag_task`` term,
    see :class:`TagSite` and :class:`TagTask`)."""
    request: object
    pair: object
    sorts = None


class MonCmd(NamedTuple):
    """``mon_cmd D Pair``: the command answered at D runs in the subtree tagged Pair."""
    dest: object
    pair: object
    sorts = None


class MonB(NamedTuple):
    """``mon_b Pair``: a command of the subtree tagged Pair (the B of a pair) has started."""
    pair: object
    sorts = None


class MonPlan(NamedTuple):
    """``mon_plan P R C Ts Cur``: plan instance P (a fresh name) of request R of constraint C, with
    tasks Ts (a list of ``vtsk T``); Cur is ``tt`` while it is R's current plan, else ``ff``."""
    plan: object
    request: object
    cst: object
    tasks: object
    current: object
    sorts = None


class MonGot(NamedTuple):
    """``mon_got S I``: the request activation I sent at site S (a constant) was achieved."""
    site: object
    inst: object
    sorts = None


class MonUndone(NamedTuple):
    """``mon_undone A B`` (only in the state right after the step): B (a site constant, or
    ``mtag_end`` when the recipe ended) was achieved while site A's predicate was false."""
    a: object
    b: object
    sorts = None


class TagSite(NamedTuple):
    """``mtag_site S I`` (a term): the request activation I sent at site S (a constant), and its subtree."""
    site: object
    inst: object
    sorts = None


class TagTask(NamedTuple):
    """``mtag_task P T`` (a term): task T (a constant) of plan instance P (see :class:`MonPlan`)."""
    plan: object
    task: object
    sorts = None


class RbRun(NamedTuple):
    """``rb_run D``: the call answered at D runs on the robot."""
    dest: object
    sorts = None


class RbSleep(NamedTuple):
    """``rb_sleep Ctl Ticks``: an activation's control fact, asleep for ``rbt_<n>`` ticks."""
    ctl: object
    ticks: object
    sorts = None


# ------------------------------------------------------------------ terms (constructors with several arguments)


class Cons(NamedTuple):
    """``vcons Head Tail``: a list cell."""
    head: object
    tail: object
    sorts = ("val", "val")


class VPair(NamedTuple):
    """``vpair A B``: a pair of values (a mask entry is ``vpair (vtsk T) (vreq R)``)."""
    first: object
    second: object
    sorts = ("val", "val")


class MCall(NamedTuple):
    """``m_call D Site``: an activation waits for the call answered at D, made at Site."""
    dest: object
    site: object
    sorts = ("dest", "site")


class CCons(NamedTuple):
    """``ccons Site Rest``: code, the site to run next and the rest."""
    site: object
    rest: object
    sorts = ("site", "code")


class KCst(NamedTuple):
    """``k_cst C ErrorContext``: a recipe ends because constraint C it emitted failed."""
    cst: object
    ec: object
    sorts = ("cst", "val")


#: family name -> record, for the framework's families (checked against the signature)
FACTS: dict = {
    CONTAINS: Contains, RQ: Rq, RS: Rs, ECF: Ecf, HS: Hs, MASK: Mask, ABORTREQ: Abortreq, CRES: Cres,
    ACT: Act, CHK: Chk, CTL: Ctl, RSTAT: Rstat, OWNS: Owns, RDONE: Rdone, PENDING: Pending, RETURN: Return,
    CALLFAIL: Callfail, CEP: Cep,
}
#: family name -> record, for the facts the explorers add (never declared in the framework)
EXPLORER_FAMILIES: dict = {MON_IN: MonIn, MON_CMD: MonCmd, MON_B: MonB, MON_PLAN: MonPlan, MON_GOT: MonGot,
                           MON_UNDONE: MonUndone, RB_RUN: RbRun, RB_SLEEP: RbSleep}
#: constructor name -> record, for the terms the explorers build (never declared in the framework)
EXPLORER_TERMS: dict = {MTAG_SITE: TagSite, MTAG_TASK: TagTask}
#: constructor name -> record, for the framework's terms of several arguments
TERMS: dict = {"vcons": Cons, "vpair": VPair, "m_call": MCall, "ccons": CCons, "k_cst": KCst}
#: constructor name -> the sort of its one argument (read with :func:`unwrap`)
WRAPPERS: dict = {
    "vnum": "number", "vbool": "bool", "vstr": "string", "vrec": "val", "vopq": "number", "vsome": "val",
    "vtsk": "task", "vcst": "cst", "vviol": "cst", "vbroke": "cst", "vconf": "task", "vsite": "site", "vunavail": "agent",
    "m_make": "req", "m_block": "val", "h_write": "val",
    "k_local": "site", "k_switch": "cst", "k_retask": "task", "k_task": "task",
}

_RECORDS = {**FACTS, **EXPLORER_FAMILIES, **EXPLORER_TERMS, **TERMS}


# ------------------------------------------------------------------ decoders


def contains(f) -> Contains:
    return _new(Contains, f.args)


def rq(f) -> Rq:
    return _new(Rq, f.args)


def rs(f) -> Rs:
    return _new(Rs, f.args)


def ecf(f) -> Ecf:
    return _new(Ecf, f.args)


def hs(f) -> Hs:
    return _new(Hs, f.args)


def mask(f) -> Mask:
    return _new(Mask, f.args)


def abortreq(f) -> Abortreq:
    return _new(Abortreq, f.args)


def cres(f) -> Cres:
    return _new(Cres, f.args)


def act(f) -> Act:
    return _new(Act, f.args)


def chk(f) -> Chk:
    return _new(Chk, f.args)


def ctl(f) -> Ctl:
    return _new(Ctl, f.args)


def rstat(f) -> Rstat:
    return _new(Rstat, f.args)


def owns(f) -> Owns:
    return _new(Owns, f.args)


def rdone(f) -> Rdone:
    return _new(Rdone, f.args)


def pending(f) -> Pending:
    return _new(Pending, f.args)


def return_(f) -> Return:
    return _new(Return, f.args)


def callfail(f) -> Callfail:
    return _new(Callfail, f.args)


def cep(f) -> Cep:
    return _new(Cep, f.args)


def mon_in(f) -> MonIn:
    return _new(MonIn, f.args)


def mon_cmd(f) -> MonCmd:
    return _new(MonCmd, f.args)


def mon_b(f) -> MonB:
    return _new(MonB, f.args)


def mon_plan(f) -> MonPlan:
    return _new(MonPlan, f.args)


def mon_got(f) -> MonGot:
    return _new(MonGot, f.args)


def mon_undone(f) -> MonUndone:
    return _new(MonUndone, f.args)


def tag_site(t) -> TagSite:
    return _new(TagSite, t.args)


def tag_task(t) -> TagTask:
    return _new(TagTask, t.args)


def rb_run(f) -> RbRun:
    return _new(RbRun, f.args)


def rb_sleep(f) -> RbSleep:
    return _new(RbSleep, f.args)


def cons(t) -> Cons:
    return _new(Cons, t.args)


def vpair(t) -> VPair:
    return _new(VPair, t.args)


def m_call(t) -> MCall:
    return _new(MCall, t.args)


def ccons(t) -> CCons:
    return _new(CCons, t.args)


def k_cst(t) -> KCst:
    return _new(KCst, t.args)


def unwrap(t):
    """The one argument of a one-argument constructor (those of :data:`WRAPPERS`: ``vnum N``,
    ``vsome V``, ``vtsk T``, ``m_make R``, ``k_local S``, ...)."""
    (x,) = t.args
    return x


def subject(f):
    """What a fact of :data:`REQUEST_FAMILIES` or :data:`INSTANCE_FAMILIES` is about: its request
    or its activation (the first argument of each of those families)."""
    return f.args[0]


def decode(f) -> Optional[tuple]:
    """The record of a fact or term of a known family or constructor, else None."""
    if type(f) is not Root or type(f.head) is not Const:
        return None
    cls = _RECORDS.get(f.head.name)
    return _new(cls, f.args) if cls is not None else None


def head_name(t) -> Optional[str]:
    """The name of a term's head constant (a family, a constructor, a constant), None for any other head."""
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None

