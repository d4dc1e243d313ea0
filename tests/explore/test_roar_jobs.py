"""Verification jobs on ROAR specs (checker/*.toml with a ``spec`` key): verdicts, and
independent oracles for their counterexamples.

The oracles are written here, over the engine's own enumerator (``Program.steps`` /
``Program.successor``), and do not reuse the explorer, the property checkers or the
replay module: a breadth-first search for the shortest deadlock, a breadth-first
search whose state identity is a renaming key written in this file for the shortest
sequential-achievement violation, a step-by-step replay of a livelock's cycle and a
depth-first cycle search on the explored graph.

Every job is run once (``job_result`` caches it); the whole file takes ~30 s, most of
it ``ordered_pick`` (~11 s).
"""

from __future__ import annotations

import json
import re
import tomllib
from collections import deque
from pathlib import Path

import pytest
from checker_cache import checker_result

from roar_formal.cli import main
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.state import canonical_key
from roar_formal.errors import Pos, RoarError
from roar_formal.verify.check import roar_events, run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import Options
from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem, roar_final, sequential_pairs
from roar_formal.trace.format import read_trace
from roar_formal.verify.replay import replay

from repo import ROOT
CHECKER = ROOT / "checker"
FAULTY = ROOT / "models" / "faulty"


def _is_spec_job(path: Path) -> bool:
    return "spec" in tomllib.loads(path.read_text(encoding="utf-8"))


SPEC_JOBS = sorted(p.name for p in CHECKER.glob("*.toml") if _is_spec_job(p))

def job_result(name: str):
    """The result of ``checker/<name>``, run once per test session (shared: tests/checker_cache.py)."""
    return checker_result(name)


def big(fn, *args):
    """Run on a big stack, as the explorer does (deep terms recurse)."""
    return with_big_stack(fn, *args)


# ------------------------------------------------------------------ 1. expected verdicts


def test_the_spec_jobs_are_the_eighteen_seeded_faults_and_fixes_and_two_examples():
    assert SPEC_JOBS == ["aim.toml", "aim_fixed.toml", "camera_bounded.toml", "camera_retry.toml", "conflict.toml",
                         "demo_loco.toml", "door_sensor.toml", "door_sensor_fixed.toml",
                         "ensure_slammed.toml", "ensure_slammed_fixed.toml",
                         "mutual_make.toml", "mutual_make_fixed.toml", "ordered_pick.toml", "ordered_pick_fixed.toml",
                         "retry_bounded.toml", "retry_forever.toml", "survey.toml", "survey_fixed.toml",
                         "track_switch.toml", "track_switch_fixed.toml"]


@pytest.mark.parametrize("name", SPEC_JOBS)
def test_spec_job_gives_its_expected_verdicts(name):
    res = job_result(name)
    job = res.job
    assert job.is_roar and job.expect
    assert res.ok, res.mismatches
    assert res.backend == "general" and res.graph.complete
    assert set(res.verdicts) == set(job.props.check) >= set(job.expect)
    for prop, want in job.expect.items():
        v = res.verdicts[prop]
        assert v.status == want, (prop, v.message)
        if want == "violated":
            cx = v.counterexample
            assert cx is not None and cx.length() > 0
            if prop == "mission-completion":   # a fair cycle that never succeeds, or a run that ends otherwise
                assert cx.kind in ("lasso", "path")
            else:
                assert cx.kind == ("lasso" if prop == "livelock" else "path")
            assert roar_events(res, v) is not None
        else:
            assert v.counterexample is None


# ------------------------------------------------------------------ helpers of the oracles


_FRESH = re.compile(r"([A-Za-z_][A-Za-z0-9_']*)#(\d+)")


