"""The agents' domain rules in the logic layer (4.3: the task's post-conditions "and the rules
associated to the domain of the constraint"): a rule makes a candidate that conjunct matching
misses, logic variables range over expressions, and a rule over functions is reported unused."""

from __future__ import annotations

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
