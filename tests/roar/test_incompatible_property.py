"""The ``incompatible-tasks`` property: no two live requests of one agent hold incompatible tasks.

Verdicts are checked against an independent oracle: a plain breadth-first search over the engine
(``Program.steps`` / ``Program.successor``, no explorer, no property code) whose states carry, as
an extra fact ``o_commit R Ts``, the task list of the last decision the path made for request R
(read off the step that produced ``hs R (h_dec (d_plan Ts))`` or ``(d_guard Ts)``). A request holds
those tasks while it is live (not failed, not aborted) and still has an entry in its agent's mask.
The property code instead reads the committed tasks out of the mask's entries; the two share
nothing beyond the engine.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import pytest

from roar_formal.clf.rules import LIN
from roar_formal.clf.state import canonical_key
from roar_formal.clf.terms import Const, const
from roar_formal.errors import RoarError
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.spec import load_spec
from roar_formal.testing.api import load
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job

from .seq_oracle import head_name, vlist

DATA = Path(__file__).parent / "data"
REQUEST = "boss::done == true"


# ------------------------------------------------------------------ the oracle


def _facts(ctx, fam: str) -> list:
    bag = ctx.index.get(Const(fam))
    return list(bag.items) if bag else []


class Oracle:
    """Breadth-first over (state, last decision per request); ``depth_of_first_bad`` is the depth
    of the shallowest state where two live requests of one agent hold a pair of ``pairs``
    (frozensets of task names), None when no reachable state does."""

    def __init__(self, spec: Path, pairs: set, stop_at_first: bool = True):
        model = compile_spec(load_spec(spec), REQUEST, functional="abstract")
        self.model, program = model, model.program()
        start = program.start_context(next(d for d in program.sig.directives
                                           if type(d).__name__ == "ExecDirective").start)
        self.task_of = {k: v for k, v in model.tasks.items()}
        self.pairs = pairs
        self.held_seen: set = set()
        self.depth_of_first_bad = None
        self.n_states = 1
        seen = {canonical_key(start)}
        level, depth = [start], 0
        while level:
            if any(self.bad(c) for c in level):
                self.depth_of_first_bad = depth
                if stop_at_first:
                    return
            nxt_level = []
            for ctx in level:
                for c in program.steps(ctx):
                    nxt, step = program.successor(ctx, c)
                    self.grow(nxt, step)
                    k = canonical_key(nxt)
                    if k not in seen:
                        seen.add(k)
                        nxt_level.append(nxt)
            self.n_states += len(nxt_level)
            level, depth = nxt_level, depth + 1

    def grow(self, nxt, step) -> None:
        for _m, f in step.produced:
            if head_name(f) != "hs" or head_name(f.args[1]) != "h_dec":
                continue
            d = f.args[1].args[0]
            if head_name(d) not in ("d_plan", "d_guard"):
                continue
            r = f.args[0]
            for old in _facts(nxt, "o_commit"):
                if old.args[0] == r:
                    nxt.remove_fact(old, LIN)
            nxt.add_fact(const("o_commit", r, d.args[0]), LIN)

    def held(self, ctx) -> list:
        """(agent, request, task names) of every request holding its last decision's tasks."""
        gone = {f.args[0] for f in _facts(ctx, "rs") if head_name(f.args[1]) in ("s_failure", "s_aborted")}
        live = {f.args[0]: self.model.agents[head_name(f.args[1])] for f in _facts(ctx, "rq")}
        in_mask = set()
        for mk in _facts(ctx, "mask"):
            for e in vlist(mk.args[1]):
                in_mask.add(e.args[1].args[0])
        out = []
        for f in _facts(ctx, "o_commit"):
            r = f.args[0]
            if r in live and r not in gone and r in in_mask:
                tasks = [self.task_of[head_name(x.args[0])][1] for x in vlist(f.args[1])]
                out.append((live[r], r, tasks))
                self.held_seen.update((live[r], t) for t in tasks)
        return out

    def bad(self, ctx) -> bool:
        h = self.held(ctx)
        return any(a1 == a2 and r1 != r2 and frozenset((t, u)) in self.pairs
                   for a1, r1, ts1 in h for a2, r2, ts2 in h for t in ts1 for u in ts2)


# ------------------------------------------------------------------ jobs


def _job(tmp_path: Path, spec: Path, pairs: Optional[list] = None, extra: str = "", bounds: str = "") -> Path:
    props = tmp_path / "props.toml"
    table = "[incompatible-tasks]\n" + (f"pairs = {json.dumps(pairs)}\n" if pairs is not None else "")
    props.write_text(extra + table)
    job = tmp_path / "job.toml"
    job.write_text(f'name = "inc"\nspec = "{spec}"\nrequest = "{REQUEST}"\nproperties = ["props.toml"]\n{bounds}')
    return job


def test_declared_pair_is_violated_as_the_oracle_says(tmp_path):
    """grasp and release of incompatible_declared.roar do not contradict, so nothing masks them: a
    user who declares them incompatible gets the shortest path to both being held."""
    job = _job(tmp_path, DATA / "incompatible_declared.roar", [["gripper::grasp", "gripper::release"]],
               bounds="[bounds]\nmax_states = 2000\n")
    res = run_job(load_job(job))
    v = res.verdicts["incompatible-tasks"]
    oracle = Oracle(DATA / "incompatible_declared.roar", {frozenset(("grasp", "release"))})
    assert oracle.depth_of_first_bad is not None
    assert v.status == "violated"
    assert len(v.counterexample.prefix) == oracle.depth_of_first_bad
    assert "declared incompatible; the spec's post-conditions do not contradict" in v.message
    assert "(gripper::holding == true)" in v.message and "(gripper::dropped == true)" in v.message


