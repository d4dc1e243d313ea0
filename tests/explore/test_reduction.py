"""Partial-order reduction (stubborn sets) on the general backend: same verdicts, fewer states."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from hypothesis import given, settings, strategies as st

from roar_formal.clf.program import Program
from roar_formal.clf.query import with_big_stack
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import load_job
from roar_formal.explore.properties import check_deadlock
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import ClfSystem, Options
from roar_formal.verify.replay import replay

from leveled import leveled_program
from repo import ROOT

_spec = importlib.util.spec_from_file_location("phil_gen", ROOT / "models/philosophers/generate.py")
gen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen)


def explore(src, reduction: bool, budget: Budget = Budget(), **opts):
    """``src``: a program's text, or the program (keys of states holding rules name the rules'
    templates: two explorations compare keys only when they read one program)."""
    p = Program.from_text(src) if isinstance(src, str) else src
    system = ClfSystem(p, p.start_context(p.sig.directives[-1].start), Options(reduction=reduction, **opts))
    ex = Explorer(system)
    g = with_big_stack(ex.run, budget)
    return ex, g


def quiescent_keys(ex: Explorer, g) -> set:
    out = g.out_degree()
    return {ex.system.key(ex.states[s]) for s in range(g.n_states) if g.expanded[s] and out[s] == 0}


def same_deadlocks(src: str, budget: Budget = Budget()):
    """Explore with and without reduction; the reachable quiescent states must be the same."""
    src = Program.from_text(src)
    full_ex, full = explore(src, False, budget)
    red_ex, red = explore(src, True, budget)
    if not (full.complete and red.complete):
        return None
    assert red.n_states <= full.n_states
    assert quiescent_keys(red_ex, red) == quiescent_keys(full_ex, full)
    a, b = check_deadlock(full), check_deadlock(red)
    assert a.status == b.status
    for s in range(red.n_states):  # every state of the reduced graph is a state of the full one
        assert red_ex.system.key(red_ex.states[s]) in full_ex.ids
    # what the reduction says it left out: every step enabled at a reduced graph's state is a
    # transition of it or a step left out (counted afresh by the engine)
    enabled = sum(len(red_ex.system.program.steps(red_ex.states[s])) for s in range(red.n_states))
    assert enabled == red.n_edges + red_ex.steps_left_out
    assert (red_ex.steps_left_out > 0) == (red_ex.reduced_expansions > 0)
    return full, red, red_ex


# ------------------------------------------------------------ philosophers


@pytest.mark.parametrize("variant", ["dl", "ok", "ll"])
@pytest.mark.parametrize("n", [3, 4])
def test_philosophers_deadlock_verdicts_are_unchanged(variant, n):
    got = same_deadlocks(gen.program(variant, n))
    assert got is not None
    full, red, _ = got
    assert red.n_edges < full.n_edges  # local steps (eat) are taken alone somewhere


def _job(tmp: Path, model: Path, reduction: bool, check: str = '["deadlock", "livelock"]') -> Path:
    props = tmp / "props.toml"
    livelock = '[livelock]\nprogress = ["eat"]\nfairness = "first-argument"\n' if "livelock" in check else ""
    props.write_text(f'check = {check}\n{livelock}', encoding="utf-8")
    job = tmp / f"job_{model.stem}_{reduction}.toml"
    job.write_text(f'model = "{model}"\nproperties = "{props}"\nbackend = "general"\n'
                   f'reduction = {str(reduction).lower()}\n', encoding="utf-8")
    return job


@pytest.mark.parametrize("variant", ["dl", "ok", "ll"])
@pytest.mark.parametrize("n", [3, 4])
def test_philosophers_job_verdicts_with_and_without_reduction(tmp_path, variant, n):
    model = tmp_path / f"{variant}{n}.clf"
    model.write_text(gen.program(variant, n), encoding="utf-8")
    off = run_job(load_job(_job(tmp_path, model, False)))
    on = run_job(load_job(_job(tmp_path, model, True)))
    assert on.backend == off.backend == "general"
    assert on.reduction == "on"
    for p in ("deadlock", "livelock"):
        assert on.verdicts[p].status == off.verdicts[p].status
        assert "partial-order reduction" in on.verdicts[p].message
    if off.verdicts["livelock"].status == "holds":
        # weak fairness: "no fair livelock" on a reduced graph is confirmed without reduction
        assert "confirmed without reduction" in on.verdicts["livelock"].message
        assert on.verdicts["livelock"].details["confirmed_states"] == off.graph.n_states
    else:
        # a fair cycle of the reduced graph is a fair cycle of the full system: replay it
        cx = on.verdicts["livelock"].counterexample
        assert cx.kind == "lasso" and cx.cycle
        assert on.graph.n_states <= off.graph.n_states
    # deadlock alone: reduction on, same verdict
    sub = tmp_path / "dl_only"
    sub.mkdir()
    on_dl = run_job(load_job(_job(sub, model, True, '["deadlock"]')))
    assert on_dl.reduction == "on" and on_dl.verdicts["deadlock"].details["reduction"] == "on"
    left = on_dl.verdicts["deadlock"].details["steps_left_out"]
    assert left > 0 and f"{left:,} step(s) not taken" in on_dl.verdicts["deadlock"].message
    assert on_dl.verdicts["deadlock"].status == off.verdicts["deadlock"].status
    assert on_dl.graph.n_states <= off.graph.n_states


def test_ground_backend_ignores_reduction(tmp_path):
    model = tmp_path / "dl3.clf"
    model.write_text(gen.program("dl", 3), encoding="utf-8")
    job = _job(tmp_path, model, True, '["deadlock"]')
    job.write_text(job.read_text().replace('backend = "general"', 'backend = "auto"'))
    res = run_job(load_job(job))
    assert res.backend == "ground" and res.reduction == "not used by the ground backend"
    assert res.verdicts["deadlock"].violated


def test_reduction_key_must_be_a_boolean(tmp_path):
    from roar_formal.errors import RoarError

    model = tmp_path / "dl3.clf"
    model.write_text(gen.program("dl", 3), encoding="utf-8")
    job = _job(tmp_path, model, True)
    job.write_text(job.read_text().replace("reduction = true", 'reduction = "yes"'))
    with pytest.raises(RoarError, match="reduction"):
        load_job(job)
    assert load_job(_job(tmp_path, model, False)).reduction is False


# ------------------------------------------------------------ independent processes


def independent(k: int, stuck: bool = False) -> str:
    src = ("pid : type.\n" + "".join(f"q{i} : pid.\n" for i in range(k))
           + "a : pid -> type. b : pid -> type. d : pid -> type. e : pid -> type.\n"
           + "ab : a P -o {b P}.\nbd : b P -o {d P}.\nde : d P -o {e P}.\n")
    if stuck:
        src += "fin : e q0 * e q1 -o {1}.\n"
    return src + "#exec * " + " * ".join(f"a q{i}" for i in range(k)) + ".\n"


def test_independent_processes_give_a_strictly_smaller_graph():
    full, red, ex = same_deadlocks(independent(4))
    assert full.n_states == 4 ** 4
    assert red.n_states == 3 * 4 + 1  # one interleaving
    assert ex.reduced_expansions > 0
    full, red, _ = same_deadlocks(independent(3, stuck=True))
    assert red.n_states < full.n_states


# ------------------------------------------------------------ fresh names

CHANNELS = """
pid : type. p0 : pid. p1 : pid. p2 : pid.
chan : type.
idle : pid -> type.
wait : pid -> chan -> type.
msg : chan -> type.
got : pid -> type.
open : idle P -o {Exists c:chan. wait P c * msg c}.
recv : wait P C * msg C -o {got P}.
#exec * idle p0 * idle p1 * idle p2.
"""

SHARED = """
pid : type. p0 : pid. p1 : pid.
tok : type.
idle : pid -> type.
hold : pid -> tok -> type.
pool : tok -> type.
made : type.
mk : made -o {Exists t:tok. pool t}.
take : idle P * pool T -o {hold P T}.
give : hold P T -o {pool T}.
#exec * idle p0 * idle p1 * made * made.
"""

SHARED_STUCK = SHARED.replace("give : hold P T -o {pool T}.", "give : hold p0 T -o {pool T}.")


@pytest.mark.parametrize("src", [CHANNELS, SHARED, SHARED_STUCK], ids=["channels", "shared", "shared-stuck"])
def test_programs_with_fresh_names(src):
    got = same_deadlocks(src, Budget(max_states=5000))
    assert got is not None


def test_channels_reduce():
    full, red, _ = same_deadlocks(CHANNELS)
    assert red.n_states < full.n_states


# ------------------------------------------------------------ random programs


@st.composite
def programs(draw):
    names = ["k0", "k1"]
    fams = ["p", "q", "r", "u"]
    atom = st.tuples(st.sampled_from(fams), st.sampled_from(names + ["X", "Y"]))
    rules = []
    for i in range(draw(st.integers(1, 5))):
        prem = draw(st.lists(atom, min_size=1, max_size=3))
        bound = {a for _, a in prem if a in ("X", "Y")}
        concl = draw(st.lists(atom, max_size=2))
        concl = [(f, a if a not in ("X", "Y") or a in bound else "k1") for f, a in concl]
        bang = draw(st.booleans()) and len(prem) > 1
        lhs = " * ".join(("!" if bang and j == 0 else "") + f"{f} {a}" for j, (f, a) in enumerate(prem))
        rhs = " * ".join(f"{f} {a}" for f, a in concl) or "1"
        if draw(st.booleans()) and concl:  # a fresh name somewhere in the head
            f, _ = concl[0]
            rhs = f"Exists n:k. {f} n" + (" * " + " * ".join(f"{g} {a}" for g, a in concl[1:]) if concl[1:] else "")
        rules.append(f"r{i} : {lhs} -o {{{rhs}}}.")
    start = draw(st.lists(st.tuples(st.sampled_from(fams), st.sampled_from(names)), min_size=1, max_size=5))
    pers = draw(st.lists(st.tuples(st.sampled_from(fams), st.sampled_from(names)), max_size=2))
    return ("k : type. k0 : k. k1 : k.\n" + "".join(f"{f} : k -> type.\n" for f in fams)
            + "\n".join(rules) + "\n#exec * " + " * ".join([f"{f} {a}" for f, a in start]
                                                            + [f"!{f} {a}" for f, a in pers]) + ".\n")


@settings(max_examples=20, deadline=None)
@given(programs())
def test_random_programs_keep_their_deadlocks(src):
    same_deadlocks(src, Budget(max_states=400, max_seconds=2))


@st.composite
def programs_with_rules(draw):
    """Programs whose heads put rules in the context: a continuation waiting for a fact (on a
    name the head makes fresh, or one the rule matched), alternatives joined by ``&``, and
    plain facts, so that states hold rules as a destination-passing program's do."""
    names = ["k0", "k1"]
    fams = ["p", "q", "r", "u"]
    atom = st.tuples(st.sampled_from(fams), st.sampled_from(names + ["X"]))
    rules = []
    for i in range(draw(st.integers(1, 4))):
        prem = draw(st.lists(atom, min_size=1, max_size=2))
        bound = any(a == "X" for _, a in prem)

        def arg(a: str) -> str:
            return a if a != "X" or bound else "k1"

        concl = [f"{f} {arg(a)}" for f, a in draw(st.lists(atom, max_size=2))]
        fresh = draw(st.booleans())
        if draw(st.booleans()):   # a rule put in the context
            wait_on = "n" if fresh else arg(draw(st.sampled_from(names + ["X"])))
            f1, f2, g1, g2 = (draw(st.sampled_from(fams)) for _ in range(4))
            alt1 = f"{f1} {wait_on} -o {{{g1} {wait_on}}}"
            if draw(st.booleans()):
                concl.append(f"(({alt1}) & ({f2} {wait_on} -o {{{g2} k0}}))")
            else:
                concl.append(f"({alt1})")
            if fresh:
                concl.append(f"{draw(st.sampled_from(fams))} n")
        elif fresh and concl:
            concl[0] = concl[0].rsplit(" ", 1)[0] + " n"
        rhs = " * ".join(concl) or "1"
        if fresh and " n" in rhs:
            rhs = f"Exists n:k. {rhs}"
        lhs = " * ".join(f"{f} {a}" for f, a in prem)
        rules.append(f"r{i} : {lhs} -o {{{rhs}}}.")
    start = draw(st.lists(st.tuples(st.sampled_from(fams), st.sampled_from(names)), min_size=1, max_size=4))
    return ("k : type. k0 : k. k1 : k.\n" + "".join(f"{f} : k -> type.\n" for f in fams)
            + "\n".join(rules) + "\n#exec * " + " * ".join(f"{f} {a}" for f, a in start) + ".\n")


