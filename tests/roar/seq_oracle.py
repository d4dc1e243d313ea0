"""An independent oracle for sequential achievement (tests only).

A plain breadth-first search over the engine (``Program.steps`` / ``Program.successor``, no
``RoarSystem``) whose states carry, as extra facts, the task tree of the path that reached them:
who sent each request and called each command (``o_up X I``: X was made by activation I), which
request each activation handles (``o_of I R``), which requests a pair's statements sent
(``o_site R S I``), which commands run (``o_run D``), the plans decided (``o_plan P Ts``,
``o_cur R P``) and the planned task each activation runs (``o_task I P T``). When a command
starts, the oracle walks its ancestors up the tree and records that the subtrees rooted there
have started (``o_bstart S I``, ``o_tstart P T``). The order is broken in a state when a second
subtree has started while a command whose ancestors include the first subtree's root is running.
``kept``: a statement's request reaching success is recorded (``o_got S I``); when a later
statement of the pair succeeds, or the activation's recipe ends well, the first statement's
predicate is evaluated by a Python function written in the test on the decoded variables.

Unlike the monitor (``roar/explore.py``), nothing is inherited or forgotten: the tree only grows
and every question is answered by walking it, so the two share no code beyond the engine and
the fact decoders.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path
from typing import Callable, Optional

from roar_formal.clf.rules import LIN
from roar_formal.clf.state import canonical_key
from roar_formal.clf.terms import Const, Param, Root, const, param_term
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.functional import load_registry
from roar_formal.roar.report import decode_state
from roar_formal.roar.spec import load_spec

DATA = Path(__file__).parent / "data"
TOOLS = DATA / "seq_tools.py"


def head_name(t) -> Optional[str]:
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None


def vlist(t) -> list:
    out = []
    while head_name(t) == "vcons":
        out.append(t.args[0])
        t = t.args[1]
    return out


_COMPILED: dict = {}


def compiled(spec: str, request: str):
    """(model, program, start context) of a spec of ``DATA`` (or a path) on ``request``, compiled once."""
    if (spec, request) not in _COMPILED:
        _COMPILED[(spec, request)] = _compile(spec, request)
    model, program, start = _COMPILED[(spec, request)]
    return model, program, start.copy()


def _compile(spec: str, request: str):
    reg = load_registry(TOOLS)
    model = compile_spec(load_spec(DATA / spec), request, registry=reg, functional="abstract")
    program = model.program()
    start = program.start_context(next(d for d in program.sig.directives
                                       if type(d).__name__ == "ExecDirective").start)
    return model, program, start


class SeqOracle:
    """Every reachable (state, task tree) of ``spec`` on ``request``; ``bad[s]`` lists what state
    ``s`` breaks: ``("seq", a_text, b_text)``, ``("plan", task_a, task_b)`` or ``("kept", a_text,
    b_text or "end")``.

    ``pairs`` says what to watch, as plain data: ``seq`` is a list of (site A, site B, text A,
    text B), ``plan`` the agents whose plans are watched, ``kept`` a list of (site A, site B, text
    A, text B) and ``ends`` the sites checked when their recipe ends, with ``preds`` mapping a
    statement's text to its predicate on the decoded variables ({"lamp::on": "true", ...})."""

    def __init__(self, spec: str, request: str, seq=(), plan=(), kept=(), ends=(),
                 preds: Optional[dict[str, Callable[[dict], bool]]] = None):
        self.model, self.program, start = compiled(spec, request)
        m = self.model
        self.seq, self.plan_agents, self.kept, self.preds = list(seq), set(plan), list(kept), preds or {}
        self.texts = {}
        for a, b, ta, tb in list(seq) + list(kept):
            self.texts[a], self.texts[b] = ta, tb
        self.sites = set(self.texts)
        self.ends = set(ends)
        self.recipe_sites: dict[str, set] = {}
        for s in self.ends:
            site = m.sites[s]
            rc = next(k for k, v in m.recipes.items() if v == (site.agent, site.task, site.recipe))
            self.recipe_sites.setdefault(rc, set()).add(s)
        self.task_const = {v: k for k, v in m.tasks.items()}
        self.states, self.depth = [start], [0]
        ids = {canonical_key(start): 0}
        queue = deque([0])
        while queue:
            s = queue.popleft()
            ctx = self.states[s]
            for c in self.program.steps(ctx):
                nxt, step = self.program.successor(ctx, c)
                self._grow(ctx, nxt, step)
                k = canonical_key(nxt)
                if k not in ids:
                    ids[k] = len(self.states)
                    self.states.append(nxt)
                    self.depth.append(self.depth[s] + 1)
                    queue.append(ids[k])
        self.bad = [self._broken(ctx) for ctx in self.states]

    # ------------------------------------------------------------ the tree, grown by each step
    @staticmethod
    def _facts(ctx, fam: str) -> list:
        bag = ctx.index.get(Const(fam))
        return list(bag.items) if bag else []

    @staticmethod
    def _add(ctx, f) -> None:
        if not ctx.count(f, LIN):
            ctx.add_fact(f, LIN)

    def _grow(self, ctx, nxt, step) -> None:
        prod = [f for _m, f in step.produced if type(f) is Root]
        cons = [f for _m, f in step.consumed if type(f) is Root]
        m = self.model
        known = {f.args[0] for f in self._facts(ctx, "o_of")}
        for f in prod:
            if head_name(f) in ("act", "chk") and f.args[0] not in known:
                inst, req = f.args[0], f.args[1]
                self._add(nxt, const("o_of", inst, req))
                if head_name(f) == "act":
                    task = head_name(f.args[2])
                else:
                    agent, tname, _r = m.recipes[head_name(f.args[2])]
                    task = self.task_const[(agent, tname)]
                for cur in self._facts(ctx, "o_cur"):
                    if cur.args[0] is req:
                        plan = next(g for g in self._facts(ctx, "o_plan") if g.args[0] is cur.args[1])
                        if task in [head_name(x.args[0]) for x in vlist(plan.args[1])]:
                            self._add(nxt, const("o_task", inst, cur.args[1], const(task)))
        if step.rule == "tasks_chosen":
            for f in prod:
                if head_name(f) == "hs" and head_name(f.args[1]) == "h_write" and head_name(f.args[1].args[0]) == "vsome":
                    req, ts = f.args[0], f.args[1].args[0].args[0]
                    q = next(g for g in self._facts(ctx, "rq") if g.args[0] is req)
                    if m.agents[head_name(q.args[1])] not in self.plan_agents:
                        continue
                    for cur in self._facts(nxt, "o_cur"):
                        if cur.args[0] is req:
                            nxt.remove_fact(cur, LIN)
                    if len(vlist(ts)) >= 2:
                        p = param_term(Param("oplan"))
                        nxt.add_fact(const("o_plan", p, ts), LIN)
                        nxt.add_fact(const("o_cur", req, p), LIN)
        old = {f.args[0] for f in cons if head_name(f) == "rq"}
        site = _site(step.rule)
        for f in prod:
            if head_name(f) == "rq" and f.args[0] not in old and head_name(f.args[3]) is None:   # sent by an activation
                self._add(nxt, const("o_up", f.args[0], f.args[3]))
                if site in self.sites:
                    self._add(nxt, const("o_site", f.args[0], const(site), f.args[3]))
        caller = next((g.args[0] for g in cons if head_name(g) == "ctl"), None)
        for f in prod:
            if head_name(f) == "pending" and caller is not None:
                d = f.args[2]
                self._add(nxt, const("o_up", d, caller))
                self._add(nxt, const("o_run", d))
                for kind, node in self._ancestors(nxt, d):
                    if kind == "req":
                        for g in self._facts(nxt, "o_site"):
                            if g.args[0] is node:
                                self._add(nxt, const("o_bstart", g.args[1], g.args[2]))
                    else:
                        for g in self._facts(nxt, "o_task"):
                            if g.args[0] is node:
                                self._add(nxt, const("o_tstart", g.args[1], g.args[2]))
        for f in cons:
            if head_name(f) in ("return", "callfail"):
                d = f.args[1] if head_name(f) == "return" else f.args[0]
                for g in self._facts(nxt, "o_run"):
                    if g.args[0] is d:
                        nxt.remove_fact(g, LIN)
        if self.kept or self.ends:
            self._kept(ctx, nxt, prod, cons, step.rule)

    def _kept(self, ctx, nxt, prod, cons, rule) -> None:
        before = {f.args[0]: head_name(f.args[1]) for f in cons if head_name(f) == "rs"}
        for f in prod:
            if head_name(f) != "rs" or head_name(f.args[1]) != "s_success" or before.get(f.args[0]) == "s_success":
                continue
            for g in self._facts(nxt, "o_site"):
                if g.args[0] is not f.args[0]:
                    continue
                site, inst = head_name(g.args[1]), g.args[2]
                self._add(nxt, const("o_got", g.args[1], inst))
                for a, b, ta, tb in self.kept:
                    if b == site and nxt.count(const("o_got", const(a), inst), LIN) and not self._pred(ta, nxt):
                        self._add(nxt, const("o_bad", const(a), const(b)))
        if rule == "recipe_end":
            for f in cons:
                if head_name(f) == "act":
                    for s in self.recipe_sites.get(head_name(f.args[3]), ()):
                        if nxt.count(const("o_got", const(s), f.args[0]), LIN) and not self._pred(self.texts[s], nxt):
                            self._add(nxt, const("o_bad", const(s), const("end")))

    def _pred(self, text: str, ctx) -> bool:
        table = decode_state(self.model, ctx, {}, {})["agents"]
        values = {f"{a}::{v}": x for a, row in table.items() for v, x in row["variables"].items()}
        return bool(self.preds[text](values))

    def _ancestors(self, ctx, x) -> list:
        up = {g.args[0]: g.args[1] for g in self._facts(ctx, "o_up")}
        of = {g.args[0]: g.args[1] for g in self._facts(ctx, "o_of")}
        out = []
        while x in up:
            inst = up[x]
            out.append(("act", inst))
            if inst not in of:
                break
            x = of[inst]
            out.append(("req", x))
        return out

    # ------------------------------------------------------------ what a state breaks
    def _broken(self, ctx) -> list:
        out = []
        running = [g.args[0] for g in self._facts(ctx, "o_run")]
        lines = [self._ancestors(ctx, d) for d in running]
        roots = {}   # (site, inst) -> request
        for g in self._facts(ctx, "o_site"):
            roots[(head_name(g.args[1]), g.args[2])] = g.args[0]
        for g in self._facts(ctx, "o_bstart"):
            b, inst = head_name(g.args[0]), g.args[1]
            for a, bb, ta, tb in self.seq:
                root = roots.get((a, inst))
                if bb == b and root is not None and any(("req", root) in line for line in lines):
                    out.append(("seq", ta, tb))
        tasks = {}
        for g in self._facts(ctx, "o_task"):
            tasks.setdefault((g.args[1], head_name(g.args[2])), []).append(g.args[0])
        for g in self._facts(ctx, "o_tstart"):
            p, t = g.args[0], head_name(g.args[1])
            plan = next(x for x in self._facts(ctx, "o_plan") if x.args[0] is p)
            ts = [head_name(x.args[0]) for x in vlist(plan.args[1])]
            k = ts.index(t)
            if k > 0:
                firsts = tasks.get((p, ts[k - 1]), [])
                if any(("act", i) in line for line in lines for i in firsts):
                    out.append(("plan", self.model.tasks[ts[k - 1]][1], self.model.tasks[t][1]))
        for g in self._facts(ctx, "o_bad"):
            a, b = head_name(g.args[0]), head_name(g.args[1])
            out.append(("kept", self.texts[a], self.texts.get(b, "end")))
        return out

    def shallowest(self):
        """(depth, what is broken there) of the shallowest bad state, or None."""
        hits = [(self.depth[s], s) for s, b in enumerate(self.bad) if b]
        if not hits:
            return None
        d = min(hits)[0]
        return d, {x for dd, s in hits if dd == d for x in self.bad[s]}


def _site(rule: str) -> Optional[str]:
    import re
    m = re.match(r"st(\d+)_([a-z_]+?)(?:_false|_wake)?$", rule)
    return f"pp{m.group(1)}_{m.group(2)}" if m else None
