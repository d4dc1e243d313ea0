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

_REQ_FAMILIES = {"hs", "rs", "rq", "wrq", "tfn", "abortreq", "cres", "ppz", "rdone", "ecf", "cfail", "tfe"}
_INST_FAMILIES = {"ctl", "rstat", "alive", "ending", "kill", "fin", "act", "chk", "owns"}
_SITE_RULE = re.compile(r"st(\d+)_([a-z_]+?)(?:_false|_wake)?$")


def _h(t) -> Optional[str]:
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None


def roar_final(ctx: Context) -> bool:
    """Every request in a final state and no recipe activation left."""
    for _m, f, _n in ctx.facts():
        h = _h(f)
        if h == "ctl":
            return False
        if h == "rs" and _h(f.args[1]) not in FINAL_STATES:
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
        return Successor(choice.rule, self.agent_of(choice, state), self._progress(choice.rule), nxt, step)

    def _group_of(self, state: Context, choice) -> str:
        return self.agent_of(choice, state)

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
                who = self._req_agent(state, f.args[0])
                if who:
                    return who
            elif h in _INST_FAMILIES:
                who = self._inst_agent(state, f.args[0])
                if who:
                    return who
            elif h == "contains" and _h(f.args[0]) in m.cells:
                return m.cells[_h(f.args[0])][0]
            elif h == "mask" and _h(f.args[0]) in m.agents:
                return m.agents[_h(f.args[0])]
            elif h == "pending":
                owner, _name = m.functions.get(_h(f.args[0]), (None, None))
                if owner:
                    return owner
        return rule

    def _req_agent(self, state: Context, r) -> Optional[str]:
        bag = state.index.get(Const("rq"))
        if bag:
            for f in bag.items:
                if f.args[0] is r:
                    return self.model.agents.get(_h(f.args[1]))
        return None

    def _inst_agent(self, state: Context, i) -> Optional[str]:
        for fam, k in (("act", 3), ("chk", 2)):
            bag = state.index.get(Const(fam))
            if bag:
                for f in bag.items:
                    if f.args[0] is i:
                        rc = self.model.recipes.get(_h(f.args[k]))
                        if rc:
                            return rc[0]
        return None

    # ---------------------------------------------------------------- sequential achievement monitor
    def _monitor(self, state: Context, nxt: Context, step) -> None:
        consumed = [f for _m, f in step.consumed if type(f) is Root]
        produced = [f for _m, f in step.produced if type(f) is Root]
        site = _SITE_RULE.match(step.rule)
        site_c = f"pp{site.group(1)}_{site.group(2)}" if site else None
        old_reqs = {f.args[0] for f in consumed if _h(f) == "rq"}
        # new requests inherit the subtrees of the request their emitter handles
        for f in produced:
            if _h(f) != "rq" or f.args[0] in old_reqs:
                continue
            r, emitter = f.args[0], f.args[3]
            tags = set(self._tags_of_inst(state, emitter))
            if site_c in self._a_sites or site_c in self._b_sites:
                tags.add(site_c)
            for b in self._resets.get(site_c, ()):   # a new instance of A: B has not started
                _remove(nxt, "mon_b", lambda g, b=b: _h(g.args[0]) == b)
            for t in tags:
                nxt.add_fact(const("mon_in", r, const(t)), LIN)
        # commands start in the subtrees of the request their activation handles
        for f in produced:
            if _h(f) != "pending":
                continue
            inst = next((g.args[0] for g in consumed if _h(g) == "ctl"), None)
            tags = self._tags_of_inst(state, inst) if inst is not None else set()
            for t in tags:
                nxt.add_fact(const("mon_cmd", f.args[2], const(t)), LIN)
                if t in self._b_sites and not _has(nxt, "mon_b", lambda g, t=t: _h(g.args[0]) == t):
                    nxt.add_fact(const("mon_b", const(t)), LIN)
        # commands end; requests disappear
        for f in consumed:
            h = _h(f)
            if h in ("return", "callfail"):
                d = f.args[-1]
                _remove(nxt, "mon_cmd", lambda g, d=d: g.args[0] is d)
        gone = old_reqs - {f.args[0] for f in produced if _h(f) == "rq"}
        for r in gone:
            _remove(nxt, "mon_in", lambda g, r=r: g.args[0] is r)

    def _tags_of_inst(self, state: Context, inst) -> set:
        """The subtrees (pair sites) of the request activation ``inst`` handles."""
        req = None
        for fam in ("act", "chk"):
            bag = state.index.get(Const(fam))
            if bag:
                for f in bag.items:
                    if f.args[0] is inst:
                        req = f.args[1]
                        break
            if req is not None:
                break
        if req is None:
            return set()
        bag = state.index.get(Const("mon_in"))
        return {_h(f.args[1]) for f in bag.items if f.args[0] is req} if bag else set()

    def violates_sequence(self, state: Context) -> Optional[Pair]:
        """The pair whose order the state breaks: a command of A's subtree running after one of
        B's subtree started."""
        started = {_h(f.args[0]) for f in _facts(state, "mon_b")}
        if not started:
            return None
        running = {_h(f.args[1]) for f in _facts(state, "mon_cmd")}
        for p in self.pairs:
            if p.b in started and p.a in running:
                return p
        return None

    # ---------------------------------------------------------------- exclusive writes
    def shared_write(self, state: Context) -> Optional[tuple[str, list[str]]]:
        """A variable two live accepted constraints write through where clauses, if any."""
        cells: dict = {}
        rq = {f.args[0]: _h(f.args[2]) for f in _facts(state, "rq")}
        for f in _facts(state, "hs"):
            if _h(f.args[5]) == "vsome":
                # its where values are not written yet: still deciding (h_select, h_dec), or
                # waiting after a conflict (h_cwait) until the holder releases the task
                continue
            c = rq.get(f.args[0])
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
        if _h(f) == "rq":
            nar.label(f.args[0])
            nar.req_info["R0"] = (model.request_agent, model.csts[model.request_cst][1])
    out = []
    for i, step in enumerate(steps, 1):
        # a robot-backed step (a launch, the physics advancing) is narrated by its parts: each answer
        parts = getattr(step, "parts", None)
        for part in (parts if parts is not None else (step,)):
            out.extend(nar.events(i, part))
    return out, nar