@settings(max_examples=30, deadline=None)
@given(programs_with_rules())
def test_random_programs_with_rules_in_the_context_keep_their_deadlocks(src):
    same_deadlocks(src, Budget(max_states=400, max_seconds=2))


CONTINUATIONS = """
pid : type. p0 : pid. p1 : pid. p2 : pid.
dst : type.
job : pid -> type.
val : dst -> type.
done : pid -> type.
start : job P -o {Exists d:dst. (val d -o {done P}) * val d}.
#exec * job p0 * job p1 * job p2.
"""


def test_continuations_in_the_context_reduce():
    """Independent processes each waiting on their own fresh destination: the rules they put in
    the context do not stop the reduction (one interleaving is explored)."""
    full, red, ex = same_deadlocks(CONTINUATIONS)
    assert full.n_states == 3 ** 3
    assert red.n_states == 2 * 3 + 1
    assert ex.system.reducer.reduced > 0


# Programs an audit of the reduction found it unsound on (each missed a reachable quiescent state):
# a linear goal proved from clauses that use up a linear fact (bug 1); a rule that consumes one
# copy of a fact and makes two (2); rules in the start state (3); a persistent fact a proof reads
# through a clause (4); a "read" of a fact served by a persistent one, which adds a linear copy (5).
AUDIT = {
    "proof-consumes": "a : type. b : type. c : type. d : type.\nb_from_a : b o- a.\nr : b -o {c}.\n"
                      "r2 : b -o {d}.\n#exec * a.\n",
    "two-copies": "a : type. x : type. y : type. done : type. zz : type. fuel : type.\ne : x -o {y}.\n"
                  "z : x * done -o {zz}.\ndup : a * fuel -o {a * a}.\nq : a * a -o {done}.\n#exec * x * a * fuel.\n",
    "start-rules": "p : type. q : type. r : type.\ns : p -o {r}.\n#exec * (p -o {q}) * p.\n",
    "proof-reads": "a : type. b : type. c : type. d : type. x : type. y : type.\nbc : b <- a.\ne : x -o {d}.\n"
                   "mk : y -o {!a}.\nr : !b * x -o {c}.\n#exec * x * y.\n",
    "persistent-read": "r : type. a : type. b : type. done : type.\nuse : b * r -o {done}.\n"
                       "rd : a * r -o {r}.\n#exec * !r * a * b.\n",
}