def renaming_key(program, ctx) -> tuple:
    """The state printed, fresh names renamed in order of first occurrence after sorting
    the facts by their shape (fresh names masked). Equal keys mean equal states up to a
    renaming of fresh names (the renaming is a bijection); isomorphic states may get
    different keys when two facts have the same shape, which only makes a breadth-first
    search see more states, never a wrong depth. Independent of ``canonical_key``."""
    assert not ctx.rules and not ctx.inert  # compiled ROAR states hold facts only
    lines = [(m, program.show(f), n) for m, f, n in ctx.facts()]
    lines.sort(key=lambda x: (_FRESH.sub(r"\1#", x[1]), x[0], x[2], x[1]))
    ren: dict = {}
    out = []
    for m, text, n in lines:
        out.append((m, _FRESH.sub(lambda mo: ren.setdefault(mo.group(0), f"{mo.group(1)}#{len(ren)}"), text), n))
    return tuple(out)


def shape_of_step(program, step) -> tuple:
    """What a step consumed and produced, printed, fresh names masked."""
    def show(x):
        return _FRESH.sub(r"\1#", program.show(x.source if hasattr(x, "source") else x))
    return (step.rule, sorted(m + show(t) for m, t in step.consumed if m != "!"),
            sorted(m + show(t) for m, t in step.produced))


def bfs_deadlock(program, start):
    """Plain BFS over the engine's enumerator: (number of reachable states, depth of the
    shallowest quiescent state that roar_final rejects or None, its state)."""
    seen = {canonical_key(start)}
    queue = deque([(start, 0)])
    found = None
    while queue:
        ctx, d = queue.popleft()
        choices = program.steps(ctx)
        if not choices and not roar_final(ctx) and found is None:
            found = (d, ctx)  # BFS pops states in non-decreasing depth: the first is shallowest
        for c in choices:
            nxt, _step = program.successor(ctx, c)
            k = canonical_key(nxt)
            if k not in seen:
                seen.add(k)
                queue.append((nxt, d + 1))
    return len(seen), (found[0] if found else None), (found[1] if found else None)


def simple_cycles_exist(n: int, src, dst, keep) -> bool:
    """Is there a cycle through edges ``keep`` (a boolean per edge)? Iterative three-colour DFS."""
    adj: dict[int, list[int]] = {}
    for e in range(len(src)):
        if keep[e]:
            adj.setdefault(int(src[e]), []).append(int(dst[e]))
    colour = [0] * n  # 0 white, 1 on the stack, 2 done
    for root in range(n):
        if colour[root]:
            continue
        colour[root] = 1
        stack = [(root, iter(adj.get(root, ())))]
        while stack:
            u, it = stack[-1]
            for v in it:
                if colour[v] == 1:
                    return True
                if colour[v] == 0:
                    colour[v] = 1
                    stack.append((v, iter(adj.get(v, ()))))
                    break
            else:
                colour[u] = 2
                stack.pop()
    return False


# ------------------------------------------------------------------ 2a. deadlock of mutual_make


def test_mutual_make_deadlock_is_the_shortest_by_an_independent_bfs():
    res = job_result("mutual_make.toml")
    model, start, explorer = res.roar
    program = res.program
    n, depth, dead = big(bfs_deadlock, program, start)
    v = res.verdicts["deadlock"]
    assert depth is not None
    assert v.counterexample.length() == depth == 27
    assert n == res.graph.n_states
    # the reported final state is the one the oracle found, and it is a real deadlock
    final = explorer.states[v.counterexample.final_state]
    assert canonical_key(final) == canonical_key(dead)
    assert program.steps(final) == [] and not roar_final(final)
    # the counterexample path is a path of the engine from the start state
    ctx = start
    for e in v.counterexample.prefix:
        want = shape_of_step(program, explorer.steps[e])
        nexts = [nxt for c in program.steps(ctx) if c.rule == want[0]
                 for nxt, st in [program.successor(ctx, c)] if shape_of_step(program, st) == want]
        assert nexts, f"edge {e} ({want[0]}) is not an enabled step"
        ctx = nexts[0]
    assert canonical_key(ctx) == canonical_key(final)
    # both recipes blocked in make: neither the arm's request nor the door's is final
    events = [ev for step in roar_events(res, v) for ev in step]
    assert any(ev.kind == "sent" and ev.agent == "arm" and "make R1 to door" in ev.text for ev in events)
    assert any(ev.kind == "sent" and ev.agent == "door" and "make R2 to arm" in ev.text for ev in events)


