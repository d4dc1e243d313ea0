"""Counterexamples as people read them: one public place for the printed and the JSON form.

``roar-verify check``, ``check --json``, the charts and the testing API all read the
same :func:`counterexample_report`, so what a test asserts, what a CI log shows and
what a picture draws agree. For jobs on a ROAR spec the report is at the ROAR level
(per step the agent, its events and the variables it changed; the final state per
agent; at a deadlock the blocked activities and the wait-for cycle). The printed form
is a :class:`~roar_formal.lines.Lines` document: the command line shows it in colour,
the testing API as plain text.
"""

from __future__ import annotations

from typing import Optional

from ..lines import Lines
from ..roar.report import decode_state
from ..trace.render import KIND_STYLE
from ..explore.search import path_steps
from .results import counterexample_steps

__all__ = ["counterexample_report", "counterexample_lines", "replay_step_lines", "replay_state_lines",
           "replay_report", "run_report"]


def counterexample_report(res, prop: str) -> dict:
    """The counterexample of ``prop`` in job result ``res`` as plain data (JSON-ready).

    Keys: ``property``, ``shape`` (path or lasso), ``steps`` (each: ``step``, ``loop``,
    ``group``, ``rule``, ``agent``, ``events``, ``changes``), ``requests`` (label ->
    agent, constraint; ROAR only), ``final`` (per-agent table; ROAR only, else the facts),
    ``deadlock`` (blocked activities, wait-for edges and cycle; deadlocks on a spec only)."""
    v = res.verdicts[prop]
    cx = v.counterexample
    cache = getattr(res, "_cx_reports", None)
    if cache is None:
        cache = res._cx_reports = {}
    if prop in cache:
        return cache[prop]
    recs = counterexample_steps(res.graph, v, res)
    steps = []
    for i, r in enumerate(recs, 1):
        steps.append({"step": i, "loop": r["loop"], "group": r["group"], "rule": r["rule"], "agent": r["group"],
                      "events": [], "changes": []})
    out = {"property": prop, "shape": cx.kind, "steps": steps, "requests": {}, "final": None, "deadlock": None}
    roar = getattr(res, "roar", None)
    if roar is None:
        if res.graph.describe_state:
            out["final"] = {"facts": [x for x in res.graph.describe_state(cx.final_state) if not x.startswith("!")]}
        cache[prop] = out
        return out
    from ..roar.explore import path_narration
    from ..roar.report import decode_state, step_changes
    model, start, explorer = roar
    edges = list(cx.prefix) + list(cx.cycle)
    engine_steps = path_steps(explorer, edges)
    events, nar = path_narration(model, start, engine_steps)
    for ev in events:
        steps[ev.step - 1]["events"].append(ev.as_json())
    for s, st in zip(steps, engine_steps):
        s["changes"] = step_changes(model, st)
    out["requests"] = {lab: {"agent": a, "constraint": t} for lab, (a, t) in sorted(
        nar.req_info.items(), key=lambda kv: (len(kv[0]), kv[0]))}
    final = decode_state(model, explorer.states[cx.final_state], nar.labels, nar.req_info)
    out["final"] = final["agents"]
    if cx.kind == "path" and prop == "deadlock":
        blocked = [{"agent": a, **act} for a, row in final["agents"].items() for act in row["activities"]]
        out["deadlock"] = {"blocked": blocked, "wait_for": final["wait_for"], "cycle": final["cycle"]}
    cache[prop] = out
    return out