@pytest.mark.parametrize("name", sorted(AUDIT))
def test_the_audits_programs_keep_their_quiescent_states(name):
    got = same_deadlocks(AUDIT[name])
    assert got is not None


@settings(max_examples=100, deadline=None)
@given(st.randoms(use_true_random=False))
def test_leveled_random_programs_keep_their_deadlocks(rnd):
    """(400 such programs: every one keeps its quiescent states, about a quarter with a smaller
    graph; before the audit's fixes 12 of the 400 lost a quiescent state.)"""
    same_deadlocks(leveled_program(rnd), Budget(max_states=800, max_seconds=3))


# ------------------------------------------------------------ counterexamples replay


def test_reduced_counterexamples_replay(tmp_path):
    # (models without fresh names: the replayer matches produced facts by their printed form)
    for name, src in (("indep", independent(3, stuck=True)), ("dl4", gen.program("dl", 4))):
        model = tmp_path / f"{name}.clf"
        model.write_text(src, encoding="utf-8")
        sub = tmp_path / name
        sub.mkdir()
        res = run_job(load_job(_job(sub, model, True, '["deadlock"]')))
        assert res.reduction == "on"
        v = res.verdicts["deadlock"]
        assert v.violated, name
        trace = save_counterexample(res, "deadlock", sub)
        rr = replay(trace, model=model)
        assert rr.steps == len(v.counterexample.prefix)
        # the replayed end state is the reported deadlock, and it is quiescent
        assert not res.program.steps(rr.states[-1])


