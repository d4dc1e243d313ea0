"""Bitstate hashing (``visited = "bitstate"``, Holzmann's supertrace), against the exact search.

With a bit array large enough, the search visits exactly the states and transitions of the exact
search and reaches the same verdicts with counterexamples as short; with a tiny array it visits
fewer, and a "holds" says it is not verified, with the probability of omission. What it cannot
decide (cycles, events on steps) is refused at the job's line.
"""

from __future__ import annotations

import importlib.util
import json

import pytest
from repo import ROOT

from roar_formal.clf.program import Program
from roar_formal.explore.properties import check_deadlock
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import ClfSystem, Options
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job

_spec = importlib.util.spec_from_file_location("gen", ROOT / "models" / "philosophers" / "generate.py")
gen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen)


def _explore(variant: str, n: int, visited: str, **kw):
    p = Program.from_text(gen.program(variant, n))
    ex = Explorer(ClfSystem(p, p.start_context(p.sig.directives[0].start), Options()), "bfs", None, visited, **kw)
    g = ex.run(Budget())
    return ex, g, check_deadlock(g)


@pytest.mark.parametrize("variant,n", [("dl", 5), ("ok", 5), ("ll", 5), ("dl", 7)])
def test_a_large_array_visits_what_the_exact_search_visits(variant, n):
    _, g, d = _explore(variant, n, "exact")
    ex, gb, db = _explore(variant, n, "bitstate")
    assert (gb.n_states, gb.n_edges + gb.n_unrecorded) == (g.n_states, g.n_edges)
    assert gb.n_edges == gb.n_states - 1          # only the discovery tree is recorded
    assert ex.stats()["transitions"] == g.n_edges   # progress counts them all (it showed states - 1)
    assert db.status == d.status
    if d.counterexample is not None:
        assert db.counterexample.length() == d.counterexample.length() == n
    assert 0 < ex.omission_probability() < 1e-9


def test_a_tiny_array_misses_states_and_says_how_likely_that_was():
    _, g, d = _explore("dl", 7, "exact")
    ex, gb, db = _explore("dl", 7, "bitstate", bits=2048)
    assert gb.n_states < g.n_states and d.status == "violated"
    assert ex.omission_probability() > 0.1 and ex.expected_omissions() > 1


def _job(tmp_path, body: str):
    path = tmp_path / "job.toml"
    path.write_text(body.replace("ROOT", str(ROOT)), encoding="utf-8")
    return path


def test_a_spec_job_with_bitstate_agrees_with_the_exact_one(tmp_path, checker_job):
    path = _job(tmp_path, '''name = "op"
spec = "ROOT/models/faulty/ordered_pick.roar"
request = "cell::done == true"
functional = "ROOT/models/faulty/reliable_tools.py"
properties = ["ROOT/properties/sequence.toml"]
visited = "bitstate"
[expect]
deadlock = "holds"
sequential-achievement = "violated"
''')
    res = run_job(load_job(path))
    ref = checker_job("ordered_pick.toml")
    assert res.ok, res.unexpected
    assert res.backend == "general, bitstate"
    assert res.graph.n_states == ref.graph.n_states
    assert res.graph.n_edges + res.graph.n_unrecorded == ref.graph.n_edges
    v, r = res.verdicts["sequential-achievement"], ref.verdicts["sequential-achievement"]
    assert len(v.counterexample.prefix) == len(r.counterexample.prefix)
    dl = res.verdicts["deadlock"]
    assert "[bitstate: not verified;" in dl.message and dl.details["omission_probability"] > 0


def test_a_holds_from_a_tiny_array_is_not_verified_in_json(tmp_path, roar_cli):
    path = _job(tmp_path, '''name = "bs"
model = "ROOT/models/philosophers/ok.clf"
visited = "bitstate"
[bitstate]
bits = 1024
[expect]
deadlock = "holds"
''')
    code, out, _ = roar_cli("check", path, "--json", "--no-traces")
    doc = json.loads(out)
    job = doc["jobs"][0] if "jobs" in doc else doc[0]
    v = job["verdicts"]["deadlock"]
    assert code == 0 and v["status"] == "holds" and "not verified" in v["message"]
    assert v["visited"] == "bitstate" and v["omission_probability"] > 0.01 and v["bits"] == 1024
    # the search ended, but its "holds" proves nothing: the job says so, and so does the table
    assert job["complete"] is True and job["exhaustive"] is False and job["visited"] == "bitstate"
    assert "the bit array is too small for this model: give [bitstate] bits at least" in v["message"]
    code, out, _ = roar_cli("check", path, "--no-traces")
    table = out[out.index("verification summary"):]
    assert code == 0 and "(bitstate, bit array too small)" in table and "as expected, not verified" in table


