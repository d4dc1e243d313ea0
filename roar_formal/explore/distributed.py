"""Breadth-first search on a Dask cluster: the visited set partitioned by a state hash.

Every worker process builds the transition system itself (from a picklable *factory*:
``factory.key()`` names it, ``factory.build()`` makes it) and owns the states whose
partition hash (``portable.ContextCodec.partition``: equal in every process, and for every
renaming of fresh names) falls to it. The search is level-synchronous, in rounds:

1. each worker expands up to ``batch`` states of the current level that it owns, and
   sorts the successors into one batch per owner (the state and the step, as bytes);
2. each batch goes to its owner (worker to worker: the driver only names the futures),
   which reads each state back, computes its key with its own system (the exact key a
   single-process search uses), and records the edge; a state not seen before is kept;
3. when every worker's share of the level is expanded, the driver numbers the states the
   level discovered, in the order a single-process breadth-first search numbers them (by
   the parent's number, then the step's position among the parent's successors; the
   parent kept is the first, and the state kept is the one that step made), and the next
   level begins.

So the state numbers, parents, depths and edges are those of ``search.Explorer`` in
breadth-first order: the driver gathers them into a :class:`StateGraph`, with every state
and every step as bytes, read back on demand (``states[i]``, ``steps[e]``), and the
verdict code runs on it unchanged; a counterexample is a path of that graph, shortest
as in any breadth-first search. A state's fresh names keep their identity across
processes (``portable``), so a step read back consumes the names of the state it leaves.

Budgets are checked between rounds (states, the driver's memory) and by the workers
while they expand (time, their own memory): a search stops at the end of the round that
reaches a bound, so the graph may hold a few states past ``max_states``. A stopped search
resumes (``run`` again) where it stopped, as ``Explorer`` does.
"""

from __future__ import annotations

import operator
import threading
import time
import uuid
from array import array
from collections import deque
from typing import Callable, Optional

import numpy as np

from ..clf.query import with_big_stack
from .graph import Interner, StateGraph
from .portable import ContextCodec, NotPortable
from .search import Budget, current_rss_mb, describe_path

__all__ = ["DistributedExplorer", "DistributedError", "SwarmResult", "codec_for", "swarm_member"]

#: frontier states each worker expands per round, unless the caller says otherwise
BATCH = 1_000
#: up to this many workers, each receives the others' whole output of a round (one task less on
#: the way); past it, outputs are split on the worker that made them and each batch sent alone
SPLIT_ABOVE = 2


class DistributedError(Exception):
    """The distributed search could not run (a worker failed, a state could not be sent)."""


def codec_for(system, origin: int):
    """The wire format of the system's states: its own (``system.portable_codec(origin)``), or
    the CLF context codec."""
    make = getattr(system, "portable_codec", None)
    if make is not None:
        return make(origin)
    initial = system.initial()
    return ContextCodec(origin, getattr(initial, "implicit", None))


# ====================================================================== worker side

_RUNS: dict = {}      # run id -> _Share: this process's part of a search
_SYSTEMS: dict = {}   # factory key -> transition system (built once per worker process)
_LOCK = threading.Lock()


def _system(factory):
    key = factory.key()
    with _LOCK:
        s = _SYSTEMS.get(key)
        if s is None:
            while len(_SYSTEMS) >= 4:
                _SYSTEMS.pop(next(iter(_SYSTEMS)))
            s = _SYSTEMS[key] = factory.build()
        return s


