"""How a job searches: budget rounds, the swarm, and the notes its visited-set mode adds to
the verdicts. Below the cluster (which runs these searches on its workers) and the runners."""

from __future__ import annotations

import time

from .jobs import Job
from ..explore.properties import Verdict
from ..explore.search import Budget
from ..explore.system import Options


FIRST_ROUND = 20_000


def explorer_order(job: Job) -> str:
    """The explorer's order for the job's search (a swarm's members search depth first)."""
    return "dfs" if job.search == "swarm" else "bfs" if job.search == "distributed" else job.search


#: what a job's visited-set mode adds to its backend's name
VISITED_NOTE = {"exact": "", "hash": ", hash compaction", "bitstate": ", bitstate"}


def hashed_note(explorer, verdicts: dict) -> None:
    """Under hash compaction, say what each verdict is worth: a "holds" is a bug-hunting result
    with a bound on the probability that a state was missed, never a proof; a counterexample is
    real once replay confirms it (a collision could join two paths that are not one). Under
    bitstate hashing the same, with the probability that a new state was taken for a visited one."""
    if getattr(explorer, "bitstate", None) is not None:
        bitstate_note(explorer, verdicts)
        return
    if not getattr(explorer, "hashed", False):
        return
    p = explorer.omission_probability()
    for v in verdicts.values():
        v.details["visited"] = "hash"
        v.details["omission_probability"] = p
        if v.status == "holds":
            v.message += (f" [hash compaction: not verified; the probability that a state was missed is at "
                          f"most {p:.1e}]")
        elif v.status == "violated":
            v.message += " [hash compaction: replay the trace to confirm it]"


#: past this probability of omission a bit array is too small for the model: most of its states
#: may be unexplored (the verdict says so, and the summary table too)
TOO_SMALL = 1e-2


def bitstate_note(explorer, verdicts: dict) -> None:
    g = explorer.graph
    p, lost = explorer.omission_probability(), explorer.expected_omissions()
    what = (f"{g.n_states:,} states in {explorer.bits:,} bits, 3 bits each: at the end a new state was taken "
            f"for a visited one with probability {p:.1e}; about {_about(lost)} states were so taken, and their "
            f"successors may be missed too")
    if p > TOO_SMALL:   # the array is too small: most of the state space may be unexplored
        need = _bits_for(g.n_states)
        what += (f"; the bit array is too small for this model: give [bitstate] bits at least {need:,} "
                 f"(more, as the states it missed are found)")
    for v in verdicts.values():
        v.details.update(visited="bitstate", omission_probability=p, expected_omissions=lost, bits=explorer.bits,
                         unrecorded_transitions=g.n_unrecorded)
        if v.status == "holds":
            v.message += f" [bitstate: not verified; {what}]"
        elif v.status == "violated":
            v.message += " [bitstate: a real path; replay the trace to confirm it]"


def _about(x: float) -> str:
    """An expected count as said: below one, as a probability-sized number, not "0.0"."""
    return f"{x:,.1f}" if x >= 0.1 else f"{x:.1e}"


def _bits_for(n: int) -> int:
    """The bits a bitstate array needs for ``n`` states to keep the end-of-search omission
    probability (1 - e^(-3n/m))^3 below 1e-3 (m at least 3n / -ln(1 - 0.1)), rounded up to a
    power of two."""
    import math
    m = int(3 * max(n, 1) / -math.log(0.9)) + 1
    return 1 << (m - 1).bit_length()


def stated_time(job: Job, graph) -> None:
    """A search stopped by the time bound is given what the job's bound left after loading and
    compiling; its reason names the job's bound, the number the user wrote."""
    if job.budget.max_seconds is not None and graph.stop_reason.startswith("time budget of "):
        graph.stop_reason = f"time budget of {job.budget.max_seconds:g} s reached, loading and compiling included"


def search_rounds(job: Job, t0: float, explorer, decide):
    limit = job.budget.max_states
    k = FIRST_ROUND if limit is None else min(FIRST_ROUND, limit)
    graph = verdicts = None
    while True:
        remaining = None
        if job.budget.max_seconds is not None:
            remaining = max(0.0, job.budget.max_seconds - (time.perf_counter() - t0))
            # a resumed search counts its time over every round (``elapsed``): its bound is what it
            # has spent so far plus what the job has left (without this, a round stopped when its
            # whole search time reached what was left, well before the job's bound)
            remaining += getattr(explorer, "elapsed", 0.0)
        graph = verdicts = None  # a restarting backend (ground) gives the last round's memory back first
        graph = explorer.run(Budget(max_states=k, max_seconds=remaining, max_memory_mb=job.budget.max_memory_mb))
        stated_time(job, graph)
        verdicts = decide(graph)
        if graph.complete or all(v.violated for v in verdicts.values()):
            return graph, verdicts
        if "state budget" not in graph.stop_reason or (limit is not None and k >= limit):
            return graph, verdicts
        grow = getattr(explorer, "GROWTH", 4)
        k = k * grow if limit is None else min(k * grow, limit)


