"""``verify.searching.search_rounds``: the state budget grows round by round on one resumed
search; each round's time bound is the job's, counted as the search counts its own time."""

from __future__ import annotations

import time
from types import SimpleNamespace

from roar_formal.explore.graph import StateGraph
from roar_formal.verify.jobs import Job
from roar_formal.verify.searching import FIRST_ROUND, search_rounds


class _Resumed:
    """A search that counts its time over every round (as ``Explorer.elapsed`` does): each round
    spends 5 s of it and stops at its state budget."""

    def __init__(self):
        self.elapsed = 0.0
        self.budgets = []

    def run(self, budget):
        self.budgets.append(budget)
        self.elapsed += 5.0
        g = StateGraph()
        g.add_state(-1, -1, 0)
        g.stop_reason = f"state budget of {budget.max_states} reached"
        return g


def test_each_round_is_bounded_by_what_the_job_has_left_not_by_its_own_total():
    job = Job(path=None, name="rounds", model=None)
    job.budget.max_seconds = 100.0
    job.budget.max_states = FIRST_ROUND * 16
    ex = _Resumed()
    t0 = time.perf_counter()
    search_rounds(job, t0, ex, lambda g: {"deadlock": SimpleNamespace(violated=False)})
    assert [b.max_states for b in ex.budgets] == [FIRST_ROUND, FIRST_ROUND * 4, FIRST_ROUND * 16]
    # round k may search until its total reaches what it spent before plus what the job has left
    # (wall time here is ~0): 100, 105, 110; it used to be 100, 100, 100, so a search with
    # several rounds stopped when its total, not the job's time, reached the bound
    for k, b in enumerate(ex.budgets):
        assert abs(b.max_seconds - (100.0 + 5.0 * k)) < 1.0