class _Share:
    """One worker's part of a search: the states it owns (keys, bytes, numbers), the edges into
    them, and its share of the current level."""

    def __init__(self, system, index: int, n: int, hashed: bool):
        self.system = system
        self.index = index
        self.n = n
        self.hashed = hashed
        self.codec = codec_for(system, index + 1)   # origin 0 is the driver
        self.ids: dict = {}              # key -> local index (the visited set)
        self.blobs: list = []            # local index -> the state as bytes (b"" once expanded and collected)
        self.gid = array("q")            # local index -> global number (-1 until numbered)
        self.best: dict = {}             # local index (not numbered yet) -> (parent number, successor position)
        self.pending: list = []          # local indices discovered, not numbered yet
        self.reported: list = []         # pending, in the order their keys were reported
        self.frontier: deque = deque()   # local indices of the current level, to expand
        self.upcoming: list = []         # numbered local indices of the next level
        self.strings: dict = {}          # labels and groups, one object each (pickled once a batch)
        self.received = 0                # edges recorded here, in all
        self._clear_chunk()

    def _clear_chunk(self) -> None:
        self.e_src = array("q")
        self.e_pos = array("q")
        self.e_dst = array("q")          # local index of the target (owned here)
        self.e_label = array("q")
        self.e_group = array("q")
        self.e_prog = array("b")
        self.e_step: list = []
        self.labels = Interner()
        self.groups = Interner()
        self.new_states: list = []       # (number, parent number, successor position, local index)
        self.expanded = array("q")       # numbers of the states expanded since the last collect

    # -------------------------------------------------------------- a round
    def seed(self, blob: bytes) -> None:
        light = self.codec.light(blob)
        key = self.system.key(light)
        self.ids[hash(key) if self.hashed else key] = 0
        self.blobs.append(blob)
        self.gid.append(0)
        self.new_states.append((0, -1, -1, 0))
        self.frontier.append(0)

    def assign(self, numbers: Optional[list], level_over: bool) -> None:
        """Number the states reported last (``numbers`` in the order reported); at the end of a
        level, the next level's states become the frontier."""
        if numbers is not None:
            for loc, g in zip(self.reported, numbers):
                self.gid[loc] = g
                src, pos = self.best.pop(loc)
                self.new_states.append((g, src, pos, loc))
                self.upcoming.append(loc)
            self.reported = []
        if level_over:
            if self.frontier:   # pragma: no cover - the driver ends a level only when every share is expanded
                raise DistributedError("a level ended with states left to expand")
            self.frontier = deque(self.upcoming)
            self.upcoming = []

    def expand(self, limit: int, seconds: Optional[float], memory_mb: Optional[float]) -> tuple:
        out: list = [[] for _ in range(self.n)]
        began = time.perf_counter()
        deadline = time.monotonic() + seconds if seconds is not None else None
        codec, system, n = self.codec, self.system, self.n
        planner = getattr(system, "planned_successors", None)
        strings = self.strings
        done = 0
        stopped = ""
        while self.frontier and done < limit:
            if deadline is not None and time.monotonic() >= deadline:
                stopped = "time"
                break
            if memory_mb is not None and done % 16 == 0 and current_rss_mb() > memory_mb:
                stopped = "memory"
                break
            loc = self.frontier.popleft()
            g = self.gid[loc]
            ctx = codec.context(self.blobs[loc])
            # the successors' facts are all that is sent: a system that can plan them gives them
            # without building each context (the owner reads it back from the bytes anyway)
            planned = planner(ctx) if planner is not None else None
            if planned is None:
                planned = [(succ, None) for succ in system.successors(ctx)]
            for pos, (succ, view) in enumerate(planned):
                nxt = succ.state if view is None else view
                label = strings.setdefault(succ.label, succ.label)
                group = strings.setdefault(succ.group, succ.group)
                out[codec.partition(nxt) % n].append(
                    (g, pos, label, group, bool(succ.progress), codec.state(nxt), codec.step(succ.step)))
            self.expanded.append(g)
            done += 1
        return (*out, (done, stopped, current_rss_mb(), time.perf_counter() - began))

    def receive(self, info: tuple, batches: list, want_keys: bool) -> dict:
        began = time.perf_counter()
        codec, system, hashed = self.codec, self.system, self.hashed
        ids, best = self.ids, self.best
        for batch in batches:
            for src, pos, label, group, prog, blob, step in batch:
                key = system.key(codec.light(blob))
                if hashed:
                    key = hash(key)
                loc = ids.get(key)
                if loc is None:
                    loc = ids[key] = len(self.blobs)
                    self.blobs.append(blob)
                    self.gid.append(-1)
                    best[loc] = (src, pos)
                    self.pending.append(loc)
                else:
                    b = best.get(loc)
                    if b is not None and (src, pos) < b:
                        # the parent a sequential search keeps is the first to reach the state,
                        # and the state it keeps is the one that step made
                        best[loc] = (src, pos)
                        self.blobs[loc] = blob
                self.e_src.append(src)
                self.e_pos.append(pos)
                self.e_dst.append(loc)
                self.e_label.append(self.labels(label))
                self.e_group.append(self.groups(group))
                self.e_prog.append(1 if prog else 0)
                self.e_step.append(step)
        done, stopped, rss, busy = info
        self.received += sum(len(b) for b in batches)
        out = {"expanded": done, "stopped": stopped, "frontier": len(self.frontier), "pending": len(self.pending),
               "memory_mb": max(rss, current_rss_mb()), "owned": len(self.ids), "edges": self.received,
               "busy": busy + time.perf_counter() - began}
        if want_keys:
            out["keys"] = self.keys()
        return out

    def keys(self) -> list:
        """The states discovered and not numbered yet, by (parent number, successor position),
        in that order (the driver numbers them by merging every share's list)."""
        self.reported = sorted(self.pending, key=self.best.__getitem__)
        self.pending = []
        return [self.best[loc] for loc in self.reported]

    def collect(self) -> dict:
        """What the driver has not got yet: the states numbered and the edges recorded since the
        last collect, and the states expanded."""
        gid = self.gid
        states = [(g, src, pos, self.blobs[loc]) for g, src, pos, loc in self.new_states]
        out = {"states": states,
               "src": self.e_src.tobytes(), "pos": self.e_pos.tobytes(),
               "dst": array("q", [gid[loc] for loc in self.e_dst]).tobytes(),
               "label": self.e_label.tobytes(), "group": self.e_group.tobytes(), "progress": self.e_prog.tobytes(),
               "steps": self.e_step, "labels": list(self.labels.names), "groups": list(self.groups.names),
               "expanded": self.expanded.tobytes()}
        # the bytes of the states expanded are the driver's now: keep only those still to expand
        self._forget_expanded(set(self.frontier) | set(self.upcoming))
        self._clear_chunk()
        return out

    def _forget_expanded(self, keep: set) -> None:
        blobs = self.blobs
        for loc in range(len(blobs)):
            if blobs[loc] and loc not in keep and loc not in self.best and self.gid[loc] >= 0:
                blobs[loc] = b""