def test_mutual_make_fixed_has_no_deadlock_and_the_same_state_count():
    res = job_result("mutual_make_fixed.toml")
    _model, start, _explorer = res.roar
    n, depth, _ = big(bfs_deadlock, res.program, start)
    assert depth is None
    assert n == res.graph.n_states == 53
    assert res.verdicts["deadlock"].status == "holds"


# ------------------------------------------------------------------ 2b. sequential achievement of ordered_pick


def _sequence_system(res, canonical: bool) -> RoarSystem:
    model, start, _ = res.roar
    opts = Options(progress_rules=PROGRESS_RULES, fairness="agent", canonical=canonical)
    return RoarSystem(model, start, opts, sequential_pairs(model))


def test_ordered_pick_has_one_sequential_pair():
    model = job_result("ordered_pick.toml").roar[0]
    pairs = sequential_pairs(model)
    assert [(p.where, p.a_text, p.b_text) for p in pairs] == [
        ("cell.work.clamp_then_drill", "make(vise::clamped == true)", "make(drill::drilled == true)")]


def test_ordered_pick_violation_is_the_shortest_under_a_renaming_key_written_here():
    res = job_result("ordered_pick.toml")
    v = res.verdicts["sequential-achievement"]
    system = _sequence_system(res, canonical=True)
    program = res.program

    def search():
        start = system.initial()
        seen = {renaming_key(program, start)}
        level, depth = [start], 0
        while level:
            bad = [s for s in level if system.violates_sequence(s)]
            if bad:
                return depth, len(seen)
            nxt_level = []
            for s in level:
                for succ in system.successors(s):  # the engine's steps, plus the monitor's facts
                    k = renaming_key(program, succ.state)
                    if k not in seen:
                        seen.add(k)
                        nxt_level.append(succ.state)
            level, depth = nxt_level, depth + 1
        return None, len(seen)

    depth, _n = big(search)
    assert depth == v.counterexample.length() == 47


def test_ordered_pick_plain_keys_reach_the_same_states_up_to_renaming():
    # A search with Options(canonical=False) (plain keys: fresh names by identity) cannot
    # reach depth 47: every interleaving of the two concurrent subtrees makes its own fresh
    # names, so the plain graph is the tree of interleavings (about 1,100 states at depth
    # 38 against 41 canonical ones; 20,000 states get no deeper than ~40). So the plain
    # search is bounded here, and its levels that are complete are compared with the
    # canonical graph: the same states up to renaming, more plain states, no violation.
    res = job_result("ordered_pick.toml")
    g = res.graph
    _model, _start, cexp = res.roar
    system = _sequence_system(res, canonical=False)
    ex = Explorer(system)
    pg = big(ex.run, Budget(max_states=600))
    assert not pg.complete
    depth = list(pg.depth)
    # level d is complete when every state of depth d - 1 was expanded
    complete = max(d for d in range(max(depth) + 1)
                   if all(pg.expanded[s] for s in range(pg.n_states) if depth[s] < d))
    assert complete >= 30
    plain = {canonical_key(ex.states[s]) for s in range(pg.n_states) if depth[s] <= complete}
    canon = {k for k, s in cexp.ids.items() if g.depth[s] <= complete}
    assert plain == canon
    assert sum(1 for d in depth if d <= complete) > len(canon)  # really plain keys
    assert not any(system.violates_sequence(ex.states[s]) for s in range(pg.n_states))
    assert res.verdicts["sequential-achievement"].counterexample.length() > complete


