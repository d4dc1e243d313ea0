"""Robot-backed exploration: the explorer over (CLF state, robot state) pairs (robot/explore.py, verify/robot.py).

Oracles: a plain enumerator of every path of a small spec (a fresh robot per path, the events
replayed from the start: no tree, no snapshot); a straight-line robot driven through a
counterexample (replay --on-robot); the ROAR narrator's events on explored paths.
"""

from __future__ import annotations

import copy
import itertools
import json
import re
import math
from pathlib import Path

import pytest

from roar_formal.clf.query import with_big_stack
from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.robot.explore import Abstraction, robot_key
from roar_formal.trace.format import read_trace

from repo import ROOT
DATA = Path(__file__).parent / "data" / "explore"
DOOR = ROOT / "checker" / "robot" / "door_nav.toml"
STUCK = ROOT / "checker" / "robot" / "door_nav_stuck.toml"
CABLE = ROOT / "checker" / "robot" / "conflict_cable.toml"


def _job(path: Path, compare: bool = False, **robot):
    job = load_job(path)
    job.robot.compare = compare
    for k, v in robot.items():
        setattr(job.robot, k, v)
    return job


# ------------------------------------------------------------------ the door scenario


@pytest.fixture(scope="module")
def door():
    return run_job(_job(DOOR))


def test_door_no_deadlock_no_livelock(door):
    assert door.verdicts["deadlock"].status == "holds"
    assert door.verdicts["livelock"].status == "holds"
    assert door.graph.complete
    assert "robot-backed" in door.verdicts["deadlock"].message
    # the abstraction is printed with the verdicts
    assert "position 0.05 m" in door.robot.describe() and "door_closes at drive" in door.robot.describe()


def test_door_has_the_paused_then_resumed_path_to_the_goal(door):
    """A path to a final state where the door closed: the base's recipe is paused, then resumed,
    and the robot arrives (the paper's figure 3 on the robot)."""
    from roar_formal.roar.explore import path_events
    g = door.graph
    ex = door.robot.explorer
    finals = [s for s in range(g.n_states) if door.robot.system.final(ex.states[s]) and
              not door.robot.system.successors(ex.states[s])]
    assert finals
    found = None
    for s in finals:
        node = ex.states[s].node
        if "door_closes" in node.armed:
            found = s
            break
    assert found is not None, "no final state with the door fault armed"
    edges = g.path_to(found)
    model, start, _ = door.roar
    texts = [e.text for e in path_events(model, start, [ex.steps[e] for e in edges])]
    paused = next(i for i, t in enumerate(texts) if "running -> paused" in t)
    resumed = next(i for i, t in enumerate(texts) if "paused -> running" in t and i > paused)
    assert paused < resumed
    node = ex.states[found].node
    assert math.hypot(node.pose[0] - 9.0, node.pose[1] - 3.0) < 0.25
    # and without the fault the robot arrives sooner
    plain = [ex.states[s].node.time for s in finals if not ex.states[s].node.armed]
    assert plain and min(plain) < node.time


def test_door_never_reopening_livelock_replays_on_the_robot(tmp_path):
    """With the door staying closed the planner retries forever in front of the door: a fair
    livelock whose counterexample a straight robot run realises, ending at the same pose."""
    from roar_formal.robot.setup import prepare
    from roar_formal.robot.onrobot import replay_robot_path
    res = run_job(_job(STUCK))
    v = res.verdicts["livelock"]
    assert v.status == "violated" and v.counterexample.cycle
    assert res.verdicts["deadlock"].status == "holds"
    path = save_counterexample(res, "livelock", tmp_path)
    header, records = read_trace(path)
    assert header["robot"]["faults"] == {"door_stays_closed": ["drive"]}
    assert all("pose" in r and "t" in r for r in records)
    assert any(r.get("robot", {}).get("arm") == ["door_stays_closed"] for r in records)
    _ast, model, binding, sc = prepare(res.job.spec, res.job.request, res.job.robot.scenario)
    rp = replay_robot_path(model, binding.robot, sc, header, records, loops=2)
    assert rp.realised, rp.message
    stem_end = [r for r in records if not r.get("loop")][-1]["pose"]
    assert max(abs(a - b) for a, b in zip(rp.robot.world.base.pose[:2], stem_end[:2])) < 0.05
    assert rp.robot.world.base.pose[0] < 6.0   # in front of the closed door
    assert not rp.robot.world.door_open("d1")
    # a doctored trace is not realised: the robot's answer differs from the recorded one
    bad = copy.deepcopy(records)
    rec = next(r for r in bad if r.get("robot", {}).get("kind") == "advance" and r["robot"]["ended"])
    rec["robot"]["ended"][0]["result"]["status"] = "teleported"
    assert not replay_robot_path(model, binding.robot, sc, header, bad).realised


