"""Deadlock and livelock over an explored :class:`StateGraph`, with counterexamples.

Deadlock: a quiescent state (no enabled step) that is not an accepted final
state. In breadth-first order the first such state has a shortest path.

Livelock: a reachable cycle with no progress event that is fair. Weak
fairness is per group (a process: a philosopher, an agent): a cycle is unfair
when some group is enabled in every state of it and never moves on it. In a
strongly connected component C of the non-progress graph, the cycle through
every edge of C is fair iff every group enabled in all states of C has an
edge inside C; and if that fails no cycle inside C can be fair (such a group
is enabled all along any of them). So one SCC computation decides it. Only
fully expanded states are used: a fair cycle among them is a fair cycle of
the whole system, so a livelock found in a partial graph is real, while
"no livelock" needs the complete graph.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from .graph import StateGraph


@dataclass
class Counterexample:
    """A path (deadlock, safety) or a lasso (livelock): edge indices into the graph."""

    kind: str  # 'path' or 'lasso'
    prefix: list[int]
    cycle: list[int] = field(default_factory=list)
    final_state: int = 0

    def length(self) -> int:
        return len(self.prefix) + len(self.cycle)


@dataclass
class Verdict:
    prop: str
    status: str  # 'holds', 'violated' or 'incomplete'
    message: str
    counterexample: Optional[Counterexample] = None
    details: dict = field(default_factory=dict)

    @property
    def violated(self) -> bool:
        return self.status == "violated"


def incomplete_note(prop: str, g: StateGraph, what: Optional[str] = None) -> Verdict:
    """No violation in a partial graph: what was looked for (``what``, default the property's
    name) said as the complete verdict would say it, with why the search stopped."""
    if what is None:
        what = prop if prop in ("deadlock", "livelock") else f"violation of {prop}"   # not "no invariant"
    return Verdict(prop, "incomplete",
                   f"no {what} in {g.n_states:,} states; search incomplete ({g.stop_reason})")


# ---------------------------------------------------------------- state properties


def check_states(g: StateGraph, prop: str, bad: Callable[[int], Optional[str]]) -> Verdict:
    """A safety property read on states: the shortest path to a state ``bad`` describes
    (it returns the reason, or None for a good state)."""
    for s in range(g.n_states):  # ids follow discovery order: breadth-first depth is non-decreasing
        why = bad(s)
        if why:
            cx = Counterexample("path", g.path_to(s), final_state=s)
            return Verdict(prop, "violated", f"{why} (reached in {len(cx.prefix)} steps)", cx, {"reason": why})
    if not g.complete:
        return incomplete_note(prop, g)
    return Verdict(prop, "holds", f"no violation in {g.n_states:,} states")


# ---------------------------------------------------------------- deadlock


def check_deadlock(g: StateGraph, accept: Optional[Callable[[int], bool]] = None) -> Verdict:
    """The shortest path to a quiescent state that ``accept`` does not accept."""
    outdeg = g.out_degree()  # a graph that stores its edges by source knows them without a pass
    expanded = np.asarray(g.expanded, dtype=bool)
    quiescent = np.flatnonzero(expanded & (outdeg == 0))
    n_final = 0
    for s in quiescent:  # in discovery order: BFS depth is non-decreasing
        s = int(s)
        if accept is not None and accept(s):
            n_final += 1
            continue
        cx = Counterexample("path", g.path_to(s), final_state=s)
        n_dead = sum(1 for q in quiescent if accept is None or not accept(int(q)))
        return Verdict("deadlock", "violated",
                       f"deadlock reachable in {len(cx.prefix)} steps ({n_dead} deadlock state"
                       f"{'s' if n_dead != 1 else ''} among {g.n_states:,} states)",
                       cx, {"deadlock_states": n_dead, "final_states": len(quiescent) - n_dead})
    if not g.complete:
        return incomplete_note("deadlock", g)
    return Verdict("deadlock", "holds", f"no deadlock in {g.n_states:,} states ({n_final} accepted final)",
                   details={"final_states": n_final})


# ---------------------------------------------------------------- livelock


def strongly_connected(n: int, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Strongly connected component label of each node."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    m = csr_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n))
    _, labels = connected_components(m, directed=True, connection="strong")
    return labels


def fair_components(g: StateGraph, comp, base, cand_edges, src, grp):
    """The weakly fair components among those holding ``cand_edges`` (edges inside a component):
    every fairness group enabled in all of a component's ``base`` states must move on one of its
    edges. Returns (member states, fair component ids, component of each candidate edge, the
    groups always enabled per component). Vectorised over all components at once."""
    n_groups = max(1, len(g.groups.names))
    ci = comp[src[cand_edges]]
    cand_comps = np.unique(ci)
    is_cand = np.zeros(comp.max() + 1, dtype=bool)
    is_cand[cand_comps] = True
    member = base & is_cand[comp]
    size = np.bincount(comp[member], minlength=len(is_cand))
    pairs = g.enabled_pairs(n_groups)
    pairs = pairs[member[pairs // n_groups]]
    pc = comp[pairs // n_groups]
    always = np.bincount(pc * n_groups + pairs % n_groups, minlength=len(is_cand) * n_groups)
    always = always.reshape(len(is_cand), n_groups) == size[:, None]
    moving = np.zeros((len(is_cand), n_groups), dtype=bool)
    moving[ci, grp[cand_edges]] = True
    starving = (always & ~moving).any(axis=1)
    return member, cand_comps[~starving[cand_comps]], ci, always


def strong_fair_components(g: StateGraph, inner: np.ndarray, src, dst, grp, allowed: np.ndarray):
    """The strongly fair components of the subgraph of ``inner`` edges (Emerson and Lei): in a
    component, every fairness group enabled at *any* of its states must move on one of its
    edges. States that enable a group which never moves in their component cannot be on a
    strongly fair cycle: they are removed and the components recomputed, until a fair one is
    found or none is left. Same return shape as :func:`fair_components`, with the groups
    enabled anywhere in each component as the last item."""
    n = g.n_states
    n_groups = max(1, len(g.groups.names))
    allowed = allowed.copy()
    pairs = g.enabled_pairs(n_groups)
    pstate, pgroup = pairs // n_groups, pairs % n_groups
    while True:
        live = inner & allowed[src] & allowed[np.minimum(dst, n - 1)] & (dst < n)
        isrc, idst = src[live], dst[live]
        if len(isrc) == 0:
            return None
        comp = strongly_connected(n, isrc, idst)
        internal = comp[isrc] == comp[idst]
        cand_edges = np.flatnonzero(live)[internal]
        if len(cand_edges) == 0:
            return None
        ci = comp[src[cand_edges]]
        n_comp = int(comp.max()) + 1
        is_cand = np.zeros(n_comp, dtype=bool)
        is_cand[ci] = True
        member = allowed & is_cand[comp]
        here = member[pstate]
        enabled = np.zeros((n_comp, n_groups), dtype=bool)
        enabled[comp[pstate[here]], pgroup[here]] = True
        moving = np.zeros((n_comp, n_groups), dtype=bool)
        moving[ci, grp[cand_edges]] = True
        bad = enabled & ~moving
        cand_comps = np.unique(ci)
        fair = cand_comps[~bad[cand_comps].any(axis=1)]
        if len(fair):
            return member, fair, ci, enabled, comp, cand_edges
        drop = here & bad[comp[pstate], pgroup]
        allowed[pstate[drop]] = False


def check_livelock(g: StateGraph, strong: bool = False) -> Verdict:
    """A fair cycle without progress, as a lasso; none on a complete graph means none at all.
    Fairness is weak by default (a group enabled all along the cycle moves on it); ``strong``:
    a group enabled infinitely often moves infinitely often."""
    a = g.arrays()
    n = g.n_states
    expanded = np.asarray(g.expanded, dtype=bool)
    src, dst, grp, prog = a["src"], a["dst"], a["group"], a["progress"]
    inner = ~prog & expanded[src] & (dst < n)
    inner &= expanded[np.minimum(dst, n - 1)]
    if strong:
        found = strong_fair_components(g, inner, src, dst, grp, expanded)
        if found is None:   # were there cycles without progress at all?
            isrc, idst = src[inner], dst[inner]
            comp = strongly_connected(n, isrc, idst) if len(isrc) else None
            cyclic = comp is not None and bool(np.any(comp[isrc] == comp[idst]))
            return _no_livelock(g, unfair=cyclic, strong=True)
        member, fair, ci, required, comp, cand_edges = found
    else:
        isrc, idst = src[inner], dst[inner]
        if len(isrc) == 0:
            return _no_livelock(g)
        comp = strongly_connected(n, isrc, idst)
        internal = comp[isrc] == comp[idst]
        cand_edges = np.flatnonzero(inner)[internal]
        if len(cand_edges) == 0:
            return _no_livelock(g)
        # Per candidate component: groups enabled in every member state (by an outgoing edge,
        # progress or not, or by a step a reduced expansion left out) must all move inside it.
        # Vectorised over all components at once.
        member, fair, ci, required = fair_components(g, comp, expanded, cand_edges, src, grp)
    if not len(fair):
        return _no_livelock(g, unfair=True, strong=strong)
    depth = np.asarray(g.depth, dtype=np.int64)
    # the fair component holding the shallowest state: shortest prefix
    fm = np.flatnonzero(member & np.isin(comp, fair))
    entry = int(fm[np.argmin(depth[fm])])
    c = comp[entry]
    edges_c = cand_edges[ci == c]
    cycle = cycle_tour(g, entry, edges_c, set(np.flatnonzero(required[c]).tolist()), src, dst, grp, strong)
    cx = Counterexample("lasso", g.path_to(entry), cycle, final_state=entry)
    names = sorted(g.groups.names[x] for x in set(grp[edges_c].tolist()))
    kind = "strongly fair" if strong else "fair"
    return Verdict("livelock", "violated",
                   f"{kind} livelock: a cycle of {len(cycle)} steps without progress, reached in "
                   f"{len(cx.prefix)} steps (groups moving: {', '.join(names)})",
                   cx, {"cycle_states": int(np.sum(comp == c))})


def _no_livelock(g: StateGraph, unfair: bool = False, strong: bool = False) -> Verdict:
    kind = "strongly fair" if strong else "fair"
    if not g.complete:   # worded as the complete verdict is: a partial graph's unfair cycles are no livelock either
        return incomplete_note("livelock", g, f"{kind} livelock")
    extra = f" (cycles without progress exist but are all {'strongly ' if strong else ''}unfair)" if unfair else ""
    return Verdict("livelock", "holds", f"no {kind} livelock in {g.n_states:,} states{extra}",
                   details={"unfair_cycles": unfair, "fairness": "strong" if strong else "weak"})


def cycle_tour(g: StateGraph, entry: int, edges_c: np.ndarray, required: set, src, dst, grp,
               strong: bool = False) -> list[int]:
    """A fair cycle from ``entry`` inside the component: start from any cycle, then splice
    in detours until every group enabled all along it either moves or meets a state
    where it is disabled (terminates: each detour fixes one group for good). ``strong``:
    every group enabled at any state of the cycle must move (the component guarantees each
    such group has an edge in it)."""
    adj: dict[int, list[int]] = {}
    for e in edges_c.tolist():
        adj.setdefault(int(src[e]), []).append(e)

    def path(a: int, goal: Callable[[int], bool]) -> list[int]:
        """Shortest edge path from ``a`` whose last edge satisfies ``goal`` (at least one edge)."""
        prev: dict[int, int] = {}
        q = deque([a])
        seen = {a}
        while q:
            u = q.popleft()
            for e in adj.get(u, ()):
                if goal(e):
                    out = [e]
                    w = u
                    while w != a:
                        e2 = prev[w]
                        out.append(e2)
                        w = int(src[e2])
                    out.reverse()
                    return out
                v = int(dst[e])
                if v not in seen:
                    seen.add(v)
                    prev[v] = e
                    q.append(v)
        raise AssertionError("component is not strongly connected")

    # enabled groups of each member state (an outgoing edge, or a step a reduced expansion left out)
    members = set(adj)
    enabled: dict[int, set] = {m: set(g.hidden_enabled.get(m, ())) for m in members}
    for e in np.flatnonzero(np.isin(src, np.fromiter(members, dtype=np.int64))).tolist():
        enabled[int(src[e])].add(int(grp[e]))
    internal_groups = {int(grp[e]) for e in edges_c.tolist()}
    cycle = path(entry, lambda e: int(dst[e]) == entry)
    while True:
        states = [int(src[e]) for e in cycle]
        moving = {int(grp[e]) for e in cycle}
        if strong:
            always = set.union(*(enabled[x] for x in states))
        else:
            always = set.intersection(*(enabled[x] for x in states))
        starving = sorted(always - moving)
        if not starving:
            return cycle
        gsel = starving[0]
        if gsel in internal_groups:  # let it move
            seg = path(entry, lambda e: int(grp[e]) == gsel)
        else:  # visit a state where it is disabled
            seg = path(entry, lambda e: gsel not in enabled.get(int(dst[e]), ()))
        here = int(dst[seg[-1]])
        back = path(here, lambda e: int(dst[e]) == entry) if here != entry else []
        cycle = seg + back + cycle
