"""The logic layer (4.3): a task is a candidate for a constraint when its post-conditions,
with the equalities the constraint's where clause establishes, entail the predicate:
symmetry and transitivity of ==, and hypotheses from where values. Checked against a
union-find closure of the equalities on random specs."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.run import run_model
from roar_formal.roar.spec import load_spec
from roar_formal.testing import load

DATA = Path(__file__).parent / "data" / "logic"
VARS = ("a", "b", "c", "d")


def test_the_arm_gripper_request_succeeds():
    """make(gripper::closed == true where gripper::want_closed == true) on a task whose post is
    closed == want_closed: entailed under the where hypothesis (it used to fail at pending)."""
    spec = DATA / "arm_gripper.roar"
    model = compile_spec(load_spec(spec), "arm::holding == true", functional="python")
    assert model.candidates == {"c1_gripper": [("gripper", "grip")], "c2_arm": [("arm", "pick")]}
    res = run_model(model, seed=0)
    assert res.outcome == "success" and res.final["gripper::closed"] is True
    ex = load(spec).explore("arm::holding == true", properties=["deadlock", "mission-completion"])
    assert ex.verdicts["deadlock"].status == "holds" and ex.verdicts["mission-completion"].status == "holds"


def spec_text(posts: list[tuple[str, str]]) -> str:
    post = " ".join(f"{{{x} == {y}}}" for x, y in posts) or ""
    return ("v = ability {\n  context = {\n    { int a; int b; int c; int d; }\n    { }\n    { }\n  }\n"
            "  export = { { } { } { } }\n  tasks = {\n    t = task {\n      pre = { }\n"
            f"      post = {{ {post} }}\n      recipes = {{ r = recipe {{ body = {{ set a 1; }} }} }}\n    }}\n  }}\n}}\n")


def entailed(posts, where, x, y) -> bool:
    parent = {}

    def find(u):
        parent.setdefault(u, u)
        while parent[u] != u:
            u = parent[u]
        return u
    for p, q in list(posts) + ([(where, "1")] if where else []):
        parent[find(p)] = find(q)
    return find(x) == find(y)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(posts=st.lists(st.tuples(st.sampled_from(VARS + ("1",)), st.sampled_from(VARS)), max_size=4),
       x=st.sampled_from(VARS), y=st.sampled_from(VARS), where=st.sampled_from((None,) + VARS))
def test_candidates_are_the_entailed_tasks(tmp_path_factory, posts, x, y, where):
    posts = [(p, q) for p, q in posts if p != q]
    if x == y or where in (x, y):
        return   # (a trivial predicate; a where clause may not write a variable its predicate reads)
    path = tmp_path_factory.mktemp("logic") / "v.roar"
    path.write_text(spec_text(posts))
    request = f"v::{x} == v::{y}" + (f" where v::{where} == 1" if where else "")
    model = compile_spec(load_spec(path), request)
    got = model.candidates[model.request_cst] == [("v", "t")]
    assert got == entailed(posts, where, x, y), (posts, request)


def test_a_pre_condition_on_another_agents_variable_is_planned_on_the_agents_own_tasks():
    """a::t needs b::ready, which b's task prep establishes and top sends to b as a constraint.
    The agent whose task it is plans its pre-conditions on its own tasks only (4.3: "other local
    tasks"): a never runs b::prep inside its own request (it did when top's constraint shared the
    predicate's candidate table: two activations of prep at once, users = 2)."""
    spec = DATA / "remote_pre.roar"
    model = compile_spec(load_spec(spec), "top::done == true", functional="python")
    assert model.candidates["c1_b"] == [("b", "prep")]        # top's ensure, planned by b on its tasks
    ex = load(spec).explore("top::done == true", properties=["invariant"], never=["b::users > 1"])
    assert ex.verdicts["invariant"].status == "holds", ex.verdicts["invariant"]


def test_a_request_no_task_can_take_says_why(tmp_path):
    """top asks a for a::done, whose one task needs b::ready (another agent's variable, false, and
    a guard for a): the request fails at once, and the event says why (it said nothing)."""
    text = (DATA / "remote_pre.roar").read_text(encoding="utf-8").replace(
        "let h ensure(b::ready == true);", "").replace("abort h;", "")
    spec = tmp_path / "guarded.roar"
    spec.write_text(text, encoding="utf-8")
    run = load(spec).run("top::done == true")
    lines = [e.text for e in run.events if e.kind == "state"]
    assert ("R1 pending -> failure  (a::done == true): none of its candidate tasks (t) can be chosen: a "
            "pre-condition does not hold and no other task of a establishes it") in lines, lines
    # a request after a temporary failure says nothing more: its error context tells the failed tasks
    assert any(x.startswith("R0 temporary failure -> failure  (top::done == true)") and x.endswith(")")
               for x in lines), lines
