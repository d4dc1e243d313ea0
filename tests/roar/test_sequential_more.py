"""Sequential achievement beyond ``make A; make B`` (docs/checking.md, "Sequential achievement").

Each kind of pair has a seeded fault that breaks it and a fixed twin that keeps it
(``tests/roar/data/seq_*.roar``, primitives that always work: ``seq_tools.py``):

* a pair that is not consecutive (``seq_later_pair``: clamp, light, drill; the light holds at
  once, so only (clamp, drill) can see the clamping subtree still pressing);
* an ensure let go before the next statement (``seq_aborted_ensure``: the abort is asynchronous);
* sub-goal tasks planned by the logic layer (``seq_plan``: ``approach then grasp``);
* an achieved goal undone later, ``kept`` (``seq_kept``: undone when the next statement is
  achieved; ``seq_kept_late``: also when the recipe ends).

Every verdict is cross-checked against an independent oracle (``seq_oracle.py``): a plain
breadth-first search over the engine that keeps the path's task tree as facts and checks the
order by walking it. The monitor's verdict, the length of its (shortest) counterexample and the
pair it names must be the oracle's.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from roar_formal.clf.query import with_big_stack
from roar_formal.errors import RoarError
from roar_formal.explore.properties import check_states
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import Options
from roar_formal.roar.explore import (MONITOR_FAMILIES, PROGRESS_RULES, RoarSystem, job_sequence_pairs,
                                      sequential_pairs)
from roar_formal.verify.check import run_job
from roar_formal.verify.jobs import load_job, load_properties

from repo import ROOT

from .seq_oracle import DATA, TOOLS, SeqOracle, compiled

RETRY = ROOT / "models" / "faulty" / "retry_bounded.roar"
SLAMMED = ROOT / "models" / "faulty" / "ensure_slammed.roar"

FAULTS = {   # spec -> (request, fixed twin)
    "seq_later_pair.roar": ("cell::done == true", "seq_later_pair_fixed.roar"),
    "seq_aborted_ensure.roar": ("cell::done == true", "seq_aborted_ensure_fixed.roar"),
    "seq_plan.roar": ("arm::holding == true", "seq_plan_fixed.roar"),
}
KEPT = {"seq_kept.roar": "cell::done == true", "seq_kept_late.roar": "cell::done == true",
        "seq_kept_fixed.roar": "cell::done == true"}
PREDS = {"make(lamp::on == true)": lambda v: v["lamp::on"] == "true",
         "make(cam::shot == true)": lambda v: v["cam::shot"] == "true"}

_RUNS: dict = {}


def explored(spec: str, request: str, kept=False):
    """(model, pairs, system, explorer, graph, verdict) of the monitor on ``spec``, once."""
    key = (spec, request, kept)
    if key not in _RUNS:
        def go():
            model, _program, start = compiled(spec, request)
            pairs = sequential_pairs(model, kept=kept)
            system = RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent"), pairs)
            ex = Explorer(system)
            g = ex.run(Budget(max_states=20_000))
            assert g.complete
            v = check_states(g, "sequential-achievement", lambda s: system.sequence_reason(ex.states[s]))
            return model, pairs, system, ex, g, v
        _RUNS[key] = with_big_stack(go)
    return _RUNS[key]


def oracle_of(spec: str, request: str, pairs, kept=False) -> SeqOracle:
    key = ("oracle", spec, request, kept)
    if key not in _RUNS:
        seq = [(p.a, p.b, p.a_text, p.b_text) for p in pairs if p.kind == "seq"]
        plan = [p.a[len("plan:"):] for p in pairs if p.kind == "plan"]
        kp = [(p.a_site, p.b, p.a_text, p.b_text) for p in pairs if p.kept]
        ends = {p.a_site for p in pairs if p.kept and p.a_end} | {p.b for p in pairs if p.kept and p.b_end}
        _RUNS[key] = with_big_stack(SeqOracle, spec, request, seq, plan, kp, ends, PREDS)
    return _RUNS[key]


def _what(pair) -> tuple:
    """A violation's pair as the oracle names it."""
    if pair.kind == "plan":
        return ("plan", pair.a_text.split("::")[1], pair.b_text.split("::")[1])
    if pair.kind == "kept":
        return ("kept", pair.a_text, pair.b_text if pair.b != "end" else "end")
    return ("seq", pair.a_text, pair.b_text)