def _in_big_stack(fn, *args):
    try:
        return with_big_stack(fn, *args)
    except NotPortable as exc:
        raise DistributedError(str(exc)) from None


def _w_open(run: str, factory, index: int, n: int, hashed: bool, seed: Optional[bytes]) -> dict:
    def go():
        system = _system(factory)
        share = _Share(system, index, n, hashed)
        if seed is not None:
            share.seed(seed)
        _RUNS[run] = share
        import os
        import socket
        return {"index": index, "host": socket.gethostname(), "pid": os.getpid()}
    return _in_big_stack(go)


def _share(run: str) -> _Share:
    s = _RUNS.get(run)
    if s is None:
        raise DistributedError(f"this worker holds no part of search {run} (was it restarted?)")
    return s


def _w_expand(run: str, assign, limit: int, seconds, memory_mb) -> tuple:
    share = _share(run)
    if assign is not None:
        share.assign(*assign)
    return _in_big_stack(share.expand, limit, seconds, memory_mb)


def _w_receive(run: str, info: tuple, batches: list, want_keys: bool, pick: Optional[int]) -> dict:
    if pick is not None:   # whole outputs of the expansions: this worker's batch of each, and its own info
        info = info[-1]
        batches = [out[pick] for out in batches]
    return _in_big_stack(_share(run).receive, info, batches, want_keys)


def _w_keys(run: str) -> list:
    return _share(run).keys()


def _w_collect(run: str, assign) -> dict:
    share = _share(run)
    if assign is not None:
        share.assign(*assign)
    return share.collect()


def _w_close(run: str) -> bool:
    return _RUNS.pop(run, None) is not None