def test_replay_cli_on_a_robot_counterexample(tmp_path, roar_cli):
    res = run_job(_job(CABLE))
    path = save_counterexample(res, "livelock", tmp_path)
    png = tmp_path / "cx.png"
    model = ROOT / "models" / "conflict.roar"
    code, out, err = roar_cli("replay", path, "--model", model, "--on-robot",
                              ROOT / "models" / "scenarios" / "ptu_cable.toml", "--png", png)
    assert code == 0, out + err
    assert "realised on the robot" in out and png.stat().st_size > 1000
    # the scenario is checked against the trace's fingerprint
    code, out, err = roar_cli("replay", path, "--model", model, "--on-robot",
                              ROOT / "models" / "scenarios" / "door.toml")
    assert code == 2 and "another scenario" in err
    code, out, err = roar_cli("replay", path, "--model", model)
    assert code == 2 and "--on-robot" in err
    # the same trace is a ROAR run TCA reads: its requests and calls as a task tree
    code, out, err = roar_cli("tca-check", path)
    assert code == 0, out + err
    n = int(out.split(": ", 1)[1].split(" messages")[0])
    assert n > 0 and "no violations" in out


def test_cable_reproduces_the_conflict_livelock_as_a_lasso():
    res = run_job(_job(CABLE))
    v = res.verdicts["livelock"]
    assert v.status == "violated"
    cx = v.counterexample
    assert cx.kind == "lasso" and cx.cycle
    ex = res.robot.explorer
    loop_states = [ex.states[int(res.graph.dst[e])] for e in cx.cycle]
    assert all("cable" in s.node.armed for s in loop_states)
    labels = [res.graph.labels.names[res.graph.label[e]] for e in cx.cycle]
    assert any(lab.startswith("launch ptu::turn_to(30)") for lab in labels)
    # the pan stands at the cable's limit, short of its target
    robot = res.robot.tree.robot_at(loop_states[0].node)
    assert abs(robot.world.ptu.angle_deg) <= 21.0 and robot.world.ptu.target_deg == 30.0
    assert res.verdicts["deadlock"].status == "holds"


# ------------------------------------------------------------------ robot invariants


def test_robot_invariant_violated_on_the_wall_and_holds_in_the_fixed_twin():
    bad = run_job(load_job(DATA / "bump_wall.job.toml"))
    good = run_job(load_job(DATA / "bump_clear.job.toml"))
    v = bad.verdicts["robot-invariant"]
    assert v.status == "violated" and "contact" in v.message and "during the advance" in v.message
    assert good.verdicts["robot-invariant"].status == "holds" and good.graph.complete
    assert bad.ok and good.ok   # both as their jobs expect
    # the violation is real: a straight robot driving the counterexample touches the wall
    from roar_formal.robot.robot import Robot
    node = bad.robot.explorer.states[v.counterexample.final_state].node
    robot = Robot(bad.robot.scenario)
    robot.world.base.set_wheel_speeds(6.0, 6.0)
    touched = False
    while robot.world.steps < node.tick and not touched:
        robot.step()
        touched = robot.world.base.bumped
    assert touched


