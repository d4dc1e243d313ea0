"""Symmetry reduction (explore/symmetry.py, roar/symmetry.py; docs/checking.md, Symmetry
reduction): the quotient search gives the plain search's verdicts in fewer states, the plain
count is the sum of the quotient states' orbit sizes, counterexamples are real paths that
replay, and a permutation that does not map the model onto itself is never used."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from roar_formal.clf.program import Program
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.signature import ExecDirective
from roar_formal.errors import RoarError
from roar_formal.explore.search import Explorer
from roar_formal.explore.symmetry import (ConstPerm, SymmetricSystem, close_group, discover_clf, transpositions,
                                          verify)
from roar_formal.explore.system import ClfSystem
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.verify.replay import replay_trace

from repo import ROOT

DATA = Path(__file__).parent / "data" / "symmetry"


def clf(name: str):
    program = Program.from_file(DATA / name if not str(name).startswith("/") else name)
    d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
    return program, program.start_context(d.start)


def job_file(tmp_path: Path, text: str, name: str = "job.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def both(tmp_path: Path, body: str):
    """(plain result, symmetric result) of a job whose text is ``body`` (paths relative to DATA)."""
    for f in DATA.iterdir():
        if f.suffix in (".clf", ".roar", ".py") and not (tmp_path / f.name).exists():
            shutil.copy(f, tmp_path / f.name)
    plain = with_big_stack(lambda: run_job(load_job(job_file(tmp_path, body, "plain.toml"))))
    sym = with_big_stack(lambda: run_job(load_job(job_file(tmp_path, "symmetry = true\n" + body, "sym.toml"))))
    return plain, sym


def orbit_sum(system: SymmetricSystem) -> tuple[int, int]:
    """(quotient states, sum of their orbit sizes): the orbits computed independently, by applying
    every element of the group to each stored representative and counting distinct states."""
    ex = Explorer(system)
    g = ex.run()
    assert g.complete
    total = 0
    for sid in range(g.n_states):
        state = ex.states[sid]
        images = {system.inner.key(p.context(state)) for p in system.group}
        total += len(images)
    return g.n_states, total


# ---------------------------------------------------------------- plain CLF models


@pytest.mark.parametrize("model,expect", [("forks3.clf", "violated"), ("mutex3.clf", "holds")])
def test_clf_quotient_same_verdict_fewer_states(tmp_path, model, expect):
    plain, sym = both(tmp_path, f'model = "{model}"\n[expect]\ndeadlock = "{expect}"\n')
    assert plain.verdicts["deadlock"].status == sym.verdicts["deadlock"].status == expect
    assert sym.graph.n_states < plain.graph.n_states
    assert "group of order" in sym.symmetry and "states of the quotient" in sym.verdicts["deadlock"].message
    assert sym.ok and plain.ok


@pytest.mark.parametrize("model,order", [("forks3.clf", 36), ("mutex3.clf", 6)])
def test_clf_plain_count_is_the_sum_of_orbit_sizes(model, order):
    program, start = clf(model)
    blocks, notes = discover_clf(program, start)
    assert not notes
    group = close_group(transpositions(blocks))
    assert len(group) == order
    n_quotient, total = orbit_sum(SymmetricSystem(ClfSystem(program, start), group))
    g = Explorer(ClfSystem(program, start)).run()
    assert g.complete and n_quotient < g.n_states
    assert total == g.n_states


def test_clf_deadlock_counterexample_is_a_real_path_that_replays(tmp_path):
    _plain, sym = both(tmp_path, 'model = "forks3.clf"\n[expect]\ndeadlock = "violated"\n')
    trace = save_counterexample(sym, "deadlock", tmp_path)
    rep = with_big_stack(lambda: replay_trace(trace, tmp_path / "forks3.clf"))
    assert rep.confirmed is True, rep.confirmation


def test_start_state_that_tells_constants_apart_gives_no_symmetry(tmp_path):
    program, start = clf("ring3.clf")
    blocks, notes = discover_clf(program, start)
    assert blocks == [] and notes and "p1, p2, p3" in notes[0]
    chk = verify(program.sig, start, ConstPerm({"p1": "p2", "p2": "p1"}))
    assert not chk.ok and "start state" in chk.reason
    _plain, sym = both(tmp_path, 'model = "ring3.clf"\n[expect]\ndeadlock = "holds"\n')
    assert sym.symmetry.startswith("symmetry: none found") and "start state tells them apart" in sym.symmetry
    assert "symmetry: none found" in sym.verdicts["deadlock"].message


def test_a_permutation_that_does_not_map_the_rules_is_rejected():
    program, start = clf(ROOT / "models" / "clf" / "deadlock.clf")
    chk = verify(program.sig, start, ConstPerm({"l1": "l2", "l2": "l1"}))
    assert not chk.ok and "has no image" in chk.reason and re.search(r"'[pq]_[ab]'", chk.reason)


def test_group_order_is_capped():
    gens = transpositions([[{"": f"c{i}"} for i in range(5)]])
    assert len(close_group(gens)) == 120
    with pytest.raises(RoarError, match="more than 100 elements"):
        close_group(gens, limit=100)


def test_job_option_bad_value_is_located():
    with pytest.raises(RoarError) as e:
        load_job(DATA / "bad_value.toml")
    assert e.value.pos is not None and (e.value.pos.line, e.value.pos.col) == (2, 12)
    assert "true or false" in e.value.message


def test_cycle_properties_are_refused_at_the_option(tmp_path):
    shutil.copy(DATA / "mutex3.clf", tmp_path / "mutex3.clf")
    job_file(tmp_path, 'check = ["livelock"]\n[livelock]\nprogress = ["enter"]\n', "p.toml")
    p = job_file(tmp_path, 'model = "mutex3.clf"\nsymmetry = true\nproperties = ["p.toml"]\n[expect]\n'
                           'livelock = "holds"\n')
    with pytest.raises(RoarError) as e:
        load_job(p)
    assert "symmetry reduction does not keep" in e.value.message and e.value.pos.line == 2


def test_invariant_naming_a_permuted_constant_is_refused_where_it_is_written(tmp_path):
    shutil.copy(DATA / "mutex3.clf", tmp_path / "mutex3.clf")
    props = job_file(tmp_path, 'check = ["invariant"]\n[invariant]\nnever = ["crit p1 * crit P"]\n', "p.toml")
    p = job_file(tmp_path, f'model = "mutex3.clf"\nsymmetry = true\nproperties = ["{props.name}"]\n'
                           '[expect]\ninvariant = "holds"\n')
    with pytest.raises(RoarError) as e:
        with_big_stack(lambda: run_job(load_job(p)))
    assert "p1" in e.value.message and e.value.pos is not None and e.value.pos.file.endswith("p.toml")
    # an invariant pattern the group leaves alone is decided on the quotient, as without symmetry
    props.write_text('check = ["invariant"]\n[invariant]\nnever = ["crit P * crit Q"]\n', encoding="utf-8")
    res = with_big_stack(lambda: run_job(load_job(p)))
    assert res.verdicts["invariant"].status == "holds" and res.graph.n_states == 7


# ---------------------------------------------------------------- ROAR specs


def roar_model(name: str):
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.spec import load_spec

    def go():
        m = compile_spec(load_spec(DATA / name), "planner::done == true", functional="abstract")
        prog = m.program()
        d = next(d for d in prog.sig.directives if isinstance(d, ExecDirective))
        return m, prog.start_context(d.start)
    return with_big_stack(go)


ROAR_JOB = 'spec = "{spec}"\nrequest = "planner::done == true"\n[expect]\ndeadlock = "holds"\n' \
           'mission-failure = "{failure}"\n'


def test_roar_identical_agents_that_act_are_told_apart_by_their_sender():
    """fan-3 of B8: the planner sends to w1 first; exchanging w1 and w2 maps that statement onto
    one the model does not have, so the candidate is refused and the search is the plain one."""
    from roar_formal.roar.symmetry import candidates, discover
    model, start = roar_model("fan3.roar")
    assert candidates(model) == [["w1", "w2"]]
    sym = with_big_stack(lambda: discover(model, start))
    assert sym.order == 1 and sym.blocks == []
    assert "w1 and w2 have identical specs" in sym.rejected[0] and "has no image" in sym.rejected[0]
    assert "; in the spec: recipe planner." in sym.rejected[0]   # what the compiled name stands for
    assert sym.note().startswith("symmetry: none found")


def test_roar_fan_job_with_symmetry_is_the_plain_search_and_says_so(tmp_path):
    plain, sym = both(tmp_path, ROAR_JOB.format(spec="fan3.roar", failure="holds") + "[bounds]\nmax_states = 1500\n")
    assert {p: v.status for p, v in plain.verdicts.items()} == {p: v.status for p, v in sym.verdicts.items()}
    assert plain.graph.n_states == sym.graph.n_states and plain.graph.n_edges == sym.graph.n_edges
    assert "symmetry: none found" in sym.verdicts["deadlock"].message


def test_roar_idle_twins_are_verified_and_exact(tmp_path):
    from roar_formal.roar.explore import RoarSystem
    from roar_formal.roar.symmetry import discover
    model, start = roar_model("twins.roar")
    sym = with_big_stack(lambda: discover(model, start))
    assert sym.order == 2 and sym.blocks == [["w1", "w2"]]
    assert sym.note() == "symmetry: 2 agents interchangeable (w1, w2), group of order 2"
    swap = sym.group[1]   # the exchange renames the workers' compiled rules too (found by their types)
    assert swap.rules.get("body_r_w1_work_r") == "body_r_w2_work_r"
    assert any(k.startswith("st") and v.startswith("st") for k, v in swap.rules.items())
    n_quotient, total = with_big_stack(lambda: orbit_sum(SymmetricSystem(RoarSystem(model, start), sym.group)))
    g = with_big_stack(lambda: Explorer(RoarSystem(model, start)).run())
    assert total == g.n_states and n_quotient <= g.n_states
    plain, symres = both(tmp_path, ROAR_JOB.format(spec="twins.roar", failure="violated"))
    assert {p: v.status for p, v in plain.verdicts.items()} == {p: v.status for p, v in symres.verdicts.items()}
    assert "2 agents interchangeable" in symres.verdicts["mission-failure"].message
    # the counterexample is a real path of the model: it replays and its claim is confirmed
    trace = save_counterexample(symres, "mission-failure", tmp_path)
    rep = with_big_stack(lambda: replay_trace(trace, tmp_path / "twins.roar"))
    assert rep.confirmed is not False, rep.confirmation


def test_roar_agents_that_differ_in_one_statement_are_no_candidates_and_fail_verification():
    from roar_formal.explore.symmetry import verify as check
    from roar_formal.roar.symmetry import LABELS, candidates, roles
    model, start = roar_model("differ.roar")
    assert candidates(model) == []
    r1, r2 = roles(model, "w1"), roles(model, "w2")
    m = {}
    for role, x in r1.items():
        m[x], m[r2[role]] = r2[role], x
    chk = with_big_stack(lambda: check(model.program().sig, start, ConstPerm(m), LABELS))
    assert not chk.ok and "has no image" in chk.reason


def test_roar_property_naming_a_permuted_agent_is_refused(tmp_path):
    for f in ("twins.roar",):
        shutil.copy(DATA / f, tmp_path / f)
    props = job_file(tmp_path, 'check = ["invariant"]\n[invariant]\nalways = ["w1::tries == 0"]\n', "p.toml")
    p = job_file(tmp_path, 'spec = "twins.roar"\nrequest = "planner::done == true"\nsymmetry = true\n'
                           f'properties = ["{props.name}"]\n[expect]\ninvariant = "holds"\n')
    with pytest.raises(RoarError) as e:
        with_big_stack(lambda: run_job(load_job(p)))
    assert "w1" in e.value.message and e.value.pos is not None and e.value.pos.file.endswith("p.toml")
    assert e.value.pos.line == 3


def test_roar_default_properties_with_symmetry_are_refused_with_advice(tmp_path):
    shutil.copy(DATA / "twins.roar", tmp_path / "twins.roar")
    p = job_file(tmp_path, 'spec = "twins.roar"\nrequest = "planner::done == true"\nsymmetry = true\n')
    with pytest.raises(RoarError, match="mission-completion") as e:
        load_job(p)
    assert "deadlock,mission-failure" in e.value.message and e.value.pos.line == 3


def test_a_cycle_of_the_quotient_lifts_to_a_real_cycle():
    """concrete_lasso follows a cycle of orbits by real steps until a real state repeats."""
    from roar_formal.explore.symmetry import concrete_lasso
    program, start = clf("mutex3.clf")
    blocks, _ = discover_clf(program, start)
    system = SymmetricSystem(ClfSystem(program, start), close_group(transpositions(blocks)))
    inner = system.inner
    s1 = next(s for s in inner.successors(start) if s.label == "want")
    s2 = next(s for s in inner.successors(s1.state) if s.label == "enter")
    s3 = next(s for s in inner.successors(s2.state) if s.label == "leave")
    keys = [system.key(x.state) for x in (s1, s2, s3)]
    assert keys[-1] == system.key(start)
    got = concrete_lasso(system, [start], keys)
    assert got is not None
    stem, cycle = got
    assert cycle and len(cycle) % 3 == 0
    cur = start
    for succ in stem + cycle:   # every step is a real successor of the state before it
        assert any(inner.key(x.state) == inner.key(succ.state) for x in inner.successors(cur))
        cur = succ.state
    first = stem[-1].state if stem else start
    assert inner.key(cur) == inner.key(first)


def test_symmetry_needs_canonical_keys(tmp_path):
    shutil.copy(DATA / "mutex3.clf", tmp_path / "mutex3.clf")
    p = job_file(tmp_path, 'model = "mutex3.clf"\ncanonical = false\nsymmetry = true\n[expect]\ndeadlock = "holds"\n')
    with pytest.raises(RoarError, match="canonical = false"):
        load_job(p)


def test_the_command_line_flag(roar_cli, tmp_path):
    shutil.copy(DATA / "forks3.clf", tmp_path / "forks3.clf")
    code, out, err = roar_cli("check", str(tmp_path / "forks3.clf"), "--symmetry", "--traces", str(tmp_path / "t"))
    assert code == 1   # the deadlock, which nothing expects
    assert "symmetry: 6 constants interchangeable (p1, p2, p3; f1, f2, f3), group of order 36" in out
    assert "(6 states," in out
    (tmp_path / "p.toml").write_text('check = ["livelock"]\n[livelock]\nprogress = ["done"]\n', encoding="utf-8")
    job = job_file(tmp_path, 'model = "forks3.clf"\nproperties = ["p.toml"]\n')
    code, out, err = roar_cli("check", str(job), "--symmetry")
    assert code == 2 and "--symmetry: livelock" in err
