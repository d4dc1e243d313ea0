"""Exploring a compiled ROAR model: the ROAR-level view the explorer needs.

The states and steps are the engine's (a :class:`~roar_formal.explore.system.ClfSystem`
over the compiled signature, with primitives as their declared outcome rules,
so the search branches on every outcome). On top of it this module gives:

* the fairness group of a step: the agent that takes it (weak fairness per agent);
* the progress events of livelock: a request reaching a final state;
* the final states of deadlock: every request final and no recipe left (DESIGN.md:
  quiescent with a request not final, or a recipe blocked, is a deadlock);
* a monitor for sequential achievement (TCA): for a pair ``make A; make B`` of
  one recipe, a command (a primitive call) in B's subtree must not start before
  every command in A's subtree has ended. The monitor keeps, as facts of the
  state (so states stay canonical), the subtree each request and running
  command belongs to and whether a command of B's subtree has started;
* the invariant ``exclusive-writes``: no controllable variable is written by the
  where clauses of two live accepted constraints;
* ROAR-level events for a counterexample path (the same narrator as runs).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Optional

from ..clf.context import Context
from ..clf.rules import LIN
from ..clf.terms import Const, Root, const
from ..explore.system import ClfSystem, Options, Successor
from .compile import CompiledModel
from . import vocabulary as V

#: rules whose step brings a request to a final state (the default progress events)
PROGRESS_RULES = ("success", "success_held", "written_holds", "written_holds_again", "written_holds_again_top",
                  "written_holds_held", "written_holds_again_held", "written_holds_again_held_top",
                  "no_task", "post_violated",
                  "conflict_failed", "aborted", "aborted_idle")
FINAL_STATES = ("s_success", "s_failure")

#: what the sequential-achievement monitor is updated from or reads (reduction: visible families)
MONITOR_FAMILIES = frozenset({"rq", "pending", "return", "callfail", "act", "chk", "mon_in", "mon_cmd", "mon_b"})
#: what the exclusive-writes invariant reads
EXCLUSIVE_WRITES_FAMILIES = frozenset({"rq", "hs"})

_REQ_FAMILIES = V.REQUEST_FAMILIES
_INST_FAMILIES = V.INSTANCE_FAMILIES
_SITE_RULE = re.compile(r"st(\d+)_([a-z_]+?)(?:_false|_wake)?$")


_h = V.head_name
_RQ, _ACT, _CHK, _MON_IN = Const(V.RQ), Const(V.ACT), Const(V.CHK), Const(V.MON_IN)


def roar_final(ctx: Context) -> bool:
    """Every request in a final state and no recipe activation left."""
    for _m, f, _n in ctx.facts():
        h = _h(f)
        if h == V.CTL:
            return False
        if h == V.RS and _h(V.rs(f).state) not in FINAL_STATES:
            return False
    return True


@dataclass(frozen=True)
class Pair:
    """``make A; make B`` in one recipe: the sites of the two makes."""

    a: str
    b: str
    where: str     # agent.task.recipe
    a_text: str
    b_text: str


def sequential_pairs(model: CompiledModel) -> list[Pair]:
    """The pairs of consecutive makes of every recipe (the TCA property's default pairs)."""
    by_pos = {(s.pos.file, s.pos.line, s.pos.col): s for s in model.sites.values() if s.kind == "make"}
    out = []
    for ag in model.spec.agents:
        for t in ag.tasks:
            for r in t.recipes:
                for ma, mb in r.sequential_pairs():
                    sa = by_pos.get((ma.pos.file, ma.pos.line, ma.pos.col))
                    sb = by_pos.get((mb.pos.file, mb.pos.line, mb.pos.col))
                    if sa and sb:
                        out.append(Pair(sa.const, sb.const, f"{ag.name}.{t.name}.{r.name}", sa.text, sb.text))
    return out


class RoarSystem(ClfSystem):
    """The compiled model's CLF system, with agents as fairness groups and the monitors."""

    def __init__(self, model: CompiledModel, start: Context, options: Optional[Options] = None,
                 pairs: Optional[list[Pair]] = None):
        opts = options or Options(progress_rules=PROGRESS_RULES)
        super().__init__(model.program(), start, opts)
        self.model = model
        self.pairs = list(pairs or [])
        self._a_sites = {p.a for p in self.pairs}
        self._b_sites = {p.b for p in self.pairs}
        self._resets = {}
        for p in self.pairs:
            self._resets.setdefault(p.a, []).append(p.b)

    # ---------------------------------------------------------------- steps
    def _successor(self, state: Context, choice) -> Successor:
        nxt, step = self.program.successor(state, choice)
        if self.pairs:
            self._monitor(state, nxt, step)
        return Successor(choice.rule, self._group_of(state, choice), self._progress(choice.rule), nxt, step)

    def _group_of(self, state: Context, choice) -> str:
        """The fairness group: the agent taking the step, or a fair outcome's own group."""
        fair = self.model.fair_outcomes.get(choice.rule)
        return fair if fair is not None else self.agent_of(choice, state)

    def agent_of(self, choice, state: Context) -> str:
        """The agent that takes a step: the fairness group of weak fairness per agent."""
        m = self.model
        rule = choice.rule
        site = _SITE_RULE.match(rule)
        if site:
            s = m.sites.get(f"pp{site.group(1)}_{site.group(2)}")
            if s is not None:
                return s.agent
        for prefix in ("select_", "reselect_", "final_"):
            if rule.startswith(prefix) and rule[len(prefix):] in m.csts:
                return m.csts[rule[len(prefix):]][0]
        for _mode, f in choice.consumed:
            h = _h(f)
            if h is None or not f.args:
                continue
            if h in _REQ_FAMILIES:
                who = self._req_agent(state, V.subject(f))
                if who:
                    return who
            elif h in _INST_FAMILIES:
                who = self._inst_agent(state, V.subject(f))
                if who:
                    return who
            elif h == V.CONTAINS:
                cell = _h(V.contains(f).cell)
                if cell in m.cells:
                    return m.cells[cell][0]
            elif h == V.MASK:
                agent = _h(V.mask(f).agent)
                if agent in m.agents:
                    return m.agents[agent]
            elif h == V.PENDING:
                owner, _name = m.functions.get(_h(V.pending(f).fn), (None, None))
                if owner:
                    return owner
        return rule

    def _req_agent(self, state: Context, r) -> Optional[str]:
        bag = state.index.get(_RQ)
        if bag:
            for f in bag.items:
                q = V.rq(f)
                if q.request is r:
                    return self.model.agents.get(_h(q.agent))
        return None

    def _inst_agent(self, state: Context, i) -> Optional[str]:
        for fam, decode in ((_ACT, V.act), (_CHK, V.chk)):
            bag = state.index.get(fam)
            if bag:
                for f in bag.items:
                    a = decode(f)
                    if a.inst is i:
                        rc = self.model.recipes.get(_h(a.recipe))
                        if rc:
                            return rc[0]
        return None

    # ---------------------------------------------------------------- sequential achievement monitor
    def _monitor(self, state: Context, nxt: Context, step) -> None:
        consumed = [f for _m, f in step.consumed if type(f) is Root]
        produced = [f for _m, f in step.produced if type(f) is Root]
        site = _SITE_RULE.match(step.rule)
        site_c = f"pp{site.group(1)}_{site.group(2)}" if site else None
        old_reqs = {V.rq(f).request for f in consumed if _h(f) == V.RQ}
        # new requests inherit the subtrees of the request their emitter handles
        for f in produced:
            if _h(f) != V.RQ:
                continue
            q = V.rq(f)
            if q.request in old_reqs:
                continue
            tags = set(self._tags_of_inst(state, q.emitter))
            if site_c in self._a_sites or site_c in self._b_sites:
                tags.add(site_c)
            for b in self._resets.get(site_c, ()):   # a new instance of A: B has not started
                _remove(nxt, V.MON_B, lambda g, b=b: _h(V.mon_b(g).pair) == b)
            for t in tags:
                nxt.add_fact(const(V.MON_IN, q.request, const(t)), LIN)
        # commands start in the subtrees of the request their activation handles
        for f in produced:
            if _h(f) != V.PENDING:
                continue
            inst = next((V.ctl(g).inst for g in consumed if _h(g) == V.CTL), None)
            tags = self._tags_of_inst(state, inst) if inst is not None else set()
            for t in tags:
                nxt.add_fact(const(V.MON_CMD, V.pending(f).dest, const(t)), LIN)
                if t in self._b_sites and not _has(nxt, V.MON_B, lambda g, t=t: _h(V.mon_b(g).pair) == t):
                    nxt.add_fact(const(V.MON_B, const(t)), LIN)
        # commands end; requests disappear
        for f in consumed:
            h = _h(f)
            if h == V.RETURN or h == V.CALLFAIL:
                d = V.return_(f).dest if h == V.RETURN else V.callfail(f).dest
                _remove(nxt, V.MON_CMD, lambda g, d=d: V.mon_cmd(g).dest is d)
        gone = old_reqs - {V.rq(f).request for f in produced if _h(f) == V.RQ}
        for r in gone:
            _remove(nxt, V.MON_IN, lambda g, r=r: V.mon_in(g).request is r)

    def _tags_of_inst(self, state: Context, inst) -> set:
        """The subtrees (pair sites) of the request activation ``inst`` handles."""
        req = None
        for fam, decode in ((_ACT, V.act), (_CHK, V.chk)):
            bag = state.index.get(fam)
            if bag:
                for f in bag.items:
                    a = decode(f)
                    if a.inst is inst:
                        req = a.request
                        break
            if req is not None:
                break
        if req is None:
            return set()
        bag = state.index.get(_MON_IN)
        return {_h(m.pair) for m in map(V.mon_in, bag.items) if m.request is req} if bag else set()

    def violates_sequence(self, state: Context) -> Optional[Pair]:
        """The pair whose order the state breaks: a command of A's subtree running after one of
        B's subtree started."""
        started = {_h(V.mon_b(f).pair) for f in _facts(state, V.MON_B)}
        if not started:
            return None
        running = {_h(V.mon_cmd(f).pair) for f in _facts(state, V.MON_CMD)}
        for p in self.pairs:
            if p.b in started and p.a in running:
                return p
        return None

    # ---------------------------------------------------------------- exclusive writes
    def shared_write(self, state: Context) -> Optional[tuple[str, list[str]]]:
        """A variable two live accepted constraints write through where clauses, if any."""
        cells: dict = {}
        rq = {q.request: _h(q.cst) for q in map(V.rq, _facts(state, V.RQ))}
        for h in map(V.hs, _facts(state, V.HS)):
            if _h(h.where) == "vsome":
                # its where values are not written yet: still deciding (h_select, h_dec), or
                # waiting after a conflict (h_cwait) until the holder releases the task
                continue
            c = rq.get(h.request)
            for cell in self.where_cells.get(c, ()):
                cells.setdefault(cell, []).append(c)
        for cell, cs in cells.items():
            if len(cs) > 1:
                agent, var = self.model.cells[cell]
                return f"{agent}::{var}", [self.model.csts[c][1] for c in cs]
        return None

    @property
    def where_cells(self) -> dict:
        return getattr(self.model, "where_cells", {})


def _facts(ctx: Context, fam: str):
    bag = ctx.index.get(Const(fam))
    return list(bag.items) if bag else []


def _has(ctx: Context, fam: str, pred) -> bool:
    return any(pred(f) for f in _facts(ctx, fam))


def _remove(ctx: Context, fam: str, pred) -> None:
    for f in _facts(ctx, fam):
        if pred(f):
            n = ctx.count(f, LIN)
            for _ in range(n):
                ctx.remove_fact(f, LIN)


def path_events(model: CompiledModel, start: Context, steps: list) -> list:
    """The ROAR-level events of a path of engine steps from ``start`` (counterexamples)."""
    return path_narration(model, start, steps)[0]


def path_narration(model: CompiledModel, start: Context, steps: list):
    """(events, narrator): the narrator keeps the request labels, to name requests of the final state."""
    from .run import Narrator
    nar = Narrator(model)
    for _m, f, _n in start.facts():
        if _h(f) == V.RQ:
            nar.label(V.rq(f).request)
            nar.req_info["R0"] = (model.request_agent, model.csts[model.request_cst][1])
    out = []
    for i, step in enumerate(steps, 1):
        # a robot-backed step (a launch, the physics advancing) is narrated by its parts: each answer
        parts = getattr(step, "parts", None)
        for part in (parts if parts is not None else (step,)):
            out.extend(nar.events(i, part))
    return out, nar
