"""The distributed breadth-first search (explore/distributed.py, verify/cluster.py) against the
single-process explorer: same states, transitions and verdicts, counterexamples that replay,
keys and partition hashes that agree across processes, and job-file errors at their place.

One local Dask cluster of 2 worker processes serves the whole module (its jobs name it by
``address``); one test starts a cluster of its own from ``workers = 2``.
"""

from __future__ import annotations

import os

import pytest
from checker_cache import checker_result
from repo import ROOT

from roar_formal.clf.query import with_big_stack
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job

#: one xdist worker runs the module, so its one cluster serves every test (pyproject: --dist loadgroup)
pytestmark = pytest.mark.xdist_group("dask")


@pytest.fixture(scope="module")
def cluster():
    """A local cluster of 2 worker processes (one thread each), for every test of the module."""
    from distributed import Client, LocalCluster
    import logging
    lc = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR)
    client = Client(lc)
    client.wait_for_workers(2, timeout=120)
    yield lc.scheduler_address, client
    client.close()
    lc.close()


def _job(tmp_path, name: str, extra: str, tag: str = ""):
    """checker/<name> with absolute paths and ``extra`` (search settings) before its tables."""
    text = (ROOT / "checker" / name).read_text(encoding="utf-8").replace('"../', f'"{ROOT}/')
    i = text.find("\n[")
    head, tail = (text[:i + 1], text[i + 1:]) if i >= 0 else (text + "\n", "")
    job = tmp_path / (tag + name)
    job.write_text(head + extra + "\n" + tail, encoding="utf-8")
    return job


def _on(address: str) -> str:
    return f'search = "distributed"\n\n[cluster]\naddress = "{address}"\n'


def _single(path):
    """The oracle: the plain single-process breadth-first search of the same job."""
    job = load_job(path)
    job.search, job.cluster, job.backend = "bfs", None, "general"
    return with_big_stack(lambda: run_job(job))


# the .clf philosophers (deadlock; livelock), and ROAR jobs: a deadlock, a lasso of a temporal
# default property, a broken sequential achievement among 1,693 states (conflict's 2,658 states
# agree too, in about 20 s: bench/b9_distributed.py runs it)
JOBS = ["philosophers_dl5.toml", "philosophers_ll5.toml", "mutual_make.toml", "camera_retry.toml",
        "ordered_pick.toml"]


@pytest.mark.parametrize("name", JOBS)
def test_distributed_and_single_process_searches_agree(cluster, tmp_path, name):
    address, _client = cluster
    path = _job(tmp_path, name, _on(address))
    res = with_big_stack(lambda: run_job(load_job(path)))
    # the oracle: the single-process breadth-first search (a ROAR job's bundled result, shared with
    # the suite's other tests, is that search's; a .clf job's bundled one is the ground backend's)
    ref = checker_result(name) if res.job.is_roar else _single(path)
    assert res.backend == "general, distributed (2 workers)"
    assert res.graph.complete and ref.graph.complete
    assert (res.graph.n_states, res.graph.n_edges) == (ref.graph.n_states, ref.graph.n_edges)
    assert {p: v.status for p, v in res.verdicts.items()} == {p: v.status for p, v in ref.verdicts.items()}
    assert res.ok, res.unexpected
    # breadth-first: every state at its shortest distance, each counterexample as short as the oracle's
    assert sorted(res.graph.depth) == sorted(ref.graph.depth)
    for p, v in res.verdicts.items():
        if v.status == "violated":
            r = ref.verdicts[p].counterexample
            assert len(v.counterexample.prefix) == len(r.prefix), p


@pytest.mark.parametrize("name,prop,model", [
    ("philosophers_dl5.toml", "deadlock", "models/philosophers/dl.clf"),
    ("camera_retry.toml", "mission-completion", "models/faulty/camera_retry.roar"),
])
def test_a_distributed_counterexample_replays_like_any_other(cluster, tmp_path, name, prop, model):
    from roar_formal.verify.replay import replay_trace
    address, _client = cluster
    res = with_big_stack(lambda: run_job(load_job(_job(tmp_path, name, _on(address)))))
    assert res.verdicts[prop].status == "violated"
    trace = save_counterexample(res, prop, tmp_path)
    rep = with_big_stack(lambda: replay_trace(trace, ROOT / model))
    assert rep.confirmed is True, getattr(rep, "reason", rep)


