"""Explicit-state search over a transition system, with budgets.

Breadth-first by default, so the discovery path of every state is a shortest
one and counterexamples read off parent pointers are shortest; depth-first as
an option. The search can be resumed with a larger budget (the livelock check
grows it until a fair cycle appears or the graph is complete). A budget that
runs out leaves ``graph.complete`` false and says why: verdicts built on an
incomplete graph are reported as such, never as "verified".
"""

from __future__ import annotations

import hashlib
import math
import os
import resource
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable, Optional

from .graph import StateGraph
from .system import TransitionSystem


#: bitstate hashing: bits in the array by default (16 MiB), and bits set per state (SPIN's -k3)
DEFAULT_BITS = 1 << 27
BIT_HASHES = 3


def _bit_positions(key, bits: int) -> tuple:
    """A state's BIT_HASHES positions in a bit array of ``bits`` bits: double hashing on a 128-bit
    BLAKE2 digest of the key: of its bytes for a canonical key (so that a bitstate search
    takes the same states for visited ones from run to run: Python's own hash of bytes
    changes with each process), of its hash for any other key (equal within one process)."""
    data = key if type(key) is bytes else hash(key).to_bytes(8, "little", signed=True)
    d = hashlib.blake2b(data, digest_size=16).digest()
    h1, h2 = int.from_bytes(d[:8], "little"), int.from_bytes(d[8:], "little") | 1
    return tuple((h1 + i * h2) % bits for i in range(BIT_HASHES))


@dataclass
class Budget:
    max_states: Optional[int] = None
    max_seconds: Optional[float] = None
    max_memory_mb: Optional[int] = None