def test_check_png_draws_the_trajectory_with_the_violation_marked(roar_cli, tmp_path):
    code, out, err = roar_cli("check", DATA / "bump_wall.job.toml", "--png", tmp_path, "--no-traces")
    assert code == 0, out + err
    pic = tmp_path / "bump_wall.robot-invariant.robot.png"
    assert pic.stat().st_size > 5000 and f"picture: {pic}" in out
    # the robot is shown where the invariant broke (mid-advance), then where the step left it
    broke = re.search(r"at t = (\d+\.\d\d) s \(contact = true\) during the advance", out)
    shown = re.search(r"robot    t = (\d+\.\d\d) s, at .*: the invariant breaks here, during the last step"
                      r"[^\n]*\n\s+at t = (\d+\.\d\d) s", out)
    assert broke and shown, out
    assert shown.group(1) == broke.group(1) and float(shown.group(2)) > float(shown.group(1))


def test_robot_invariant_errors_are_located(tmp_path):
    props = tmp_path / "p.toml"
    props.write_text('[robot-invariant]\nnever = ["contact &&"]\n')
    job = tmp_path / "j.toml"
    job.write_text(f'spec = "{DATA / "bump.roar"}"\nrequest = "base::done == true"\nproperties = ["p.toml"]\n'
                   f'[robot]\nscenario = "{DATA / "bump_clear.toml"}"\ncompare = false\n')
    with pytest.raises(RoarError) as e:
        run_job(load_job(job))
    assert e.value.pos is not None and e.value.pos.line == 2 and e.value.pos.file.endswith("p.toml")
    job.write_text(f'spec = "{DATA / "bump.roar"}"\nrequest = "base::done == true"\nproperties = ["p.toml"]\n')
    props.write_text('[robot-invariant]\nnever = ["contact"]\n')
    with pytest.raises(RoarError, match="robot-backed job"):
        load_job(job)


def test_bad_robot_tables_are_located(tmp_path):
    job = tmp_path / "j.toml"
    base = f'spec = "{DATA / "bump.roar"}"\nrequest = "base::done == true"\n'
    job.write_text(base + f'[robot]\nscenario = "{DATA / "pair.toml"}"\nfaults = ["blnd"]\n[expect]\ndeadlock = "holds"\n')
    with pytest.raises(RoarError, match="did you mean 'blind'"):
        run_job(load_job(job))
    job.write_text(base + f'[robot]\nscenario = "{DATA / "pair.toml"}"\nquantise = {{ position = -1 }}\n')
    with pytest.raises(RoarError, match="position must be a positive number") as e:
        load_job(job)
    assert e.value.pos.line == 5
    job.write_text(base + f'[robot]\nscenario = "{DATA / "pair.toml"}"\nfaults = {{ blind = ["fly"] }}\n'
                   '[expect]\ndeadlock = "holds"\n')
    with pytest.raises(RoarError, match="'fly' is not a function the spec calls"):
        run_job(load_job(job))


# ------------------------------------------------------------------ state matching


def test_coarser_quantisation_merges_what_a_finer_one_separates():
    fine = run_job(_job(DATA / "pair.job.toml", quantise=Abstraction(position=0.001, heading=0.1)))
    coarse = run_job(_job(DATA / "pair.job.toml", quantise=Abstraction(position=1.0, heading=90.0)))
    assert fine.graph.complete and coarse.graph.complete
    assert coarse.graph.n_states < fine.graph.n_states
    # two states the fine abstraction tells apart that the coarse one identifies
    ex = fine.robot.explorer
    coarse_a = Abstraction(position=1.0, heading=90.0)
    seen: dict = {}
    merged = False
    for st in ex.states:
        robot = fine.robot.tree.robot_at(st.node)
        k_coarse = (canonical_key(st.ctx), robot_key(robot, coarse_a))
        k_fine = fine.robot.system.key(st)
        if k_coarse in seen and seen[k_coarse] != k_fine:
            merged = True
            break
        seen[k_coarse] = k_fine
    assert merged
    for res in (fine, coarse):   # the quantisation is part of every verdict's details
        assert all("abstraction:" in v.details["robot"] for v in res.verdicts.values())