# ------------------------------------------------------------------ 1. which pairs


def test_every_ordered_pair_of_a_block_is_a_pair():
    model, *_ = compiled("seq_later_pair.roar", "cell::done == true")
    pairs = sequential_pairs(model)
    assert [(p.kind, p.a_text, p.b_text) for p in pairs] == [
        ("seq", "make(vise::clamped == true)", "make(light::on == true)"),
        ("seq", "make(vise::clamped == true)", "make(drill::drilled == true)"),
        ("seq", "make(light::on == true)", "make(drill::drilled == true)")]
    assert {p.where for p in pairs} == {"cell.work.clamp_light_drill"}


def test_an_ensure_is_a_first_sub_goal_only_once_let_go():
    # aborted between the two: a sequential pair; still in force over the next statement (it
    # protects it): no order pair, only a `kept` pair when asked for
    model, *_ = compiled("seq_aborted_ensure.roar", "cell::done == true")
    [p] = sequential_pairs(model)
    assert (p.kind, p.a_text, p.b_text) == ("seq", "let h ensure(jaw::pressed == true, 100)",
                                            "make(drill::drilled == true)")
    assert not p.kept and not p.a_end   # an ensure its recipe aborts is not kept to the end
    slam = compiled(str(SLAMMED), "user::done == true")[0]
    door = [p for p in sequential_pairs(slam) if p.kind != "plan"]
    assert door == []
    [k] = [p for p in sequential_pairs(slam, kept=True) if p.kind != "plan"]
    assert (k.kind, k.a, k.a_text, k.b_text, k.a_pred) == (
        "kept", f"kept:{k.a_site}", "let h ensure(door::open == true, 100)", "make(door::slammed == true)",
        "door::open == true")


def test_an_agent_that_plans_sub_goals_has_a_plan_pair():
    model, *_ = compiled("seq_plan.roar", "arm::holding == true")
    assert [(p.kind, p.a, p.where) for p in sequential_pairs(model)] == [
        ("plan", "plan:arm", "arm (planned tasks)")]
    assert sequential_pairs(model, plans=False) == []


def test_kept_selects_recipes_and_qualifies_predicates():
    model, *_ = compiled("seq_kept.roar", "cell::done == true")
    [p] = sequential_pairs(model, kept=["cell.work.light_then_shoot"])
    assert p.kept and (p.a_pred, p.b_pred, p.a_end, p.b_end) == ("lamp::on == true", "cam::shot == true", True, True)
    assert not sequential_pairs(model, kept=["cam.shoot.expose"])[0].kept


def test_the_monitor_families_include_what_the_new_pairs_read():
    # partial-order reduction keeps every rule touching these visible (docs/checking.md)
    assert {"hs", "rs", "contains", "mon_plan", "mon_got", "mon_undone"} <= MONITOR_FAMILIES


# ------------------------------------------------------------------ 2. verdicts against the oracle

MESSAGES = {   # what each seeded fault's verdict says (before "(reached in N steps)")
    "seq_later_pair.roar": "in cell.work.clamp_light_drill, a command of the subtree of 'make(drill::drilled == "
                           "true)' started before every command of the subtree of 'make(vise::clamped == true)' ended",
    "seq_aborted_ensure.roar": "in cell.work.press_then_drill, a command of the subtree of 'make(drill::drilled == "
                               "true)' started before every command of the subtree of 'let h ensure(jaw::pressed == "
                               "true, 100)' ended",
    "seq_plan.roar": "in the plan of arm for 'arm::holding == true' (approach then grasp), a command of the subtree "
                     "of 'task arm::grasp' started before every command of the subtree of 'task arm::approach' ended",
    "seq_kept.roar": "in cell.work.light_then_shoot, 'make(lamp::on == true)' was achieved, but lamp::on == true no "
                     "longer holds when 'make(cam::shot == true)' is achieved: lamp::on = false",
    "seq_kept_late.roar": "in cell.work.light_then_shoot, 'make(lamp::on == true)' was achieved, but lamp::on == "
                          "true no longer holds when 'make(cam::shot == true)' is achieved: lamp::on = false",
}


