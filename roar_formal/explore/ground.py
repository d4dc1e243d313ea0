"""A vectorised search backend for CLF programs whose state space is finite and ground.

Why: the general backend pays for a context copy and a canonical key per
transition (about 100 µs in Python); benchmark B3 needs tens of millions of
transitions. When a program makes no fresh names and no rules at run time,
its reachable facts form a finite universe, each rule has finitely many
ground instances, and a state is a vector of fact counts. This backend

1. grounds the program *with the engine*: the engine's own matcher
   (``enabled_steps``) runs on a context holding every fact seen so far, and
   the engine's own ``fire`` computes what each instance produces, until no
   new fact appears (so the semantics is the engine's, not a re-implementation);
2. explores breadth-first a whole level at a time with numpy, a chunk of frontier states
   at a time: an instance is enabled where the count columns it consumes are high enough;
   a successor's key is the parent's key plus the instance's delta (packed counts, exact);
3. keys a state by the counts of the columns that identify it on every reachable state
   (place invariants let it leave out the others: ``key_basis``), bit-packed, so the key
   is injective and no hash collision can merge two states; the visited set is an open
   addressing table over the exact keys (``_Table``);
4. stores the edges compactly (target, instance, out-degree per state) and gives the graph's
   other columns when a property first reads them (:class:`GroundGraph`).

It yields the same :class:`StateGraph` as the general backend (tests compare
the two, and an independent plain enumerator, on small instances).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..clf.context import Context
from ..clf.forward import multiset_key, enabled_steps, fire
from ..clf.program import Program
from ..clf.rules import AFF, LIN, PERS
from .graph import Interner, StateGraph
from .search import Budget, MemoryWatch, current_rss_mb
from .system import Options, is_progress, step_group


class NotGround(Exception):
    """The program is outside this backend's fragment (fresh names, run-time rules, ...)."""


class GroundingStopped(Exception):
    """Grounding ran out of the job's time or memory budget (the reason says which)."""


@dataclass
class Instance:
    rule: str
    consume: dict  # column -> count (linear/affine facts used up)
    require: tuple  # persistent columns that must be present
    produce: dict  # column -> count added
    group: str
    progress: bool


class GroundModel:
    """The ground instances of a program from a start context, over a column per (mode, fact)."""

    def __init__(self, program: Program, start: Context, options: Options, max_facts: int = 200_000,
                 budget: Optional[Budget] = None, deadline: Optional[float] = None):
        """``deadline`` (a ``time.perf_counter()`` value) and ``budget.max_memory_mb`` bound the
        grounding itself: past either, :class:`GroundingStopped` is raised."""
        self.program = program
        self.deadline = deadline
        self.memory = MemoryWatch(budget.max_memory_mb if budget is not None else None)
        self.budget = budget
        self.options = options
        for t in program.templates:
            if not t.forward:
                continue
            for act in t.head:
                if act[0] != "fact":
                    raise NotGround(f"rule '{t.name}' makes fresh names or rules at run time")
            if t.open_slots:
                raise NotGround(f"rule '{t.name}' has a variable only its head uses (its facts would hold "
                                "logic variables)")
            if any(p.backward for p in t.premises):
                raise NotGround(f"rule '{t.name}' has a premise solved by proof search")
        if start.rules or start.inert:
            raise NotGround("the start context holds rules")
        self.columns: dict[tuple, int] = {}
        self.facts: list[tuple] = []
        for mode, t, n in start.facts():
            self._col(mode, t)
        self.instances: list[Instance] = []
        self._ground(max_facts)
        self.start_row = np.zeros(len(self.facts), dtype=np.int64)
        for mode, t, n in start.facts():
            self.start_row[self.columns[(mode, t)]] = n

    def _col(self, mode: str, t) -> int:
        k = (mode, t)
        c = self.columns.get(k)
        if c is None:
            c = self.columns[k] = len(self.facts)
            self.facts.append(k)
        return c

    def _check_budget(self, work: int) -> None:
        if self.deadline is not None and time.perf_counter() >= self.deadline:
            raise GroundingStopped(f"time budget of {self.budget.max_seconds:g} s reached while grounding the model "
                                   f"({len(self.facts):,} facts, {len(self.instances):,} rule instances so far)")
        if self.memory.over(work):
            raise GroundingStopped(f"memory budget of {self.budget.max_memory_mb:g} MiB reached while grounding "
                                   f"the model ({len(self.facts):,} facts, {len(self.instances):,} rule instances "
                                   "so far)")

    def _ground(self, max_facts: int) -> None:
        seen_inst: set = set()
        done = 0
        work = 0
        while True:
            self._check_budget(work)
            universe = Context()
            for mode, t in self.facts:
                for _ in range(1 if mode == PERS else 4):
                    universe.add_fact(t, mode)
            before = len(self.facts)
            for choice in enabled_steps(self.program.templates, universe):
                work += 1
                if not work & 63:
                    self._check_budget(work)
                key = (id(choice.template), choice.bindings, multiset_key(choice.consumed))
                if key in seen_inst:
                    continue
                seen_inst.add(key)
                scratch = Context()
                for mode, t in choice.consumed:
                    scratch.add_fact(t, mode)
                step = fire(scratch, choice.template, list(choice.bindings), list(choice.consumed), None)
                consume: dict = {}
                require = []
                for mode, t in choice.consumed:
                    c = self._col(mode, t)
                    if mode == PERS:
                        require.append(c)
                    else:
                        consume[c] = consume.get(c, 0) + 1
                produce: dict = {}
                for mode, t in step.produced:
                    c = self._col(mode, t)
                    produce[c] = produce.get(c, 0) + 1
                self.instances.append(Instance(choice.rule, consume, tuple(sorted(set(require))), produce,
                                               step_group(self.program, self.options, choice),
                                               is_progress(self.options, choice.rule)))
                if len(self.facts) > max_facts:
                    raise NotGround(f"more than {max_facts} distinct facts: the state space is too large "
                                    "or infinite for the ground backend")
            done += 1
            if len(self.facts) == before:
                break
        for inst in self.instances:
            for c in inst.produce:
                if self.facts[c][0] == PERS:
                    raise NotGround(f"rule '{inst.rule}' adds persistent facts at run time")

    def describe_row(self, row: np.ndarray) -> list[str]:
        lines = []
        for c in np.flatnonzero(row):
            mode, t = self.facts[c]
            prefix = {LIN: "", AFF: "@", PERS: "!"}[mode]
            lines += [prefix + self.program.show(t)] * int(row[c])
        return sorted(lines)