def test_reduced_paths_are_runs_of_the_program():
    """With fresh names: every edge on the way to each state of the reduced graph is an
    enabled step of its source state, and leads to the recorded state."""
    p = Program.from_text(SHARED_STUCK)
    ex = Explorer(ClfSystem(p, p.start_context(p.sig.directives[-1].start), Options(reduction=True)))
    g = ex.run()
    v = check_deadlock(g)
    assert v.violated
    state = ex.states[0]
    for e in v.counterexample.prefix:
        step = ex.steps[e]
        match = [c for c in p.steps(state) if c.template is step.template
                 and sorted(map(id, (f for _, f in c.consumed))) == sorted(map(id, (f for _, f in step.consumed)))]
        assert match
        state = ex.states[g.dst[e]]
    assert not p.steps(state)


# ------------------------------------------------------------ safety and livelock under reduction


def _violating_keys(ex: Explorer, g, never) -> set:
    return {ex.system.key(ex.states[s]) for s in range(g.n_states) if never(ex.states[s])}


@settings(max_examples=20, deadline=None)
@given(programs(), st.lists(st.tuples(st.sampled_from(["p", "q", "r", "u"]), st.sampled_from(["k0", "k1", "X"])),
                            min_size=1, max_size=2))
def test_random_programs_keep_their_invariant_verdicts(src, pattern):
    """An invariant's forbidden pattern stays in every stubborn set: a state matching it is
    reachable with reduction exactly when it is without (plain search as the oracle)."""
    from roar_formal.verify.check import make_never

    text = " * ".join(f"{f} {a}" for f, a in pattern)
    never = make_never(src, "<random>", [(text, None)])
    full_ex, full = explore(src, False, Budget(max_states=400, max_seconds=2))
    p = Program.from_text(src)
    system = ClfSystem(p, p.start_context(p.sig.directives[-1].start),
                       Options(reduction=True, observers=never.templates))
    red_ex = Explorer(system)
    red = with_big_stack(red_ex.run, Budget(max_states=400, max_seconds=2))
    if not (full.complete and red.complete):
        return
    bad_full, bad_red = _violating_keys(full_ex, full, never), _violating_keys(red_ex, red, never)
    assert bool(bad_full) == bool(bad_red)
    assert bad_red <= bad_full and red.n_states <= full.n_states


