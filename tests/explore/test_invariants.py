"""Invariants: ``[invariant] never = [...]`` patterns, on CLF models and on ROAR specs.

Each verdict is cross-checked by a plain breadth-first search written here,
over the engine's enumerator, with the forbidden situation tested in Python
on the facts of each state (not through the pattern matcher under test).
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import pytest

from roar_formal.clf.printer import show
from roar_formal.clf.program import Program
from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job

from repo import ROOT


def _job(tmp_path: Path, name: str, target: str, patterns: list[str], expect: str, spec_request=None) -> Path:
    props = tmp_path / f"{name}.props.toml"
    props.write_text('check = ["invariant"]\n[invariant]\nnever = [' + ", ".join(f'"{p}"' for p in patterns) + "]\n")
    where = (f'spec = "{target}"\nrequest = "{spec_request}"\n' if spec_request else f'model = "{target}"\n')
    job = tmp_path / f"{name}.toml"
    job.write_text(f'name = "{name}"\n{where}properties = ["{props}"]\n[expect]\ninvariant = "{expect}"\n')
    return job


def _bfs(program: Program, start, bad) -> tuple[int, int]:
    """(number of reachable states, depth of the first bad state or -1)."""
    seen = {canonical_key(start)}
    queue = deque([(start, 0)])
    first = -1
    while queue:
        ctx, d = queue.popleft()
        if first < 0 and bad(ctx):
            first = d
        for choice in program.steps(ctx):
            nxt, _ = program.successor(ctx, choice)
            k = canonical_key(nxt)
            if k not in seen:
                seen.add(k)
                queue.append((nxt, d + 1))
    return len(seen), first


def _facts(ctx) -> list[tuple[str, tuple[str, ...]]]:
    out = []
    for _m, f, n in ctx.facts():
        for _ in range(n):
            out.append((f.head.name, tuple(show(a) for a in f.args)))
    return out


@pytest.fixture(scope="module")
def phil():
    p = Program.from_file(ROOT / "models/philosophers/ok.clf")
    return p, p.start_context(p.sig.directives[-1].start)


def test_philosophers_safety_job_holds_and_the_oracle_agrees(phil):
    res = run_job(load_job(ROOT / "checker/philosophers_ok5_safety.toml"))
    assert res.ok and res.verdicts["invariant"].status == "holds"
    program, start = phil
    second = {a[0]: a[1] for h, a in _facts(start) if h == "second"}
    first = {a[0]: a[1] for h, a in _facts(start) if h == "first"}

    def bad(ctx):
        facts = _facts(ctx)
        forks = {a[0] for h, a in facts if h == "fork"}
        busy = {a[0] for h, a in facts if h == "busy"}
        eating = [a[0] for h, a in facts if h == "at2"]
        shared = any(second[i] == first[j] for i in eating for j in eating if i != j)
        return bool(forks & busy) or shared

    n, depth = _bfs(program, start, bad)
    assert depth == -1 and n == res.graph.n_states


def test_violated_invariant_has_the_shortest_counterexample(tmp_path, phil):
    job = _job(tmp_path, "two-eat", ROOT / "models/philosophers/ok.clf", ["at2 I * at2 J"], "violated")
    res = run_job(load_job(job))
    v = res.verdicts["invariant"]
    assert res.ok and v.counterexample is not None
    program, start = phil
    _n, depth = _bfs(program, start, lambda ctx: sum(1 for h, _a in _facts(ctx) if h == "at2") >= 2)
    assert len(v.counterexample.prefix) == depth == 4
    assert "at2 I * at2 J" in v.message


def test_a_pattern_may_name_one_variable_twice(tmp_path):
    # the same philosopher twice: at2 p * at2 p needs two copies of one fact, which never happens
    job = _job(tmp_path, "same", ROOT / "models/philosophers/ok.clf", ["at2 I * at2 I"], "holds")
    assert run_job(load_job(job)).ok


def test_bad_pattern_is_a_located_error(tmp_path):
    job = _job(tmp_path, "bad", ROOT / "models/philosophers/ok.clf", ["at2 I * nosuch J"], "holds")
    with pytest.raises(RoarError) as e:
        run_job(load_job(job))
    assert "nosuch" in e.value.message and e.value.pos.file.endswith("bad.props.toml")


def test_invariant_needs_patterns(tmp_path):
    props = tmp_path / "p.toml"
    props.write_text('check = ["invariant"]\n')
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT / "models/philosophers/ok.clf"}"\nproperties = ["{props}"]\n')
    with pytest.raises(RoarError, match="needs patterns"):
        load_job(job)


def test_invariants_on_a_roar_spec(tmp_path):
    spec = ROOT / "models/faulty/mutual_make_fixed.roar"
    # one task is never run by two requests at once (masks), and the network does reach a running request
    ok = _job(tmp_path, "mask", spec, ["hs R1 (h_run T P1 I1) E1 F1 L1 W1 * hs R2 (h_run T P2 I2) E2 F2 L2 W2"],
              "holds", spec_request="arm::started == true")
    res = run_job(load_job(ok))
    assert res.ok
    running = _job(tmp_path, "running", spec, ["rs R s_running"], "violated", spec_request="arm::started == true")
    res2 = run_job(load_job(running))
    assert res2.ok
    # oracle: the first state with a running request, by a plain search over the same compiled program
    model, start, _explorer = res2.roar
    _n, depth = _bfs(model.program(), start,
                     lambda ctx: any(h == "rs" and a[1] == "s_running" for h, a in _facts(ctx)))
    assert len(res2.verdicts["invariant"].counterexample.prefix) == depth > 0