def counterexample_lines(res, prop: str, verbose: bool = False) -> Lines:
    """The counterexample of ``prop`` as ``roar-verify check`` prints it (after the verdict line)."""
    out = Lines()
    v = res.verdicts[prop]
    rep = counterexample_report(res, prop)
    is_roar = getattr(res, "roar", None) is not None
    steps = rep["steps"]
    raw = counterexample_steps(res.graph, v, res) if verbose and not is_roar else None
    for i, s in enumerate(steps, 1):
        if s["loop"] and (i == 1 or not steps[i - 2]["loop"]):
            out.add("    -- cycle (repeats forever) --", style="yellow", wrap=True)
        if not is_roar:
            line = f"    {i:>3}. [{s['group']}] {s['rule']}"
            if verbose:
                r = raw[i - 1]
                line += f"  {', '.join(r.get('consumed', []))} -> {', '.join(r.get('produced', []))}"
            out.add(line, wrap=True)
            continue
        rule = [(f"  ({s['rule']})", "dim")] if verbose else []
        shown = [ev for ev in s["events"] if ev["kind"] != "write"]
        for ev in shown:
            out.add(f"    {i:>3}. {ev['agent']:<12} {ev['text']}", *rule, wrap=True)
        for ch in s["changes"]:
            lead = f"    {i:>3}. {ch['agent']:<12}" if not shown else " " * 21
            out.add(f"{lead} {ch['var']}: {ch['old']} -> {ch['new']}", *rule, wrap=True)
        if verbose and not shown and not s["changes"]:
            out.add(f"    {i:>3}. ", (f"[{s['group']}] {s['rule']}", "dim"), wrap=True)
    if is_roar:
        out.extend(roar_final_lines(rep, v.counterexample.kind))
        robot = getattr(res, "robot", None)
        if robot is not None:   # where the robot is, and when
            node = robot.explorer.states[v.counterexample.final_state].node
            x, y, th = node.pose
            armed = f"; faults armed: {', '.join(sorted(node.armed))}" if node.armed else ""
            bad = node.bad[0] if prop == "robot-invariant" and node.bad else None
            if bad is not None and bad[2] < node.time:   # broken during the last step's advance
                bx, by, bth = bad[3]
                out.add(f"      robot    t = {bad[2]:.2f} s, at ({bx:.2f}, {by:.2f}), heading "
                        f"{bth * 57.29577951308232:.0f} deg: the invariant breaks here, during the last step, "
                        "which the robot ends", wrap=True)
                out.add(f"               at t = {node.time:.2f} s, at ({x:.2f}, {y:.2f}), heading "
                        f"{th * 57.29577951308232:.0f} deg{armed}", wrap=True)
            else:
                out.add(f"      robot    t = {node.time:.2f} s, at ({x:.2f}, {y:.2f}), heading "
                        f"{th * 57.29577951308232:.0f} deg{armed}", wrap=True)
    elif v.counterexample.kind == "path" and rep["final"] is not None:
        out.add("    final state: " + "; ".join(rep["final"]["facts"]), wrap=True)
    for pic in getattr(res, "pictures", {}).get(prop, ()):
        if isinstance(pic, str):
            out.add(f"    {pic}", style="yellow")
        else:
            out.add(f"    picture: {pic}", wrap=True)
    saved = getattr(res, "saved", {}).get(prop)
    if saved:
        out.add(f"    trace: {saved}  ({replay_command(res.job, saved)})", wrap=True)
    return out


def replay_command(job, trace) -> str:
    """The command that replays a job's trace: the model, and the functional-layer module when the
    job named one (replay checks the recorded sources, and finds only the one next to the spec)."""
    on_robot = f" --on-robot {job.robot.scenario}" if getattr(job, "robot", None) is not None else ""
    functional = f" --functional {job.functional}" if job.is_roar and getattr(job, "functional", None) else ""
    return f"roar-verify replay {trace} --model {job.spec if job.is_roar else job.model}{functional}{on_robot}"