def test_spec_pairs_hold_as_the_oracle_says(tmp_path):
    """incompatible.roar: grasp and release contradict, so the mask keeps them apart (the ensure
    needing release meets a concurrency issue while grasp is held): holds on the whole space, and
    the oracle, exploring it all, sees grasp held (the check is not vacuous)."""
    res = run_job(load_job(_job(tmp_path, DATA / "incompatible.roar")))
    v = res.verdicts["incompatible-tasks"]
    oracle = Oracle(DATA / "incompatible.roar", {frozenset(("grasp", "release"))}, stop_at_first=False)
    assert oracle.depth_of_first_bad is None
    assert ("gripper", "grasp") in oracle.held_seen
    assert v.status == "holds" and res.graph.complete
    assert f"no violation in {res.graph.n_states:,} states" in v.message


def test_declaring_a_pair_the_spec_already_makes_incompatible_holds(tmp_path):
    res = run_job(load_job(_job(tmp_path, DATA / "ensure_guard.roar", [["gripper::release", "gripper::grasp"]])))
    assert res.verdicts["incompatible-tasks"].status == "holds"
    oracle = Oracle(DATA / "ensure_guard.roar", {frozenset(("grasp", "release"))}, stop_at_first=False)
    assert oracle.depth_of_first_bad is None and ("gripper", "release") in oracle.held_seen


def test_counterexample_replays_and_is_confirmed(tmp_path, roar_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    job = _job(tmp_path, DATA / "incompatible_declared.roar", [["gripper::grasp", "gripper::release"]],
               bounds="[bounds]\nmax_states = 2000\n")
    code, out, _err = roar_cli("check", job)
    assert code == 1 and "incompatible-tasks: violated" in out
    trace = tmp_path / "roar-traces" / "inc.incompatible-tasks.jsonl"
    header = json.loads(trace.read_text().splitlines()[0])
    assert header["claim"] == {"incompatible": [["gripper::grasp", "gripper::release"]]}
    code, out, _err = roar_cli("replay", trace, "--model", DATA / "incompatible_declared.roar")
    assert code == 0 and "confirmed: in the final state gripper holds" in out
    # the same trace on the spec that masks the pair: the final state is not reached or not bad
    code, out, _err = roar_cli("replay", trace, "--model", DATA / "incompatible.roar")
    assert "confirmed: in the final state" not in out


def test_api_names_pairs_and_checks_them():
    spec = load(DATA / "incompatible_declared.roar")
    e = spec.explore(REQUEST, properties=[], incompatible=[("gripper::grasp", "gripper::release")],
                     budget={"max_states": 2000})
    assert e.verdicts["incompatible-tasks"].status == "violated"
    with pytest.raises(RoarError, match="pairs of tasks named 'agent::task'"):
        spec.explore(REQUEST, incompatible=[("gripper.grasp", "gripper::release")])


# ------------------------------------------------------------------ errors


def test_nothing_to_check_is_an_error(tmp_path, roar_cli):
    """compatible_twin.roar makes no two tasks incompatible: the default pairs are none."""
    code, out, err = roar_cli("check", _job(tmp_path, DATA / "compatible_twin.roar"))
    assert code != 0 and "Traceback" not in out + err
    assert "incompatible-tasks has nothing to check: no two tasks of one agent have contradicting " \
           "post-conditions" in out + err


@pytest.mark.parametrize("pairs, col, message", [
    ([["grippr::grasp", "gripper::release"]], 12, "unknown agent 'grippr' (did you mean 'gripper'?); the agents are: boss, gripper"),
    ([["gripper::grasp", "gripper::relase"]], 30, "agent 'gripper' has no task 'relase' (did you mean 'release'?); its tasks: grasp, release"),
    ([["gripper::grasp", "boss::run"]], 30, "'gripper::grasp' and 'boss::run' belong to two agents"),
    ([["gripper::grasp", "gripper::grasp"]], 12, "'gripper::grasp' is paired with itself"),
])
def test_bad_names_are_located(tmp_path, roar_cli, pairs, col, message):
    code, out, err = roar_cli("check", _job(tmp_path, DATA / "incompatible.roar", pairs))
    assert code != 0 and "Traceback" not in out + err
    assert f"props.toml:2:{col}: {message}" in out + err


@pytest.mark.parametrize("value, message", [
    ('[]', "not an empty list"),
    ('"gripper::grasp"', 'not "gripper::grasp"'),
    ('[["gripper::grasp"]]', 'not ["gripper::grasp"]'),
    ('[["gripper.grasp", "gripper::release"]]', "a task is named 'agent::task', not \"gripper.grasp\""),
])
def test_bad_shapes_are_located(tmp_path, roar_cli, value, message):
    props = tmp_path / "props.toml"
    job = _job(tmp_path, DATA / "incompatible.roar")
    props.write_text(f"[incompatible-tasks]\npairs = {value}\n")
    code, out, err = roar_cli("check", job)
    assert code != 0 and "Traceback" not in out + err
    assert "props.toml:2:" in out + err and message in out + err


def test_unknown_key_is_refused(tmp_path, roar_cli):
    job = _job(tmp_path, DATA / "incompatible.roar")
    (tmp_path / "props.toml").write_text("[incompatible-tasks]\npair = []\n")
    code, out, err = roar_cli("check", job)
    assert code != 0 and "pair" in out + err and "Traceback" not in out + err