def test_hash_compaction_and_small_batches_keep_the_counts(cluster, tmp_path):
    """Batches of 7 states per worker: many exchanges per level, and the numbering of the
    states found before a level ends; hash compaction on the owners."""
    address, _client = cluster
    path = _job(tmp_path, "philosophers_dl5.toml", _on(address) + "batch = 7\n")
    text = path.read_text().replace('search = "distributed"', 'search = "distributed"\nvisited = "hash"')
    path.write_text(text)
    res = with_big_stack(lambda: run_job(load_job(path)))
    ref = _single(path)
    assert (res.graph.n_states, res.graph.n_edges) == (ref.graph.n_states, ref.graph.n_edges)
    assert res.backend == "general, hash compaction, distributed (2 workers)"
    assert "[hash compaction" in res.verdicts["deadlock"].message


def test_a_budget_that_runs_out_gives_no_verdict_of_holds(cluster, tmp_path):
    address, _client = cluster
    path = _job(tmp_path, "conflict.toml", _on(address))
    path.write_text(path.read_text().replace("max_states = 100_000", "max_states = 200"))
    res = with_big_stack(lambda: run_job(load_job(path)))
    assert not res.graph.complete and "state budget of 200 reached" in res.graph.stop_reason
    assert res.graph.n_states >= 200
    assert res.verdicts["deadlock"].status == "incomplete"
    assert res.verdicts["exclusive-writes"].status == "incomplete"


def test_a_local_cluster_from_the_job_file(tmp_path):
    """``workers = 2``: the job starts a local cluster of its own and stops it after."""
    path = _job(tmp_path, "mutual_make.toml", 'search = "distributed"\n\n[cluster]\nworkers = 2\n')
    res = with_big_stack(lambda: run_job(load_job(path)))
    # two local workers on a machine of two cores or fewer (this one's, counted by the OS) share
    # them with the scheduler and this process: the backend says so
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert res.backend == ("general, distributed (2 workers" + (
        f" on {cores} core{'s' if cores != 1 else ''}, shared with the scheduler and this process: expect no "
        "speed-up" if cores <= 2 else "") + ")")
    assert res.graph.n_states == 28 and res.verdicts["deadlock"].status == "violated"


def test_processes_agree_on_keys_and_partition_hashes(cluster):
    """A state written in one process and read in another has the same canonical key there
    (computed by that process) as a state the other process reached itself, and the same
    partition hash; written back, it is the same state in the first process again."""
    from roar_formal.clf.state import canonical_key
    from roar_formal.explore.portable import ContextCodec
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.verify.check import load_model
    from roar_formal.explore.system import ClfSystem, Options
    _address, client = cluster
    job = load_job(ROOT / "checker" / "philosophers_dl5.toml")
    program, start = load_model(job)
    system = ClfSystem(program, start, Options())
    ex = Explorer(system)
    with_big_stack(lambda: ex.run(Budget(max_states=300)))
    here = ContextCodec(0)
    states = [ex.states[i] for i in range(len(ex.states))]
    blobs = [here.state(s) for s in states]
    mine = [here.partition(s) for s in states]
    worker = sorted(client.scheduler_info()["workers"])[0]
    theirs, back, same = client.submit(_elsewhere, str(ROOT / "checker" / "philosophers_dl5.toml"), blobs,
                                       workers=[worker], pure=False).result()
    assert theirs == mine
    assert same == list(range(len(blobs)))      # each state read there is the state it reached there
    for s, b in zip(states, back):
        assert canonical_key(here.context(b)) == canonical_key(s)


def _elsewhere(job_path: str, blobs: list):
    """In a worker: the partition hashes of the states read, the states written back, and which
    of them equal (by this process's canonical key) the state of the same number this process
    reaches with its own breadth-first search."""
    import os
    from roar_formal.clf.state import canonical_key
    from roar_formal.explore.portable import ContextCodec
    from roar_formal.explore.search import Budget, Explorer
    from roar_formal.explore.system import ClfSystem, Options
    from roar_formal.verify.check import load_model
    from roar_formal.verify.jobs import load_job
    codec = ContextCodec(7)
    read = [codec.context(b) for b in blobs]
    program, start = load_model(load_job(job_path))
    ex = Explorer(ClfSystem(program, start, Options()))
    ex.run(Budget(max_states=len(blobs)))
    keys = {canonical_key(ex.states[i]) for i in range(len(ex.states))}
    same = [i for i, c in enumerate(read) if canonical_key(c) in keys]
    assert os.getpid()
    return [codec.partition(c) for c in read], [codec.state(c) for c in read], same