class TargetsNotKept(RuntimeError):
    """A property read the edge targets of a graph searched without them."""


class Overflow(Exception):
    """A fact count outgrew the bits given to its column: retry with wider columns."""


_U64 = (1 << 64) - 1
_MAX_LOAD = 0.75  # the visited table grows past this load
_CHUNK_CELLS = 1 << 20  # frontier states x instances tested at once: bounds a level's temporaries
_MAX_REDUCE = 500_000_000  # instances x columns x rank up to which the key drops columns others fix


def key_basis(delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The columns that identify a reachable state, the others, and how the others follow.

    Every reachable count vector is ``start + x @ delta`` (x: how often each instance fired), so
    when a column's delta column is an integer combination ``delta[:, basis] @ c`` of the basis
    columns', ``row[j] = start[j] + (row[basis] - start[basis]) @ c`` on every reachable state,
    and two reachable states equal on the basis are equal (the place invariants of the net: a
    philosopher is at exactly one location, a fork is free or held). The basis is chosen
    greedily in column order (a column joins when it is independent of the columns before it,
    in floating point), but a column is left out of the key only when integer coefficients
    reproduce its delta column exactly (checked in integers): rounding can make the key
    longer, never inexact. Returns (basis, dropped, coefficients: basis x dropped)."""
    m, n = delta.shape
    allcols = np.arange(n)
    none = (allcols, np.zeros(0, dtype=np.int64), np.zeros((n, 0), dtype=np.int64))
    if n == 0 or m == 0 or m * n * min(m, n) > _MAX_REDUCE:
        return none
    d = delta.astype(np.float64)
    q = np.zeros((m, min(m, n)))
    basis = []
    for j in range(n):
        qb = q[:, :len(basis)]
        v = d[:, j].copy()
        for _ in range(2):  # Gram-Schmidt, twice for stability
            v -= qb @ (qb.T @ v)
        nv = float(np.linalg.norm(v))
        if nv > 1e-9 * max(1.0, float(np.linalg.norm(d[:, j]))):
            q[:, len(basis)] = v / nv
            basis.append(j)
            if len(basis) == m:
                break
    basis = np.asarray(basis, dtype=np.int64)
    rest = np.setdiff1d(allcols, basis)
    if not len(rest) or not len(basis):
        return none
    coef = np.linalg.lstsq(d[:, basis], d[:, rest], rcond=None)[0]
    if not np.all(np.isfinite(coef)) or np.abs(coef).max(initial=0) > 1 << 20:
        return none
    c = np.rint(coef).astype(np.int64)
    exact = np.all(delta[:, basis] @ c == delta[:, rest], axis=0)
    if not exact.any():
        return none
    # the columns without exact integer coefficients stay in the key (their coefficients: 0,
    # and their own column: 1)
    keep = rest[~exact]
    dropped = rest[exact]
    full = np.sort(np.concatenate([basis, keep]))
    pos = {int(b): k for k, b in enumerate(full)}
    c2 = np.zeros((len(full), len(dropped)), dtype=np.int64)
    for k, b in enumerate(basis):
        c2[pos[int(b)]] = c[k, exact]
    if not np.array_equal(delta[:, full] @ c2, delta[:, dropped]):  # never trust the float path
        return none
    return full, dropped, c2


def _splitmix(z: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser, in place on a fresh uint64 array."""
    z ^= z >> np.uint64(30)
    z *= np.uint64(0xBF58476D1CE4E5B9)
    z ^= z >> np.uint64(27)
    z *= np.uint64(0x94D049BB133111EB)
    z ^= z >> np.uint64(31)
    return z


def _mix(words: list) -> np.ndarray:
    with np.errstate(over="ignore"):
        h = _splitmix(words[0] + np.uint64(0x9E3779B97F4A7C15))
        for w in words[1:]:
            h ^= w
            h = _splitmix(h)
        return h


_LIBC: list = []


def _give_back_memory() -> None:
    """Return the heap's free memory to the system (glibc's ``malloc_trim``; elsewhere nothing).

    A level's temporaries are allocated and freed chunk after chunk; glibc serves blocks of a
    few MB from its heap once it has seen blocks that size freed (its mmap threshold grows),
    and keeps what is freed there resident: over a search that is a third of the peak."""
    if not _LIBC:
        try:
            import ctypes
            import ctypes.util
            lib = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            _LIBC.append(lib.malloc_trim)
        except (OSError, AttributeError):
            _LIBC.append(None)
    if _LIBC[0] is not None:
        _LIBC[0](0)


class _Buf:
    """A growable 1-d array (realloc in place: no copy of what is there, little slack)."""

    def __init__(self, dtype, cap: int = 1024) -> None:
        self.a = np.empty(cap, dtype=dtype)
        self.n = 0

    def append(self, x) -> None:
        k = len(x)
        if self.n + k > len(self.a):
            self.a.resize(max(self.n + k, len(self.a) + len(self.a) // 8 + 4096), refcheck=False)
        self.a[self.n:self.n + k] = x
        self.n += k

    def growth_bytes(self, k: int) -> int:
        """What appending ``k`` more items would add to the buffer's size."""
        if self.a is None or self.n + k <= len(self.a):
            return 0
        return (max(self.n + k, len(self.a) + len(self.a) // 8 + 4096) - len(self.a)) * self.a.itemsize

    def finish(self) -> np.ndarray:
        """The array (the buffer is not used afterwards)."""
        self.a.resize(self.n, refcheck=False)
        a, self.a = self.a, None
        return a


class _Table:
    """The visited states: an open-addressing table (linear probing) from exact key words to
    state ids, probed and filled a whole batch at a time. Exact: a state is found only when
    every key word is equal, and keys are injective on reachable states (:func:`key_basis`).
    A key word never has its top bit set (:meth:`GroundExplorer._layout`), so an all-ones
    first word marks an empty slot and probing reads the keys alone."""

    EMPTY = np.uint64(_U64)
    CLAIM = np.iinfo(np.int32).max  # taken by a new state whose id is not given yet

    def __init__(self, nwords: int) -> None:
        self.nwords = nwords
        self._alloc(12)

    def _alloc(self, log: int) -> None:
        self.ids = self.keys = None  # give the old table back first
        self.log = log
        self.mask = (1 << log) - 1
        self.keys = [np.full(1 << log, self.EMPTY, dtype=np.uint64)] + \
            [np.zeros(1 << log, dtype=np.uint64) for _ in range(self.nwords - 1)]
        self.ids = np.zeros(1 << log, dtype=np.int32)

    def size(self) -> int:
        return 1 << self.log

    def bytes_to_grow(self, n_total: int) -> int:
        log = self.log
        while n_total > _MAX_LOAD * (1 << log):
            log += 1
        return 0 if log == self.log else (1 << log) * (4 + 8 * self.nwords)

    def reserve(self, n_total: int, words: list) -> None:
        """Room for ``n_total`` states, rebuilding from ``words`` (every state's key, by id)."""
        log = self.log
        while n_total > _MAX_LOAD * (1 << log):
            log += 1
        if log != self.log:
            self._alloc(log)
            self._insert_distinct(words)

    def _slots(self, words: list) -> np.ndarray:
        return (_mix(words) >> np.uint64(64 - self.log)).astype(np.int64)

    def _claim(self, es: np.ndarray, e: np.ndarray, kw: list) -> np.ndarray:
        """Candidates ``e`` (positions in ``kw``) found slots ``es`` empty: one candidate wins
        each slot and writes its key there. Which of them did (a boolean per candidate)."""
        if self.nwords == 1:  # one word: the slot holds one of the keys written, whole
            self.keys[0][es] = kw[0][e]
            return self.keys[0][es] == kw[0][e]  # the winner, and any candidate with its key
        self.ids[es] = -2 - e.astype(np.int32)
        win = self.ids[es] == -2 - e
        for w in range(self.nwords):
            self.keys[w][es[win]] = kw[w][e[win]]
        same = np.ones(len(e), dtype=bool)
        for w in range(self.nwords):
            same &= self.keys[w][es] == kw[w][e]
        return same

    def _probe(self, words: list) -> np.ndarray:
        """The slot of each key: where it is, or the empty slot it now fills."""
        s = self._slots(words)
        res = s.copy()  # right for every key found at its first slot (most of them)
        pend = None  # the keys still probing (None: all of them, in the first round)
        kw = words
        while True:
            k0 = self.keys[0][s]
            done = k0 == kw[0]
            for w in range(1, self.nwords):
                done &= self.keys[w][s] == kw[w]
            e = np.flatnonzero(k0 == self.EMPTY)
            if len(e):
                got = e[self._claim(s[e], e, kw)]
                self.ids[s[got]] = self.CLAIM
                done[got] = True
            if pend is not None:
                res[pend[done]] = s[done]
            keep = np.flatnonzero(~done)
            if not len(keep):
                return res
            pend = keep if pend is None else pend[keep]
            s = (s[keep] + 1) & self.mask
            kw = [x[keep] for x in kw]

    def _insert_distinct(self, words: list) -> None:
        """Insert distinct keys not present yet, as ids 0, 1, ... (a slice at a time: bounded
        temporaries)."""
        n = len(words[0])
        step = 1 << 18
        for lo in range(0, n, step):
            slots = self._probe([w[lo:lo + step] for w in words])
            self.ids[slots] = np.arange(lo, lo + len(slots), dtype=np.int32)

    def lookup(self, words: list, n_states: int) -> tuple[np.ndarray, np.ndarray]:
        """The id of each candidate key; keys not seen before become states ``n_states`` on,
        numbered in the order of their first candidate. Returns (ids (int32), first candidate
        of each new state, in id order)."""
        res = self._probe(words)
        ids = self.ids[res]
        nc = np.flatnonzero(ids == self.CLAIM)  # candidates reaching a new state
        if not len(nc):
            return ids, nc
        rn = res[nc]
        np.minimum.at(self.ids, rn, nc.astype(np.int32))  # the first candidate of each
        first = nc[self.ids[rn] == nc]  # increasing: discovery order
        self.ids[res[first]] = n_states + np.arange(len(first), dtype=np.int32)
        ids[nc] = self.ids[rn]
        return ids, first


class GroundExplorer:
    """Level-synchronous breadth-first search over exact bit-packed count vectors.

    A state's key is the counts of the columns that identify it (the columns that can
    change, less those the others fix on every reachable state: :func:`key_basis`), packed
    ``bits`` per column into 64-bit words: an injective key, so no hash collision can merge
    states. An instance adds a fixed integer to each word modulo 2^64 (counts never borrow or
    carry across columns: enabledness guarantees the consumed counts, and a produced count
    that would outgrow its bits raises :class:`Overflow`, and the search restarts with wider
    columns). The visited set is a hash table over the exact words (:class:`_Table`). The
    frontier is kept as full count columns (one contiguous row per column) for the
    enabledness tests; a level is expanded in chunks of frontier states, so its temporaries
    stay bounded. Edges are stored compactly (target id, instance number, and per state its
    out-degree, since edges come sorted by source) and the graph's other edge columns are
    computed when a property first reads them (:class:`GroundGraph`).
    """

    def __init__(self, model: GroundModel, on_progress: Optional[Callable[[dict], None]] = None,
                 keep_targets: bool = True):
        """``keep_targets=False``: the graph keeps no edge targets (``dst``), a third of its
        memory on a big search. What needs only out-degrees, creating edges and states (the
        deadlock check and its shortest counterexample, invariants over states) still works;
        reading ``dst`` (livelock, temporal properties) raises :class:`TargetsNotKept`."""
        self.model = model
        self.on_progress = on_progress
        self.keep_targets = keep_targets
        insts = model.instances
        ncols = len(model.facts)
        delta = np.zeros((len(insts), ncols), dtype=np.int64)
        for i, inst in enumerate(insts):
            for c, k in inst.consume.items():
                delta[i, c] -= k
            for c, k in inst.produce.items():
                delta[i, c] += k
        self.var_cols = np.flatnonzero((delta != 0).any(axis=0))  # columns that can change
        self.delta = delta[:, self.var_cols]  # instances x variable columns
        self.nvar = len(self.var_cols)
        self.labels = Interner()
        self.groups = Interner()
        self.inst_label = np.array([self.labels(i.rule) for i in insts], dtype=np.int32)
        self.inst_group = np.array([self.groups(i.group) for i in insts], dtype=np.int32)
        self.inst_progress = np.array([i.progress for i in insts], dtype=bool)
        n = len(insts)
        self.inst_dtype = np.uint8 if n <= 255 else np.uint16 if n <= 65535 else np.int32
        self.deg_dtype = np.uint8 if n <= 255 else np.uint16 if n <= 65535 else np.int32
        vpos = {int(c): j for j, c in enumerate(self.var_cols)}
        const_row = model.start_row.copy()
        self.needs = []  # per instance: [(variable column, count)], or None if a constant column fails
        for inst in insts:
            pairs = []
            ok = True
            for c, k in list(inst.consume.items()) + [(c, 1) for c in inst.require]:
                if c in vpos:
                    pairs.append((vpos[c], k))
                elif const_row[c] < k:
                    ok = False
            self.needs.append(pairs if ok else None)
        self.live = [i for i, pairs in enumerate(self.needs) if pairs is not None]  # ever enabled
        self.live_inst = np.array(self.live, dtype=self.inst_dtype)
        # per instance, the columns it raises and by how much (what can outgrow its bits)
        self.grows = [[(int(j), int(self.delta[i, j])) for j in np.flatnonzero(self.delta[i] > 0)]
                      for i in range(n)]
        self.const_row = const_row
        self.start_var = model.start_row[self.var_cols]
        self.slots = 1 << max(0, (max(1, len(self.live)) - 1).bit_length())  # live instances, padded
        self.live_pad = np.zeros(self.slots, dtype=self.inst_dtype)
        self.live_pad[:len(self.live)] = self.live_inst
        self.slot_bits = self.slots.bit_length() - 1
        self.basis, self.dropped, self.coef = key_basis(self.delta)

    # ------------------------------------------------------------ packing
    def _layout(self, bits: int) -> None:
        self.bits = bits
        self.cap = cap = (1 << bits) - 1
        self.row_dtype = (np.int8 if cap <= 127 else np.int16 if cap <= 32767 else
                          np.int32 if cap <= 2**31 - 1 else np.int64)
        amax = int(np.abs(self.delta).max(initial=0))
        self.delta_T = np.ascontiguousarray(self.delta.T.astype(
            self.row_dtype if amax <= np.iinfo(self.row_dtype).max else np.int64))
        per_word = 63 // bits  # the top bit of a key word stays 0: all ones marks an empty slot
        nb = len(self.basis)
        self.nwords = max(1, -(-nb // per_word))
        self.key_word = np.arange(nb) // per_word
        self.key_shift = (np.arange(nb) % per_word) * bits
        wd = [[0] * len(self.delta) for _ in range(self.nwords)]
        for bi, j in enumerate(self.basis):
            w, sh = int(self.key_word[bi]), int(self.key_shift[bi])
            for i in np.flatnonzero(self.delta[:, j]):
                wd[w][i] += int(self.delta[i, j]) << sh
        # signed deltas as uint64 (two's complement): adding wraps exactly
        self.word_delta = [np.array([v & _U64 for v in wd[w]], dtype=np.uint64) for w in range(self.nwords)]
        # per instance, (column, count) pairs: the instance overflows where a count is at least that
        self.grow_keys = [tuple(sorted((c, cap - d + 1) for c, d in g)) for g in self.grows]

    def _pack(self, rows_t: np.ndarray) -> list[np.ndarray]:
        """Key words of count columns ``rows_t`` (variable columns x states)."""
        words = [np.zeros(rows_t.shape[1], dtype=np.uint64) for _ in range(self.nwords)]
        for bi, j in enumerate(self.basis):
            words[self.key_word[bi]] |= rows_t[j].astype(np.uint64) << np.uint64(self.key_shift[bi])
        return words

    def _unpack(self, words: list[np.ndarray]) -> np.ndarray:
        """Variable-column counts (states x variable columns) of key words."""
        n = len(words[0])
        rows = np.empty((n, self.nvar), dtype=np.int64)
        mask = np.uint64(self.cap)
        for bi, j in enumerate(self.basis):
            rows[:, j] = ((words[self.key_word[bi]] >> np.uint64(self.key_shift[bi])) & mask).astype(np.int64)
        if len(self.dropped):
            b = rows[:, self.basis] - self.start_var[self.basis]
            rows[:, self.dropped] = self.start_var[self.dropped] + b @ self.coef
        return rows

    # ------------------------------------------------------------ search
    def run(self, budget: Budget = Budget()) -> StateGraph:
        bits = 1
        start = self.start_var
        while (1 << bits) - 1 < max(1, int(start.max(initial=0))):
            bits *= 2
        while True:
            try:
                self._layout(bits)
                return self._run(budget)
            except Overflow:
                if bits >= 32:
                    raise NotGround("a fact count exceeds 2^32")
                bits *= 2

    def _run(self, budget: Budget) -> StateGraph:
        t0 = time.perf_counter()
        nw = self.nwords
        f_rows = np.ascontiguousarray(self.start_var.astype(self.row_dtype)[:, None])  # columns x states
        f_keys = self._pack(f_rows)
        keys = [_Buf(np.uint64) for _ in range(nw)]
        for w in range(nw):
            keys[w].append(f_keys[w])
        # a state's creating edge, as its position among its parent's edges (the edges of a
        # state are consecutive): one byte, where a 64-bit edge index would take eight
        parent, parent_pos = _Buf(np.int32), _Buf(self.deg_dtype)
        parent.append([-1])
        parent_pos.append([0])
        outdeg, dst, einst = _Buf(self.deg_dtype), _Buf(np.int32), _Buf(self.inst_dtype)
        table = _Table(nw)
        table.lookup(f_keys, 0)  # the start state: id 0
        per_depth = [1]
        n_states, n_edges = 1, 0
        f_start = 0
        complete, stop = True, ""
        chunk = max(1, _CHUNK_CELLS // self.slots)
        while f_rows.shape[1]:
            stop = self._budget_stop(budget, t0, n_states)
            if stop:
                break
            f_n = f_rows.shape[1]
            nx_rows, nx_keys = [], [[] for _ in range(nw)]
            n_level = 0
            lo = 0
            size = chunk
            while lo < f_n:
                take = size
                if budget.max_states is not None:   # near the state budget: a chunk of the states it has left
                    if n_states >= budget.max_states:
                        stop = f"state budget of {budget.max_states} reached"
                        break
                    take = min(size, budget.max_states - n_states)
                hi = min(f_n, lo + take)
                sub = f_rows[:, lo:hi]
                flat = np.flatnonzero(np.ascontiguousarray(self._enabled(sub).T))
                s_loc = flat >> self.slot_bits  # by source state, then instance: discovery order
                jj = flat & (self.slots - 1)
                del flat
                c = len(s_loc)
                if lo:  # the level's first chunk was checked with the level
                    stop = self._budget_stop(budget, t0, None)
                if not stop and budget.max_memory_mb is not None:
                    # besides the chunk's own temporaries: the buffers it may grow, and the
                    # copy the next frontier takes when the level ends
                    later = (sum(r.nbytes for r in nx_rows) + sum(x.nbytes for k in nx_keys for x in k)
                             + sum(b.growth_bytes(c) for b in [dst, einst, outdeg, parent, parent_pos, *keys])
                             + (hi - lo) * f_rows.shape[0] * f_rows.itemsize)
                    stop = self._chunk_memory_stop(budget, c, n_states, table, later)
                    if stop and hi - lo > 64:  # near the budget: smaller chunks, until even they do not fit
                        size = max(64, (hi - lo) // 4)
                        stop = ""
                        continue
                if stop:
                    break
                if n_states + c > 0.9 * table.size():
                    table.reserve(n_states + c, [k.a[:k.n] for k in keys])
                inst = self.live_pad[jj]
                del jj
                with np.errstate(over="ignore"):
                    cand = [f_keys[w][lo:hi][s_loc] + self.word_delta[w][inst] for w in range(nw)]
                deg = np.bincount(s_loc, minlength=hi - lo)
                ids, first = table.lookup(cand, n_states)
                n_new = len(first)
                if n_new:
                    ps = s_loc[first]
                    rows = sub.take(ps, axis=1)  # (take keeps rows contiguous, unlike sub[:, ps])
                    rows += self.delta_T.take(inst[first], axis=1)
                    nx_rows.append(rows)
                    for w in range(nw):
                        nk = cand[w][first]
                        nx_keys[w].append(nk)
                        keys[w].append(nk)
                    parent.append(ps + (f_start + lo))
                    parent_pos.append(first - (np.cumsum(deg) - deg)[ps])
                    n_states += n_new
                    n_level += n_new
                del cand
                outdeg.append(deg)
                if self.keep_targets:
                    dst.append(ids)
                einst.append(inst)
                n_edges += c
                del ids, inst, s_loc, first
                lo = hi
                if n_states > _MAX_LOAD * table.size():
                    table.reserve(n_states, [k.a[:k.n] for k in keys])
            per_depth.append(n_level)
            if stop:
                break
            f_start += f_n
            f_rows = np.concatenate(nx_rows, axis=1) if nx_rows else np.zeros((self.nvar, 0), self.row_dtype)
            f_keys = [np.concatenate(k) if k else np.zeros(0, np.uint64) for k in nx_keys]
            del nx_rows, nx_keys
            _give_back_memory()
            if self.on_progress is not None:
                el = time.perf_counter() - t0
                self.on_progress({"states": n_states, "transitions": n_edges, "frontier": f_rows.shape[1],
                                  "seconds": el, "states_per_s": n_states / max(el, 1e-9),
                                  "memory_mb": current_rss_mb()})
        complete = not stop
        del table, f_rows, f_keys
        expanded_upto = outdeg.n
        deg = outdeg.finish()
        if len(deg) < n_states:
            deg = np.concatenate([deg, np.zeros(n_states - len(deg), dtype=deg.dtype)])
        while per_depth and per_depth[-1] == 0:
            per_depth.pop()
        self.words = [k.finish() for k in keys]
        self.edge_inst = einst.finish()
        _give_back_memory()
        g = GroundGraph(self, parent.finish(), parent_pos.finish(), np.asarray(per_depth, dtype=np.int64),
                        (np.arange(n_states) < expanded_upto).astype(np.int8), deg,
                        dst.finish() if self.keep_targets else None, self.edge_inst, complete, stop)
        self.seconds = time.perf_counter() - t0
        return g

    @staticmethod
    def _budget_stop(budget: Budget, t0: float, n_states: Optional[int]) -> str:
        """Why the search stops before the next level ("" to go on): a state, time or memory budget."""
        if n_states is not None and budget.max_states is not None and n_states >= budget.max_states:
            return f"state budget of {budget.max_states} reached"
        if budget.max_seconds is not None and time.perf_counter() - t0 >= budget.max_seconds:
            return f"time budget of {budget.max_seconds:g} s reached"
        if budget.max_memory_mb is not None and current_rss_mb() > budget.max_memory_mb:
            return f"memory budget of {budget.max_memory_mb:g} MiB reached"
        return ""

    def _enabled(self, sub: np.ndarray) -> np.ndarray:
        """Which live instance is enabled at which state of ``sub`` (columns x states): a
        (``self.slots`` x states) boolean array, row j for live instance j (rows past the live
        instances are False). Raises :class:`Overflow` when a produced count would outgrow its
        bits."""
        k = sub.shape[1]
        out = np.zeros((self.slots, k), dtype=bool)
        cap = self.cap
        tests: dict = {}

        def at_least(c: int, kk: int) -> np.ndarray:  # count of column c >= kk, computed once
            a = tests.get((c, kk))
            if a is None:
                # counts are 0 or 1 when cap is 1: the column is its own test
                a = tests[(c, kk)] = sub[c].view(np.bool_) if cap == 1 and kk == 1 else sub[c] >= kk
            return a

        unions: dict = {}
        bad = np.zeros(k, dtype=bool)
        tmp = np.empty(k, dtype=bool)
        for j, i in enumerate(self.live):
            pairs = self.needs[i]
            row = out[j]
            if not pairs:
                row[:] = True
            elif len(pairs) == 1:
                row[:] = at_least(*pairs[0])
            else:
                np.logical_and(at_least(*pairs[0]), at_least(*pairs[1]), out=row)
                for c, kk in pairs[2:]:
                    row &= at_least(c, kk)
            grows = self.grow_keys[i]
            if not grows:
                continue
            if min(t for _, t in grows) <= 0:  # raises a count past the cap from any state
                if row.any():
                    raise Overflow
                continue
            over = unions.get(grows)  # a count it raises is already too high
            if over is None:
                over = at_least(*grows[0])
                for g in grows[1:]:
                    over = over | at_least(*g)
                unions[grows] = over
            np.logical_and(row, over, out=tmp)
            bad |= tmp
        if bad.any():
            raise Overflow
        return out

    def _chunk_memory_stop(self, budget: Budget, n_cand: int, n_states: int, table: _Table,
                           later: int = 0) -> str:
        """Why the next chunk would not fit the memory budget ("" when it fits, or has no budget);
        ``later``: bytes the chunk may add besides its candidates and the table."""
        if budget.max_memory_mb is None or not n_cand:
            return ""
        # what the chunk takes before it can be given back: the candidates' key words, slots,
        # ids and indices, the edges it adds, and the visited table if it must grow
        need = (n_cand * (24 * self.nwords + 96) + table.bytes_to_grow(n_states + n_cand) + later) / 1048576.0
        now_mb = current_rss_mb()
        if now_mb + need > budget.max_memory_mb:
            _give_back_memory()  # what the heap holds freed is not needed: measure again without it
            now_mb = current_rss_mb()
        if now_mb + need > budget.max_memory_mb:
            return (f"memory budget of {budget.max_memory_mb:g} MiB reached (the next "
                    f"{n_cand:,} transitions need about {need:,.0f} MiB more)")
        return ""

    # ------------------------------------------------------------ reading states and edges
    def row_of(self, sid: int) -> np.ndarray:
        """The full count vector (every column) of state ``sid``."""
        row = self.const_row.copy()
        row[self.var_cols] = self._unpack([w[sid:sid + 1] for w in self.words])[0]
        return row

    def describe_state(self, sid: int) -> list[str]:
        return self.model.describe_row(self.row_of(sid))

    def describe_edge(self, e: int) -> dict:
        inst = self.model.instances[int(self.edge_inst[e])]
        return {"rule": inst.rule, "consumed": self._facts(inst.consume), "produced": self._facts(inst.produce)}

    def _facts(self, cols: dict) -> list[str]:
        out = []
        for c, k in sorted(cols.items()):
            mode, t = self.model.facts[c]
            out += [{"1": "", "@": "@", "!": "!"}[mode] + self.model.program.show(t)] * k
        return out


class _Columns(Mapping):
    """A ground graph's edge columns, each computed when first read."""

    NAMES = ("src", "dst", "label", "group", "progress")

    def __init__(self, g: "GroundGraph") -> None:
        self.g = g

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.NAMES:
            raise KeyError(name)
        return self.g.progress_flags() if name == "progress" else getattr(self.g, name)

    def __iter__(self):
        return iter(self.NAMES)

    def __len__(self) -> int:
        return len(self.NAMES)


class GroundGraph(StateGraph):
    """The ground backend's :class:`StateGraph`: the same fields, stored compactly.

    Edges are kept as their target, their instance number (one byte when there are at most
    255 instances) and each state's out-degree (edges are sorted by source), a state's creating
    edge as its position among its parent's edges; ``src``, ``label``, ``group``, ``progress``,
    ``depth`` and ``parent_edge`` are computed on first use and kept, so a deadlock check (which
    reads the out-degrees, and the creating edges of one path) builds none of the edge columns.
    """

    def __init__(self, gx: GroundExplorer, parent, parent_pos, per_depth, expanded, outdeg, dst, inst,
                 complete: bool, stop_reason: str) -> None:  # no super().__init__(): lazy columns
        self.parent = parent
        self._parent_pos = parent_pos
        self.expanded = expanded
        self._dst = dst
        self.labels, self.groups = gx.labels, gx.groups
        self.hidden_enabled = {}
        self.complete, self.stop_reason = complete, stop_reason
        self.describe_state, self.describe_edge = gx.describe_state, gx.describe_edge
        self._gx = gx
        self._outdeg = outdeg
        self._inst = inst
        self._per_depth = per_depth
        self._cache: dict = {}

    def _lazy(self, name: str, make: Callable[[], np.ndarray]) -> np.ndarray:
        a = self._cache.get(name)
        if a is None:
            a = self._cache[name] = make()
        return a

    @property
    def parent_edge(self) -> np.ndarray:
        def make() -> np.ndarray:
            first_edge = np.cumsum(self._outdeg, dtype=np.int64) - self._outdeg  # of each state
            pe = first_edge[self.parent] + self._parent_pos
            pe[0] = -1
            return pe
        return self._lazy("parent_edge", make)

    @property
    def src(self) -> np.ndarray:
        # 32 bits, unless ``state * number of groups`` (fairness reads it) could outgrow them
        n = len(self.parent)
        wide = n * max(1, len(self.groups.names)) >= 2**31
        return self._lazy("src", lambda: np.repeat(np.arange(n, dtype=np.int64 if wide else np.int32),
                                                   self._outdeg))

    @staticmethod
    def _small(table: np.ndarray) -> np.ndarray:
        return table.astype(np.int16) if len(table) == 0 or table.max() < 2**15 else table

    @property
    def label(self) -> np.ndarray:
        return self._lazy("label", lambda: self._small(self._gx.inst_label)[self._inst])

    @property
    def group(self) -> np.ndarray:
        return self._lazy("group", lambda: self._small(self._gx.inst_group)[self._inst])

    def progress_flags(self) -> np.ndarray:
        """The progress column as booleans (what :meth:`arrays` gives)."""
        return self._lazy("progress", lambda: self._gx.inst_progress[self._inst])

    @property
    def progress(self) -> np.ndarray:
        return self.progress_flags().view(np.int8)

    @property
    def depth(self) -> np.ndarray:
        return self._lazy("depth", lambda: np.repeat(np.arange(len(self._per_depth), dtype=np.int32),
                                                     self._per_depth))

    @property
    def n_edges(self) -> int:
        return len(self._inst)

    @property
    def dst(self) -> np.ndarray:
        if self._dst is None:
            raise TargetsNotKept("this ground search kept no edge targets (GroundExplorer(keep_targets=False)): "
                                 "only out-degrees, creating edges and states can be read")
        return self._dst

    def arrays(self) -> Mapping:
        return _Columns(self)

    def out_degree(self) -> np.ndarray:
        return self._outdeg.astype(np.int64)