def test_ordered_pick_events_show_the_drill_spinning_while_the_jaw_presses():
    res = job_result("ordered_pick.toml")
    v = res.verdicts["sequential-achievement"]
    per_step = roar_events(res, v)
    assert len(per_step) == v.counterexample.length()
    flat = [(i, ev) for i, evs in enumerate(per_step, 1) for ev in evs]
    spin = [i for i, ev in flat if ev.kind == "primitive-start" and ev.agent == "drill" and ev.text == "spin()"]
    press = [(i, ev.kind) for i, ev in flat if ev.agent == "jaw" and ev.text.startswith("press()")]
    assert spin and press
    last_press_step, last_press_kind = press[-1]
    assert spin[0] < last_press_step  # the drilling starts before the clamping subtree's command ends
    assert last_press_kind in ("primitive-start", "primitive-end")
    # the last step of the path is the one that breaks the order
    assert last_press_step == len(per_step)
    # the vise reported its clamp done before (the ensure kept the jaw's request alive)
    assert any(ev.agent == "vise" and ev.kind == "state" and ev.data.get("to") == "success"
               and i < spin[0] for i, ev in flat)


# ------------------------------------------------------------------ 2c. livelock of retry_forever


def test_retry_forever_lasso_cycle_replays_on_the_engine():
    res = job_result("retry_forever.toml")
    v = res.verdicts["livelock"]
    cx = v.counterexample
    model, start, explorer = res.roar
    g = res.graph
    program = res.program
    a = g.arrays()
    src, dst = a["src"], a["dst"]
    assert cx.cycle
    # the prefix goes from the start to the cycle's first state; the cycle's edges chain up
    path = list(cx.prefix) + list(cx.cycle)
    assert int(src[path[0]]) == 0
    for e1, e2 in zip(path, path[1:]):
        assert dst[e1] == src[e2]
    first = int(src[cx.cycle[0]])
    assert int(dst[cx.cycle[-1]]) == first

    def run_cycle():
        ctx = explorer.states[first]
        for e in cx.cycle:
            want = shape_of_step(program, explorer.steps[e])
            nexts = [nxt for c in program.steps(ctx) if c.rule == want[0]
                     for nxt, st in [program.successor(ctx, c)] if shape_of_step(program, st) == want]
            assert nexts, f"cycle edge {e} ({want[0]}) is not enabled"
            ctx = nexts[0]
        return ctx

    back = big(run_cycle)
    assert canonical_key(back) == canonical_key(explorer.states[first])
    # every step of the cycle is non-progress, by the graph and by the rule names
    for e in cx.cycle:
        assert not a["progress"][e]
        assert g.labels.names[a["label"][e]] not in PROGRESS_RULES
    moving = {g.groups.names[a["group"][e]] for e in cx.cycle}
    assert "hand" in moving
    # weak fairness per agent: a group enabled in every state of the cycle moves in it
    cycle_states = {int(src[e]) for e in cx.cycle}
    enabled = [{g.groups.names[a["group"][e]] for e in range(g.n_edges) if src[e] == s} for s in cycle_states]
    assert set.intersection(*enabled) <= moving
    # and at the ROAR level the cycle is a retry of the recipe whose grip() fails
    cyc_events = [ev for evs in roar_events(res, v)[len(cx.prefix):] for ev in evs]
    assert any(ev.kind == "primitive-end" and ev.text == "grip() = false" for ev in cyc_events)
    assert any(ev.kind == "recipe" and ev.data.get("recipe") == "close" for ev in cyc_events)
    assert not any(ev.kind == "state" and ev.data.get("to") in ("success", "failure") for ev in cyc_events)


def test_retry_forever_has_non_progress_cycles_by_a_plain_dfs():
    res = job_result("retry_forever.toml")
    a = res.graph.arrays()
    assert simple_cycles_exist(res.graph.n_states, a["src"], a["dst"], ~a["progress"])


def test_retry_bounded_has_no_fair_cycle_and_no_cycle_at_all():
    res = job_result("retry_bounded.toml")
    g = res.graph
    v = res.verdicts["livelock"]
    assert v.status == "holds" and v.counterexample is None
    a = g.arrays()
    # The attempt counter is part of the state, so every retry reaches a new state and
    # after three attempts the request fails: the graph has no cycle at all (it is a tree,
    # one edge fewer than states), let alone a non-progress one. The checker agrees: it
    # did not even find unfair progress-free cycles.
    everything = a["progress"] | ~a["progress"]
    assert not simple_cycles_exist(g.n_states, a["src"], a["dst"], everything)
    assert not simple_cycles_exist(g.n_states, a["src"], a["dst"], ~a["progress"])
    assert g.n_edges == g.n_states - 1
    assert v.details.get("unfair_cycles") is False
    # it ends: every quiescent state is final (a success or the failure after three attempts)
    out = g.out_degree()
    _model, _start, explorer = res.roar
    finals = [s for s in range(g.n_states) if out[s] == 0]
    assert finals and all(roar_final(explorer.states[s]) for s in finals)