def rss_mb() -> float:
    """Peak resident memory of this process, in MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


_STATM: dict = {}  # pid -> open descriptor of /proc/self/statm (reopened after a fork)
_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def current_rss_mb() -> float:
    """Resident memory of this process now, in MiB: a read of ``/proc/self/statm`` (about 2 µs);
    where there is no /proc, the peak (``getrusage``), which never understates."""
    pid = os.getpid()
    fd = _STATM.get(pid)
    try:
        if fd is None:
            _STATM.clear()
            fd = _STATM[pid] = os.open("/proc/self/statm", os.O_RDONLY)
        return int(os.pread(fd, 128, 0).split()[1]) * _PAGE / 1048576.0
    except (OSError, ValueError, IndexError, AttributeError):
        return rss_mb()


class MemoryWatch:
    """Is the process above its memory budget? Reads the resident size every few units of work,
    often enough that the work between two reads cannot overshoot much: the interval adapts
    to the growth seen per unit and to the room left (every unit near the budget, at most
    every ``most`` units far from it)."""

    def __init__(self, budget_mb: Optional[float], most: int = 256):
        self.limit = budget_mb
        self.most = most
        self.next_at = 0
        self.last_units = 0
        self.last_mb = current_rss_mb() if budget_mb is not None else 0.0
        self.mb = self.last_mb

    def over(self, units: int) -> bool:
        if self.limit is None or units < self.next_at:
            return False
        mb = self.mb = current_rss_mb()
        if mb > self.limit:
            return True
        per_unit = max(mb - self.last_mb, 0.0) / max(units - self.last_units, 1)
        room = (self.limit - mb) / 8  # let the next interval use at most an eighth of the room left
        step = self.most if per_unit <= 0 else int(room / per_unit)
        self.last_units, self.last_mb = units, mb
        self.next_at = units + max(1, min(step, self.most))
        return False


#: at most this many frontier states are kept live (the others frozen until they are expanded).
#: A state is built in the order re-adding its facts gives (``Context.in_order``), the order a
#: frozen state has when thawed, so freezing one never changes the order of its enabled steps,
#: hence the numbering of states and edges (tests/explore/test_compact_states.py). 256 rather
#: than more: on a wide frontier (fan-6, 30,000 states) 2,048 live states cost 3.0 KB a visited
#: state and 256 cost 2.1 KB, at the same speed (benchmark B8).
LIVE_FRONTIER = 256


#: an expanded state built from its discovery parent by a step that only consumes and adds facts
#: is kept as nothing and rebuilt from its parent when read (see StateStore), unless its depth is
#: a multiple of this: then it is kept frozen, so that a rebuild replays fewer steps than this
REPLAY_SPAN = 4


class StateStore:
    """The visited states by id. A system with ``freeze``/``thaw`` (a CLF context without its
    matching indexes) has its expanded states kept frozen, a few hundred bytes each, and thawed
    when read again: the few read most recently stay thawed (properties read them in order).
    States waiting in a short frontier stay as they are (a successor shares its parent's indexes);
    past ``LIVE_FRONTIER`` waiting states, new ones are frozen too.

    An expanded state that a system with ``rebuild`` built from its discovery parent by a plain
    step (``append(state, plain=True)``) is not kept at all, unless its depth is a multiple of
    ``REPLAY_SPAN``: reading it replays the discovery steps from the nearest ancestor kept (the
    graph's parent pointers, the steps of ``steps``), which gives the state thawing it would."""

    def __init__(self, system, keep: int = 8):
        self.freeze = getattr(system, "freeze", None)
        self.thaw = getattr(system, "thaw", None)
        self.frozen = getattr(system, "frozen_type", None)
        self.rebuild = getattr(system, "rebuild", None) if self.thaw is not None else None
        self.items: list = []
        self.plain = bytearray()   # 1: built from its discovery parent by a plain step
        self.recent: dict = {}
        self.keep = keep
        self.graph: Optional[StateGraph] = None   # the explorer's graph and steps (for rebuilds)
        self.steps = None

    def append(self, state, plain: bool = False) -> None:
        self.items.append(state)
        self.plain.append(1 if plain else 0)

    def done(self, i: int) -> None:
        """State ``i`` is expanded (from now on it is only read back), or waits in a frontier so
        long that keeping it live costs more memory than thawing it later costs time: keep it
        frozen, or (expanded, and rebuilt from its parent when read) drop it."""
        x = self.items[i]
        if self.freeze is None or x is None:
            return
        g = self.graph
        if (self.rebuild is not None and self.plain[i] and g is not None and self.steps is not None
                and g.expanded[i] and g.depth[i] % REPLAY_SPAN):
            self.items[i] = None
            self.recent.pop(i, None)
        elif not isinstance(x, self.frozen):
            self.items[i] = self.freeze(x)
            self.recent.pop(i, None)

    def _rebuilt(self, i: int):
        """State ``i`` (dropped): its discovery steps replayed from the nearest ancestor kept."""
        g = self.graph
        edges = []
        j = i
        while True:
            x = self.items[j]
            if x is not None:
                base = x
                break
            hit = self.recent.get(j)
            if hit is not None and j != i:
                base = hit
                break
            edges.append(g.parent_edge[j])
            j = g.parent[j]
        edges.reverse()
        return self.rebuild(base, [self.steps[e] for e in edges])

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        x = self.items[i]
        if self.thaw is None or (x is not None and not isinstance(x, self.frozen)):
            return x
        if i < 0:
            i += len(self.items)
        hit = self.recent.get(i)
        if hit is None:
            hit = self.thaw(x) if x is not None else self._rebuilt(i)
            if len(self.recent) >= self.keep:
                del self.recent[next(iter(self.recent))]
            self.recent[i] = hit
        return hit

    def __iter__(self):
        return (self[i] for i in range(len(self.items)))


class StepStore:
    """The step of every transition, by edge index. A system with ``pack_step``/``unpack_step``
    has its steps kept packed (an engine step as one flat tuple of shared pairs: a few hundred
    bytes a transition instead of a step object with its lists) and unpacked when read."""

    __slots__ = ("items", "pack", "unpack")

    def __init__(self, system):
        self.items: list = []
        self.pack = getattr(system, "pack_step", None)
        self.unpack = getattr(system, "unpack_step", None)
        if self.pack is None or self.unpack is None:
            self.pack = self.unpack = None

    def append(self, step) -> None:
        self.items.append(step if self.pack is None else self.pack(step))

    def __getitem__(self, e: int):
        x = self.items[e]
        return x if self.unpack is None else self.unpack(x)

    def __len__(self) -> int:
        return len(self.items)

    def __iter__(self):
        return (self[i] for i in range(len(self.items)))


def path_steps(explorer, edges: list) -> list:
    """The steps of a path of the explored graph (edge indices, each edge leaving the state the
    one before it enters, the first leaving a state the search kept as it found it) as one run
    takes them: each step applies to the state the steps before it reached, fresh names
    included.

    Why: a transition is recorded with the names of its source state as the search kept it,
    and a state reached again by another edge is kept with the names of its first discovery,
    another renaming of the run's. Along edges by which their targets were discovered (a
    path to a state) the recorded steps are the run's; from the first other edge on (a
    lasso's cycle closes on a state found before), the path is followed by real successors:
    from the run's state, the successor with the edge's rule whose key is its target's. A
    counterexample's trace then replays step by step, and its ROAR events name the requests
    the run made. Falls back to the recorded steps if no successor matches (it always should),
    and for an explorer that exposes no graph (the robot-backed search's view of its states as
    contexts: its states are the robot's, replayed on the robot)."""
    g = getattr(explorer, "graph", None)
    if g is None:
        return [explorer.steps[e] for e in edges]
    system = explorer.system
    out: list = []
    cur = None   # the run's state, once it is not the one the search kept
    for i, e in enumerate(edges):
        dst = int(g.dst[e])
        if cur is None and int(g.parent_edge[dst]) == e:
            out.append(explorer.steps[e])
            continue
        state = cur if cur is not None else explorer.states[int(g.src[e])]
        want = system.key(explorer.states[dst])
        label = g.labels.names[g.label[e]]
        succ = next((x for x in system.successors(state) if x.label == label and system.key(x.state) == want), None)
        if succ is None:
            return out + [explorer.steps[x] for x in edges[i:]]
        out.append(succ.step)
        cur = succ.state
    return out


def describe_path(explorer, edges: list) -> list:
    """A path's steps printed (``system.describe_step``) as :func:`path_steps` gives them."""
    return [explorer.system.describe_step(st) for st in path_steps(explorer, edges)]


class Explorer:
    """Resumable BFS/DFS that records every state and transition in a :class:`StateGraph`."""

    def __init__(self, system: TransitionSystem, order: str = "bfs",
                 on_progress: Optional[Callable[[dict], None]] = None, visited: str = "exact",
                 bits: int = DEFAULT_BITS):
        if order not in ("bfs", "dfs"):
            raise ValueError("order must be 'bfs' or 'dfs'")
        if visited not in ("exact", "hash", "bitstate"):
            raise ValueError("visited must be 'exact', 'hash' or 'bitstate'")
        #: hash compaction (Holzmann): a visited state is remembered by a 64-bit hash of its key,
        #: not the key; two states with one hash are taken for one (see omission_probability)
        self.hashed = visited == "hash"
        #: bitstate hashing (Holzmann's supertrace): a visited state is remembered by BIT_HASHES bits
        #: of a bit array; a state whose bits are all set is taken as visited. The graph keeps the
        #: discovery tree (parents, shortest paths) and counts the other transitions per state
        #: without recording them, so it decides properties read on states, not cycles.
        self.bitstate: Optional[bytearray] = None
        if visited == "bitstate":
            if bits < 1024:
                raise ValueError("a bit array needs at least 1024 bits")
            self.bits = bits
            self.bitstate = bytearray((bits + 7) // 8)
        self.system = system
        self.order = order
        self.on_progress = on_progress
        self.graph = StateGraph()
        if self.bitstate is not None:
            self.graph.unrecorded = {}
        self.states = StateStore(system)  # state id -> state (kept frozen when the system can)
        self.ids: dict = {}
        s0 = system.initial()
        self._add(s0, -1, -1, 0)
        self.frontier: deque[int] = deque([0])
        self.steps = StepStore(system)  # edge index -> engine step (for describing counterexamples)
        self.states.graph, self.states.steps = self.graph, self.steps   # (rebuilding dropped states)
        self.graph.describe_state = lambda i: system.describe(self.states[i])
        self.graph.describe_edge = lambda e: system.describe_step(self.steps[e])
        self.graph.describe_steps = lambda edges: describe_path(self, edges)
        self.started = time.perf_counter()
        self.elapsed = 0.0
        # partial-order reduction (the system's ``options.reduction``): expansions that used a
        # stubborn subset, and those the cycle proviso turned back into full ones
        self.reduce = bool(getattr(getattr(system, "options", None), "reduction", False)) and hasattr(
            system, "reduced_successors")
        self.reduced_expansions = 0
        self.steps_left_out = 0
        self.proviso_expansions = 0
        self._rng = None   # shuffle(seed): successors taken in a random order (swarm searches)

    def shuffle(self, seed: int) -> None:
        """Take each state's successors in an order drawn from ``seed`` (a swarm's diversified
        searches: each member explores a different part first)."""
        import random
        self._rng = random.Random(seed)

    def _key(self, state):
        return self._from_key(self.system.key(state))

    def _from_key(self, k):
        """The visited set's key of a state whose system key is ``k``."""
        if self.bitstate is not None:
            return _bit_positions(k, self.bits)
        return hash(k) if self.hashed else k

    def _add(self, state, parent: int, edge: int, depth: int, k=None, plain: bool = False) -> int:
        sid = self.graph.add_state(parent, edge, depth)
        self.states.append(state, plain)
        if k is None:
            k = self._key(state)
        if self.bitstate is not None:
            self._seen(k)   # sets its bits
        else:
            self.ids[k] = sid
        return sid

    def _seen(self, positions) -> bool:
        """Bitstate: were all of a state's bits set already? Sets them."""
        bs = self.bitstate
        seen = True
        for b in positions:
            byte, bit = b >> 3, 1 << (b & 7)
            if not bs[byte] & bit:
                seen = False
                bs[byte] |= bit
        return seen

    def omission_probability(self) -> float:
        """Under hash compaction, a bound on the probability that two of the states visited share
        a hash, so that one was taken for the other and never explored: n(n-1)/2 pairs, each
        colliding with probability 2^-64. Under bitstate hashing, the probability that a state not
        yet visited is taken for a visited one at the end of the search, (1 - e^(-kn/m))^k for n
        states, m bits and k bits per state (it was lower earlier). 0 for an exact search."""
        n = self.graph.n_states
        if self.bitstate is not None:
            return (1.0 - math.exp(-BIT_HASHES * n / self.bits)) ** BIT_HASHES
        if not self.hashed:
            return 0.0
        return min(1.0, n * (n - 1) / 2 / 2.0 ** 64)

    def expected_omissions(self) -> float:
        """Bitstate: the expected number of states taken for visited ones while the n states were
        added (the sum of the per-state probability as the array filled), 0 otherwise."""
        if self.bitstate is None:
            return 0.0
        n, m, k = self.graph.n_states, self.bits, BIT_HASHES
        steps = min(n, 1000)
        return sum((1.0 - math.exp(-k * (i + 0.5) * n / steps / m)) ** k for i in range(steps)) * n / max(steps, 1)

    def run(self, budget: Budget = Budget()) -> StateGraph:
        g = self.graph
        t0 = self._running_since = time.perf_counter()
        last_report = t0
        pop = self.frontier.popleft if self.order == "bfs" else self.frontier.pop
        system = self.system
        lazy_fn = getattr(system, "lazy_successors", None)
        memory = MemoryWatch(budget.max_memory_mb)
        while self.frontier:
            if budget.max_states is not None and g.n_states >= budget.max_states:
                g.stop_reason = f"state budget of {budget.max_states} reached"
                break
            now = time.perf_counter()
            if budget.max_seconds is not None and self.elapsed + (now - t0) >= budget.max_seconds:
                g.stop_reason = f"time budget of {budget.max_seconds:g} s reached"
                break
            if memory.over(g.n_states + g.n_edges):  # states and transitions both take memory
                g.stop_reason = f"memory budget of {budget.max_memory_mb:g} MiB reached"
                break
            s = pop()
            state = self.states[s]
            depth = g.depth[s] + 1
            views = None
            lazy = None if self.reduce or lazy_fn is None else lazy_fn(state)
            if lazy is not None:
                # keys first, states built only for the new ones (see ClfSystem.lazy_successors)
                if self._rng is not None:
                    self._rng.shuffle(lazy)
                succs = [x[0] for x in lazy]
                keys = [self._from_key(x[1]) for x in lazy]
                views = [x[2] for x in lazy]
            elif self.reduce:
                succs, keys = self._expand_reduced(state, s)
            else:
                succs = system.successors(state)
                if self._rng is not None:
                    self._rng.shuffle(succs)
                keys = [self._key(x.state) for x in succs]
            for i, (succ, k) in enumerate(zip(succs, keys)):
                if self.bitstate is not None:
                    if self._seen(k):   # taken as visited: counted, not recorded (it has no id here)
                        un = g.unrecorded
                        un[s] = un.get(s, 0) + 1
                        continue
                    t = len(self.states)
                    plain = succ.state is None
                    if plain:
                        succ.state = system.build_successor(state, succ, views[i])
                    e = g.add_edge(s, t, succ.label, succ.group, succ.progress)
                    self.steps.append(succ.step)
                    sid = g.add_state(s, e, depth)
                    self.states.append(succ.state, plain)
                    self.frontier.append(sid)
                    if len(self.frontier) > LIVE_FRONTIER:
                        self.states.done(sid)
                    continue
                t = self.ids.get(k)
                new = t is None
                if new:
                    t = len(self.states)
                e = g.add_edge(s, t, succ.label, succ.group, succ.progress)
                self.steps.append(succ.step)
                if new:
                    plain = succ.state is None
                    if plain:
                        succ.state = system.build_successor(state, succ, views[i])
                    self._add(succ.state, s, e, depth, k, plain)
                    self.frontier.append(t)
                    if len(self.frontier) > LIVE_FRONTIER:
                        self.states.done(t)
            g.expanded[s] = 1
            self.states.done(s)
            if self.on_progress is not None and now - last_report > 0.25:
                last_report = now
                self.on_progress(self.stats())
        else:
            g.complete = True
            g.stop_reason = ""
        self.elapsed += time.perf_counter() - t0
        self._running_since = None
        return g

    def _expand_reduced(self, state, sid: int) -> tuple[list, list]:
        """A stubborn subset of the successors, or all of them under the cycle proviso: when
        a reduced expansion reaches a state already visited (expanded or in the frontier),
        every step is expanded, so no cycle of the graph is closed by reduced expansions
        alone (each edge of a reduced expansion leads to a state discovered by it)."""
        system = self.system
        succs, rest, rest_groups = system.reduced_successors(state)
        keys = [self._key(x.state) for x in succs]
        if rest is None:
            return succs, keys
        if any(k in self.ids for k in keys):
            self.proviso_expansions += 1
            more = rest()
            return succs + more, keys + [self._key(x.state) for x in more]
        self.reduced_expansions += 1
        self.steps_left_out += len(rest_groups)   # (one group per step left out)
        # the groups the skipped steps belong to are still enabled here (weak fairness)
        self.graph.add_enabled(sid, rest_groups)
        return succs, keys

    def stats(self) -> dict:
        g = self.graph
        # time so far: earlier runs, plus this one while it runs (a rate over 0 s is no rate)
        running = getattr(self, "_running_since", None)
        el = self.elapsed + (time.perf_counter() - running if running is not None else 0.0) + 1e-9
        # (a bitstate search counts the transitions it does not record: progress shows them all)
        out = {"states": g.n_states, "transitions": g.n_edges + g.n_unrecorded, "frontier": len(self.frontier),
               "seconds": el, "states_per_s": g.n_states / el, "memory_mb": current_rss_mb()}
        if self.reduce:
            out["reduced_expansions"] = self.reduced_expansions
            out["proviso_expansions"] = self.proviso_expansions
            out["steps_left_out"] = self.steps_left_out
        return out
