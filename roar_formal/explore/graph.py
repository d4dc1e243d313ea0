"""The explored state graph, shared by every search backend and every property.

States are numbered in discovery order (breadth-first by default, so the
parent pointers give shortest paths). Edges are stored column-wise in growable
arrays (source, target, label, fairness group, progress flag) so graphs of
millions of transitions stay compact; properties read them as numpy arrays.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np


class Interner:
    """Small string table: labels and fairness groups become ints."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.ids: dict[str, int] = {}

    def __call__(self, name: str) -> int:
        i = self.ids.get(name)
        if i is None:
            i = self.ids[name] = len(self.names)
            self.names.append(name)
        return i


def _np(x, dtype) -> np.ndarray:
    if isinstance(x, np.ndarray):
        return x
    if len(x) == 0:
        return np.zeros(0, dtype=dtype)
    return np.frombuffer(x, dtype=np.dtype(x.typecode)).astype(dtype, copy=False)


@dataclass
class StateGraph:
    """What a search found: states, transitions, and how each state was first reached."""

    parent: array = field(default_factory=lambda: array("q"))  # -1 for the initial state
    parent_edge: array = field(default_factory=lambda: array("q"))  # edge index, -1 for the initial state
    depth: array = field(default_factory=lambda: array("l"))
    expanded: array = field(default_factory=lambda: array("b"))  # 1 once successors are recorded
    src: array = field(default_factory=lambda: array("q"))
    dst: array = field(default_factory=lambda: array("q"))
    label: array = field(default_factory=lambda: array("l"))
    group: array = field(default_factory=lambda: array("l"))
    progress: array = field(default_factory=lambda: array("b"))
    labels: Interner = field(default_factory=Interner)
    groups: Interner = field(default_factory=Interner)
    # groups enabled at a state by steps a reduced expansion left out: state id -> group ids
    # (weak fairness reads every enabled group, expanded or not)
    hidden_enabled: dict = field(default_factory=dict)
    # bitstate search: per state, its transitions into states the bit array took as visited; they are
    # counted (a state with some is not quiescent) but not recorded, as their targets have no id
    unrecorded: Optional[dict] = None
    complete: bool = False  # every reachable state was expanded
    stop_reason: str = ""
    describe_state: Optional[Callable[[int], list[str]]] = None  # state id -> printable lines
    describe_edge: Optional[Callable[[int], str]] = None  # edge index -> printable step
    # a path's edges -> its steps printed as one run takes them (see search.path_steps); None:
    # each edge's step as recorded (describe_edge)
    describe_steps: Optional[Callable[[list], list]] = None

    @property
    def n_states(self) -> int:
        return len(self.parent)

    @property
    def n_edges(self) -> int:
        return len(self.src)

    def add_state(self, parent: int, edge: int, depth: int) -> int:
        self.parent.append(parent)
        self.parent_edge.append(edge)
        self.depth.append(depth)
        self.expanded.append(0)
        return len(self.parent) - 1

    def add_edge(self, s: int, t: int, label: str, group: str, progress: bool) -> int:
        self.src.append(s)
        self.dst.append(t)
        self.label.append(self.labels(label))
        self.group.append(self.groups(group))
        self.progress.append(1 if progress else 0)
        return len(self.src) - 1

    def add_enabled(self, s: int, groups) -> None:
        """Record groups enabled at ``s`` by steps that were not expanded."""
        ids = {self.groups(gname) for gname in groups}
        if ids:
            self.hidden_enabled.setdefault(s, set()).update(ids)

    def enabled_pairs(self, n_groups: int) -> np.ndarray:
        """``state * n_groups + group`` for every group enabled at an expanded state: by an
        edge, or by a step a reduced expansion left out."""
        a = self.arrays()
        pairs = a["src"] * n_groups + a["group"]
        if self.hidden_enabled:
            extra = [s * n_groups + gid for s, gids in self.hidden_enabled.items() for gid in gids]
            pairs = np.concatenate([pairs, np.asarray(extra, dtype=np.int64)])
        return np.unique(pairs)

    # ------------------------------------------------------------ views
    def arrays(self) -> dict[str, np.ndarray]:
        """Edge columns as numpy arrays (no copy where the storage already is one)."""
        return {
            "src": _np(self.src, np.int64),
            "dst": _np(self.dst, np.int64),
            "label": _np(self.label, np.int64),
            "group": _np(self.group, np.int64),
            "progress": _np(self.progress, np.int8).astype(bool),
        }

    def path_to(self, s: int) -> list[int]:
        """Edge indices of the discovery path from the initial state to ``s``."""
        edges = []
        while self.parent[s] >= 0:
            edges.append(self.parent_edge[s])
            s = self.parent[s]
        edges.reverse()
        return edges

    def out_degree(self) -> np.ndarray:
        deg = np.bincount(self.arrays()["src"], minlength=self.n_states)
        if self.unrecorded:
            for s, k in self.unrecorded.items():
                deg[s] += k
        return deg

    @property
    def n_unrecorded(self) -> int:
        """Transitions a bitstate search counted but did not record (0 for every other search)."""
        return sum(self.unrecorded.values()) if self.unrecorded else 0
