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
2. explores breadth-first a whole level at a time with numpy: an instance is
   enabled where the count columns it consumes are high enough; the successor
   hash is the parent hash plus the instance's delta hash (a linear hash, so
   successor rows are only built for new states);
3. stores states as packed rows and checks afterwards, for every transition,
   that the target's row is the source's row plus the instance's delta (so a
   hash collision can never silently merge two states: the check fails loudly).

It yields the same :class:`StateGraph` as the general backend (tests compare
the two, and an independent plain enumerator, on small instances).
"""

from __future__ import annotations

import time
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


class Overflow(Exception):
    """A fact count outgrew the bits given to its column: retry with wider columns."""


class GroundExplorer:
    """Level-synchronous breadth-first search over exact bit-packed count vectors.

    A state is the counts of the columns that can change, packed ``bits`` per
    column into 64-bit words: an injective key, so no hash collision can merge
    states. An instance adds a fixed signed integer to each word (counts never
    borrow or carry across columns: enabledness guarantees the consumed counts,
    and a produced count that would outgrow its bits raises :class:`Overflow`,
    and the search restarts with wider columns). The visited set is a sorted
    array of a 64-bit mix of the words, each hit confirmed on the exact words.
    """

    def __init__(self, model: GroundModel, on_progress: Optional[Callable[[dict], None]] = None):
        self.model = model
        self.on_progress = on_progress
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
        self.produced = [[(vpos[c], k) for c, k in inst.produce.items() if c in vpos] for inst in insts]
        self.const_row = const_row

    # ------------------------------------------------------------ packing
    def _layout(self, bits: int) -> None:
        self.bits = bits
        self.per_word = 64 // bits
        self.nwords = max(1, -(-self.nvar // self.per_word))
        self.cap = (1 << bits) - 1
        self.word_of = np.arange(self.nvar) // self.per_word
        self.shift = (np.arange(self.nvar) % self.per_word) * bits
        wd = np.zeros((len(self.delta), self.nwords), dtype=np.int64)
        for j in range(self.nvar):
            w, sh = self.word_of[j], int(self.shift[j])
            col = self.delta[:, j]
            nz = np.flatnonzero(col)
            for i in nz:
                wd[i, w] += int(col[i]) << sh if sh < 63 else 0
        # signed deltas as uint64 (two's complement): adding wraps exactly
        self.word_delta = [np.array([int(v) & (2**64 - 1) for v in wd[:, w]], dtype=np.uint64)
                           for w in range(self.nwords)]
        if bits * self.per_word == 64 and (self.shift >= 63).any():
            raise Overflow("column at bit 63")

    def _pack(self, rows: np.ndarray) -> list[np.ndarray]:
        words = [np.zeros(len(rows), dtype=np.uint64) for _ in range(self.nwords)]
        for j in range(self.nvar):
            words[self.word_of[j]] |= rows[:, j].astype(np.uint64) << np.uint64(self.shift[j])
        return words

    def _unpack(self, words: list[np.ndarray]) -> np.ndarray:
        n = len(words[0])
        rows = np.empty((n, self.nvar), dtype=np.int16)
        mask = np.uint64(self.cap)
        for j in range(self.nvar):
            rows[:, j] = ((words[self.word_of[j]] >> np.uint64(self.shift[j])) & mask).astype(np.int16)
        return rows

    @staticmethod
    def _mix(words: list[np.ndarray]) -> np.ndarray:
        with np.errstate(over="ignore"):
            h = words[0] * np.uint64(0x9E3779B97F4A7C15)
            for k, w in enumerate(words[1:], 1):
                h = (h ^ (h >> np.uint64(29))) + w * np.uint64(0xBF58476D1CE4E5B9 + 2 * k)
            return h ^ (h >> np.uint64(31))

    # ------------------------------------------------------------ search
    def run(self, budget: Budget = Budget()) -> StateGraph:
        bits = 1
        start = self.model.start_row[self.var_cols]
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
        start_row = self.model.start_row[self.var_cols][None, :].astype(np.int16)
        s = _Search(start_row, self._pack(start_row), self._mix)
        complete, stop = True, ""
        expanded_upto = 0
        while len(s.f_ids):
            stop = self._budget_stop(budget, t0, s.n_states)
            if stop:
                complete = False
                break
            srcs, insts = self._enabled(s.f_rows, len(s.f_ids))
            stop = self._level_memory_stop(budget, srcs, s.n_states)
            if stop:
                complete = False
                break
            expanded_upto = int(s.f_ids[-1]) + 1
            if not srcs:
                break
            self._expand_level(s, srcs, insts)
            if self.on_progress is not None:
                el = time.perf_counter() - t0
                self.on_progress({"states": s.n_states, "transitions": s.n_edges, "frontier": len(s.f_ids),
                                  "seconds": el, "states_per_s": s.n_states / max(el, 1e-9),
                                  "memory_mb": current_rss_mb()})
        if complete:
            expanded_upto = s.n_states
        g = self._graph(s, complete, stop, expanded_upto)
        self.seconds = time.perf_counter() - t0
        return g

    @staticmethod
    def _budget_stop(budget: Budget, t0: float, n_states: int) -> str:
        """Why the search stops before the next level ("" to go on): a state, time or memory budget."""
        if budget.max_states is not None and n_states >= budget.max_states:
            return f"state budget of {budget.max_states} reached"
        if budget.max_seconds is not None and time.perf_counter() - t0 >= budget.max_seconds:
            return f"time budget of {budget.max_seconds:g} s reached"
        if budget.max_memory_mb is not None and current_rss_mb() > budget.max_memory_mb:
            return f"memory budget of {budget.max_memory_mb:g} MiB reached"
        return ""

    def _enabled(self, f_rows: np.ndarray, n: int) -> tuple[list, list]:
        """The transitions of a frontier of ``n`` states: per enabled instance, the frontier
        positions where it is enabled and the instance number repeated (raises :class:`Overflow`
        when a produced count would outgrow its bits)."""
        cap = self.cap
        srcs, insts = [], []
        for i, pairs in enumerate(self.needs):
            if pairs is None:
                continue
            mask = None
            for c, k in pairs:
                m = f_rows[:, c] >= k
                mask = m if mask is None else (mask & m)
            idx = np.flatnonzero(mask) if mask is not None else np.arange(n)
            if not len(idx):
                continue
            for c, _k in self.produced[i]:
                if int(f_rows[idx, c].max()) + int(self.delta[i, c]) > cap:
                    raise Overflow
            srcs.append(idx)
            insts.append(np.full(len(idx), i, dtype=np.int16))
        return srcs, insts

    def _level_memory_stop(self, budget: Budget, srcs: list, n_states: int) -> str:
        """Why the next level would not fit the memory budget ("" when it fits, or has no budget)."""
        if budget.max_memory_mb is None or not srcs:
            return ""
        # what this level will take before it can be given back: the candidate
        # transitions' words, hashes and indices, the copies the visited arrays make
        # when they grow, and the edge arrays of the graph
        n_cand = sum(len(x) for x in srcs)
        need = (n_cand * (16 * self.nwords + 136) + n_states * (16 + 8 * self.nwords)) / 1048576.0
        now_mb = current_rss_mb()
        if now_mb + need > budget.max_memory_mb:
            return (f"memory budget of {budget.max_memory_mb:g} MiB reached (the next "
                    f"level, {n_cand:,} transitions, needs about {need:,.0f} MiB more)")
        return ""

    def _expand_level(self, s: "_Search", srcs: list, insts: list) -> None:
        """Take every transition of the frontier: record its edges, add the new states, and make
        them the next frontier."""
        src_local = np.concatenate(srcs)
        inst = np.concatenate(insts)
        order = np.lexsort((inst, src_local))  # discovery order: by source, then instance
        src_local, inst = src_local[order], inst[order]
        with np.errstate(over="ignore"):
            words = [s.f_words[w][src_local] + self.word_delta[w][inst] for w in range(self.nwords)]
        dst = self._visited_ids(s, words)
        new_tr = np.flatnonzero(dst < 0)
        if len(new_tr):
            next_ids, new_rows, new_words = self._add_new_states(s, dst, new_tr, words, src_local, inst)
        else:
            next_ids = np.zeros(0, dtype=np.int64)
            new_rows = s.f_rows[:0]
            new_words = [w[:0] for w in words]
        s.e_src.append(s.f_ids[src_local].astype(np.int32))
        s.e_dst.append(dst.astype(np.int32))
        s.e_inst.append(inst)
        s.n_edges += len(dst)
        # column-major: the enabledness tests read whole columns
        s.f_ids, s.f_rows, s.f_words = next_ids, np.asfortranarray(new_rows), new_words
        s.level += 1

    def _visited_ids(self, s: "_Search", words: list) -> np.ndarray:
        """The id of each target state (its exact words) among the visited states, -1 if new."""
        mix = self._mix(words)
        # search in sorted order: sequential access into the big visited array
        so = np.argsort(mix)
        pos = np.empty(len(mix), dtype=np.int64)
        pos[so] = np.searchsorted(s.vis_mix, mix[so])
        np.minimum(pos, len(s.vis_mix) - 1, out=pos)
        cand = s.vis_id[pos]
        found = s.vis_mix[pos] == mix
        for w in range(self.nwords):
            found &= s.all_words[w][cand] == words[w]
        dst = np.where(found, cand, -1)
        # rare: same mix, different state, not at the searched position: resolve exactly
        suspect = np.flatnonzero(~found & (s.vis_mix[pos] == mix))
        for t in suspect.tolist():
            lo = np.searchsorted(s.vis_mix, mix[t], side="left")
            hi = np.searchsorted(s.vis_mix, mix[t], side="right")
            for j in range(lo, hi):
                sid = int(s.vis_id[j])
                if all(s.all_words[w][sid] == words[w][t] for w in range(self.nwords)):
                    dst[t] = sid
                    break
        return dst

    def _add_new_states(self, s: "_Search", dst: np.ndarray, new_tr: np.ndarray, words: list,
                        src_local: np.ndarray, inst: np.ndarray) -> tuple:
        """Number the distinct new targets of transitions ``new_tr`` in discovery order, fill in
        their ids in ``dst``, add them to the visited set with their parent, creating edge and
        depth; (their ids, rows, words)."""
        # exact dedupe of the new states: sort by all words, mark run starts
        nw = [w[new_tr] for w in words]
        o = np.lexsort(tuple(reversed(nw)))
        starts = np.ones(len(o), dtype=bool)
        if len(o) > 1:
            same = np.ones(len(o) - 1, dtype=bool)
            for w in nw:
                ws = w[o]
                same &= ws[1:] == ws[:-1]
            starts[1:] = ~same
        grp_id = np.cumsum(starts) - 1  # group of each sorted candidate
        n_new = int(grp_id[-1]) + 1
        # first transition (in discovery order) of each group
        first = np.full(n_new, len(o), dtype=np.int64)
        np.minimum.at(first, grp_id, o)
        rank_order = np.argsort(first, kind="stable")
        rank = np.empty(n_new, dtype=np.int64)
        rank[rank_order] = np.arange(n_new)
        grp_of_cand = np.empty(len(o), dtype=np.int64)
        grp_of_cand[o] = grp_id
        n_states = s.n_states
        dst[new_tr] = n_states + rank[grp_of_cand]
        first_tr = new_tr[first[rank_order]]  # creating transition of each new state, id order
        new_words = [w[first_tr] for w in words]
        new_rows = s.f_rows[src_local[first_tr]] + self.delta[inst[first_tr]].astype(np.int16)
        s.parent.append(s.f_ids[src_local[first_tr]].astype(np.int32))
        s.parent_edge.append(s.n_edges + first_tr)
        s.depth.append(np.full(n_new, s.level + 1, dtype=np.int32))
        nmix = self._mix(new_words)
        so = np.argsort(nmix, kind="stable")
        ins = np.searchsorted(s.vis_mix, nmix[so])
        s.vis_mix = np.insert(s.vis_mix, ins, nmix[so])
        s.vis_id = np.insert(s.vis_id, ins, (n_states + np.arange(n_new))[so])
        s.all_words = [np.concatenate([s.all_words[w], new_words[w]]) for w in range(self.nwords)]
        s.n_states = n_states + n_new
        return n_states + np.arange(n_new), new_rows, new_words

    def _graph(self, s: "_Search", complete: bool, stop: str, expanded_upto: int) -> StateGraph:
        """The state graph of the search (and what describing its states and edges needs)."""
        g = StateGraph()
        g.parent = np.concatenate(s.parent)
        g.parent_edge = np.concatenate(s.parent_edge)
        g.depth = np.concatenate(s.depth)
        g.expanded = (np.arange(s.n_states) < expanded_upto).astype(np.int8)
        g.src = np.concatenate(s.e_src) if s.e_src else np.zeros(0, np.int32)
        g.dst = np.concatenate(s.e_dst) if s.e_dst else np.zeros(0, np.int32)
        inst_all = np.concatenate(s.e_inst) if s.e_inst else np.zeros(0, np.int16)
        s.e_src, s.e_dst, s.e_inst = [], [], []
        g.label = self.inst_label[inst_all]
        g.group = self.inst_group[inst_all]
        g.progress = self.inst_progress[inst_all].astype(np.int8)
        g.labels, g.groups = self.labels, self.groups
        g.complete, g.stop_reason = complete, stop
        self.words = s.all_words
        self.edge_inst = inst_all
        g.describe_state = self.describe_state
        g.describe_edge = self.describe_edge
        return g

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


class _Search:
    """The search so far: the visited states (sorted mixes with their ids, exact words per id,
    parent, creating edge and depth per id), the edges, and the frontier (ids, rows, words)."""

    def __init__(self, start_row: np.ndarray, start_words: list, mix: Callable):
        self.vis_mix = mix(start_words)
        self.vis_id = np.zeros(1, dtype=np.int64)
        self.all_words = [w.copy() for w in start_words]  # flat per-word arrays (grown per level)
        self.parent = [np.full(1, -1, dtype=np.int32)]
        self.parent_edge = [np.full(1, -1, dtype=np.int64)]
        self.depth = [np.zeros(1, dtype=np.int32)]
        self.e_src: list = []
        self.e_dst: list = []
        self.e_inst: list = []
        self.n_states, self.n_edges = 1, 0
        self.f_ids = np.zeros(1, dtype=np.int64)
        self.f_rows = start_row
        self.f_words = start_words
        self.level = 0