@pytest.mark.parametrize("extra,message,line,col", [
    ('search = "distributed"\n[cluster]\nworkers = 0\n', "[cluster] workers is the number of worker processes, "
     "a whole number from 1 to 256, not 0", 5, 11),
    ('search = "distributed"\n[cluster]\nworkers = "two"\n', 'not "two"', 5, 11),
    ('search = "distributed"\n[cluster]\nbatch = 1.5\n', "[cluster] batch is the number of frontier states", 5, 9),
    ('search = "distributed"\n[cluster]\naddress = "localhost:8786"\n',
     '[cluster] address is a Dask scheduler\'s address such as "tcp://10.0.0.5:8786", not "localhost:8786"', 5, 11),
    ('search = "distributed"\n[cluster]\nworkers = 2\naddress = "tcp://h:1"\n', "either workers", 6, 11),
    ('search = "distributed"\n[cluster]\nnodes = 2\n', "unknown key 'nodes' in [cluster]", 5, 1),
    ('search = "bfs"\n[cluster]\nworkers = 2\n', 'a [cluster] table needs search = "distributed"', 4, 1),
    ('search = "distributed"\nreduction = true\n', 'not available for partial-order reduction', 3, 1),
    ('search = "distributed"\nbackend = "ground"\n', 'not available for the ground backend', 3, 1),
    ('search = "parallel"\n', "'search' must be one of bfs, dfs, swarm, distributed, not 'parallel'", 3, 1),
])
def test_bad_cluster_settings_are_located(tmp_path, extra, message, line, col):
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT}/models/philosophers/dl.clf"\n'
                   f'properties = ["{ROOT}/properties/philosophers.toml"]\n'
                   + extra, encoding="utf-8")
    with pytest.raises(RoarError) as e:
        load_job(job)
    assert message in e.value.message and e.value.pos.file == str(job)
    assert (e.value.pos.line, e.value.pos.col) == (line, col), e.value.pos


def test_an_unreachable_scheduler_is_a_located_error(tmp_path):
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT}/models/philosophers/dl.clf"\n'
                   f'properties = ["{ROOT}/properties/philosophers.toml"]\n'
                   'search = "distributed"\n[cluster]\naddress = "tcp://127.0.0.1:9"\nconnect_seconds = 2\n',
                   encoding="utf-8")
    with pytest.raises(RoarError) as e:
        with_big_stack(lambda: run_job(load_job(job)))
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in e.value.message
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == (str(job), 5, 11)


def test_the_command_line_reports_a_bad_cluster_table_without_a_traceback(tmp_path, capsys):
    from roar_formal.cli import main
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT}/models/philosophers/dl.clf"\n'
                   f'properties = ["{ROOT}/properties/philosophers.toml"]\n'
                   'search = "distributed"\n[cluster]\nworkers = -1\n', encoding="utf-8")
    with pytest.raises(SystemExit) as e:
        main(["check", str(job), "--no-traces"])
    out, err = capsys.readouterr()
    assert e.value.code == 2
    assert f"{job}:5:11:" in out + err and "Traceback" not in out + err


def test_a_swarm_on_the_cluster_finds_the_seeded_deadlock(cluster, tmp_path):
    """Search = "swarm" with a [cluster] table: the members run as tasks; the one that finds the
    deadlock gives a real counterexample, which replays on the model."""
    from roar_formal.verify.replay import replay_trace
    address, _client = cluster
    path = _job(tmp_path, "philosophers_dl8.toml",
                f'search = "swarm"\n\n[swarm]\nruns = 4\nmax_states = 300\n\n[cluster]\naddress = "{address}"\n')
    res = with_big_stack(lambda: run_job(load_job(path)))
    assert res.backend == "general, swarm on a cluster (2 workers)"
    v = res.verdicts["deadlock"]
    assert v.status == "violated" and "[swarm: found by randomized depth-first search" in v.message
    # the budget is checked before each expansion: the last one may add its successors past it
    assert res.graph.n_states <= 300 + max(res.graph.out_degree()) and not res.graph.complete
    trace = save_counterexample(res, "deadlock", tmp_path)
    rep = with_big_stack(lambda: replay_trace(trace, ROOT / "models" / "philosophers" / "dl8.clf"))
    assert rep.confirmed is True