def test_exact_state_count_matches_an_independent_enumeration():
    """Every path of pair.roar on pair.toml, enumerated one by one: agent steps first, then every
    order and fault choice of the pending calls, then the physics. A fresh robot per robot
    event, replayed from the start (no tree, no snapshot). States are told apart as the exact
    abstraction does: by CLF state up to renaming and robot history."""
    res = run_job(load_job(DATA / "pair.job.toml"))
    assert res.graph.complete
    want = with_big_stack(_enumerate, res)
    assert res.graph.n_states == want["states"]
    from roar_formal.roar.explore import roar_final
    finals = sorted(round(s.node.time, 4) for s in res.robot.explorer.states
                    if roar_final(s.ctx) and not s.node.at_horizon and not res.robot.system.successors(s))
    assert finals == sorted(want["final_times"])


def _enumerate(res) -> dict:
    from roar_formal.clf.rules import LIN
    from roar_formal.clf.terms import Const, Root, const
    from roar_formal.robot.robot import Robot
    from roar_formal.robot.sim import poll_period, result_term
    from roar_formal.roar.run import Values, list_items
    from roar_formal.roar.explore import roar_final
    model = res.roar[0]
    registry = res.robot.tree.registry
    scenario = res.robot.scenario
    program = model.program()
    start = res.roar[1]
    values = Values(model)
    horizon = round(scenario.horizon / scenario.dt)
    faults = list(res.job.robot.faults)

    def robot_after(events):
        r = Robot(scenario, seed=0)
        out = None
        for ev in events:
            if ev[0] == "launch":
                for f in ev[2]:
                    r.world.arm(f)
                out = []
                for fc, args in ev[1]:
                    owner, name = model.functions[fc]
                    v = registry.lookup(name, owner)(*args)
                    out.append(r.start(v))
            else:
                done = []
                stop = horizon if ev[1] is None else min(horizon, ev[1])
                while not done and r.world.steps < stop:
                    done = r.step()
                out = done
        return r, out

    seen = set()
    finals = []

    def fams(ctx, name):
        b = ctx.index.get(Const(name))
        return list(b.items) if b else []

    def visit(ctx, events, handles, tick):
        key = (canonical_key(ctx), tuple((e[0], repr(e[1]), e[2] if e[0] == "launch" else None) for e in events))
        if key in seen:
            return
        seen.add(key)
        if tick >= horizon:
            return
        steps = program.steps(ctx)
        if steps:
            for c in steps:
                nxt, step = program.successor(ctx, c)
                p = poll_period(model, step)
                if p is not None:
                    ctl = next(f for _m, f in step.produced if type(f) is Root and f.head.name == "ctl")
                    nxt.remove_fact(ctl, LIN)
                    nxt.add_fact(const("rb_sleep", ctl, const(f"rbt_{max(1, round(p / scenario.dt))}")), LIN)
                visit(nxt, events, handles, tick)
            return
        running = {f.args[0] for f in fams(ctx, "rb_run")}
        fresh = [f for f in fams(ctx, "pending") if f.args[2] not in running]
        if fresh:
            for order in itertools.permutations(fresh):
                calls = []
                for f in order:
                    fc = f.args[0].head.name
                    calls.append((fc, [values.python(x) for x in list_items(f.args[1])]))
                armed = {n for e in events if e[0] == "launch" for n in e[2]}
                free = [n for n in faults if n not in armed]
                for k in range(len(free) + 1):
                    for sub in itertools.combinations(free, k):
                        ev = ("launch", calls, tuple(sorted(sub)))
                        robot, out = robot_after(events + [ev])
                        nxt = ctx.copy()
                        hs = dict(handles)
                        for f, (h, r) in zip(order, out):
                            if r is None:
                                nxt.add_fact(const("rb_run", f.args[2]), LIN)
                                hs[f.args[2]] = h
                            else:
                                t = result_term(model, values, f.args[0].head.name, r)
                                nxt.remove_fact(f, LIN)
                                nxt.add_fact(const("return", t, f.args[2]) if t is not None
                                             else const("callfail", f.args[2]), LIN)
                        visit(nxt, events + [ev], hs, robot.world.steps)
            return
        sleepers = fams(ctx, "rb_sleep")
        if running or sleepers:
            rem = [int(f.args[1].head.name[4:]) for f in sleepers]
            until = tick + min(rem) if rem else None
            ev = ("advance", until, ())
            robot, done = robot_after(events + [ev])
            elapsed = robot.world.steps - tick
            nxt = ctx.copy()
            hs = dict(handles)
            inv = {h: d for d, h in hs.items()}
            pend = {f.args[2]: f for f in fams(ctx, "pending")}
            for h, r in done:
                d = inv[h]
                del hs[d]
                nxt.remove_fact(const("rb_run", d), LIN)
                f = pend[d]
                t = result_term(model, values, f.args[0].head.name, r)
                nxt.remove_fact(f, LIN)
                nxt.add_fact(const("return", t, d) if t is not None else const("callfail", d), LIN)
            for f in sleepers:
                nxt.remove_fact(f, LIN)
                left = int(f.args[1].head.name[4:]) - elapsed
                nxt.add_fact(f.args[0] if left <= 0 else const("rb_sleep", f.args[0], const(f"rbt_{left}")), LIN)
            visit(nxt, events + [ev], hs, robot.world.steps)
            return
        if roar_final(ctx):
            finals.append(tick * scenario.dt)

    visit(start, [], {}, 0)
    return {"states": len(seen), "final_times": [round(t, 4) for t in finals]}