# ------------------------------------------------------------------ 3. partial-order reduction


def _deadlock_only_job(tmp: Path, spec: str, expect: str, reduction: bool) -> Path:
    job = tmp / f"{spec}_{'por' if reduction else 'full'}.toml"
    job.write_text(f'name = "{spec} deadlock only"\nspec = "{FAULTY / (spec + ".roar")}"\n'
                   f'request = "arm::started == true"\nreduction = {str(reduction).lower()}\n'
                   f'[expect]\ndeadlock = "{expect}"\n', encoding="utf-8")
    return job


@pytest.mark.parametrize("spec,expect", [("mutual_make", "violated"), ("mutual_make_fixed", "holds")])
def test_reduction_keeps_the_deadlock_verdicts(tmp_path, spec, expect):
    full = job_result(f"{spec}.toml")
    res = run_job(load_job(_deadlock_only_job(tmp_path, spec, expect, True)))
    assert res.reduction == "on"
    assert res.ok, res.mismatches
    assert list(res.verdicts) == ["deadlock"]
    v, w = res.verdicts["deadlock"], full.verdicts["deadlock"]
    assert v.status == w.status == expect
    assert "(partial-order reduction: it saved nothing here, no state having a smaller set of steps" in v.message
    assert v.details["reduced_expansions"] == v.details["steps_left_out"] == 0
    # On these two specs the reducer finds no smaller stubborn set (mutual_make's graph is a
    # single path of 27 steps; both runs report 0 reduced expansions), so today the reduced
    # graph is the full one; only "never larger" is asserted.
    assert res.graph.complete and res.graph.n_states <= full.graph.n_states
    assert {"reduced_expansions", "proviso_expansions"} <= set(res.roar[2].stats())
    if expect == "violated":
        _model, _start, explorer = res.roar
        final = explorer.states[v.counterexample.final_state]
        assert res.program.steps(final) == [] and not roar_final(final)  # quiescent in the full system
        trace = save_counterexample(res, "deadlock", tmp_path / "traces")
        rr = big(lambda: replay(trace, None, res.job.spec, functional=res.job.functional))
        assert rr.steps == v.counterexample.length() and rr.cycle_closes is None
        assert canonical_key(rr.states[-1]) == canonical_key(final)


def test_reduction_with_livelock_confirms_holds_without_reduction(tmp_path):
    job = _deadlock_only_job(tmp_path, "mutual_make_fixed", "holds", True)
    job.write_text(job.read_text() + 'livelock = "holds"\n', encoding="utf-8")
    res = run_job(load_job(job))
    assert res.reduction == "on" and res.ok, res.mismatches
    full = job_result("mutual_make_fixed.toml")
    assert "confirmed without reduction" in res.verdicts["livelock"].message
    assert res.verdicts["livelock"].details["confirmed_states"] == full.graph.n_states


@pytest.mark.parametrize("name", ["retry_forever.toml", "retry_bounded.toml", "ordered_pick.toml",
                                  "ordered_pick_fixed.toml"])
def test_reduction_keeps_every_verdict_of_the_seeded_faults(tmp_path, name):
    """The checker jobs again with reduction on: the same verdicts; a violation's path is a
    path of the full system and still breaks the property there."""
    full = job_result(name)
    job = tmp_path / name
    text = (CHECKER / name).read_text(encoding="utf-8")
    text = text.replace('"../', f'"{ROOT}/')  # the job's paths, from its new folder
    job.write_text("reduction = true\n" + text, encoding="utf-8")
    res = run_job(load_job(job))
    assert res.reduction == "on" and res.ok, res.mismatches
    assert res.graph.n_states <= full.graph.n_states
    for p, v in res.verdicts.items():
        assert v.status == full.verdicts[p].status, p
        if v.violated:
            _model, _start, explorer = res.roar
            trace = save_counterexample(res, p, tmp_path / "traces")
            rr = big(lambda: replay(trace, None, res.job.spec, functional=res.job.functional))  # on the enumerator
            assert rr.steps == v.counterexample.length()
            if v.counterexample.kind == "lasso":
                assert rr.cycle_closes
            if p == "sequential-achievement":
                assert explorer.system.violates_sequence(explorer.states[v.counterexample.final_state])