def test_a_swarm_member_on_the_cluster_that_covers_everything_gives_the_complete_verdicts(cluster, tmp_path):
    address, _client = cluster
    exact = _single(ROOT / "checker" / "mutual_make_fixed.toml")
    path = _job(tmp_path, "mutual_make_fixed.toml",
                f'search = "swarm"\n\n[swarm]\nruns = 3\n\n[cluster]\naddress = "{address}"\n')
    res = with_big_stack(lambda: run_job(load_job(path)))
    assert res.graph.complete and res.graph.n_states == exact.graph.n_states
    assert {p: v.status for p, v in res.verdicts.items()} == {p: v.status for p, v in exact.verdicts.items()}
    assert all("covered the whole state space" in v.message for v in res.verdicts.values())


def test_a_model_with_rules_in_its_states_is_refused_at_the_job(cluster, tmp_path):
    """A state holding a rule cannot be sent as facts: the search stops with an error at the job's
    [cluster] table, never a verdict."""
    address, _client = cluster
    model = tmp_path / "nested.clf"
    model.write_text("a : type.\nb : type.\nc : type.\n"
                     "r : a -o {b -o {c}}.\n\n#exec * a * b.\n", encoding="utf-8")
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{model}"\nsearch = "distributed"\n[cluster]\naddress = "{address}"\n'
                   '[expect]\ndeadlock = "holds"\n', encoding="utf-8")
    with pytest.raises(RoarError) as e:
        with_big_stack(lambda: run_job(load_job(job)))
    assert "distributed search: " in e.value.message and "states of facts only" in e.value.message, e.value.message
    assert (e.value.pos.file, e.value.pos.line) == (str(job), 3)


def test_the_wire_format_keeps_every_kind_of_term_and_the_identity_of_fresh_names():
    """Linear facts with multiplicities, affine and persistent facts, literals (numbers, strings),
    lambdas over bound variables and fresh names: read back in another codec (another process's),
    then written back, the context is the one written, fresh names included (by identity)."""
    from fractions import Fraction
    from roar_formal.clf.context import Context
    from roar_formal.clf.rules import AFF, LIN, PERS
    from roar_formal.clf.state import canonical_key
    from roar_formal.clf.terms import BVar, Const, Lam, Lit, Param, Root
    from roar_formal.explore.portable import ContextCodec
    c = lambda name, *args: Root(Const(name), tuple(args))   # noqa: E731
    p, q = Param("r"), Param("x")
    num = Root(Lit(Fraction(7, 2), Const("number"), "3.5"), ())
    text = Root(Lit("hello", Const("string"), '"hello"'), ())
    lam = Lam(c("g", Root(BVar(0), ()), c("k")))
    ctx = Context()
    for fact, mode in ((c("f", Root(p, ()), num), LIN), (c("f", Root(p, ()), num), LIN), (c("h", text, lam), LIN),
                       (c("a", Root(q, ()), Root(p, ())), AFF), (c("s", c("k")), PERS)):
        ctx.add_fact(fact, mode)
    here, there = ContextCodec(0), ContextCodec(1)
    read = there.context(here.state(ctx))
    assert canonical_key(read) == canonical_key(ctx)
    assert read.lin[c("h", text, lam)] == 1 and sum(read.lin.values()) == 3 and len(read.aff) == 1
    # the other process has names of its own
    assert not ({p, q} & {getattr(a, "head", None) for t in [*read.lin, *read.aff] for a in t.args})
    back = here.context(there.state(read))
    assert back.lin == ctx.lin and back.aff == ctx.aff and back.pers == ctx.pers   # the very same terms
    assert here.partition(ctx) == there.partition(read)
    renamed = Context()
    p2, q2 = Param("r"), Param("x")
    for fact, mode in ((c("f", Root(p2, ()), num), LIN), (c("f", Root(p2, ()), num), LIN),
                       (c("h", text, lam), LIN), (c("a", Root(q2, ()), Root(p2, ())), AFF), (c("s", c("k")), PERS)):
        renamed.add_fact(fact, mode)
    assert here.partition(renamed) == here.partition(ctx)    # invariant under renaming of fresh names


def test_a_swarm_on_a_cluster_refuses_reduction(tmp_path):
    job = tmp_path / "j.toml"
    job.write_text(f'model = "{ROOT}/models/philosophers/dl.clf"\n'
                   f'properties = ["{ROOT}/properties/philosophers.toml"]\n'
                   'search = "swarm"\nreduction = true\n[cluster]\nworkers = 2\n', encoding="utf-8")
    with pytest.raises(RoarError) as e:
        load_job(job)
    assert "a swarm on a cluster is not available for partial-order reduction" in e.value.message
    assert (e.value.pos.line, e.value.pos.col) == (3, 1)
