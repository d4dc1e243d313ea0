"""The framework's generic patterns (paper section 8.1) run on the engine."""

import pytest

from roar_formal.clf.query import run_directives, show_context, with_big_stack
from roar_formal.roar.framework import framework_text, with_framework


def run(text):
    return with_big_stack(run_directives, with_framework(text), emit=lambda s: None)


def test_framework_type_checks_and_declares_the_paper_rules():
    p = with_framework("")
    for rule in ("ev_llet", "ev_newref", "ev_assign", "ev_deref", "ev_writeMsg", "ev_readMsg"):
        assert rule in p.rule_names
    assert "% ---------------------------------------------------------------- references" in framework_text()


def test_references_let_r_newref_1_assign_2_deref():
    # let r = newref 1 in (assign r 2; deref r): 2, and the cell holds 2
    (res,) = run("#query * 1 * 1 Pi d. eval (llet (newref (lit (vnat (s z)))) (\\r. "
                 "seq (assign (lit r) (lit (vnat (s (s z))))) (deref (lit r)))) d "
                 "-o {Exists c. contains c W * return V d}.")
    assert res.answers == [{"W": "vnat (s (s z))", "V": "vnat (s (s z))"}]


def test_a_message_is_read_once():
    # a channel, one message written, two readers: exactly one reader gets it
    (res,) = run("#exec * Exists d0. Exists d1. Exists d2. Exists ch. "
                 "eval (writeMsg (lit (vchan ch)) (lit (vnat z))) d0 * "
                 "eval (readMsg (lit (vchan ch))) d1 * eval (readMsg (lit (vchan ch))) d2.")
    lines = show_context(res.final)
    assert sum(1 for l in lines if l.startswith("return (vnat z)")) == 1
    assert sum(1 for l in lines if l.startswith("return vunit")) == 1
    assert sum(1 for l in lines if "msg" in l and "-o" in l) == 1  # the other reader still waits
    assert not any(l.startswith("msg ") for l in lines)


@pytest.mark.parametrize("cond,branch", [("tt", "vnat z"), ("ff", "vnat (s z)")])
def test_if_takes_one_branch(cond, branch):
    (res,) = run(f"#query * 1 * 1 Pi d. eval (if (lit (vbool {cond})) (lit (vnat z)) (lit (vnat (s z)))) d "
                 "-o {return V d}.")
    assert res.answers == [{"V": branch}]
