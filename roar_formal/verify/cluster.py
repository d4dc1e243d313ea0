"""Jobs on a Dask cluster: ``search = "distributed"`` and a swarm's members as tasks.

A job's ``[cluster]`` table names the cluster: ``workers = N`` starts a local one (N worker
processes on this machine, one thread each), ``address = "tcp://host:8786"`` connects to a
running scheduler. Each worker builds the job's transition system itself from a
:class:`JobSystem` (the job as read from its file, and the fingerprint of the sources the
driver explores: a worker that reads other sources refuses to search). The search itself
is ``explore/distributed.py``'s; this module opens the cluster around it and plugs the
distributed explorer in where ``check.py`` makes explorers.
"""

from __future__ import annotations

import contextvars
import hashlib
import json
import logging
import os
import pickle
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Optional

from ..errors import RoarError
from .jobs import ADDRESS, ClusterSetup, PropertySpec
from .models import load_model, roar_setup
from .searching import hashed_note, search_rounds, swarm

__all__ = ["ClusterSetup", "JobSystem", "make_explorer", "on_cluster", "cluster_note", "ADDRESS"]

_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("roar_cluster_session", default=None)


@dataclass
class _Session:
    job: object
    client: object
    factory: "JobSystem"
    setup: ClusterSetup
    workers: list = field(default_factory=list)
    explorers: list = field(default_factory=list)
    swarm: Optional[list] = None        # the swarm's members, submitted at once: futures by member
    swarm_codec: object = None
    swarm_initial: object = None


class JobSystem:
    """What a worker needs to build a job's transition system: the job (paths, request, options,
    properties) and the fingerprint of the sources the driver explores. Picklable."""

    def __init__(self, job, fingerprint: Optional[dict]):
        from dataclasses import replace
        # what building the system reads (check.load_model, check.roar_setup); the properties in
        # the spec's terms are bound to the driver's compiled model, and stay there
        p = job.props
        props = PropertySpec(check=list(p.check), progress=list(p.progress), fairness=p.fairness, strong=p.strong,
                             sequence_recipes=list(p.sequence_recipes), sequence_kept=p.sequence_kept,
                             sources=list(p.sources))
        self.job = replace(job, props=props, expect={}, robot=None, cluster=None)
        self.fingerprint = fingerprint
        self._key = hashlib.sha256(pickle.dumps(self.job) + json.dumps(fingerprint, sort_keys=True, default=str)
                                   .encode()).hexdigest()

    def key(self) -> str:
        return self._key

    def build(self):
        """The job's system, built as the driver builds it (verify/check.py)."""
        from ..explore.distributed import DistributedError
        from ..explore.system import ClfSystem, Options
        job = self.job
        if job.is_roar:
            from ..roar.compile import compile_spec
            from ..roar.explore import RoarSystem
            from ..roar.functional import functional_module, load_registry
            from ..roar.sources import spec_fingerprint
            from ..roar.spec import load_spec
            fn_path = functional_module(job.spec, job.functional)
            reg = load_registry(fn_path)
            spec_ast = load_spec(job.spec)
            mine = spec_fingerprint(job.spec, spec_ast, fn_path)
            self._same(mine)
            model = compile_spec(spec_ast, job.request, registry=reg, functional="abstract", request_at=job.request_at,
                                 crashes=getattr(job, "crashes", None))
            _program, start, options, pairs = roar_setup(job, model)
            return RoarSystem(model, start, options, pairs)
        from ..trace.fingerprint import clf_fingerprint
        self._same(clf_fingerprint(job.model))
        program, start = load_model(job)
        props = job.props
        options = Options(progress_rules=tuple(props.progress), fairness=props.fairness, canonical=job.canonical)
        try:
            return ClfSystem(program, start, options)
        except Exception as exc:   # pragma: no cover
            raise DistributedError(str(exc)) from None

    def _same(self, mine) -> None:
        if self.fingerprint is not None and mine != self.fingerprint:
            from ..explore.distributed import DistributedError
            import socket
            raise DistributedError(f"worker on {socket.gethostname()} reads other sources than the driver "
                                   f"(fingerprint {json.dumps(mine, sort_keys=True, default=str)[:200]}): give "
                                   "the workers the same files")


def job_fingerprint(job) -> Optional[dict]:
    """The fingerprint of the sources a job explores (as its counterexample traces record it)."""
    if job.is_roar:
        from ..roar.functional import functional_module
        from ..roar.sources import spec_fingerprint
        from ..roar.spec import load_spec
        fn_path = functional_module(job.spec, job.functional)
        return spec_fingerprint(job.spec, load_spec(job.spec), fn_path)
    from ..trace.fingerprint import clf_fingerprint
    return clf_fingerprint(job.model)


