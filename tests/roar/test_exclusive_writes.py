"""exclusive-writes counts only constraints whose where values were written (a request waiting
after a conflict, h_cwait, has written nothing: counting it was a false alarm on conflict.roar)."""

from __future__ import annotations

from roar_formal.clf.terms import Const, Root


def _name(t):
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None


def test_a_request_waiting_after_a_conflict_writes_nothing(checker_job):
    res = checker_job("conflict.toml")   # checker/conflict.toml checks exclusive writes too
    assert res.graph.complete
    assert res.verdicts["exclusive-writes"].status == "holds", res.verdicts["exclusive-writes"].message
    # independently, on the explored states: while a request waits after its conflict, the
    # variable its where clause names still holds the holder's value (30), never the waiter's (120)
    states = res.roar[2].states
    waiting = 0
    for sid in range(res.graph.n_states):
        ctx = states[sid]
        facts = [f for _m, f, _n in ctx.facts()]
        if not any(_name(f) == "hs" and _name(f.args[1]) == "h_cwait" for f in facts):
            continue
        waiting += 1
        target = next(f.args[1] for f in facts if _name(f) == "contains" and _name(f.args[0]) == "v_ptu_target")
        shown = res.program.show(target)
        assert "120" not in shown, f"state {sid}: the waiting request's value was written ({shown})"
    assert waiting > 0, "no state with a request waiting after a conflict: the case was not explored"
