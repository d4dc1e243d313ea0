"""The ROAR-level facts of a counterexample: what each step changed, and the state it ends in.

A robotics engineer reads a deadlock as agents waiting for each other, not as CLF
facts; this module decodes a state of the compiled model into a per-agent table
(variables, live requests and their states, blocked activities) and a wait-for
graph between agents, whose cycle (networkx) names who waits for whom.
"""

from __future__ import annotations

import re

from ..clf.terms import Root
from . import vocabulary as V
from .compile import CompiledModel
from .run import STATE_NAMES, format_value, value_of

_QUALIFIED = re.compile(r"\b([A-Za-z_][A-Za-z0-9_]*)::([A-Za-z_][A-Za-z0-9_]*)")


_h = V.head_name


def step_changes(model: CompiledModel, step) -> list[dict]:
    """The variables a step changed, old -> new, read from the ``contains`` facts it swapped
    (within one step the fresh names agree, so no replay is needed)."""
    old = {_h(c.cell): c.value for c in (V.contains(f) for _m, f in step.consumed if _h(f) == V.CONTAINS)}
    out = []
    for _m, f in step.produced:
        if _h(f) != V.CONTAINS:
            continue
        c = V.contains(f)
        cell = _h(c.cell)
        if cell in old and cell in model.cells:
            a, b = format_value(value_of(old[cell])), format_value(value_of(c.value))
            if a != b:
                agent, var = model.cells[cell]
                out.append({"agent": agent, "var": f"{agent}::{var}", "old": a, "new": b})
    return out


