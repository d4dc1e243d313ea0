"""A lasso whose cycle re-enters a state the search found first by another path: the state is
kept with the names of that first discovery, so the cycle's recorded steps name its fresh
names differently from the steps before them. The counterexample's steps must be those of one
run (search.path_steps), so that the saved trace replays on the plain engine, the oracle."""

from __future__ import annotations

from roar_formal.clf.query import with_big_stack
from roar_formal.trace.format import read_trace
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.verify.replay import replay

# b is found first from the start (name t); the cycle a -> b -> c -> a enters it from a with
# another name (u): the cycle's step bc was recorded on b as kept, with t
MODEL = """tok : type.
s0 : type.
a : tok -> type.
b : tok -> type.
c : tok -> type.
start_a : s0 -o {Exists t. a t}.
start_b : s0 -o {Exists t. b t}.
ab : a T -o {Exists u. b u}.
bc : b T -o {Exists u. c u}.
ca : c T -o {Exists u. a u}.
#exec * s0.
"""


def _job(tmp_path):
    (tmp_path / "cyc.clf").write_text(MODEL, encoding="utf-8")
    (tmp_path / "props.toml").write_text('check = ["livelock"]\n[livelock]\nprogress = ["start_*"]\n'
                                         'fairness = "none"\n', encoding="utf-8")
    (tmp_path / "cyc.toml").write_text('name = "cyc"\nmodel = "cyc.clf"\nproperties = ["props.toml"]\n'
                                       '[expect]\nlivelock = "violated"\n', encoding="utf-8")
    return load_job(tmp_path / "cyc.toml")


def test_a_lasso_re_entering_a_state_found_first_by_another_path_replays(tmp_path):
    res = with_big_stack(run_job, _job(tmp_path))
    v = res.verdicts["livelock"]
    assert v.violated and v.counterexample.kind == "lasso"
    g = res.graph
    # the case at issue: some edge of the cycle is not the one its target was discovered by
    assert any(int(g.parent_edge[int(g.dst[e])]) != e for e in v.counterexample.cycle)
    path = save_counterexample(res, "livelock", tmp_path / "traces")
    _header, records = read_trace(path)
    # one run: every fact a step consumes is in the start state or produced by a step before it
    have = {"s0"}
    for r in records:
        for f in r["consumed"]:
            assert f in have, (r["rule"], f, sorted(have))
            have.discard(f)
        have.update(r["produced"])
    rr = with_big_stack(replay, path, None, tmp_path / "cyc.clf")
    assert rr.steps == v.counterexample.length() and rr.cycle_closes