# ------------------------------------------------------------------ 4. saved traces replay


@pytest.mark.parametrize("name,prop,kinds", [
    ("mutual_make.toml", "deadlock", {"sent", "state", "tasks", "recipe"}),
    ("retry_forever.toml", "livelock", {"state", "primitive-start", "primitive-end", "recipe-end"}),
    ("ordered_pick.toml", "sequential-achievement", {"sent", "state", "abort", "primitive-start"}),
])
def test_saved_counterexamples_replay_with_roar_events(tmp_path, name, prop, kinds):
    res = job_result(name)
    v = res.verdicts[prop]
    path = save_counterexample(res, prop, tmp_path / "traces")
    assert path.parent == tmp_path / "traces" and path.name.endswith(f".{prop}.jsonl")
    header, records = read_trace(path)
    assert header["kind"] == "counterexample" and header["property"] == prop
    assert header["spec"] == str(res.job.spec) and header["request"] == res.job.request
    assert header["shape"] == v.counterexample.kind
    assert len(records) == v.counterexample.length()
    assert sum(1 for r in records if r["loop"]) == len(v.counterexample.cycle)
    with_events = [r["event"] for r in records if r["event"] is not None]
    assert with_events and len(with_events) < len(records)  # bookkeeping steps carry none
    seen = set()
    for ev in with_events:
        for x in (ev["events"] if ev["kind"] == "several" else [ev]):
            seen.add(x["kind"])
            assert x["agent"] and x["text"]
    assert kinds <= seen, seen
    rr = big(lambda: replay(path, None, res.job.spec, functional=res.job.functional))
    assert rr.steps == len(records)
    assert rr.cycle_closes is (True if prop == "livelock" else None)


# ------------------------------------------------------------------ 5. job-file errors


def _write(tmp: Path, text: str) -> Path:
    p = tmp / "job.toml"
    p.write_text(text, encoding="utf-8")
    return p


def _in_error(exc: RoarError, path: Path) -> bool:
    return str(path) in exc.message or (exc.pos is not None and exc.pos.file == str(path))


SPEC = FAULTY / "mutual_make.roar"
MODEL = ROOT / "models" / "philosophers" / "dl.clf"


@pytest.mark.parametrize("text,msg,line", [
    (f'spec = "{SPEC}"\n[expect]\ndeadlock = "violated"\n', "needs 'request", 1),
    (f'model = "{MODEL}"\nspec = "{SPEC}"\nrequest = "arm::started == true"\n[expect]\ndeadlock = "holds"\n',
     "either 'model'", 1),
    (f'name = "m"\nmodel = "{MODEL}"\nrequest = "arm::started == true"\n[expect]\ndeadlock = "holds"\n',
     "'request' belongs to a job on a spec", 3),
    (f'model = "{MODEL}"\nfunctional = "x.py"\n[expect]\ndeadlock = "holds"\n',
     "'functional' belongs to a job on a spec", 2),
    (f'model = "{MODEL}"\n[expect]\nsequential-achievement = "holds"\n', "reads ROAR events", 3),
    (f'spec = "{SPEC}"\nrequest = "arm::started == true"\nbackend = "ground"\n',
     'backend = "ground" runs plain CLF models', 3),   # (it was silently the general backend)
    (f'spec = "{SPEC}"\nrequest = "arm::started == true"\n[expect]\ndeadlock = "violated"\ninvariant = "holds"\n',
     "[expect] invariant: the job's properties do not check it, and [expect] adds it; property 'invariant' needs "
     "patterns", 5),   # (it was at 1:1)
])
def test_spec_job_file_errors_are_located(tmp_path, text, msg, line):
    job = _write(tmp_path, text)
    with pytest.raises(RoarError) as e:
        load_job(job)
    assert msg in e.value.message
    assert _in_error(e.value, job)
    assert e.value.pos is not None and e.value.pos.file == str(job) and e.value.pos.line == line


