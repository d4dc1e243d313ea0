"""The agents' domain rules in the logic layer (4.3: the task's post-conditions "and the rules
associated to the domain of the constraint"): a rule makes a candidate that conjunct matching
misses, logic variables range over expressions, and a rule over functions is reported unused."""

from __future__ import annotations

import pytest

from roar_formal.roar.compile import compile_spec
from roar_formal.roar.parser import parse_roar
from roar_formal.roar.run import run_model
from repo import ROOT


def _spec(rules: str, post: str, body: str, decls: str = "bool calibrated = false; bool ready = false; int pos = 0; int goal = 3;"):
    return parse_roar(f"""
arm = ability {{
  context = {{
    {{ }}
    {{ {decls} }}
    {{ }}
  }}
  export = {{
    {{ }}
    {{ }}
    {{ {rules} }}
  }}
  tasks = {{
    work = task {{
      pre = {{ }}
      post = {{ {{{post}}} }}
      recipes = {{
        r = recipe {{ body = {{ {body} }} }}
      }}
    }}
  }}
}}
""", "arm.roar")


def test_a_rule_makes_a_candidate_that_conjunct_matching_misses():
    with_rule = _spec("cal_ready = calibrated == true |- ready == true;", "calibrated == true",
                      "set calibrated true; set ready true;")
    m = compile_spec(with_rule, "arm::ready == true")
    assert list(m.candidates.values()) == [[("arm", "work")]]
    assert run_model(m).outcome == "success"
    without = _spec("", "calibrated == true", "set calibrated true; set ready true;")
    m0 = compile_spec(without, "arm::ready == true")
    assert list(m0.candidates.values()) == [[]]
    r = run_model(m0)
    assert r.outcome == "failure" and r.error_context == []   # no task: nothing was tried


def test_logic_variables_range_over_expressions():
    spec = _spec("eq_ge = X == Y |- X >= Y;", "pos == goal", "set pos goal;")
    m = compile_spec(spec, "arm::pos >= arm::goal")
    assert list(m.candidates.values()) == [[("arm", "work")]]
    r = run_model(m)
    assert r.outcome == "success" and r.final["arm::pos"] == 3
    # the rule's direction matters: it says nothing about <=, and nothing else proves it
    m2 = compile_spec(spec, "arm::pos <= arm::goal")
    assert list(m2.candidates.values()) == [[]]


def test_rules_chain_within_the_proof_budget():
    rules = "a1 = calibrated == true |- ready == true; a2 = ready == true |- pos == goal;"
    m = compile_spec(_spec(rules, "calibrated == true", "set calibrated true; set ready true; set pos goal;"),
                     "arm::pos == arm::goal")
    assert list(m.candidates.values()) == [[("arm", "work")]]


def test_rules_over_functions_are_listed_as_unused():
    from roar_formal.roar.spec import load_spec
    m = compile_spec(load_spec(ROOT / "models" / "mana_nav.roar"),
                     "locomotion::arrived == true where locomotion::gx == 3.0 && locomotion::gy == 4.0")
    assert m.unused_rules == ["planner::dist_sym", "planner::dist_zero"]


def _agent(name: str, rules: str, imports: str = "") -> str:
    return f"""{imports}
{name} = ability {{
  context = {{
    {{ }}
    {{ int level = 0; }}
    {{ }}
  }}
  export = {{
    {{ }}
    {{ }}
    {{ {rules} }}
  }}
  tasks = {{
    raise_it = task {{
      pre = {{ }}
      post = {{ {{level > 5}} }}
      recipes = {{ r = recipe {{ body = {{ set level 6; }} }} }}
    }}
  }}
}}
"""


def test_a_rule_applies_to_the_agents_that_see_its_agent(tmp_path):
    """A rule is part of its agent's exported domain: the agent itself, its importers and the
    agents of the same .roar file use it; an agent that does not see the exporter does not."""
    from roar_formal.roar.spec import load_spec
    (tmp_path / "lib.roar").write_text(_agent("arm", "gt = X > 5 |- X > 3;"))
    (tmp_path / "blind.roar").write_text(_agent("cam", ""))
    (tmp_path / "seeing.roar").write_text(_agent("ptu", "", 'import "lib.roar"'))
    (tmp_path / "main.roar").write_text(_agent("user", "", 'import "blind.roar"\nimport "seeing.roar"\nimport "lib.roar"'))
    spec = load_spec(tmp_path / "main.roar")
    for agent, sees in (("arm", True), ("ptu", True), ("user", True), ("cam", False)):
        m = compile_spec(spec, f"{agent}::level > 3")
        assert list(m.candidates.values()) == [[(agent, "raise_it")] if sees else []], agent
        assert run_model(m).outcome == ("success" if sees else "failure"), agent
    # without the rule nobody proves it: the scope is what differs above
    (tmp_path / "lib.roar").write_text(_agent("arm", ""))
    m = compile_spec(load_spec(tmp_path / "main.roar"), "ptu::level > 3")
    assert list(m.candidates.values()) == [[]]


@pytest.mark.parametrize("rule, where, message", [
    ("r = X == Y |- Z == Y;", "10:21", "logic variable 'Z' is a whole side of a conclusion but does not occur"),
    ("r = |- X == 1;", "10:14", "logic variable 'X' is a whole side of a conclusion"),
    ("r = X |- calibrated == true;", "10:11", "'X' is a bare logic variable"),
    ("r = calibrated == true |- !X;", "10:33", "'!X' is a bare logic variable"),
    ("r = pos == X, X == true |- ready == true;", "10:21", "logic variable 'X' is bool here but int at 10:18"),
])
def test_rules_that_would_conclude_anything_are_refused_at_their_place(tmp_path, rule, where, message):
    from roar_formal.roar.spec import load_spec
    from roar_formal.roar.checks import SpecCheckError
    path = tmp_path / "arm.roar"
    path.write_text(_spec_text(rule))
    with pytest.raises(SpecCheckError) as e:
        load_spec(path)
    text = "\n".join(f"{x.pos.line}:{x.pos.col}: {x}" for x in e.value.errors)
    assert f"{where}: " in text and message in text, text


def _spec_text(rule: str) -> str:
    return f"""arm = ability {{
  context = {{
    {{ }}
    {{ bool calibrated = false; bool ready = false; int pos = 0; }}
    {{ }}
  }}
  export = {{
    {{ }}
    {{ }}
    {{ {rule} }}
  }}
  tasks = {{
    work = task {{
      pre = {{ }}
      post = {{ {{calibrated == true}} }}
      recipes = {{ r = recipe {{ body = {{ set calibrated true; }} }} }}
    }}
  }}
}}
"""