def swarm(job: Job, t0: float, explore, options: Options):
    """Search = "swarm": up to ``job.swarm_runs`` depth-first searches, each taking successors in
    its own random order and stopping once it holds ``job.swarm_states`` states, until one finds a
    violation (its counterexample is real but not the shortest) or covers the whole state space
    (then the verdicts are those of a complete search). Otherwise no verdict is "holds": the
    properties not found violated are "incomplete", with what the swarm covered."""
    total = 0
    last = None
    cap = job.budget.max_states   # the job's bounds hold for the swarm as a whole
    stop = ""   # the job's bound that ended the swarm before its last search, if one did
    cap_reached = f"state budget of {cap:,} reached" if cap is not None else ""
    for i in range(job.swarm_runs):
        per_run = job.swarm_states
        if cap is not None:
            if total >= cap and last is not None:
                stop = cap_reached
                break
            per_run = min(per_run, max(1, cap - total))
        remaining = None
        if job.budget.max_seconds is not None:
            remaining = job.budget.max_seconds - (time.perf_counter() - t0)
            if remaining <= 0 and last is not None:
                stop = f"time budget of {job.budget.max_seconds:g} s reached"
                break
        explorer, decide = explore(options)
        explorer.shuffle(i)
        graph = explorer.run(Budget(max_states=per_run, max_seconds=remaining,
                                    max_memory_mb=job.budget.max_memory_mb))
        stated_time(job, graph)
        verdicts = decide(graph)
        total += graph.n_states
        hashed_note(explorer, verdicts)
        last = (explorer, graph, verdicts, i + 1)
        if graph.complete:
            for v in verdicts.values():
                v.message += f" [swarm: search {i + 1} covered the whole state space]"
            return explorer, graph, verdicts
        if any(v.violated for v in verdicts.values()):
            for v in verdicts.values():
                if v.violated:
                    v.message += (f" [swarm: found by randomized depth-first search {i + 1} of {job.swarm_runs}; "
                                  f"a real counterexample, not the shortest]")
            break
        if "time budget" in graph.stop_reason or "memory budget" in graph.stop_reason:
            stop = graph.stop_reason   # the job's own bound: the searches after it would not run
            break
        if cap is not None and total >= cap and (i + 1 < job.swarm_runs or per_run < job.swarm_states):
            stop = cap_reached
            break
    explorer, graph, verdicts, done = last
    # what ended the swarm, for the budget hint: a bound of the job (raise it), or every search
    # stopped at its own bound ([swarm] runs and max_states)
    graph.stop_reason = stop or "swarm: every search stopped at its own bound"
    runs = (f"{done} randomized depth-first search{'es' if done != 1 else ''}" if not stop else
            f"{done} of {job.swarm_runs} randomized depth-first searches")
    for p, v in verdicts.items():
        if not v.violated:
            verdicts[p] = Verdict(p, "incomplete",
                                  f"no violation found by {runs} ({total:,} states visited in all, each search "
                                  f"stopping at {job.swarm_states:,}"
                                  + ((f"; {job.swarm_runs - done} did not run: the {stop}" if done < job.swarm_runs
                                      else f"; the {stop}") if stop else "")
                                  + "): a bug-hunting result, not verified",
                                  v.counterexample, {**v.details, "swarm_runs": done, "swarm_states": total,
                                                     **({"swarm_stop": stop} if stop else {})})
    return explorer, graph, verdicts


def mark_reduction(job: Job, verdicts: dict, reduction: str, explorer=None) -> None:
    """Say on every verdict that the search was reduced, and what the reduction left out (a
    verdict of a budget-bound reduced search says what the reduction saved, too)."""
    if job.reduction:
        saved = ""
        if reduction == "on" and getattr(explorer, "reduce", False):
            n, left = explorer.reduced_expansions, explorer.steps_left_out
            saved = (f": {n:,} of {explorer.graph.n_states:,} states expanded by a subset of their steps, "
                     f"{left:,} step(s) not taken" if n else ": it saved nothing here, no state having a smaller "
                     "set of steps to take")
        for v in verdicts.values():
            v.message += f" (partial-order reduction{saved})" if reduction == "on" else f" (reduction {reduction})"
            v.details.setdefault("reduction", reduction)
            if saved:
                v.details["reduced_expansions"] = explorer.reduced_expansions
                v.details["steps_left_out"] = explorer.steps_left_out
