"""Livelock under weak and strong fairness, against a brute-force oracle on random graphs.

A fair non-progress run exists iff some set S of reachable states is strongly connected by
non-progress edges inside S and, for every process (fairness group), either one of its
edges lies inside S, or (weak) it is disabled at some state of S / (strong) it is enabled at
no state of S. The oracle tries every S; the explorer's check (SCCs, Emerson-Lei pruning for
strong fairness) must agree, and its lasso must itself be a fair cycle.
"""

from __future__ import annotations

from collections import deque
from itertools import combinations

from hypothesis import given, settings
from hypothesis import strategies as st

from roar_formal.explore.graph import StateGraph
from roar_formal.explore.properties import check_livelock

GROUPS = ("a", "b", "c")


def build(n: int, edges: list) -> tuple[StateGraph, list]:
    """The reachable part of a random graph as a complete StateGraph, states in BFS order."""
    out: dict[int, list] = {}
    for e in edges:
        out.setdefault(e[0], []).append(e)
    order, parent = [0], {0: None}
    q = deque([0])
    while q:
        u = q.popleft()
        for (s, t, g, p) in out.get(u, ()):
            if t not in parent:
                parent[t] = (s, t, g, p)
                order.append(t)
                q.append(t)
    sid = {v: i for i, v in enumerate(order)}
    g = StateGraph()
    depth = {0: 0}
    g.add_state(-1, -1, 0)
    kept = []
    tree_edge = {}
    for v in order[1:]:   # tree edges first, so that parents are known
        s, t, grp, p = parent[v]
        depth[v] = depth[s] + 1
        e = g.add_edge(sid[s], sid[t], f"{grp}{'+' if p else ''}", grp, p)
        tree_edge[v] = e
        kept.append((sid[s], sid[t], grp, p))
        g.add_state(sid[s], e, depth[v])
    for (s, t, grp, p) in edges:
        if s in sid and (s, t, grp, p) != parent.get(t):
            g.add_edge(sid[s], sid[t], f"{grp}{'+' if p else ''}", grp, p)
            kept.append((sid[s], sid[t], grp, p))
    for i in range(len(order)):
        g.expanded[i] = 1
    g.complete = True
    return g, kept


def oracle(n: int, edges: list, strong: bool) -> bool:
    """Is there a (weakly / strongly) fair cycle of non-progress edges?"""
    enabled = {s: set() for s in range(n)}
    for s, _t, grp, _p in edges:
        enabled[s].add(grp)
    for k in range(1, n + 1):
        for S in combinations(range(n), k):
            Sset = set(S)
            inner = [(s, t, grp) for s, t, grp, p in edges if not p and s in Sset and t in Sset]
            if not inner or not _strongly_connected(Sset, inner):
                continue
            moving = {grp for _s, _t, grp in inner}
            if strong:
                need = set().union(*(enabled[s] for s in S))
            else:
                need = set.intersection(*(enabled[s] for s in S))
            if need <= moving:
                return True
    return False


def _strongly_connected(S: set, inner: list) -> bool:
    adj: dict = {}
    radj: dict = {}
    for s, t, _g in inner:
        adj.setdefault(s, set()).add(t)
        radj.setdefault(t, set()).add(s)
    start = next(iter(S))
    for a in (adj, radj):
        seen, q = {start}, [start]
        while q:
            u = q.pop()
            for v in a.get(u, ()):
                if v not in seen:
                    seen.add(v)
                    q.append(v)
        if seen != S:
            return False
    return all(s in adj for s in S)


def graphs():
    return st.integers(1, 6).flatmap(lambda n: st.tuples(st.just(n), st.lists(
        st.tuples(st.integers(0, n - 1), st.integers(0, n - 1), st.sampled_from(GROUPS), st.booleans()),
        max_size=14, unique=True)))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(graphs(), st.booleans())
def test_livelock_verdicts_match_the_oracle(gr, strong):
    n, edges = gr
    g, kept = build(n, edges)
    v = check_livelock(g, strong=strong)
    assert v.violated == oracle(g.n_states, kept, strong), (kept, v.message)
    if v.violated:   # the lasso's cycle is itself a fair non-progress cycle
        a = g.arrays()
        cyc = v.counterexample.cycle
        src, dst, grp, prog = a["src"], a["dst"], a["group"], a["progress"]
        assert all(dst[x] == src[y] for x, y in zip(cyc, cyc[1:] + cyc[:1]))
        assert not prog[cyc].any()
        states = {int(src[x]) for x in cyc}
        en = [{int(grp[e]) for e in range(len(src)) if src[e] == s} for s in states]
        need = set().union(*en) if strong else set.intersection(*en)
        assert need <= {int(grp[x]) for x in cyc}


def test_a_process_enabled_only_now_and_then_is_starved_only_under_strong_fairness():
    """a cycles between s0 and s1; b (progress, leaving the cycle) is enabled at s0 only."""
    edges = [(0, 1, "a", False), (1, 0, "a", False), (0, 2, "b", True)]
    g, _ = build(3, edges)
    weak = check_livelock(g)
    assert weak.violated and weak.message.startswith("fair livelock")
    strong = check_livelock(g, strong=True)
    assert not strong.violated
    assert strong.message == "no strongly fair livelock in 3 states (cycles without progress exist but are all strongly unfair)"