def test_a_holds_from_a_large_enough_array_reads_not_verified(tmp_path, roar_cli):
    path = _job(tmp_path, 'name = "bs"\nmodel = "ROOT/models/philosophers/ok.clf"\nvisited = "bitstate"\n'
                          '[expect]\ndeadlock = "holds"\n')
    code, out, _ = roar_cli("check", path, "--no-traces")
    table = out[out.index("verification summary"):]
    assert code == 0 and "(bitstate, not verified)" in table and "too small" not in out


def test_an_exact_complete_search_is_exhaustive_in_json(tmp_path, roar_cli):
    path = _job(tmp_path, 'name = "ex"\nmodel = "ROOT/models/philosophers/ok.clf"\n[expect]\ndeadlock = "holds"\n')
    code, out, _ = roar_cli("check", path, "--json", "--no-traces")
    doc = json.loads(out)
    job = doc["jobs"][0] if "jobs" in doc else doc[0]
    assert code == 0 and job["exhaustive"] is True and job["visited"] == "exact"


def test_a_bitstate_search_takes_the_same_states_whatever_the_hash_seed(tmp_path):
    """The bit positions come from the canonical key's bytes, not Python's per-process hash:
    two processes with different hash seeds visit the same states with a tiny array."""
    import os
    import subprocess
    import sys
    path = _job(tmp_path, 'name = "bs"\nmodel = "ROOT/models/philosophers/dl.clf"\nvisited = "bitstate"\n'
                          '[bitstate]\nbits = 2048\n[expect]\ndeadlock = "violated"\n')
    code = ("import sys, json\nfrom roar_formal.verify.check import run_job\n"
            "from roar_formal.verify.jobs import load_job\n"
            "r = run_job(load_job(sys.argv[1]))\nprint(json.dumps([r.graph.n_states, r.graph.n_unrecorded]))\n")
    got = set()
    for seed in ("1", "2", "3"):
        out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, check=True,
                             env={**os.environ, "PYTHONHASHSEED": seed})
        got.add(out.stdout.strip().splitlines()[-1])
    assert len(got) == 1, got


@pytest.mark.parametrize("body,message", [
    ('model = "ROOT/models/philosophers/dl.clf"\nproperties = ["ROOT/properties/philosophers.toml"]\n'
     'visited = "bitstate"\n', "livelock needs the cycles of the graph"),
    ('spec = "ROOT/models/faulty/mutual_make.roar"\nrequest = "arm::started == true"\nvisited = "bitstate"\n',
     "a default property of a spec"),
    ('model = "ROOT/models/philosophers/dl.clf"\nvisited = "bitstate"\nreduction = true\n[expect]\ndeadlock = "violated"\n',
     "not available with partial-order reduction"),
    ('model = "ROOT/models/philosophers/dl.clf"\nvisited = "bitstate"\nbackend = "ground"\n[expect]\ndeadlock = "violated"\n',
     "a mode of the general backend"),
    ('model = "ROOT/models/philosophers/dl.clf"\n[bitstate]\nbits = 4096\n[expect]\ndeadlock = "violated"\n',
     'a [bitstate] table needs visited = "bitstate"'),
    ('model = "ROOT/models/philosophers/dl.clf"\nvisited = "bitstate"\n[bitstate]\nbits = 12\n[expect]\ndeadlock = "violated"\n',
     "[bitstate] bits is the size of the bit array, a whole number from 1,024 to 2^40, not 12"),
])
def test_what_bitstate_cannot_decide_is_refused_at_its_place(tmp_path, roar_cli, body, message):
    code, out, err = roar_cli("check", _job(tmp_path, body))
    assert code == 2 and message in out + err and "Traceback" not in out + err
    assert "job.toml:" in out + err
