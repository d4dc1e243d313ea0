"""Accepted final states: an ``accept`` pattern is tested afresh on every final state (its
variables bind per state), checked against a plain enumeration of the final states."""

from __future__ import annotations

import json
from collections import deque
from pathlib import Path

import pytest

from roar_formal.clf.printer import show
from roar_formal.clf.program import Program
from roar_formal.clf.state import canonical_key
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.verify.replay import replay_trace

# three coins fall one after another; each lands heads or tails. A run ends with three
# ``done`` facts; the pattern accepts the endings where the first two results agree.
MODEL = """
side : type. h : side. t : side.
coin : type. c1 : coin. c2 : coin. c3 : coin.
up : coin -> type.
done : coin -> side -> type.
heads : up C -o {done C h}.
tails : up C -o {done C t}.
#exec * up c1 * up c2 * up c3.
"""


def _finals(program: Program, start) -> list[dict[str, str]]:
    """Every reachable state without a successor, as coin -> side (a plain BFS)."""
    seen, queue, out = {canonical_key(start)}, deque([start]), []
    while queue:
        ctx = queue.popleft()
        steps = list(program.steps(ctx))
        if not steps:
            out.append({show(f.args[0]): show(f.args[1]) for _m, f, _n in ctx.facts() if f.head.name == "done"})
        for choice in steps:
            nxt, _ = program.successor(ctx, choice)
            if canonical_key(nxt) not in seen:
                seen.add(canonical_key(nxt))
                queue.append(nxt)
    return out


@pytest.mark.parametrize("backend", ["ground", "general"])
@pytest.mark.parametrize("accept, ok", [
    ("done c1 X * done c2 X * done c3 Y", lambda f: f["c1"] == f["c2"]),
    ("done c1 X * done c2 Y * done c3 Z", lambda f: True),
    ("done c1 X * done c2 X * done c3 X", lambda f: len(set(f.values())) == 1),
])
def test_accept_binds_its_variables_per_state(tmp_path: Path, backend, accept, ok):
    (tmp_path / "coins.clf").write_text(MODEL)
    (tmp_path / "p.toml").write_text(f'check = ["deadlock"]\n[deadlock]\naccept = "{accept}"\n')
    (tmp_path / "j.toml").write_text(f'model = "coins.clf"\nproperties = ["p.toml"]\nbackend = "{backend}"\n'
                                     '[expect]\ndeadlock = "violated"\n')
    program = Program.from_text(MODEL, "coins.clf")
    finals = _finals(program, program.start_context(program.sig.directives[-1].start))
    assert len(finals) == 8
    bad = [f for f in finals if not ok(f)]
    res = run_job(load_job(tmp_path / "j.toml"))
    v = res.verdicts["deadlock"]
    assert v.status == ("violated" if bad else "holds")
    assert v.details["final_states"] == len(finals) - len(bad)
    if bad:
        assert v.details["deadlock_states"] == len(bad)


def test_a_deadlock_trace_carries_the_accept_pattern_and_replay_re_decides_it(tmp_path: Path):
    """Replay re-decides a deadlock under the job's accept pattern: the explorer's trace is
    confirmed, and the same steps claimed under a pattern that accepts their end are not."""
    (tmp_path / "coins.clf").write_text(MODEL)
    (tmp_path / "p.toml").write_text('check = ["deadlock"]\n[deadlock]\naccept = "done c1 h * done c2 X * done c3 Y"\n')
    (tmp_path / "j.toml").write_text('model = "coins.clf"\nproperties = ["p.toml"]\n[expect]\ndeadlock = "violated"\n')
    res = run_job(load_job(tmp_path / "j.toml"))
    trace = save_counterexample(res, "deadlock", tmp_path)
    lines = trace.read_text(encoding="utf-8").splitlines()
    header = json.loads(lines[0])
    assert header["claim"]["accept"] == "done c1 h * done c2 X * done c3 Y"
    rep = replay_trace(trace, tmp_path / "coins.clf")
    assert rep.confirmed is True, rep.confirmation
    header["claim"]["accept"] = "done c1 X * done c2 Y * done c3 Z"   # every ending accepted
    forged = tmp_path / "forged.jsonl"
    forged.write_text("\n".join([json.dumps(header)] + lines[1:]) + "\n", encoding="utf-8")
    rep = replay_trace(forged, tmp_path / "coins.clf")
    assert rep.confirmed is False and "accept" in rep.confirmation


@pytest.mark.parametrize("section, key, text, message", [
    ("deadlock", "accept", "done c1", "accept pattern 'done c1': type family 'done' takes 2 arguments, given 1"),
    ("invariant", "never", "done c1 X * dnoe c2 Y", "invariant pattern 'done c1 X * dnoe c2 Y': unknown type family"),
])
def test_a_bad_pattern_is_located_inside_its_string(tmp_path: Path, section, key, text, message):
    (tmp_path / "coins.clf").write_text(MODEL)
    value = f'"{text}"' if key == "accept" else f'["{text}"]'
    (tmp_path / "p.toml").write_text(f'check = ["{section}"]\n\n[{section}]\n{key} = {value}\n')
    (tmp_path / "j.toml").write_text('model = "coins.clf"\nproperties = ["p.toml"]\n')
    with pytest.raises(RoarError) as e:
        run_job(load_job(tmp_path / "j.toml"))
    col = len(f"{key} = ") + (3 if key == "never" else 2)
    pos = e.value.pos
    assert (pos.file, pos.line, pos.col) == (str(tmp_path / "p.toml"), 4, col) and message in e.value.message