# ====================================================================== driver side


class ShippedStates:
    """The driver's view of the states: state 0 is its own initial state, the others are read
    back from their bytes when asked for (the few read last are kept)."""

    def __init__(self, explorer: "DistributedExplorer", keep: int = 8):
        self.ex = explorer
        self.recent: dict = {}
        self.keep = keep

    def __len__(self) -> int:
        return len(self.ex.blobs)

    def __getitem__(self, i: int):
        if i < 0:
            i += len(self.ex.blobs)
        if i == 0:
            return self.ex.initial
        hit = self.recent.get(i)
        if hit is None:
            blob = self.ex.blobs[i]
            hit = self.ex.codec.context(blob)
            if len(self.recent) >= self.keep:
                del self.recent[next(iter(self.recent))]
            self.recent[i] = hit
        return hit

    def __iter__(self):
        return (self[i] for i in range(len(self)))


class ShippedSteps:
    """The driver's view of the steps, edge by edge, read back from their bytes when asked for."""

    def __init__(self, explorer: "DistributedExplorer"):
        self.ex = explorer

    def __len__(self) -> int:
        return len(self.ex.step_blobs)

    def __getitem__(self, e: int):
        return self.ex.codec.read_step(self.ex.step_blobs[e])


class DistributedExplorer:
    """Resumable level-synchronous breadth-first search over the workers of a Dask ``client``;
    the same interface as ``search.Explorer`` (``run``, ``graph``, ``states``, ``steps``,
    ``stats``, ``system``, ``hashed``, ``omission_probability``) for the code that decides
    verdicts. ``system`` is the driver's own copy of the system (for the initial state, and for
    describing states and steps); ``factory`` builds the workers' copies."""

    def __init__(self, system, client, factory, *, workers: Optional[list] = None, batch: int = BATCH,
                 on_progress: Optional[Callable[[dict], None]] = None, visited: str = "exact",
                 poll_seconds: float = 5.0):
        if visited not in ("exact", "hash"):
            raise ValueError("visited must be 'exact' or 'hash'")
        self.system = system
        self.client = client
        self.factory = factory
        self.batch = max(1, int(batch))
        self.on_progress = on_progress
        self.hashed = visited == "hash"
        self.poll_seconds = poll_seconds
        self.workers = list(workers) if workers else sorted(client.scheduler_info()["workers"])
        if not self.workers:
            raise DistributedError("the cluster has no workers")
        self.n = len(self.workers)
        self.run_id = "roar-bfs-" + uuid.uuid4().hex[:12]
        self.codec = codec_for(system, 0)
        self.initial = system.initial()
        self.graph = StateGraph()
        self.blobs: list = [b""]          # state number -> bytes (state 0: the driver's own)
        self.step_blobs: list = []        # edge index -> bytes
        self.states = ShippedStates(self)
        self.steps = ShippedSteps(self)
        self.graph.describe_state = lambda i: system.describe(self.states[i])
        self.graph.describe_edge = lambda e: system.describe_step(self.steps[e])
        self.graph.describe_steps = lambda edges: describe_path(self, edges)
        try:
            seed = self.codec.state(self.initial)
            owner = self.codec.partition(self.initial) % self.n
        except NotPortable as exc:
            raise DistributedError(str(exc)) from None
        self.graph.add_state(-1, -1, 0)
        self.frontier = [0] * self.n      # states of the current level each worker has to expand
        self.frontier[owner] = 1
        self.upcoming = [0] * self.n      # states of the next level numbered already
        self.pending = 0                  # states discovered, not numbered yet (all workers)
        self.numbered = 1
        self.level = 0
        self.transitions = 0
        self.worker_memory = [0.0] * self.n
        self.worker_seconds = 0.0         # the workers' time expanding and receiving, all together
        self.rounds = 0
        self._assign: list = [None] * self.n
        self.elapsed = 0.0
        self._running_since: Optional[float] = None
        self.closed = False
        futs = [self._submit(_w_open, j, self.run_id, factory, j, self.n, self.hashed,
                             seed if j == owner else None) for j in range(self.n)]
        self.hosts = self._gather(futs)

    # -------------------------------------------------------------- plumbing
    def _submit(self, fn, j: int, *args):
        return self.client.submit(fn, *args, workers=[self.workers[j]], allow_other_workers=False, pure=False)

    def _gather(self, futs: list) -> list:
        """The futures' results; a worker that leaves the cluster, or a task that fails, ends the
        search with an error (never a verdict)."""
        from distributed import wait
        while True:
            try:
                wait(futs, timeout=self.poll_seconds)
                break
            except TimeoutError:
                pass
            alive = set(self.client.scheduler_info()["workers"])
            gone = [w for w in self.workers if w not in alive]
            if gone:
                raise DistributedError(f"worker {', '.join(gone)} left the cluster during the search")
        try:
            return self.client.gather(futs)
        except DistributedError:
            raise
        except Exception as exc:
            raise DistributedError(f"a worker failed: {type(exc).__name__}: {exc}") from exc

    def close(self) -> None:
        """Free the workers' part of the search (the driver keeps the graph, states and steps)."""
        if self.closed:
            return
        self.closed = True
        try:
            futs = [self._submit(_w_close, j, self.run_id) for j in range(self.n)]
            self.client.gather(futs)
        except Exception:   # pragma: no cover - a cluster already gone has nothing to free
            pass

    # -------------------------------------------------------------- the search
    def omission_probability(self) -> float:
        if not self.hashed:
            return 0.0
        n = self.graph.n_states
        return min(1.0, n * (n - 1) / 2 / 2.0 ** 64)

    def shuffle(self, seed: int) -> None:
        raise DistributedError("a distributed search is breadth-first: it takes no random order")

    def _number(self, keys: list, level_over: bool) -> int:
        """Number the states the shares reported, in the order of their (parent, position) keys."""
        merged = sorted((k, j, i) for j, ks in enumerate(keys) for i, k in enumerate(ks))
        numbers: list = [[0] * len(ks) for ks in keys]
        for g, (_k, j, i) in enumerate(merged, start=self.numbered):
            numbers[j][i] = g
        self.numbered += len(merged)
        for j in range(self.n):
            self.upcoming[j] += len(keys[j])
            self._assign[j] = (numbers[j], level_over)
        if level_over:
            self.frontier = list(self.upcoming)
            self.upcoming = [0] * self.n
            self.level += 1
        self.pending = 0
        return len(merged)

    def run(self, budget: Budget = Budget()) -> StateGraph:
        if self.closed:
            raise DistributedError("this search is closed")
        t0 = self._running_since = time.perf_counter()
        last_report = t0
        g = self.graph
        stop = ""
        complete = False
        while True:
            if not any(self.frontier):
                complete = True
                break
            if budget.max_states is not None and self.numbered + self.pending >= budget.max_states:
                stop = f"state budget of {budget.max_states} reached"
                break
            remaining = None
            if budget.max_seconds is not None:
                remaining = budget.max_seconds - self.elapsed - (time.perf_counter() - t0)
                if remaining <= 0:
                    stop = f"time budget of {budget.max_seconds:g} s reached"
                    break
            if budget.max_memory_mb is not None and current_rss_mb() > budget.max_memory_mb:
                stop = f"memory budget of {budget.max_memory_mb:g} MiB reached (driver)"
                break
            want = all(f <= self.batch for f in self.frontier)
            exp = [self._submit(_w_expand, j, self.run_id, self._assign[j], self.batch, remaining,
                                budget.max_memory_mb) for j in range(self.n)]
            self._assign = [None] * self.n
            if self.n <= SPLIT_ABOVE:
                # few workers: each receives the others' whole output and reads its batch (one hop less)
                parts = None
                recv = [self._submit(_w_receive, k, self.run_id, exp[k], exp, want, k) for k in range(self.n)]
            else:
                # many: each output is split where it was made, and each batch goes to its owner alone
                parts = [[self.client.submit(operator.getitem, exp[j], k, workers=[self.workers[j]],
                                             allow_other_workers=False, pure=False) for k in range(self.n + 1)]
                         for j in range(self.n)]
                recv = [self._submit(_w_receive, k, self.run_id, parts[k][self.n],
                                     [parts[j][k] for j in range(self.n)], want, None) for k in range(self.n)]
            res = self._gather(recv)
            del exp, parts, recv
            self.frontier = [r["frontier"] for r in res]
            self.pending = sum(r["pending"] for r in res)
            self.transitions = sum(r["edges"] for r in res)
            self.worker_memory = [r["memory_mb"] for r in res]
            self.worker_seconds += sum(r["busy"] for r in res)
            self.rounds += 1
            stopped = {r["stopped"] for r in res} - {""}
            level_over = not any(self.frontier)
            if level_over or stopped:
                keys = [r["keys"] for r in res] if want else \
                    self._gather([self._submit(_w_keys, j, self.run_id) for j in range(self.n)])
                self._number(keys, level_over)
            elif want:   # keys were reported: number them now (the level goes on)
                self._number([r["keys"] for r in res], False)
            if "time" in stopped:
                stop = f"time budget of {budget.max_seconds:g} s reached"
                break
            if "memory" in stopped:
                stop = f"memory budget of {budget.max_memory_mb:g} MiB reached (a worker)"
                break
            now = time.perf_counter()
            if self.on_progress is not None and now - last_report > 0.25:
                last_report = now
                self.on_progress(self.stats())
        if self.pending:   # number what was discovered before the stop (it joins the graph unexpanded)
            keys = self._gather([self._submit(_w_keys, j, self.run_id) for j in range(self.n)])
            self._number(keys, False)
        self._collect()
        g.complete = complete
        g.stop_reason = "" if complete else stop
        self.elapsed += time.perf_counter() - t0
        self._running_since = None
        return g

    def _collect(self) -> None:
        """Gather what the workers found since the last collect into the driver's graph."""
        chunks = self._gather([self._submit(_w_collect, j, self.run_id, self._assign[j]) for j in range(self.n)])
        self._assign = [None] * self.n
        g = self.graph
        states = sorted(s for c in chunks for s in c["states"] if s[0] != 0)
        srcs, poss, dsts, labs, grps, progs, steps = [], [], [], [], [], [], []
        for c in chunks:
            lmap = np.array([g.labels(x) for x in c["labels"]] or [0], dtype=np.int64)
            gmap = np.array([g.groups(x) for x in c["groups"]] or [0], dtype=np.int64)
            srcs.append(np.frombuffer(c["src"], dtype=np.int64))
            poss.append(np.frombuffer(c["pos"], dtype=np.int64))
            dsts.append(np.frombuffer(c["dst"], dtype=np.int64))
            labs.append(lmap[np.frombuffer(c["label"], dtype=np.int64)])
            grps.append(gmap[np.frombuffer(c["group"], dtype=np.int64)])
            progs.append(np.frombuffer(c["progress"], dtype=np.int8))
            steps.extend(c["steps"])
        src = np.concatenate(srcs)
        pos = np.concatenate(poss)
        order = np.lexsort((pos, src))
        base = g.n_edges
        src, pos = src[order], pos[order]
        g.src.frombytes(src.astype(np.int64).tobytes())
        g.dst.frombytes(np.concatenate(dsts)[order].astype(np.int64).tobytes())
        g.label.frombytes(np.concatenate(labs)[order].astype(np.dtype(g.label.typecode)).tobytes())
        g.group.frombytes(np.concatenate(grps)[order].astype(np.dtype(g.group.typecode)).tobytes())
        g.progress.frombytes(np.concatenate(progs)[order].astype(np.int8).tobytes())
        self.step_blobs.extend(steps[i] for i in order.tolist())
        # each new state's parent edge: (parent, position) among this chunk's edges, sorted alike
        if states:
            width = int(pos.max()) + 2 if len(pos) else 1
            combined = src * width + pos
            for gnum, parent, ppos, blob in states:
                if gnum != g.n_states:   # pragma: no cover - numbering is contiguous by construction
                    raise DistributedError(f"state {gnum} gathered out of order (expected {g.n_states})")
                i = int(np.searchsorted(combined, parent * width + ppos))
                if i >= len(combined) or combined[i] != parent * width + ppos:   # pragma: no cover
                    raise DistributedError(f"the edge that discovered state {gnum} was not gathered")
                g.add_state(parent, base + i, g.depth[parent] + 1)
                self.blobs.append(blob)
        for c in chunks:
            for s in np.frombuffer(c["expanded"], dtype=np.int64).tolist():
                g.expanded[s] = 1

    def stats(self) -> dict:
        running = self._running_since
        el = self.elapsed + (time.perf_counter() - running if running is not None else 0.0) + 1e-9
        states = self.numbered + self.pending
        return {"states": states, "transitions": self.transitions, "frontier": sum(self.frontier) + self.pending,
                "seconds": el, "states_per_s": states / el,
                "memory_mb": max([current_rss_mb(), *self.worker_memory]), "workers": self.n,
                "worker_seconds": self.worker_seconds, "rounds": self.rounds}