def _against_the_oracle(spec: str, request: str, kept: bool, faulty: bool):
    """The monitor's verdict, its counterexample's length and pair, and every kind of violation it
    reaches (with the depth it is first reached at) are the oracle's."""
    model, pairs, system, ex, g, v = explored(spec, request, kept)
    oracle = oracle_of(spec, request, pairs, kept)
    want = oracle.shallowest()
    assert v.status == ("violated" if faulty else "holds") == ("violated" if want else "holds")
    if faulty:
        depth, broken = want
        assert v.counterexample.length() == depth
        assert _what(system.violates_sequence(ex.states[v.counterexample.final_state])) in broken
        assert v.message.split(" (reached")[0] == MESSAGES[spec]
    mine: dict = {}
    for s in range(g.n_states):
        p = system.violates_sequence(ex.states[s])
        if p is not None:
            mine[_what(p)] = min(mine.get(_what(p), 10 ** 9), int(g.depth[s]))
    theirs: dict = {}
    for s, bad in enumerate(oracle.bad):
        for x in bad:
            theirs[x] = min(theirs.get(x, 10 ** 9), oracle.depth[s])
    assert mine == theirs
    return mine, system, ex, g


@pytest.mark.parametrize("spec", sorted(FAULTS) + sorted(f[1] for f in FAULTS.values()))
def test_order_verdicts_agree_with_the_oracle(spec):
    request = next(r for s, (r, fixed) in FAULTS.items() if spec in (s, fixed))
    reached, *_ = _against_the_oracle(spec, request, False, spec in FAULTS)
    if spec == "seq_later_pair.roar":
        # no consecutive pair is ever broken, in any reachable state: only the later pair
        assert set(reached) == {("seq", "make(vise::clamped == true)", "make(drill::drilled == true)")}


# ------------------------------------------------------------------ 3. kept: an achieved goal undone later


@pytest.mark.parametrize("spec", sorted(KEPT))
def test_kept_verdicts_agree_with_the_oracle(spec):
    reached, system, ex, g = _against_the_oracle(spec, KEPT[spec], True, "fixed" not in spec)
    if spec != "seq_kept_fixed.roar":
        # undone when the shot is achieved, and (other runs, or later in the same) when the recipe ends
        assert set(reached) == {("kept", "make(lamp::on == true)", "make(cam::shot == true)"),
                                ("kept", "make(lamp::on == true)", "end")}
        ends = {system.sequence_reason(ex.states[s]) for s in range(g.n_states)}
        assert MESSAGES[spec].replace("when 'make(cam::shot == true)' is achieved", "when the recipe ends") in ends


def test_without_kept_an_undone_goal_is_not_an_order_violation():
    *_, v = explored("seq_kept.roar", "cell::done == true")
    assert v.status == "holds"


def test_a_kept_predicate_the_property_language_cannot_read_is_a_located_error():
    model, _program, start = compiled("seq_kept.roar", "cell::done == true")
    [p] = sequential_pairs(model, kept=True)
    from dataclasses import replace
    bad = replace(p, a_pred="lamp::no_such_var == true")
    with pytest.raises(RoarError) as e:
        RoarSystem(model, start, None, [bad])
    assert "make(lamp::on == true)" in e.value.message and e.value.pos is not None
    assert e.value.pos.file.endswith("seq_kept.roar") and e.value.pos.line > 1


# ------------------------------------------------------------------ 4. jobs: pairs, errors, property files


def _job(tmp: Path, spec: str, request: str, props: str) -> Path:
    (tmp / "p.toml").write_text(props, encoding="utf-8")
    job = tmp / "j.toml"
    job.write_text(f'spec = "{DATA / spec}"\nrequest = "{request}"\nfunctional = "{TOOLS}"\n'
                   f'properties = ["p.toml"]\n', encoding="utf-8")
    return job


@pytest.mark.parametrize("spec", ["seq_aborted_ensure.roar", "seq_plan.roar"])
def test_a_job_reports_the_new_pairs(tmp_path, spec):
    res = run_job(load_job(_job(tmp_path, spec, FAULTS[spec][0], 'check = ["sequential-achievement"]\n')))
    v = res.verdicts["sequential-achievement"]
    assert v.status == "violated" and v.message.split(" (reached")[0] == MESSAGES[spec]