def roar_final_lines(rep: dict, shape: str, head: Optional[str] = None) -> Lines:
    """The final state as a per-agent table, then the deadlock's wait-for cycle."""
    out = Lines()
    head = head or ("final state" if shape == "path" else "state where the cycle starts")
    out.add(f"    {head}:", wrap=True)
    rows = rep["final"]
    width = max([len(a) for a in rows] + [5])
    for agent, row in rows.items():
        lines = []
        vs = ", ".join(f"{k} = {val}" for k, val in sorted(row["variables"].items()))
        lines.append(f"variables: {vs or '-'}")
        for r in row["requests"]:
            lines.append(f"request {r['request']} {r['constraint']}: {r['state']}")
        for a in row["activities"]:
            handles = f" (for {a['request']})" if a.get("request") else ""
            what = f": {a['text']}" if a.get("text") else ""
            lines.append(f"{a['status']}: {a['task']}.{a['recipe']}{handles}{what}")
        for k, text in enumerate(lines):
            name = agent if k == 0 else ""
            out.add(f"      {name:<{width}}  {text}")
    dl = rep.get("deadlock")
    if dl is None:
        return out
    if dl["cycle"]:
        cyc = dl["cycle"]
        out.add(f"    wait-for cycle: {' -> '.join(cyc + [cyc[0]])}", style="red", wrap=True)
        pairs = list(zip(cyc, cyc[1:] + cyc[:1]))
        for a, b in pairs:
            why = "; ".join(e["why"] for e in dl["wait_for"] if e["from"] == a and e["to"] == b)
            if a == b:   # a cycle of one: a wait on the agent's own variables, which nothing else will change
                out.add(f"      {a} waits for its own variables: {why}")
            else:
                out.add(f"      {a} waits for {b}: {why}")
    elif dl.get("wait_for"):
        edges = dl["wait_for"]
        out.add("    no wait-for cycle between agents: the blocked activities wait for agents that have nothing "
                "left to do", style="red", wrap=True)
        for e in edges:
            out.add(f"      {e['from']} waits for {e['to']}: {e['why']}", wrap=True)
        idle = [b for b in dict.fromkeys(e["to"] for e in edges) if not any(e["from"] == b for e in edges)]
        for b in idle:
            if rows.get(b, {}).get("activities"):
                out.add(f"      {b} is blocked itself, on no agent (its activities are above)", wrap=True)
            else:
                out.add(f"      {b} runs nothing that could change it (no live request: none was sent, or it "
                        f"was aborted or ended)", wrap=True)
    else:
        out.add("    no wait-for cycle between agents: the blocked activities wait for no agent "
                "(a request no recipe handles, for instance)", style="red", wrap=True)
    return out


def wait_for_pairs(rep: dict) -> list[tuple[str, str]]:
    """The edges of the deadlock's wait-for cycle, in order (for charts)."""
    dl = rep.get("deadlock") or {}
    cyc = dl.get("cycle") or []
    return list(zip(cyc, cyc[1:] + cyc[:1]))


def chart_title(res, prop: str) -> str:
    """A line naming the job, the property and the verdict, for pictures."""
    v = res.verdicts[prop]
    return f"{res.job.name}: {prop} {v.status}"


def replay_step_lines(rep, i: int, verbose: bool = False, always: bool = False) -> Lines:
    """Step ``i`` (from 1) of a replayed trace (:class:`~roar_formal.verify.replay.TraceReplay`):
    for a spec, the agent, its ROAR events and the variables it changed (the CLF step with
    ``verbose``; a step with no ROAR event prints nothing unless ``always``); for a ``.clf``
    model, the rule and the facts it consumed and produced."""
    out = Lines()
    s = rep.steps[i - 1]
    rec = rep.result.records[i - 1]
    if s["loop"] and (i == 1 or not rep.steps[i - 2]["loop"]):
        out.add("    -- cycle (repeats forever) --", style="yellow")
    clf = f"{', '.join(rec['consumed'])} -> {', '.join(rec['produced'])}"
    if rep.compiled is None:
        out.add((f"  {i:>4}. ", "bold"), (f"[{s['group']}] ", "dim"), f"{s['rule']}", f"  {clf}")   # as check prints it
        return out
    shown = [ev for ev in s["events"] if ev["kind"] != "write"]
    rule = [(f"  ({s['rule']})", "dim")] if verbose else []
    for ev in shown:
        out.add(f"  {i:>4}. {ev['agent']:<12} ", (ev["text"], KIND_STYLE.get(ev["kind"], "")), *rule)
    for ch in s["changes"]:
        lead = f"  {i:>4}. {ch['agent']:<12}" if not shown else " " * 19
        out.add(f"{lead} {ch['var']}: {ch['old']} -> {ch['new']}", *rule)
    if (verbose or always) and not shown and not s["changes"]:
        out.add(f"  {i:>4}. {s['group']:<12} ", (f"({s['rule']}: no ROAR event)", "dim"))
    if verbose:
        out.add((f"          {clf}", "dim"))
    return out