@contextmanager
def open_cluster(setup: ClusterSetup):
    """A Dask client on the job's cluster: a local one started for the job (and stopped after it),
    or the running one at ``setup.address``."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:   # pragma: no cover - a dependency of the package
        raise RoarError("search = \"distributed\" needs the Dask 'distributed' package: pip install distributed",
                        setup.pos) from None
    cluster = None
    if setup.address:
        try:
            client = Client(setup.address, timeout=setup.connect_seconds)
        except (OSError, TimeoutError) as exc:
            raise RoarError(f"cannot reach the Dask scheduler at {setup.address}: {exc}",
                            setup.address_pos or setup.pos) from None
        try:
            client.wait_for_workers(1, timeout=setup.connect_seconds)
        except (OSError, TimeoutError):
            client.close()
            raise RoarError(f"the Dask scheduler at {setup.address} has no worker (waited "
                            f"{setup.connect_seconds:g} s): start one with 'dask worker {setup.address}'",
                            setup.address_pos or setup.pos) from None
    else:
        cluster = LocalCluster(n_workers=setup.workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
        client = Client(cluster)
        client.wait_for_workers(setup.workers, timeout=max(setup.connect_seconds, 60.0))
    try:
        yield client
    finally:
        try:
            client.close()
        finally:
            if cluster is not None:
                cluster.close()


def on_cluster(job, t0: float, explore, options):
    """``check._search`` for a job with a [cluster] table: open the cluster, run the search the job
    names on it (breadth-first, distributed; or a swarm's members as tasks), free the cluster.
    The graph, states and steps the verdicts read are on this machine when it returns."""
    from ..explore.distributed import DistributedError
    setup = job.cluster
    fingerprint = job_fingerprint(job)
    with open_cluster(setup) as client:
        session = _Session(job, client, JobSystem(job, fingerprint), setup,
                           sorted(client.scheduler_info()["workers"]))
        token = _ACTIVE.set(session)
        try:
            if job.search == "swarm":
                return swarm(job, t0, explore, options)
            explorer, decide = explore(options)
            graph, verdicts = search_rounds(job, t0, explorer, decide)
            hashed_note(explorer, verdicts)
            return explorer, graph, verdicts
        except DistributedError as exc:
            raise RoarError(f"distributed search: {exc}", setup.pos) from None
        finally:
            _ACTIVE.reset(token)
            for ex in session.explorers:
                ex.close()
            if session.swarm:   # members the swarm did not need (it stopped at an earlier one)
                client.cancel(session.swarm)


def make_explorer(job, system, on_progress, order: str):
    """The explorer a job's search uses: the distributed one inside :func:`on_cluster`, a swarm
    member run as a task there, else ``search.Explorer``."""
    from ..explore.search import Explorer
    session = _ACTIVE.get()
    if session is None or session.job is not job:
        return Explorer(system, order, on_progress, job.visited)
    from ..explore.distributed import DistributedError, DistributedExplorer
    if job.search == "swarm":
        ex = SwarmMember(system, session)
    else:
        try:
            ex = DistributedExplorer(system, session.client, session.factory, workers=session.workers,
                                     batch=session.setup.batch, on_progress=on_progress, visited=job.visited)
        except DistributedError as exc:
            raise RoarError(f"distributed search: {exc}", session.setup.pos) from None
    ex.local = not session.setup.address   # (a local cluster: cluster_note weighs its workers against the cores)
    session.explorers.append(ex)
    return ex


def cluster_note(explorer) -> str:
    """What the job's backend says of the cluster: ', distributed (2 workers)'."""
    n = getattr(explorer, "n", None)
    if n is None or not hasattr(explorer, "run_id"):
        return ""
    kind = "swarm on a cluster" if getattr(explorer, "swarm", False) else "distributed"
    note = f", {kind} ({n} worker{'s' if n != 1 else ''}"
    cores = _cores()
    if getattr(explorer, "local", False) and n >= cores and kind == "distributed":
        # the workers, the scheduler and this process share the cores: no speed-up to expect
        note += (f" on {cores} core{'s' if cores != 1 else ''}, shared with the scheduler and this process: "
                 "expect no speed-up")
    return note + ")"


def _cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):   # (not on every platform)
        return os.cpu_count() or 1




class SwarmMember:
    """A swarm member (``check.swarm`` makes one per search, calls ``shuffle(i)`` then ``run``)
    whose search runs as a task on the cluster. The first member asks for all of them at once, so
    the cluster works on the next members while the swarm decides on the first; ``run`` waits for
    member i and reads its graph back (``explore.distributed.SwarmResult``)."""

    swarm = True

    def __init__(self, system, session: _Session):
        self.system = system
        self.session = session
        self.hashed = session.job.visited == "hash"
        self.n = len(session.workers)
        self.run_id = "swarm"
        self.index = 0
        self.result = None
        from ..explore.distributed import ShippedStates, ShippedSteps
        # what check.py's deciders bind when the explorer is made, filled in by run()
        self.blobs: list = [b""]
        self.step_blobs: list = []
        self.codec = None
        self.initial = system.initial()
        self.states = ShippedStates(self)
        self.steps = ShippedSteps(self)

    def shuffle(self, seed: int) -> None:
        self.index = seed

    def _submit_all(self) -> None:
        from ..explore.distributed import codec_for, swarm_member
        s, job = self.session, self.session.job
        s.swarm_codec = codec_for(self.system, 0)
        s.swarm_initial = self.system.initial()
        seed = s.swarm_codec.state(s.swarm_initial)
        b = job.budget
        s.swarm = [s.client.submit(swarm_member, s.factory, seed, i, "dfs", job.swarm_states, b.max_seconds,
                                   b.max_memory_mb, job.visited, pure=False, key=f"roar-swarm-{i}-{id(s):x}")
                   for i in range(job.swarm_runs)]

    def run(self, budget):
        from ..explore.distributed import DistributedError, SwarmResult
        s = self.session
        if s.swarm is None:
            try:
                self._submit_all()
            except Exception as exc:
                raise DistributedError(str(exc)) from None
        fut = s.swarm[self.index]
        try:
            out = fut.result()
        except DistributedError:
            raise
        except Exception as exc:
            raise DistributedError(f"swarm member {self.index + 1} failed: {type(exc).__name__}: {exc}") from exc
        self.result = r = SwarmResult(self.system, s.swarm_codec, s.swarm_initial, out)
        self.graph, self.blobs, self.step_blobs = r.graph, r.blobs, r.step_blobs
        self.codec, self.initial = s.swarm_codec, s.swarm_initial
        return self.graph

    def omission_probability(self) -> float:
        return self.result.omission_probability() if self.result is not None else 0.0

    def close(self) -> None:
        pass
