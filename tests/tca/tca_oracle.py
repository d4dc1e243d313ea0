"""Independent oracles for the TCA trace checker: plain Python on the intervals, no Z3.

``sequencing_violations`` checks the sequential-achievement property pair by
pair. ``consistent`` decides whether some achievement intervals (and times
the trace has not reached) satisfy axioms 1-8 as ground difference
constraints, by Bellman-Ford with strictness carried as an infinitesimal.
"""

from __future__ import annotations

from fractions import Fraction
from itertools import product

EXECUTES = ("command", "monitor")


def messages_of(records: list[dict]) -> tuple[dict, list[tuple[str, str, str]], Fraction]:
    """Messages (id -> fields) and declarations from well-formed trace records."""
    msgs: dict[str, dict] = {}
    declared = []
    times = []
    for r in records:
        if "time" in r:
            times.append(Fraction(str(r["time"])))
        ev = r.get("event")
        if ev == "constraint_sent":
            msgs[r["msg"]] = {"kind": r["kind"], "parent": r.get("parent"), "sent": Fraction(str(r["time"]))}
        elif ev in ("started", "ended", "achieving_started", "achieving_ended"):
            field = {"started": "start", "ended": "end", "achieving_started": "ach_start",
                     "achieving_ended": "ach_end"}[ev]
            msgs[r["msg"]][field] = Fraction(str(r["time"]))
        elif ev in ("seq_ach", "precedes", "delay_planning"):
            declared.append((ev, r["m1"], r["m2"]))
    return msgs, declared, max(times, default=Fraction(0))


def subtree(msgs: dict, root: str) -> list[str]:
    out = [root]
    for m, f in msgs.items():
        here = f["parent"]
        while here is not None:
            if here == root:
                out.append(m)
                break
            here = msgs[here]["parent"]
    return out


def sequencing_violations(records: list[dict]) -> set[tuple[str, str]]:
    """Declared SeqAch(m1, m2) where some command/monitor under m1 does not end
    before (or when) one under m2 starts; a command not yet ended ends after all."""
    msgs, declared, _ = messages_of(records)
    bad = set()
    for relation, m1, m2 in declared:
        if relation != "seq_ach":
            continue
        firsts = [x for x in subtree(msgs, m1) if msgs[x]["kind"] in EXECUTES]
        seconds = [y for y in subtree(msgs, m2) if msgs[y]["kind"] in EXECUTES]
        for x, y in product(firsts, seconds):
            end, start = msgs[x].get("end"), msgs[y].get("start")
            if start is not None and (end is None or end > start):
                bad.add((m1, m2))
    return bad


def consistent(records: list[dict]) -> bool:
    """Whether the axioms can hold: a difference-constraint system over the unknown times."""
    msgs, declared, horizon = messages_of(records)
    edges: list[tuple[str, str, Fraction, int]] = []  # (y, x, c, strict): x - y <= c (or < c)

    def var(m: str, f: str) -> str:
        return f"{f}({m})"

    def le(x: str, y: str, strict: bool = False) -> None:  # x <= y  (or x < y)
        edges.append((y, x, Fraction(0), -1 if strict else 0))

    for m, f in msgs.items():
        for field in ("sent", "start", "end", "ach_start", "ach_end"):
            v = f.get(field)
            if v is not None:
                edges.append(("zero", var(m, field), v, 0))
                edges.append((var(m, field), "zero", -v, 0))
        for field in ("start", "end"):
            late = f.get(field) is None and (field == "end" or f.get("end") is None)
            if late:  # not reached by the trace: after its last time
                edges.append((var(m, field), "zero", -horizon, -1))
        le(var(m, "start"), var(m, "end"), strict=True)
        le(var(m, "sent"), var(m, "start"))
        le(var(m, "ach_start"), var(m, "ach_end"), strict=True)
        if f["kind"] in EXECUTES:
            for a, b in (("start", "ach_start"), ("end", "ach_end")):
                le(var(m, a), var(m, b))
                le(var(m, b), var(m, a))
        if f["kind"] == "goal":
            le(var(m, "start"), var(m, "ach_start"))
            le(var(m, "end"), var(m, "ach_end"))
        p = f["parent"]
        if p is not None:
            if msgs[p]["kind"] == "query":
                return False
            le(var(p, "start"), var(m, "sent"))
            le(var(m, "sent"), var(p, "end"))
            if f["kind"] != "query":
                le(var(p, "ach_start"), var(m, "ach_start"))
                le(var(m, "ach_end"), var(p, "ach_end"))
    for relation, m1, m2 in declared:
        if relation == "seq_ach":
            le(var(m1, "ach_end"), var(m2, "ach_start"), strict=True)
        elif relation == "delay_planning":
            le(var(m1, "ach_end"), var(m2, "start"), strict=True)
        else:
            le(var(m1, "end"), var(m2, "start"))
    return not _negative_cycle(edges)


def _negative_cycle(edges: list[tuple[str, str, Fraction, int]]) -> bool:
    nodes = {n for y, x, _, _ in edges for n in (x, y)}
    dist = {n: (Fraction(0), 0) for n in nodes}
    for _ in range(len(nodes)):
        changed = False
        for y, x, c, s in edges:
            cand = (dist[y][0] + c, dist[y][1] + s)
            if cand < dist[x]:
                dist[x] = cand
                changed = True
        if not changed:
            return False
    return True