def growing_variables(model: CompiledModel, graph, steps) -> list[str]:
    """The number variables that kept growing (or shrinking) as a search that ran out of budget
    went deeper, said with where their values first appeared: each of their last four values
    (the largest, or the smallest) first reached at a greater depth than the one before, the
    last within the deepest tenth of the search. Why: a counter that grows without bound (``set
    tries tries + 1`` with nothing bounding it) is the usual reason a state space never ends,
    and nothing else in an incomplete verdict points at it. ``steps`` are the transitions'
    steps by edge (engine steps, or the explorer's packed ones)."""
    from ..explore.system import PackedStep
    depth, src = graph.depth, graph.src
    first: dict = {}   # cell -> {value: the depth it was first produced at}
    for e in range(graph.n_edges):
        st = steps[e]
        produced = st[4 + st[3]:] if type(st) is PackedStep else st.produced
        d = None
        for _m, f in produced:
            if _h(f) != V.CONTAINS:
                continue
            c = V.contains(f)
            if _h(c.value) != "vnum":
                continue
            if d is None:
                d = depth[src[e]] + 1
            seen = first.setdefault(_h(c.cell), {})
            if c.value not in seen or seen[c.value] > d:
                seen[c.value] = d
    deepest = max(depth) if len(depth) else 0
    out = []
    for cell, seen in first.items():
        if cell not in model.cells or len(seen) < 4:
            continue
        vals = sorted((value_of(v), d) for v, d in seen.items())
        for how, run in (("growing", vals[-4:]), ("shrinking", vals[:4][::-1])):
            ds = [d for _v, d in run]
            if all(a < b for a, b in zip(ds, ds[1:])) and ds[-1] >= deepest - max(2, deepest // 10):
                agent, var = model.cells[cell]
                out.append(f"{agent}::{var} kept {how} as the search went deeper ("
                           + ", ".join(f"{format_value(v)} at depth {d}" for v, d in run) + f", of {deepest})")
                break
    return sorted(out)


def decode_state(model: CompiledModel, ctx, labels: dict, req_info: dict) -> dict:
    """A state as agents see it: per agent its variables, live requests and activities, and
    the wait-for edges between agents (a recipe blocked on a make/ensure waits for the agent
    handling that request; a wait waits for the agents whose variables it reads)."""
    facts = [f for _m, f, _n in ctx.facts() if type(f) is Root]
    by: dict = {}
    for f in facts:
        by.setdefault(_h(f), []).append(f)
    agents = sorted(set(model.agents.values()))
    table = {a: {"variables": {}, "requests": [], "activities": []} for a in agents}
    for c in map(V.contains, by.get(V.CONTAINS, ())):
        cell = _h(c.cell)
        if cell in model.cells:
            agent, var = model.cells[cell]
            table.setdefault(agent, {"variables": {}, "requests": [], "activities": []})
            table[agent]["variables"][var] = format_value(value_of(c.value))
    by_text = {}
    for lab, info in req_info.items():
        by_text.setdefault(info, []).append(lab)

    def label(r, agent, text) -> str:
        if r in labels:
            return labels[r]
        cands = by_text.get((agent, text), [])
        return cands[0] if len(cands) == 1 else "R?"

    states = {x.request: STATE_NAMES.get(_h(x.state), _h(x.state)) for x in map(V.rs, by.get(V.RS, ()))}
    reqs = {}
    for q in map(V.rq, by.get(V.RQ, ())):
        agent = model.agents.get(_h(q.agent), "?")
        text = model.csts.get(_h(q.cst), ("?", "?"))[1]
        reqs[q.request] = {"request": label(q.request, agent, text), "agent": agent, "constraint": text,
                           "state": states.get(q.request, "?")}
    for r in reqs.values():
        table.setdefault(r["agent"], {"variables": {}, "requests": [], "activities": []})["requests"].append(
            {k: r[k] for k in ("request", "constraint", "state")})
    acts = {a.inst: a for a in map(V.act, by.get(V.ACT, ()))}
    edges = []
    for c in map(V.ctl, by.get(V.CTL, ())):
        mode = c.mode
        a = acts.get(c.inst)
        agent, task, recipe = model.recipes.get(_h(a.recipe), ("?", "?", "?")) if a is not None else ("?", "?", "?")
        handles = reqs.get(a.request, {}).get("request") if a is not None else None
        act = {"task": task, "recipe": recipe, "request": handles, "status": "running"}
        m = _h(mode)
        if m == "m_make" and V.unwrap(mode) in reqs:
            r = reqs[V.unwrap(mode)]
            act.update(status="waiting for a make", waits_for=[r["agent"]], on=r["request"],
                       text=f"make {r['request']} ({r['constraint']}) handled by {r['agent']}, {r['state']}")
            edges.append({"from": agent, "to": r["agent"], "request": r["request"],
                          "why": f"{task}.{recipe} waits for {r['request']} ({r['constraint']})"})
        elif m == "m_block":
            code = c.code
            site = model.sites.get(_h(V.ccons(code).site)) if code.args else None
            text = site.text if site else "a wait"
            owners = sorted({x for x, _v in _QUALIFIED.findall(text) if x in table}) or [agent]
            act.update(status="blocked in a wait", waits_for=owners, on=None,
                       text=f"{text}: until a variable of {', '.join(owners)} changes")
            for o in owners:
                edges.append({"from": agent, "to": o, "request": None, "why": f"{task}.{recipe} waits in {text}"})
        elif m == "m_call":
            act.update(status="waiting for a primitive", text="a primitive call to return")
        table.setdefault(agent, {"variables": {}, "requests": [], "activities": []})["activities"].append(act)
    for row in table.values():
        row["requests"].sort(key=lambda r: (len(r["request"]), r["request"]))
        row["activities"].sort(key=lambda x: (x["task"], x["recipe"]))
    edges.sort(key=lambda e: (e["from"], e["to"], e["why"]))
    return {"agents": table, "wait_for": edges, "cycle": wait_for_cycle(edges)}


def wait_for_cycle(edges: list[dict]) -> list[str]:
    """The shortest cycle of the agents' wait-for graph (first by name), [] when there is none;
    an agent waiting for itself is a cycle of one."""
    import networkx as nx
    g = nx.DiGraph()
    g.add_edges_from((e["from"], e["to"]) for e in edges)
    best = None
    for c in nx.simple_cycles(g):
        i = c.index(min(c))
        c = c[i:] + c[:i]
        if best is None or (len(c), c) < (len(best), best):
            best = c
    return best or []