# ====================================================================== a swarm's members as tasks


class _Seeded:
    """A system whose initial state is the one given (the driver's, read back in a worker), all
    else delegated."""

    def __init__(self, system, initial):
        self._system = system
        self._initial = initial

    def initial(self):
        return self._initial

    def __getattr__(self, name):
        return getattr(self._system, name)


def swarm_member(factory, seed: bytes, index: int, order: str, max_states: Optional[int],
                 max_seconds: Optional[float], max_memory_mb: Optional[float], visited: str) -> dict:
    """One member of a swarm, run in a worker: the search of ``search.Explorer`` from the driver's
    initial state (``seed``), its successors in the random order of seed ``index``; returns its graph,
    its states and its steps as bytes (read back on the driver by :class:`SwarmResult`)."""
    from .search import Explorer

    def go() -> dict:
        system = _system(factory)
        codec = codec_for(system, index + 1)
        ex = Explorer(_Seeded(system, codec.context(seed)), order, None, visited)
        ex.shuffle(index)
        g = ex.run(Budget(max_states=max_states, max_seconds=max_seconds, max_memory_mb=max_memory_mb))
        return {"parent": g.parent.tobytes(), "parent_edge": g.parent_edge.tobytes(), "depth": g.depth.tobytes(),
                "expanded": g.expanded.tobytes(), "src": g.src.tobytes(), "dst": g.dst.tobytes(),
                "label": g.label.tobytes(), "group": g.group.tobytes(), "progress": g.progress.tobytes(),
                "labels": list(g.labels.names), "groups": list(g.groups.names),
                "complete": bool(g.complete), "stop_reason": g.stop_reason,
                "omission": ex.omission_probability(),
                "states": [b"" if i == 0 else codec.state(ex.states[i]) for i in range(len(ex.states))],
                "steps": [codec.step(s) for s in ex.steps]}
    return _in_big_stack(go)


class SwarmResult:
    """A swarm member's search, read back on the driver: the graph, states and steps as an explorer
    of this process has them (``states[0]`` is the driver's own initial state)."""

    def __init__(self, system, codec, initial, out: dict):
        self.system = system
        self.codec = codec
        self.initial = initial
        g = self.graph = StateGraph()
        for name in ("parent", "parent_edge", "depth", "expanded", "src", "dst", "label", "group", "progress"):
            getattr(g, name).frombytes(out[name])
        for x in out["labels"]:
            g.labels(x)
        for x in out["groups"]:
            g.groups(x)
        g.complete = out["complete"]
        g.stop_reason = out["stop_reason"]
        self.blobs = out["states"]
        self.step_blobs = out["steps"]
        self.omission = out["omission"]
        self.states = ShippedStates(self)
        self.steps = ShippedSteps(self)
        g.describe_state = lambda i: system.describe(self.states[i])
        g.describe_edge = lambda e: system.describe_step(self.steps[e])
        g.describe_steps = lambda edges: describe_path(self, edges)

    def omission_probability(self) -> float:
        return self.omission
