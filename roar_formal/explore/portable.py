"""States and steps that another process can read back: the wire format of the distributed search.

A CLF context cannot be sent as it is: its terms are hash-consed per process (their
hashes are object identities), and the state keys of ``clf/state.py`` number hypotheses
once per process. :class:`ContextCodec` writes a context of facts (linear, affine and
persistent, in the order of its dictionaries, so the receiver rebuilds its indexes in the
order the sender's successors follow) as bytes (``marshal`` of nested tuples: constants by
name, literals by value, de Bruijn indices, lambdas), and reads them back into the
receiving process's hash-consed terms.

**Fresh names keep their identity across processes.** A fresh name (a ``Param``) is written
as (the process that made it, its number there, its hint); each process maps such a pair
to one local ``Param`` for the run, and writes a name it received under the pair it came
with. So two states that share a fresh name in one process share it in every process,
exactly as in a single-process search: a step read back on the driver consumes the very
names of the state it leaves, and a state compared without renaming (``canonical =
false``) is compared as the single-process search compares it.

**The partition hash** (:meth:`ContextCodec.partition`) is the same in every process and
for every renaming of the fresh names: each fact is hashed with its fresh names erased
(constants by a CRC of their name, so Python's per-process string hashing plays no part),
and the state hash is the hash of the sorted multiset of fact hashes. Two states equal up
to renaming get one hash, so one owner sees both and dedups them with its own (exact,
process-local) key; the converse need not hold (it only spreads states over owners).

Only contexts of facts are portable: a state holding a rule, an inert hypothesis or a fact
with a logic variable is refused (:class:`NotPortable`), never approximated.
"""

from __future__ import annotations

import marshal
import zlib
from fractions import Fraction
from typing import Optional

from ..clf.context import Context, FrozenContext
from ..clf.rules import AFF, LIN, PERS
from ..clf.terms import BVar, CanonParam, Const, Lam, Lit, Node, Param, Root

__all__ = ["ContextCodec", "NotPortable", "PortableStep"]

_MODES = {LIN: 0, AFF: 1, PERS: 2}
_CACHE = 300_000   # entries of each cache of a codec (emptied when full)

# tags of the nested tuples (a constant-headed root is (name, *args): its first item is a str)
_LIT, _PARAM, _BVAR, _LAM, _CANON = 0, 1, 2, 3, 4


class NotPortable(Exception):
    """A state or step the wire format cannot carry (rules or logic variables in a state)."""


class PortableStep:
    """An engine step read back in another process: its rule, the facts it consumed and those it
    produced (``(mode, fact)`` pairs), which is what describing a step, the ROAR narration and
    events read. It carries no template or bindings: it is read, never fired."""

    __slots__ = ("rule", "consumed", "produced", "template", "bindings", "ctx_rule")

    def __init__(self, rule: str, consumed: list, produced: list):
        self.rule = rule
        self.consumed = consumed
        self.produced = produced
        self.template = None
        self.bindings = ()
        self.ctx_rule = None

    def __repr__(self) -> str:
        return f"PortableStep({self.rule!r}, {len(self.consumed)} consumed, {len(self.produced)} produced)"