def test_sequential_achievement_from_a_property_file_on_a_model_job(tmp_path):
    props = tmp_path / "seq.toml"
    props.write_text('check = ["sequential-achievement"]\n', encoding="utf-8")
    job = _write(tmp_path, f'model = "{MODEL}"\nproperties = "{props}"\n')
    with pytest.raises(RoarError) as e:
        load_job(job)
    assert "reads ROAR events" in e.value.message and _in_error(e.value, job)


def _sequence_job(tmp: Path, recipes: list[str]) -> Path:
    props = tmp / "seq.toml"
    props.write_text('check = ["sequential-achievement"]\n[sequential-achievement]\n'
                     f'recipes = {json.dumps(recipes)}\n', encoding="utf-8")
    return _write(tmp, f'spec = "{FAULTY / "ordered_pick_fixed.roar"}"\nrequest = "cell::done == true"\n'
                       f'functional = "{FAULTY / "reliable_tools.py"}"\nproperties = "{props}"\n')


@pytest.mark.parametrize("recipe", ["vise.clamp.close_jaws", "cell.work.no_such_recipe"])
def test_sequence_recipe_without_a_make_make_pair_fails_when_the_job_runs(tmp_path, recipe):
    # vise.clamp.close_jaws exists but makes only one constraint; the other does not exist
    job = _sequence_job(tmp_path, [recipe, "cell.work.clamp_then_drill"])
    loaded = load_job(job)  # the file itself is well formed
    assert loaded.props.sequence_recipes == [recipe, "cell.work.clamp_then_drill"]
    with pytest.raises(RoarError) as e:
        run_job(loaded)
    # at the property file's line and column that name the recipe (it was at the job file)
    props = tmp_path / "seq.toml"
    line = props.read_text(encoding="utf-8").splitlines()[2]
    assert e.value.pos == Pos(str(props), 3, line.index(recipe) + 1)
    why = "no 'make A; make B' pair" if "no_such" not in recipe else "names a recipe the spec does not have"
    assert why in e.value.message and recipe in e.value.message
    assert "clamp_then_drill" not in e.value.message


def test_sequence_recipe_with_a_pair_is_checked(tmp_path):
    res = run_job(load_job(_sequence_job(tmp_path, ["cell.work.clamp_then_drill"])))
    assert res.verdicts["sequential-achievement"].status == "holds"


def test_malformed_sequence_recipe_name_is_located(tmp_path):
    job = _sequence_job(tmp_path, ["cell.clamp_then_drill"])
    with pytest.raises(RoarError) as e:
        load_job(job)
    assert "agent.task.recipe" in e.value.message and e.value.pos.file == str(tmp_path / "seq.toml")


def test_spec_job_error_through_the_cli(tmp_path, capsys):
    job = _write(tmp_path, f'spec = "{SPEC}"\n[expect]\ndeadlock = "violated"\n')
    with pytest.raises(SystemExit) as e:
        main(["check", str(job), "--no-traces"])
    assert e.value.code == 2
    err = capsys.readouterr().err.replace("\n", "")
    assert f"{job}:1:1" in err and "needs 'request" in err and "Traceback" not in err


# ------------------------------------------------------------------ 6. the command