def replay_state_lines(rep, i: int, agent: Optional[str] = None) -> Lines:
    """The state after step ``i`` of a replayed trace (0: the start): per agent for a spec (only
    ``agent``'s row when given), the facts for a ``.clf`` model; at the end of a deadlock, the
    wait-for cycle."""
    table = rep.state_table(i)
    if rep.compiled is None:
        return Lines().add("    state: " + "; ".join(table["facts"]))
    if agent is not None:
        if agent not in table:
            return Lines().add(f"    no agent {agent!r}; the agents are: {', '.join(table)}", style="red")
        table = {agent: table[agent]}
    doc = {"final": table, "deadlock": None}
    last = i == len(rep.steps)
    if last and agent is None and rep.header.get("property") == "deadlock":
        final = decode_state(rep.compiled, rep.result.states[i], *rep._labels)
        blocked = [{"agent": a, **act} for a, row in final["agents"].items() for act in row["activities"]]
        doc["deadlock"] = {"blocked": blocked, "wait_for": final["wait_for"], "cycle": final["cycle"]}
    return roar_final_lines(doc, "path" if last else "step", head=None if last else f"state after step {i}")


def replay_report(rep) -> dict:
    """A replayed trace (:class:`~roar_formal.verify.replay.TraceReplay`) in the form of
    :func:`counterexample_report`, for charts."""
    n = len(rep.steps)
    out = {"property": rep.header.get("property"), "shape": rep.header.get("shape", "path"), "steps": rep.steps,
           "requests": rep.requests, "final": None, "deadlock": None}
    table = rep.state_table(n)
    out["final"] = table
    if rep.compiled is not None and rep.header.get("property") == "deadlock" and rep.confirmed:
        final = decode_state(rep.compiled, rep.result.states[n], *rep._labels)
        blocked = [{"agent": a, **act} for a, row in final["agents"].items() for act in row["activities"]]
        out["deadlock"] = {"blocked": blocked, "wait_for": final["wait_for"], "cycle": final["cycle"]}
    return out


def run_report(res) -> dict:
    """A run (:class:`~roar_formal.roar.run.RunResult`) in the form of :func:`counterexample_report`:
    its ROAR events per CLF step, the variables each step wrote, the requests it sent."""
    steps: dict[int, dict] = {}
    for e in res.events:
        j = e.as_json()
        s = steps.setdefault(e.step, {"step": e.step, "loop": False, "group": j.get("agent", ""), "rule": "",
                                      "events": [], "changes": []})
        s["events"].append(j)
        if j["kind"] == "write":
            agent, _, var = str(j.get("var", "")).partition("::")
            s["changes"].append({"agent": agent or j.get("agent", ""), "var": var or j.get("var", ""),
                                 "old": None, "new": j.get("value")})
    requests = {}
    for label, text in res.requests.items():
        agent, _, constraint = text.partition(": ")
        requests[label] = {"agent": agent, "constraint": constraint}
    agents = {ag.name: {} for ag in res.model.spec.agents}
    return {"property": None, "shape": "path", "steps": [steps[k] for k in sorted(steps)], "requests": requests,
            "final": agents, "deadlock": None}
