"""The explorer a job searches with: in this process, or on a cluster (verify/cluster.py),
and the search that drives it (rounds, swarm)."""

from __future__ import annotations

from dataclasses import replace

from .jobs import Job
from ..explore.search import Explorer
from ..explore.system import Options
from .cluster import make_explorer as on_the_cluster, on_cluster
from .searching import explorer_order, hashed_note, search_rounds, swarm


def run_search(job: Job, t0: float, explore, options: Options):
    """Explore in growing rounds until the graph is complete, every property is violated, or
    a budget runs out; returns (explorer, graph, verdicts).

    ``explore(options)`` makes an explorer and the function deciding the verdicts on its
    graph. Under reduction with weak fairness, a livelock verdict of "holds" is confirmed on
    the unreduced graph: a reduced graph keeps every fair cycle it shows (fairness is judged
    with every enabled group, expanded or not) but may miss one (docs/checking.md)."""
    if getattr(job, "cluster", None) is not None:   # search = "distributed", or a swarm on a cluster
        return on_cluster(job, t0, explore, options)
    if job.search == "swarm":
        return swarm(job, t0, explore, options)
    explorer, decide = explore(options)
    graph, verdicts = search_rounds(job, t0, explorer, decide)
    hashed_note(explorer, verdicts)
    lv = verdicts.get("livelock")
    if options.reduction and lv is not None and lv.status == "holds" and options.fairness != "none":
        full_options = replace(options, reduction=False)
        ex2, decide2 = explore(full_options)
        graph2, verdicts2 = search_rounds(job, t0, ex2, decide2)
        lv2 = verdicts2["livelock"]
        if lv2.status == "holds":
            saved = graph2.n_states - graph.n_states
            lv.message += (f"; confirmed without reduction ({graph2.n_states:,} states"
                           + (f": the reduction saved {saved:,} states, {100 * saved / graph2.n_states:.0f}%)"
                              if saved > 0 else ": the reduction saved no state here, and the confirmation "
                              "doubled the search; leave reduction off for this model)"))
            lv.details["confirmed_states"] = graph2.n_states
        else:
            # keep one graph for every counterexample: the unreduced one
            for v in verdicts2.values():
                v.details["reduction"] = "missed a fair livelock; verdicts from the unreduced graph"
            return ex2, graph2, verdicts2
    return explorer, graph, verdicts


def make_explorer(job: Job, system, on_progress):
    """The explorer of a job's search: ``search.Explorer``, or on a cluster (a job with a [cluster]
    table, inside ``cluster.on_cluster``) the distributed one or a swarm member run as a task."""
    if getattr(job, "cluster", None) is not None:
        return on_the_cluster(job, system, on_progress, explorer_order(job))
    return Explorer(system, explorer_order(job), on_progress, job.visited, job.bits)