class ContextCodec:
    """Contexts and steps to bytes and back, for one process of one search run.

    ``origin`` names this process among the run's (a small int, distinct per process):
    fresh names made here are written under it. ``implicit`` is the program's table of
    implicit arguments, given to every context read back (it only matters for printing)."""

    def __init__(self, origin: int, implicit: Optional[dict] = None):
        self.origin = origin
        self.implicit = implicit
        self._own: dict[int, Param] = {}            # id of a name made here -> the name
        self._names: dict[tuple, Param] = {}        # (origin, id) of a name made elsewhere -> local name
        self._whence: dict[Param, tuple] = {}       # local name of a name made elsewhere -> (origin, id, hint)
        self._code: dict = {}                       # term -> its nested tuple
        self._wire: dict = {}                       # fact -> its bytes
        self._read: dict = {}                       # bytes of a fact read -> the fact
        self._hash: dict = {}                       # term -> its partition hash
        self._const_hash: dict = {}

    # ------------------------------------------------------------ writing
    def _param(self, p: Param) -> tuple:
        if type(p) is CanonParam:
            return (_CANON, p.index)
        w = self._whence.get(p)
        if w is not None:
            return (_PARAM, w[0], w[1], w[2])
        self._own[p.id] = p
        return (_PARAM, self.origin, p.id, p.hint)

    def term(self, t: Node):
        """The nested tuple of a term (written once per term and run: a fresh name keeps the
        (origin, number) it was first written or read under)."""
        c = self._code.get(t)
        if c is not None:
            return c
        tt = type(t)
        if tt is Root:
            h = t.head
            th = type(h)
            args = tuple([self.term(a) for a in t.args])
            if th is Const:
                c = (h.name,) + args
            elif th is Lit:
                v = h.value
                c = (_LIT, h.family.name, h.text, (v.numerator, v.denominator) if isinstance(v, Fraction) else v)
            elif isinstance(h, Param):
                c = self._param(h) + (args,)
            elif th is BVar:
                c = (_BVAR, h.index, args)
            else:
                raise NotPortable(f"a term headed by {type(h).__name__} ({t!r}) cannot be sent to another process")
        elif tt is Lam:
            c = (_LAM, self.term(t.body))
        else:
            raise NotPortable(f"a {tt.__name__} term cannot be sent to another process")
        if len(self._code) >= _CACHE:
            self._code.clear()
        self._code[t] = c
        return c

    def wire(self, t: Node) -> bytes:
        """A fact as bytes: equal bytes are equal facts (fresh names by their global identity), so
        a reader keeps the facts it has read by their bytes and reads each one once."""
        b = self._wire.get(t)
        if b is None:
            try:
                b = marshal.dumps(self.term(t))
            except ValueError as exc:   # nested past marshal's depth limit
                raise NotPortable(f"a fact too deep to send to another process: {exc}") from None
            if len(self._wire) >= _CACHE:
                self._wire.clear()
            self._wire[t] = b
        return b

    def state(self, ctx) -> bytes:
        """A context of facts as bytes (its dictionaries' order kept)."""
        if isinstance(ctx, FrozenContext):
            lin, aff, pers = _tally(ctx.lin), _tally(ctx.aff), {t: 1 for t in ctx.pers}
            rules, inert, opened = ctx.rules, ctx.inert, ctx.open
        else:
            lin, aff, pers = ctx.lin, ctx.aff, ctx.pers
            rules, inert, opened = ctx.rules, ctx.inert, ctx.open
        if rules or inert or opened:
            raise NotPortable("the model keeps rules, inert hypotheses or facts with logic variables in its "
                              "states: the distributed search sends states of facts only")
        wire = self.wire
        return marshal.dumps((tuple([(wire(t), n) for t, n in lin.items()]),
                              tuple([(wire(t), n) for t, n in aff.items()]),
                              tuple([wire(t) for t in pers])))

    def step(self, step) -> bytes:
        """An engine step as bytes: its rule, consumed and produced facts."""
        term = self.wire
        consumed = []
        for m, f in step.consumed:
            if not isinstance(f, Node) or f.evars:
                raise NotPortable(f"step {step.rule} consumed a hypothesis that is not a ground fact")
            consumed.append((_MODES[m], term(f)))
        produced = []
        for m, x in step.produced:
            if type(x) is not Root or x.evars:
                raise NotPortable(f"step {step.rule} produced a rule or a fact with logic variables: the "
                                  "distributed search sends steps of facts only")
            produced.append((_MODES[m], term(x)))
        return marshal.dumps((step.rule, tuple(consumed), tuple(produced)))

    # ------------------------------------------------------------ reading
    def _read_param(self, c: tuple) -> Param:
        origin, pid, hint = c[1], c[2], c[3]
        if origin == self.origin:
            p = self._own.get(pid)
            if p is None:   # pragma: no cover - a name of this process it never wrote
                raise NotPortable(f"fresh name {hint}!{pid} of this process is unknown to it")
            return p
        key = (origin, pid)
        p = self._names.get(key)
        if p is None:
            p = self._names[key] = Param(hint)
            self._whence[p] = (origin, pid, hint)
        return p

    def read_term(self, c, memo: dict) -> Node:
        r = memo.get(id(c))
        if r is not None:
            return r
        tag = c[0]
        if type(tag) is str:
            r = Root(Const(tag), tuple([self.read_term(a, memo) for a in c[1:]]))
        elif tag == _LIT:
            v = c[3]
            value = Fraction(v[0], v[1]) if type(v) is tuple else v
            r = Root(Lit(value, Const(c[1]), c[2]), ())
        elif tag == _PARAM:
            r = Root(self._read_param(c), tuple([self.read_term(a, memo) for a in c[4]]))
        elif tag == _BVAR:
            r = Root(BVar(c[1]), tuple([self.read_term(a, memo) for a in c[2]]))
        elif tag == _LAM:
            r = Lam(self.read_term(c[1], memo))
        elif tag == _CANON:
            r = Root(CanonParam(c[1]), tuple([self.read_term(a, memo) for a in c[2]]))
        else:   # pragma: no cover
            raise NotPortable(f"unknown term tag {tag!r}")
        memo[id(c)] = r
        return r

    def fact(self, b: bytes) -> Node:
        """The fact whose bytes are ``b`` (read once per codec)."""
        t = self._read.get(b)
        if t is None:
            t = self.read_term(marshal.loads(b), {})
            if len(self._read) >= _CACHE:
                self._read.clear()
            self._read[b] = t
        return t

    def frozen(self, blob: bytes) -> FrozenContext:
        """The context of ``blob``, kept frozen (thaw it to step it)."""
        lin, aff, pers = marshal.loads(blob)
        read = self.fact
        f = FrozenContext.__new__(FrozenContext)
        f.lin = tuple([t for c, n in lin for t in [read(c)] for _ in range(n)])
        f.aff = tuple([t for c, n in aff for t in [read(c)] for _ in range(n)])
        f.pers = tuple([read(c) for c in pers])
        f.rules = f.inert = f.open = ()
        f.implicit = self.implicit
        f.canon = None
        return f

    def light(self, blob: bytes) -> Context:
        """The context of ``blob`` with its facts only, no matching indexes: enough for a state key
        (``canonical_key`` reads the facts), not for stepping."""
        lin, aff, pers = marshal.loads(blob)
        read = self.fact
        c = Context()
        c.lin = {read(b): n for b, n in lin}
        if aff:
            c.aff = {read(b): n for b, n in aff}
        if pers:
            c.pers = dict.fromkeys([read(b) for b in pers])
        c.implicit = self.implicit
        return c

    def context(self, blob: bytes) -> Context:
        """The context of ``blob``, with its matching indexes built (ready to step)."""
        return self.frozen(blob).thaw()

    def read_step(self, blob: bytes) -> PortableStep:
        rule, consumed, produced = marshal.loads(blob)
        modes = (LIN, AFF, PERS)
        return PortableStep(rule, [(modes[m], self.fact(c)) for m, c in consumed],
                            [(modes[m], self.fact(c)) for m, c in produced])

    # ------------------------------------------------------------ partition
    def _term_hash(self, t: Node) -> int:
        r = self._hash.get(t)
        if r is not None:
            return r
        tt = type(t)
        if tt is Root:
            h = t.head
            th = type(h)
            if th is Const:
                hh = self._const_hash.get(h)
                if hh is None:
                    hh = self._const_hash[h] = zlib.crc32(h.name.encode("utf-8"))
            elif th is Lit:
                hh = zlib.crc32(f"{h.family.name}\0{h.text}".encode("utf-8")) + (1 << 33)
            elif isinstance(h, Param):
                hh = 1 << 34            # fresh names erased: the hash is invariant under renaming
            elif th is BVar:
                hh = (1 << 35) + h.index
            else:
                hh = 1 << 36
            r = hash((hh, *[self._term_hash(a) for a in t.args]))
        elif tt is Lam:
            r = hash((1 << 37, self._term_hash(t.body)))
        else:
            r = 1 << 38
        if len(self._hash) >= _CACHE:
            self._hash.clear()
        self._hash[t] = r
        return r

    def partition(self, ctx) -> int:
        """A hash of the state that every process computes alike, equal for states equal up to
        renaming of fresh names (Python hashes tuples of ints the same way in every process)."""
        th = self._term_hash
        # a sum of well-mixed fact hashes: a hash of the multiset, whatever the facts' order
        s = sum([hash((0, th(t), n)) for t, n in ctx.lin.items()])
        if ctx.aff:
            s += sum([hash((1, th(t), n)) for t, n in ctx.aff.items()])
        if ctx.pers:
            s += sum([hash((2, th(t))) for t in ctx.pers])
        return s & 0x7FFF_FFFF_FFFF_FFFF


def _tally(facts) -> dict:
    d: dict = {}
    for t in facts:
        d[t] = d.get(t, 0) + 1
    return d
