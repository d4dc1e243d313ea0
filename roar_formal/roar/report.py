"""The ROAR-level facts of a counterexample: what each step changed, and the state it ends in.

A robotics engineer reads a deadlock as agents waiting for each other, not as CLF
facts; this module decodes a state of the compiled model into a per-agent table
(variables, live requests and their states, blocked activities) and a wait-for
graph between agents, whose cycle (networkx) names who waits for whom.
"""

from __future__ import annotations

import re
from typing import Optional

from ..clf.terms import Const, Root
from .compile import CompiledModel
from .run import STATE_NAMES, format_value, value_of

_QUALIFIED = re.compile(r"\b([A-Za-z_][A-Za-z0-9_]*)::([A-Za-z_][A-Za-z0-9_]*)")


def _h(t) -> Optional[str]:
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None


def step_changes(model: CompiledModel, step) -> list[dict]:
    """The variables a step changed, old -> new, read from the ``contains`` facts it swapped
    (within one step the fresh names agree, so no replay is needed)."""
    old = {_h(f.args[0]): f.args[1] for _m, f in step.consumed if _h(f) == "contains"}
    out = []
    for _m, f in step.produced:
        if _h(f) != "contains":
            continue
        cell = _h(f.args[0])
        if cell in old and cell in model.cells:
            a, b = format_value(value_of(old[cell])), format_value(value_of(f.args[1]))
            if a != b:
                agent, var = model.cells[cell]
                out.append({"agent": agent, "var": f"{agent}::{var}", "old": a, "new": b})
    return out


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
    for f in by.get("contains", ()):
        cell = _h(f.args[0])
        if cell in model.cells:
            agent, var = model.cells[cell]
            table.setdefault(agent, {"variables": {}, "requests": [], "activities": []})
            table[agent]["variables"][var] = format_value(value_of(f.args[1]))
    by_text = {}
    for lab, info in req_info.items():
        by_text.setdefault(info, []).append(lab)

    def label(r, agent, text) -> str:
        if r in labels:
            return labels[r]
        cands = by_text.get((agent, text), [])
        return cands[0] if len(cands) == 1 else "R?"

    states = {f.args[0]: STATE_NAMES.get(_h(f.args[1]), _h(f.args[1])) for f in by.get("rs", ())}
    reqs = {}
    for f in by.get("rq", ()):
        agent = model.agents.get(_h(f.args[1]), "?")
        text = model.csts.get(_h(f.args[2]), ("?", "?"))[1]
        reqs[f.args[0]] = {"request": label(f.args[0], agent, text), "agent": agent, "constraint": text,
                           "state": states.get(f.args[0], "?")}
    for r in reqs.values():
        table.setdefault(r["agent"], {"variables": {}, "requests": [], "activities": []})["requests"].append(
            {k: r[k] for k in ("request", "constraint", "state")})
    acts = {f.args[0]: f for f in by.get("act", ())}
    edges = []
    for f in by.get("ctl", ()):
        inst, mode = f.args[0], f.args[1]
        a = acts.get(inst)
        agent, task, recipe = model.recipes.get(_h(a.args[3]), ("?", "?", "?")) if a is not None else ("?", "?", "?")
        handles = reqs.get(a.args[1], {}).get("request") if a is not None else None
        act = {"task": task, "recipe": recipe, "request": handles, "status": "running"}
        m = _h(mode)
        if m == "m_make" and mode.args[0] in reqs:
            r = reqs[mode.args[0]]
            act.update(status="waiting for a make", waits_for=[r["agent"]], on=r["request"],
                       text=f"make {r['request']} ({r['constraint']}) handled by {r['agent']}, {r['state']}")
            edges.append({"from": agent, "to": r["agent"], "request": r["request"],
                          "why": f"{task}.{recipe} waits for {r['request']} ({r['constraint']})"})
        elif m == "m_block":
            code = f.args[2]
            site = model.sites.get(_h(code.args[0])) if code.args else None
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