@settings(max_examples=20, deadline=None)
@given(programs(), st.sampled_from(["r0", "r1", "r2"]))
def test_random_programs_keep_their_non_progress_cycles(src, progress):
    """Without fairness a livelock is any cycle without progress; progress steps are visible
    and the cycle proviso holds, so the verdict is the same with and without reduction."""
    from roar_formal.explore.properties import check_livelock

    opts = dict(fairness="none", progress_rules=(progress,))
    _, full = explore(src, False, Budget(max_states=400, max_seconds=2), **opts)
    _, red = explore(src, True, Budget(max_states=400, max_seconds=2), **opts)
    if not (full.complete and red.complete):
        return
    assert check_livelock(red).status == check_livelock(full).status


# A fair livelock that a reduced graph misses: group h can take `t` (never needed) or loop;
# group g waits. Unreduced, `e` then h's loop forever is fair (g is disabled: no g0, no tok).
# Reduced, `t` is taken alone first (it is independent of everything), after which g's `u`
# stays enabled along h's loop, so every cycle left is unfair to g. Hence "holds" under
# reduction is confirmed on the unreduced graph.
HIDDEN_FAIR = """
grp : type. h : grp. g : grp.
a : grp -> type. tok : grp -> type. g0 : grp -> type. k : grp -> type.
l0 : grp -> type. l1 : grp -> type. fin : grp -> type.
t : a h -o {tok g}.
e : g0 g -o {k h}.
loop1 : l0 h * k h -o {l1 h * k h}.
loop2 : l1 h * k h -o {l0 h * k h}.
u : tok g * k h -o {fin g}.
#exec * a h * g0 g * l0 h.
"""


def test_weak_fairness_livelock_missed_by_reduction_is_confirmed(tmp_path):
    from roar_formal.explore.properties import check_livelock

    _, full = explore(HIDDEN_FAIR, False, fairness="first-argument")
    red_ex, red = explore(HIDDEN_FAIR, True, fairness="first-argument")
    assert check_livelock(full).violated
    assert red_ex.reduced_expansions > 0 and red.n_states < full.n_states
    assert check_livelock(red).status == "holds"  # the reduced graph alone would say so
    model = tmp_path / "hidden.clf"
    model.write_text(HIDDEN_FAIR, encoding="utf-8")
    props = tmp_path / "p.toml"
    props.write_text('check = ["livelock"]\n[livelock]\nprogress = ["u"]\nfairness = "first-argument"\n',
                     encoding="utf-8")
    job = tmp_path / "job.toml"
    job.write_text(f'model = "{model}"\nproperties = "{props}"\nbackend = "general"\nreduction = true\n',
                   encoding="utf-8")
    res = run_job(load_job(job))
    v = res.verdicts["livelock"]
    assert v.violated and "missed" in v.details["reduction"]
    assert res.graph.n_states == full.n_states  # the verdict and its lasso come from the full graph


def test_the_json_report_says_what_the_reduction_left_out(tmp_path, capsys):
    import json
    from roar_formal.cli import main
    model = tmp_path / "dl4.clf"
    model.write_text(gen.program("dl", 4), encoding="utf-8")
    job = _job(tmp_path, model, True, '["deadlock"]')
    with pytest.raises(SystemExit):
        main(["check", str(job), "--json", "--no-traces"])
    d = json.loads(capsys.readouterr().out)[0]["verdicts"]["deadlock"]
    direct = run_job(load_job(job)).verdicts["deadlock"]
    assert d["steps_left_out"] == direct.details["steps_left_out"] > 0
    assert d["reduced_expansions"] == direct.details["reduced_expansions"] > 0
    assert f"{d['steps_left_out']:,} step(s) not taken" in d["message"]