# ------------------------------------------------------------------ side by side, budgets, CLI


def test_side_by_side_names_why_the_verdicts_differ():
    res = run_job(_job(DATA / "bump_wall.job.toml", compare=True))
    rows = {p: (a, r, why) for p, a, r, why in res.robot.comparison}
    assert "deadlock" in rows
    a, r, why = rows["deadlock"]
    assert (a == r and why == "agree") or "not realised" in why


def test_a_budget_gives_incomplete_never_holds():
    job = _job(DATA / "pair.job.toml")
    job.budget.max_states = 50
    res = run_job(job)
    assert not res.graph.complete
    assert {v.status for v in res.verdicts.values()} == {"incomplete"}


def test_a_comparison_cut_short_says_which_search_ran_out():
    job = _job(DATA / "pair.job.toml", compare=True)
    job.budget.max_states = 50
    res = run_job(job)
    rows = {p: why for p, a, r, why in res.robot.comparison}
    assert rows and all(why.startswith("no comparison: both searches ran out of budget (the abstract model's after ")
                        and re.search(r"the robot's after \d+ states\)$", why) for why in rows.values()), rows


def test_check_prints_the_abstraction_and_the_comparison(roar_cli):
    code, out, err = roar_cli("check", DATA / "pair.job.toml", "--no-traces", "--json")
    assert code == 0, out + err
    data = json.loads(out)
    assert data[0]["backend"] == "robot" and data[0]["robot"]["abstraction"]["exact"] is True
    assert data[0]["robot"]["robot_states"] > 1


def test_the_comparison_search_reports_its_progress_as_its_own(monkeypatch):
    """The abstract model's search (often the longer one) reports progress through the job's
    callback, each report marked as the abstract model's (the command line shows it so)."""
    import roar_formal.verify.robot as vr
    real = vr.run_roar_job
    handed: list = []

    def spy(job, on_progress):
        handed.append(on_progress)
        return real(job, on_progress)

    monkeypatch.setattr(vr, "run_roar_job", spy)
    seen: list = []
    run_job(_job(DATA / "bump_wall.job.toml", compare=True), on_progress=seen.append)
    assert len(handed) == 1 and handed[0] is not None
    handed[0]({"states": 7, "transitions": 9})
    assert seen[-1] == {"states": 7, "transitions": 9, "phase": "abstract model"}