def test_cli_prints_roar_level_counterexample(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    with pytest.raises(SystemExit) as e:
        main(["check", "checker/mutual_make.toml", "--no-traces"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "deadlock: violated" in out and "livelock: holds" in out
    lines = [ln.split() for ln in out.splitlines()]
    numbered = [ln for ln in lines if len(ln) > 2 and ln[0].rstrip(".").isdigit()]
    assert {ln[1] for ln in numbered} == {"arm", "door"}  # each line names the agent
    assert any(" ".join(ln[1:]) == "arm make R1 to door: door::open == true" for ln in numbered)
    assert any(" ".join(ln[1:]) == "door make R2 to arm: arm::parked == true" for ln in numbered)
    assert "final state:" in out and "trace:" not in out
    assert "as expected" in out


def test_cli_json_counterexample_steps_carry_events(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    with pytest.raises(SystemExit) as e:
        main(["check", "checker/mutual_make.toml", "--no-traces", "--json"])
    assert e.value.code == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc) == 1 and doc[0]["ok"] and doc[0]["states"] == job_result("mutual_make.toml").graph.n_states
    d = doc[0]["verdicts"]["deadlock"]
    assert d["status"] == "violated" and d["expected"] == "violated" and "trace" not in d
    steps = d["counterexample"]["steps"]
    assert d["counterexample"]["shape"] == "path" and len(steps) == 27
    events = [s["event"] for s in steps if s["event"] is not None]
    assert events
    flat = [x for ev in events for x in (ev["events"] if ev["kind"] == "several" else [ev])]
    assert {"sent", "state"} <= {x["kind"] for x in flat}
    assert any(x["kind"] == "sent" and x["agent"] == "arm" and x["text"].startswith("make R1 to door") for x in flat)
    assert all(s["group"] in ("arm", "door") for s in steps)
    assert doc[0]["verdicts"]["livelock"]["status"] == "holds"


# ------------------------------------------------------------------ the mask holds only live requests


@pytest.mark.parametrize("name", ["ordered_pick.toml", "ensure_slammed_fixed.toml", "conflict.toml"])
def test_no_reachable_mask_entry_outlives_its_request(name):
    """Regression (an abort between a decision and ``tasks_chosen`` left the committed tree in the
    mask with no holder, reachable in ordered_pick and ensure_slammed_fixed): in every explored
    state, every mask entry belongs to a request that still exists and has neither failed nor been
    aborted. Read from the printed facts, independently of the framework's decoders."""
    res = job_result(name)
    states = res.roar[2].states
    program = res.program
    for sid in range(res.graph.n_states):
        facts = [program.show(f) for _m, f, _n in states[sid].facts()]
        live = {f.split()[1] for f in facts if f.startswith("rq ")}
        gone = {f.split()[1] for f in facts if f.startswith("rs ") and f.split()[2] in ("s_failure", "s_aborted")}
        held = {r for f in facts if f.startswith("mask ") for r in re.findall(r"\(vreq ([^ )]+)\)", f)}
        assert held <= live - gone, (sid, held - (live - gone))


def test_a_time_bound_is_reported_as_the_job_wrote_it(tmp_path):
    """The search gets what the bound leaves after compiling; the verdict names the bound the user
    wrote (a check with --max-seconds 150 used to say 'time budget of 116.3 s')."""
    from roar_formal.verify.check import run_job
    job = _write(tmp_path, f'spec = "{ROOT / "models" / "spa_loop.roar"}"\n'
                           f'request = "exec::arrived == true where exec::goal == 7"\n'
                           f'[bounds]\nmax_seconds = 3\n')
    res = run_job(load_job(job))
    assert not res.graph.complete
    assert "time budget of 3 s reached, loading and compiling included" in res.graph.stop_reason


def test_the_printed_replay_command_names_the_jobs_functional_module(tmp_path):
    """A job that names its functional-layer module: the replay command printed with its
    counterexample names it too (replay checks the recorded sources; without it, the command as
    printed was refused)."""
    from roar_formal.testing import replay
    from roar_formal.verify.check import run_job, save_counterexample
    from roar_formal.verify.report import replay_command
    job = load_job(ROOT / "checker" / "ordered_pick.toml")
    assert job.functional is not None
    res = run_job(job)
    trace = save_counterexample(res, "sequential-achievement", tmp_path)
    cmd = replay_command(job, trace)
    assert f"--functional {job.functional}" in cmd
    rep = replay(trace, model=job.spec, functional=job.functional)
    assert rep.confirmed
