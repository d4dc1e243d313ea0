"""Exploring a compiled ROAR model: the ROAR-level view the explorer needs.

The states and steps are the engine's (a :class:`~roar_formal.explore.system.ClfSystem`
over the compiled signature, with primitives as their declared outcome rules,
so the search branches on every outcome). On top of it this module gives:

* the fairness group of a step: the agent that takes it (weak fairness per agent);
* the progress events of livelock: a request reaching a final state;
* the final states of deadlock: every request final and no recipe left (DESIGN.md:
  quiescent with a request not final, or a recipe blocked, is a deadlock);
* a monitor for sequential achievement (TCA): for two sequential sub-goals A and
  B, a command (a primitive call) in B's subtree must not start before every
  command in A's subtree has ended. The sub-goals are any two constraint-sending
  statements (``make`` or ``ensure``) of one block of a recipe, in order (every
  ordered pair, per activation), and consecutive tasks of a plan the logic layer
  chose for a request (``d_plan [T1, ..., Tk, main]``: T_i before T_i+1, per
  decision). Optionally (``kept``) an achieved statement's predicate must still
  hold when each later statement of its block is achieved and when the recipe
  ends. The monitor keeps, as facts of the state (so states stay canonical), the
  subtrees each request and running command belongs to, whether a command of a
  second subtree started while its first one was still live, the plans, and the
  statements achieved;
* the invariant ``exclusive-writes``: no controllable variable is written by the
  where clauses of two live accepted constraints;
* ROAR-level events for a counterexample path (the same narrator as runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from ..clf.context import Context
from ..clf.rules import LIN
from ..clf.terms import Const, Param, Root, const, param_term
from ..errors import Pos, RoarError
from ..explore.system import ClfSystem, Options, Successor, unchanged_system
from .compile import CompiledModel
from . import vocabulary as V
from .run import list_items

#: rules whose step brings a request to a final state (the default progress events)
PROGRESS_RULES = ("success", "success_held", "written_holds", "written_holds_again", "written_holds_again_top",
                  "written_holds_held", "written_holds_again_held", "written_holds_again_held_top",
                  "no_task", "post_violated",
                  "conflict_failed", "aborted", "aborted_idle",
                  "aborted_held")   # (timed: a held ensure aborted while it waits for its re-check)
FINAL_STATES = ("s_success", "s_failure")

#: the sequential-achievement monitor's own facts besides mon_in / mon_cmd / mon_b (never
#: framework families; named, with their records and decoders, in roar/vocabulary.py):
#: ``mon_plan P R C Ts Cur`` a plan instance P (a fresh name) of request R of constraint C with
#: tasks Ts (Cur: tt while it is R's current plan), ``mon_got S I`` the request activation I sent
#: at site S was achieved, ``mon_undone A B`` (only in the state right after the step) B was
#: achieved, or the recipe ended (B = ``mtag_end``), while A's predicate was false
MON_PLAN, MON_GOT, MON_UNDONE = V.MON_PLAN, V.MON_GOT, V.MON_UNDONE
#: subtree tags (the second argument of mon_in / mon_cmd, the argument of mon_b): ``mtag_site S I``
#: the request activation I sent at site S and its subtree; ``mtag_task P T`` task T of plan P
#: (decoded by ``V.tag_site`` / ``V.tag_task``)
TAG_SITE, TAG_TASK, TAG_END = V.MTAG_SITE, V.MTAG_TASK, V.MTAG_END
#: what the sequential-achievement monitor is updated from or reads (reduction: visible families)
MONITOR_FAMILIES = frozenset({"rq", "pending", "return", "callfail", "act", "chk", "mon_in", "mon_cmd", "mon_b",
                              "hs", "rs", "contains", MON_PLAN, MON_GOT, MON_UNDONE})
#: what the exclusive-writes invariant reads
EXCLUSIVE_WRITES_FAMILIES = frozenset({"rq", "hs"})

_REQ_FAMILIES = V.REQUEST_FAMILIES
_INST_FAMILIES = V.INSTANCE_FAMILIES


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
    """Two sequential sub-goals A and B (docs/checking.md, sequential achievement).

    ``kind``:

    * ``seq``: two constraint-sending statements of one block of a recipe, A before B, where A
      is a ``make``, or an ``ensure`` whose handle is aborted between them: no command of B's
      subtree starts before every command of A's subtree has ended. ``a`` and ``b`` are the
      statements' sites;
    * ``kept``: A is an ``ensure`` still in force when B is sent (it protects B rather than
      precedes it): only its ``kept`` check (``a`` is ``kept:SITE``, so that a trace's TCA
      reading declares nothing for it);
    * ``plan``: the tasks a decision of agent AGENT plans for a request (``a`` = ``b`` =
      ``plan:AGENT``): consecutive planned tasks are sequential sub-goals. A violation names
      the two tasks with a pair of this kind.

    ``kept`` (``seq`` and ``kept`` pairs): once A is achieved (its request succeeds; for an
    ensure, is held), A's predicate ``a_pred`` still holds when B is achieved; ``a_end`` and
    ``b_end``: and when the recipe ends (not for an ensure its recipe aborts)."""

    a: str
    b: str
    where: str     # agent.task.recipe (seq, kept); 'AGENT (planned tasks)' (plan)
    a_text: str
    b_text: str
    kind: str = "seq"
    kept: bool = False
    a_pred: str = ""
    b_pred: str = ""
    a_end: bool = False
    b_end: bool = False

    @property
    def a_site(self) -> str:
        return self.a[len("kept:"):] if self.kind == "kept" else self.a


def sequential_pairs(model: CompiledModel, kept=False, plans: bool = True) -> list[Pair]:
    """The sequential sub-goals of a compiled model (docs/checking.md, sequential achievement).

    * every ordered pair of constraint-sending statements of one block (body, or end) of a
      recipe whatever stands between them, not only consecutive ones: the monitor reads
      commands only, so a sub-goal whose subtree issues none (its predicate already holds)
      does not carry the order of its neighbours over. A ``make`` first is a ``seq`` pair; an
      ``ensure`` first is one only when its handle is aborted between the two (it does not
      block: still in force, it protects what follows rather than precedes it);
    * with ``plans``, one ``plan`` pair per agent whose decisions may plan sub-goal tasks (a
      task with pre-conditions, or a candidate under an abduced hypothesis).

    ``kept``: True (every recipe), or a collection of 'agent.task.recipe' names whose pairs also
    check that an achieved sub-goal is not undone; then an ``ensure`` still in force over a
    later statement gives a ``kept`` pair."""
    from . import ast as a
    by_pos = {(s.pos.file, s.pos.line, s.pos.col): s for s in model.sites.values() if s.kind in ("make", "ensure")}
    out = []
    for ag in model.spec.agents:
        for t in ag.tasks:
            for r in t.recipes:
                where = f"{ag.name}.{t.name}.{r.name}"
                keep = kept is True or (not isinstance(kept, bool) and where in kept)
                aborted = {st.handle for st in r.statements() if isinstance(st, a.Abort)}
                for block in (r.body, r.end):
                    sends = []      # (index in the block, statement, site, predicate)
                    aborts: dict[str, list[int]] = {}
                    for k, st in enumerate(block):
                        if isinstance(st, a.Abort):
                            aborts.setdefault(st.handle, []).append(k)
                        elif isinstance(st, (a.Make, a.Ensure)):
                            site = by_pos.get((st.pos.file, st.pos.line, st.pos.col))
                            if site is not None:
                                sends.append((k, st, site, _predicate_text(st.constraint.expr, ag.name)))

                    def to_end(st) -> bool:
                        return isinstance(st, a.Make) or not (st.handle and st.handle in aborted)
                    for i, (ka, sta, sa, pa) in enumerate(sends):
                        for kb, stb, sb, pb in sends[i + 1:]:
                            common = dict(a_pred=pa, b_pred=pb, a_end=to_end(sta), b_end=to_end(stb))
                            if isinstance(sta, a.Make):
                                out.append(Pair(sa.const, sb.const, where, sa.text, sb.text, "seq", keep, **common))
                            elif sta.handle and any(ka < k < kb for k in aborts.get(sta.handle, ())):
                                out.append(Pair(sa.const, sb.const, where, sa.text, sb.text, "seq", False, **common))
                            elif keep:
                                out.append(Pair(f"kept:{sa.const}", sb.const, where, sa.text, sb.text, "kept",
                                                True, **common))
    if plans:
        planning = {h[0] for hs in model.hypotheses.values() for h in hs}
        for ag in model.spec.agents:
            if any(t.pre for t in ag.tasks) or ag.name in planning:
                out.append(Pair(f"plan:{ag.name}", f"plan:{ag.name}", f"{ag.name} (planned tasks)",
                                "a planned sub-goal task", "the next planned task", "plan"))
    return out


def job_sequence_pairs(model: CompiledModel, recipes=(), kept=False, source: str = "",
                       at: Optional[dict] = None) -> list[Pair]:
    """The pairs a sequential-achievement check on ``model`` monitors: every pair of
    :func:`sequential_pairs` (with ``kept``), or only those of ``recipes`` ('agent.task.recipe').
    A recipe named with no pair, and a check left with no pair at all, are errors (``source``:
    the job or property file, at the head of the message; ``at``: where each recipe name is
    written, which an error about it names instead): never a silent pass."""
    every = sequential_pairs(model, kept=kept)
    at = at or {}
    head = f"{source}: " if source else ""

    def located(name: str) -> tuple[str, Optional[Pos]]:
        pos = at.get(name)
        return ("" if pos is not None else head), pos
    known = {f"{ag.name}.{t.name}.{r.name}" for ag in model.spec.agents for t in ag.tasks for r in t.recipes}
    unknown = sorted(set(recipes) - known)
    if unknown:
        from .props import did_you_mean
        lead, pos = located(unknown[0])
        raise RoarError(f"{lead}[sequential-achievement] names a recipe the spec does not have: {unknown[0]}"
                        f"{did_you_mean(unknown[0], sorted(known))}; recipes are named 'agent.task.recipe'", pos)
    if recipes:
        missing = set(recipes) - {p.where for p in every}
        if missing:
            lead, pos = located(sorted(missing)[0])
            raise RoarError(f"{lead}[sequential-achievement] names recipes with no 'make A; make B' pair (nor an "
                            f"ensure aborted before a later make or ensure): {', '.join(sorted(missing))}", pos)
    if kept is not True and kept:
        unknown = set(kept) - known
        if unknown:
            lead, pos = located(sorted(unknown)[0])
            from .props import did_you_mean
            first = sorted(unknown)[0]
            raise RoarError(f"{lead}[sequential-achievement] kept names recipes the spec does not have: "
                            f"{', '.join(sorted(unknown))}{did_you_mean(first, sorted(known))}", pos)
    pairs = [p for p in every if not recipes or p.where in recipes]
    if not pairs:
        raise RoarError(f"{head}sequential-achievement has nothing to check: the spec has no sequential sub-goals "
                        f"(two constraint-sending statements in one block of a recipe, the first a make or an "
                        f"ensure aborted before the second; or an agent whose decisions plan sub-goal tasks)")
    return pairs


def _predicate_text(e, own: str) -> str:
    """A constraint's predicate with the sender's unqualified names written ``own::name``."""
    import dataclasses
    from . import ast as a
    from .pretty import format_expr

    def q(x):
        if isinstance(x, a.Name):
            return a.Remote(own, x.name, pos=x.pos)
        if isinstance(x, a.Call) or not isinstance(x, a.Expr):
            return x
        kw = {f.name: q(getattr(x, f.name)) for f in dataclasses.fields(x)
              if f.compare and isinstance(getattr(x, f.name), a.Expr)}
        return dataclasses.replace(x, **kw) if kw else x
    return format_expr(q(e))


@dataclass(frozen=True)
class SeqViolation:
    """A broken sequential-achievement pair in a state, and what to print about it."""

    pair: Pair
    message: str


class RoarSystem(ClfSystem):
    """The compiled model's CLF system, with agents as fairness groups and the monitors."""

    def __init__(self, model: CompiledModel, start: Context, options: Optional[Options] = None,
                 pairs: Optional[list[Pair]] = None):
        opts = options or Options(progress_rules=PROGRESS_RULES)
        super().__init__(model.program(), start, opts)
        self.model = model
        self.pairs = list(pairs or [])
        self._init_monitor()

    # ---------------------------------------------------------------- steps
    def _successor(self, state: Context, choice) -> Successor:
        nxt, step = self.program.successor(state, choice)
        if self.pairs:
            self._monitor(state, nxt, step)
        return Successor(choice.rule, self._group_of(state, choice), self._progress(choice.rule), nxt.in_order(),
                         step)

    def _lazy_ok(self) -> bool:
        """Lazily built successors (see ClfSystem.lazy_successors) when no monitor reads them."""
        return not self.pairs and self.options.canonical and unchanged_system(self, RoarSystem)

    def _group_of(self, state: Context, choice) -> str:
        """The fairness group: the agent taking the step, or a fair outcome's own group."""
        fair = self.model.fair_outcomes.get(choice.rule)
        return fair if fair is not None else self.agent_of(choice, state)

    def agent_of(self, choice, state: Context) -> str:
        """The agent that takes a step: the fairness group of weak fairness per agent."""
        m = self.model
        rule = choice.rule
        s = m.site_of_rule(rule)
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
    def _init_monitor(self) -> None:
        m = self.model
        seq = [p for p in self.pairs if p.kind == "seq"]
        self._seq = seq
        self._preds: dict[str, list[Pair]] = {}          # site B -> the pairs (A, B)
        for p in seq:
            self._preds.setdefault(p.b, []).append(p)
        self._plan_agents = {p.a[len("plan:"):] for p in self.pairs if p.kind == "plan"}
        self._task_const = {v: k for k, v in m.tasks.items()}            # (agent, task) -> const
        # kept: the statements whose achievement is remembered, their predicates, the checks
        kept = [p for p in self.pairs if p.kept and p.kind in ("seq", "kept")]
        self._kept_after: dict[str, list[Pair]] = {}     # site B -> kept pairs (A, B)
        self._kept_info: dict[str, tuple] = {}           # site -> (where, text, predicate text)
        self._kept_of_recipe: dict[str, list[str]] = {}  # recipe const -> its sites checked at its end
        rconst = {v: k for k, v in m.recipes.items()}
        for p in kept:
            self._kept_after.setdefault(p.b, []).append(p)
            for site, text, pred, at_end in ((p.a_site, p.a_text, p.a_pred, p.a_end),
                                             (p.b, p.b_text, p.b_pred, p.b_end)):
                if site not in self._kept_info:
                    self._kept_info[site] = (p.where, text, pred)
                    rc = rconst.get(tuple(p.where.split(".")))
                    if rc is not None and at_end:
                        self._kept_of_recipe.setdefault(rc, []).append(site)
        # the sites whose requests are tagged: the statements of order pairs, and the kept ones
        self._seq_sites = {p.a for p in seq} | {p.b for p in seq} | set(self._kept_info)
        self._kept_formula: dict = {}
        if kept:
            from .props import parse_formula
            for site, (_where, text, pred) in self._kept_info.items():
                at = m.sites[site].pos if site in m.sites else None
                try:
                    self._kept_formula[site] = parse_formula(pred, temporal=False).bind(m)
                except RoarError as exc:
                    raise RoarError(f"sequential-achievement (kept): the predicate of '{text}' cannot be "
                                    f"evaluated on a state: {exc.message}", at) from None

    def _monitor(self, state: Context, nxt: Context, step) -> None:
        consumed = [f for _m, f in step.consumed if type(f) is Root]
        produced = [f for _m, f in step.produced if type(f) is Root]
        site_c = self.model.rule_sites.get(step.rule)
        if self._kept_formula:
            _remove(nxt, MON_UNDONE, lambda g: True)     # a violation flag lives one state
        old_reqs = {V.rq(f).request for f in consumed if _h(f) == V.RQ}
        # a decision planned tasks: a new plan instance for the request
        if self._plan_agents and step.rule == "tasks_chosen":
            for f in produced:
                if _h(f) == V.HS and _h(V.hs(f).phase) == "h_write":
                    chosen = V.unwrap(V.hs(f).phase)
                    if _h(chosen) == "vsome":
                        self._new_plan(state, nxt, V.hs(f).request, V.unwrap(chosen))
        # new requests inherit the subtrees of the activation that sends them; a sending
        # statement of a pair roots its own subtree (one per activation)
        for f in produced:
            if _h(f) != V.RQ:
                continue
            q = V.rq(f)
            if q.request in old_reqs:
                continue
            tags = set(self._tags_of_inst(state, q.emitter))
            if site_c in self._seq_sites:
                tags.add(const(TAG_SITE, const(site_c), q.emitter))
            for t in tags:
                nxt.add_fact(const(V.MON_IN, q.request, t), LIN)
        # commands start in the subtrees of the activation that calls
        inst = None
        for f in produced:
            if _h(f) != V.PENDING:
                continue
            if inst is None:
                inst = next((V.ctl(g).inst for g in consumed if _h(g) == V.CTL), False)
            for t in (self._tags_of_inst(state, inst) if inst is not False else ()):
                nxt.add_fact(const(V.MON_CMD, V.pending(f).dest, t), LIN)
                if self._second(t) and not _has(nxt, V.MON_B, lambda g, t=t: V.mon_b(g).pair is t):
                    nxt.add_fact(const(V.MON_B, t), LIN)
        # commands end; requests disappear
        for f in consumed:
            h = _h(f)
            if h == V.RETURN or h == V.CALLFAIL:
                d = V.return_(f).dest if h == V.RETURN else V.callfail(f).dest
                _remove(nxt, V.MON_CMD, lambda g, d=d: V.mon_cmd(g).dest is d)
        gone = old_reqs - {V.rq(f).request for f in produced if _h(f) == V.RQ}
        for r in gone:
            _remove(nxt, V.MON_IN, lambda g, r=r: V.mon_in(g).request is r)
        if self._kept_formula:
            self._kept_step(nxt, consumed, produced, step.rule)
        self._collect(nxt)

    def _second(self, tag) -> bool:
        """Can ``tag`` be the second subtree of a pair (so its first command is recorded)?"""
        h = _h(tag)
        return h == TAG_TASK or (h == TAG_SITE and _h(V.tag_site(tag).site) in self._preds)

    def _firsts(self, ctx: Context, tag) -> list:
        """The subtrees that must be over before a command of ``tag``'s starts."""
        h = _h(tag)
        if h == TAG_SITE:
            ts = V.tag_site(tag)
            return [const(TAG_SITE, const(p.a), ts.inst) for p in self._preds.get(_h(ts.site), ())]
        if h == TAG_TASK:
            tt = V.tag_task(tag)
            plan = self._plan(ctx, tt.plan)
            if plan is not None:
                ts = list_items(plan.tasks)
                for k in range(1, len(ts)):
                    if V.unwrap(ts[k]) is tt.task:
                        return [const(TAG_TASK, tt.plan, V.unwrap(ts[k - 1]))]
        return []

    def _collect(self, nxt: Context) -> None:
        """Forget what can no longer matter (so that retried recipes do not grow the state): a
        second subtree's start once no first subtree of its pairs is live (no request, no
        running command: a live activation always handles a live request), a plan no longer
        current once no request or command of it is live."""
        started = _facts(nxt, V.MON_B)
        plans = _facts(nxt, MON_PLAN)
        if not started and not plans:
            return
        live = {V.mon_in(g).pair for g in _facts(nxt, V.MON_IN)} | \
            {V.mon_cmd(g).pair for g in _facts(nxt, V.MON_CMD)}
        for g in started:
            if not any(t in live for t in self._firsts(nxt, V.mon_b(g).pair)):
                nxt.remove_fact(g, LIN)
        if plans:
            reqs = {V.rq(f).request for f in _facts(nxt, V.RQ)}
            used = {V.tag_task(t).plan for t in live if _h(t) == TAG_TASK}
            for g in plans:
                pl = V.mon_plan(g)
                if (_h(pl.current) != "tt" or pl.request not in reqs) and pl.plan not in used:
                    nxt.remove_fact(g, LIN)

    def _new_plan(self, state: Context, nxt: Context, req, tasks) -> None:
        q = next((V.rq(f) for f in _facts(state, V.RQ) if V.rq(f).request is req), None)
        if q is None or self.model.agents.get(_h(q.agent)) not in self._plan_agents:
            return
        for g in _facts(nxt, MON_PLAN):   # the plan it replaces is no longer current
            pl = V.mon_plan(g)
            if pl.request is req and _h(pl.current) == "tt":
                nxt.remove_fact(g, LIN)
                nxt.add_fact(const(MON_PLAN, pl.plan, pl.request, pl.cst, pl.tasks, const("ff")), LIN)
        if len(list_items(tasks)) >= 2:
            nxt.add_fact(const(MON_PLAN, param_term(Param("plan")), req, q.cst, tasks, const("tt")), LIN)

    def _plan(self, ctx: Context, p) -> Optional[V.MonPlan]:
        """The (decoded) mon_plan fact of plan instance ``p``, or None."""
        return next((pl for pl in map(V.mon_plan, _facts(ctx, MON_PLAN)) if pl.plan is p), None)

    def _inst_info(self, state: Context, inst):
        """(request, task const) of the activation ``inst`` (a recipe's or a checker's)."""
        bag = state.index.get(_ACT)
        if bag:
            for f in bag.items:
                a = V.act(f)
                if a.inst is inst:
                    return a.request, _h(a.task)
        bag = state.index.get(_CHK)
        if bag:
            for f in bag.items:
                c = V.chk(f)
                if c.inst is inst:
                    rc = self.model.recipes.get(_h(c.recipe))
                    return c.request, (self._task_const.get(rc[:2]) if rc else None)
        return None, None

    def _tags_of_inst(self, state: Context, inst) -> set:
        """The subtrees the activation ``inst`` works in: those of the request it handles, and the
        task it runs when that task is part of the request's current plan."""
        req, task = self._inst_info(state, inst)
        if req is None:
            return set()
        bag = state.index.get(_MON_IN)
        tags = {m.pair for m in map(V.mon_in, bag.items) if m.request is req} if bag else set()
        if task is not None and self._plan_agents:
            for pl in map(V.mon_plan, _facts(state, MON_PLAN)):
                if pl.request is req and _h(pl.current) == "tt":
                    if any(_h(V.unwrap(x)) == task for x in list_items(pl.tasks)):
                        tags.add(const(TAG_TASK, pl.plan, const(task)))
        return tags

    def _kept_step(self, nxt: Context, consumed: list, produced: list, rule: str) -> None:
        """Remember the statements achieved; flag one undone when a later statement of its block
        is achieved or its recipe ends."""
        before = {V.rs(f).request: _h(V.rs(f).state) for f in consumed if _h(f) == V.RS}
        for f in produced:
            if _h(f) != V.RS or _h(V.rs(f).state) != "s_success" or before.get(V.rs(f).request) == "s_success":
                continue
            r = V.rs(f).request
            q = next((V.rq(g) for g in _facts(nxt, V.RQ) if V.rq(g).request is r), None)
            if q is None:
                continue
            for mi in map(V.mon_in, _facts(nxt, V.MON_IN)):
                t = mi.pair
                if mi.request is not r or _h(t) != TAG_SITE:
                    continue
                ts = V.tag_site(t)
                if ts.inst is not q.emitter:
                    continue
                s = _h(ts.site)
                if s not in self._kept_info:
                    continue
                got = const(MON_GOT, ts.site, q.emitter)
                if not nxt.count(got, LIN):
                    nxt.add_fact(got, LIN)
                for p in self._kept_after.get(s, ()):
                    if nxt.count(const(MON_GOT, const(p.a_site), q.emitter), LIN) and not self._holds(p.a_site, nxt):
                        self._undone(nxt, p.a_site, const(s))
        ended = {V.act(f).inst: _h(V.act(f).recipe) for f in consumed if _h(f) == V.ACT}
        if rule == "recipe_end":
            for i, rc in ended.items():
                for s in self._kept_of_recipe.get(rc, ()):
                    if nxt.count(const(MON_GOT, const(s), i), LIN) and not self._holds(s, nxt):
                        self._undone(nxt, s, const(TAG_END))
        for i in set(ended) - {V.act(f).inst for f in produced if _h(f) == V.ACT}:
            _remove(nxt, MON_GOT, lambda g, i=i: V.mon_got(g).inst is i)

    def _undone(self, nxt: Context, a: str, b) -> None:
        f = const(MON_UNDONE, const(a), b)
        if not nxt.count(f, LIN):
            nxt.add_fact(f, LIN)

    def _holds(self, site: str, ctx: Context) -> bool:
        from .props import view_of
        return bool(self._kept_formula[site].pf(view_of(self.model, ctx)))

    def sequence_violation(self, state: Context) -> Optional[SeqViolation]:
        """The sequential-achievement pair the state breaks, with its message in the spec's terms:
        a command of A's subtree running after one of B's subtree started (the first such pair
        in the order of ``pairs``, then the plans), or (kept) an achieved predicate undone."""
        started = {V.mon_b(g).pair for g in _facts(state, V.MON_B)}
        if started:
            running = {V.mon_cmd(g).pair for g in _facts(state, V.MON_CMD)}
            for p in self._seq:
                for t in started:
                    if _h(t) == TAG_SITE and _h(V.tag_site(t).site) == p.b and \
                            const(TAG_SITE, const(p.a), V.tag_site(t).inst) in running:
                        return SeqViolation(p, _order_message(p))
            for t in sorted((t for t in started if _h(t) == TAG_TASK), key=lambda t: V.tag_task(t).task.head.name):
                for first in self._firsts(state, t):
                    if first in running:
                        p = self._plan_pair(state, first, t)
                        return SeqViolation(p, _order_message(p))
        for u in map(V.mon_undone, _facts(state, MON_UNDONE)):
            a, b = _h(u.a), _h(u.b)
            where, a_text, pred = self._kept_info[a]
            b_text = self._kept_info[b][1] if b in self._kept_info else "the recipe ends"
            when = f"when '{b_text}' is achieved" if b in self._kept_info else "when the recipe ends"
            f = self._kept_formula[a]
            from .props import view_of
            values = f.explain(view_of(self.model, state))
            return SeqViolation(Pair(f"kept:{a}", b if b in self._kept_info else "end", where, a_text, b_text,
                                     "kept", True, pred),
                                f"in {where}, '{a_text}' was achieved, but {pred} no longer holds {when}"
                                + (f": {values}" if values else ""))
        return None

    def _plan_pair(self, state: Context, first, second) -> Pair:
        m = self.model
        first, second = V.tag_task(first), V.tag_task(second)
        plan = self._plan(state, first.plan)
        agent, cst = m.csts.get(_h(plan.cst), ("?", "?"))
        names = [m.tasks.get(_h(V.unwrap(x)), ("?", "?"))[1] for x in list_items(plan.tasks)]
        ta, tb = (m.tasks.get(_h(t.task), ("?", "?")) for t in (first, second))
        return Pair(_h(first.task), _h(second.task), f"the plan of {agent} for '{cst}' "
                    f"({' then '.join(names)})", f"task {ta[0]}::{ta[1]}", f"task {tb[0]}::{tb[1]}", "plan")

    def violates_sequence(self, state: Context) -> Optional[Pair]:
        """The pair the state breaks (see :meth:`sequence_violation`), or None."""
        v = self.sequence_violation(state)
        return v.pair if v is not None else None

    def sequence_reason(self, state: Context) -> Optional[str]:
        """What the state breaks, in the spec's terms (the verdict's message), or None."""
        v = self.sequence_violation(state)
        return v.message if v is not None else None

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


def _order_message(p: Pair) -> str:
    return (f"in {p.where}, a command of the subtree of '{p.b_text}' started before every command of the "
            f"subtree of '{p.a_text}' ended")


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