@pytest.mark.parametrize("text,col,msg", [
    ("kept = 3", 8, "not 3"),
    ('kept = "all"', 8, 'not "all"'),
    ('kept = ["cell.work"]', 10, 'not "cell.work"'),
    ('kept = ["a.b.c", 4]', 8, "not 4"),
    ("kept = { x = 1 }", 8, "not a table"),
    ("kep = true", 1, "unknown key 'kep' in [sequential-achievement]"),
])
def test_kept_errors_are_located(tmp_path, text, col, msg):
    p = tmp_path / "p.toml"
    p.write_text(f'check = ["sequential-achievement"]\n[sequential-achievement]\n{text}\n', encoding="utf-8")
    with pytest.raises(RoarError) as e:
        load_properties(p)
    assert msg in e.value.message
    assert (e.value.pos.file, e.value.pos.line, e.value.pos.col) == (str(p), 3, col)


def test_kept_is_parsed_and_a_sequential_achievement_table_is_checked(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[sequential-achievement]\nkept = ["cell.work.light_then_shoot"]\n', encoding="utf-8")
    props = load_properties(p)
    assert props.sequence_kept == ["cell.work.light_then_shoot"] and props.check == ["sequential-achievement"]
    p.write_text('[sequential-achievement]\nkept = true\n', encoding="utf-8")
    assert load_properties(p).sequence_kept is True
    p.write_text('[sequential-achievement]\nkept = false\n', encoding="utf-8")
    assert load_properties(p).sequence_kept is False


def test_job_pairs_refuse_to_check_nothing():
    model, *_ = compiled("seq_kept.roar", "cell::done == true")
    assert len(job_sequence_pairs(model)) == 1
    with pytest.raises(RoarError) as e:
        job_sequence_pairs(model, ["cam.shoot.expose"], source="j.toml")
    assert "no 'make A; make B' pair" in e.value.message and e.value.message.startswith("j.toml: ")
    with pytest.raises(RoarError) as e:
        job_sequence_pairs(model, kept=["cell.work.nope"], source="j.toml")
    assert "kept names recipes the spec does not have: cell.work.nope" in e.value.message
    some = next(f"{ag.name}.{t.name}.{r.name}" for ag in model.spec.agents for t in ag.tasks for r in t.recipes)
    with pytest.raises(RoarError) as e:   # a misspelt recipe: not "it has no pair"
        job_sequence_pairs(model, [some[:-1]], source="j.toml")
    assert f"names a recipe the spec does not have: {some[:-1]} (did you mean '{some}'?)" in e.value.message
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.functional import functional_module, load_registry
    from roar_formal.roar.spec import load_spec
    single = compile_spec(load_spec(RETRY), "hand::holding == true", functional="abstract",
                          registry=load_registry(functional_module(RETRY, None)))
    with pytest.raises(RoarError) as e:   # one make per recipe, no plan
        job_sequence_pairs(single, source="j.toml")
    assert "sequential-achievement has nothing to check" in e.value.message


def test_a_job_checks_kept_and_prints_it_in_the_specs_terms(tmp_path):
    job = _job(tmp_path, "seq_kept.roar", "cell::done == true",
               '[sequential-achievement]\nkept = ["cell.work.light_then_shoot"]\n')
    v = run_job(load_job(job)).verdicts["sequential-achievement"]
    assert v.status == "violated" and "lamp::on == true no longer holds" in v.message
    job = _job(tmp_path, "seq_kept_fixed.roar", "cell::done == true", '[sequential-achievement]\nkept = true\n')
    assert run_job(load_job(job)).verdicts["sequential-achievement"].status == "holds"


def test_a_job_with_nothing_to_check_is_an_error(tmp_path):
    spec = RETRY
    (tmp_path / "p.toml").write_text('check = ["sequential-achievement"]\n', encoding="utf-8")
    job = tmp_path / "j.toml"
    job.write_text(f'spec = "{spec}"\nrequest = "hand::holding == true"\nproperties = ["p.toml"]\n', encoding="utf-8")
    with pytest.raises(RoarError) as e:
        run_job(load_job(job))
    assert "nothing to check" in e.value.message and str(job) in e.value.message