def test_a_job_chooses_the_strength_of_fairness(tmp_path, roar_cli):
    (tmp_path / "m.clf").write_text(
        "st : type. s0 : st. s1 : st.\nat : st -> type. done : type.\n"
        "a01 : at s0 -o {at s1}.\na10 : at s1 -o {at s0}.\nb : at s0 -o {done}.\n#exec * at s0.\n")
    for strength, verdict in (("weak", "violated"), ("strong", "holds")):
        (tmp_path / f"{strength}.toml").write_text(
            f'check = ["livelock"]\n[livelock]\nprogress = ["b"]\nfairness = "rule"\nstrength = "{strength}"\n')
        (tmp_path / f"job_{strength}.toml").write_text(
            f'name = "{strength}"\nmodel = "m.clf"\nproperties = ["{strength}.toml"]\n'
            f'[expect]\nlivelock = "{verdict}"\n')
        code, out, _err = roar_cli("check", tmp_path / f"job_{strength}.toml", "--no-traces")
        assert code == 0, out
    (tmp_path / "bad.toml").write_text('check = ["livelock"]\n[livelock]\nstrength = "very"\n')
    (tmp_path / "job_bad.toml").write_text('name = "bad"\nmodel = "m.clf"\nproperties = ["bad.toml"]\n')
    code, _out, err = roar_cli("check", tmp_path / "job_bad.toml")
    assert code == 2 and "bad.toml:3:12: strength must be 'weak'" in err


# ------------------------------------------------------------------ eventually / leads-to


def eventually_oracle(n: int, edges: list, target: set, hit: set, strong: bool) -> bool:
    """Is 'eventually goal' violated from state 0, the goal being a ``target`` state or a step on
    one of the edges ``hit`` (indices): a run that never reaches it and ends, or closes a (weakly /
    strongly) fair cycle?"""
    if 0 in target:
        return False
    region, todo = {0}, [0]
    while todo:
        u = todo.pop()
        for i, (s, t, _g, _p) in enumerate(edges):
            if s == u and i not in hit and t not in target and t not in region:
                region.add(t)
                todo.append(t)
    if any(not any(s == u for s, _t, _g, _p in edges) for u in region):
        return True
    # a fair cycle inside the region: edges leaving it, or goal steps, cannot be inside S
    inner = [(s, t, g, i in hit or not (s in region and t in region)) for i, (s, t, g, _p) in enumerate(edges)]
    return oracle(n, inner, strong)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(graphs(), st.booleans(), st.sets(st.integers(0, 5), max_size=3), st.sets(st.integers(0, 13), max_size=4))
def test_eventually_verdicts_match_the_oracle(gr, strong, target_ids, hit_ids):
    """Goal states, goal steps (events), or both; weak and strong fairness."""
    import numpy as np
    from roar_formal.roar.props import check_eventually
    n, edges = gr
    g, kept = build(n, edges)
    target = {t for t in target_ids if t < g.n_states}
    hit = {i for i in hit_ids if i < len(kept)}
    tmask = np.zeros(g.n_states, dtype=bool)
    tmask[list(target)] = True
    emask = np.zeros(len(kept), dtype=bool)
    emask[list(hit)] = True
    seeds = np.zeros(g.n_states, dtype=bool)
    seeds[0] = True
    v = check_eventually(g, "p", tmask, seeds, lambda s: "ends", lambda s, k: "cycles", "holds", strong=strong,
                         target_edges=emask)
    assert v.violated == eventually_oracle(g.n_states, kept, target, hit, strong), (kept, target, hit, v.message)
    if v.violated:   # the run never reaches the goal; a cycle is fair
        cx = v.counterexample
        a = g.arrays()
        src, dst, grp = a["src"], a["dst"], a["group"]
        taken = list(cx.prefix) + list(cx.cycle or [])
        assert not emask[taken].any() and not tmask[[int(dst[e]) for e in taken]].any()
        if cx.kind == "lasso":
            states = {int(src[x]) for x in cx.cycle}
            en = [{int(grp[e]) for e in range(len(src)) if src[e] == s} for s in states]
            need = set().union(*en) if strong else set.intersection(*en)
            assert need <= {int(grp[x]) for x in cx.cycle}


def test_a_temporal_property_chooses_strong_fairness(tmp_path, roar_cli):
    """Per property, in the job's [temporal] table: a formula, or { formula, fairness }."""
    from repo import ROOT

    def job(props: str):
        (tmp_path / "p.toml").write_text(props)
        (tmp_path / "job.toml").write_text(
            f"name = \"demo\"\nspec = \"{ROOT / 'models' / 'demo_loco'}\"\n"
            "request = \"demo_loco::pos == demo_loco::goal where demo_loco::goal == 5\"\n"
            "properties = [\"p.toml\"]\n")
        return roar_cli("check", tmp_path / "job.toml", "--no-traces")
    code, out, err = job("[temporal]\n"
                         "arrives = \"eventually request R0 succeeded\"\n"
                         "arrives-strong = { formula = \"eventually request R0 succeeded\", fairness = \"strong\" }\n")
    assert code == 0, err
    assert "arrives: holds" in out and "under weak fairness per agent" in out
    assert "arrives-strong: holds" in out and "under strong fairness per agent" in out
    code, out, err = job("[temporal]\nx = { formula = \"eventually request R0 succeeded\", fairness = \"sometimes\" }\n")
    assert code == 2 and "p.toml:2:" in err and "fairness must be 'weak'" in err, err
