"""The vocabulary's decoders read real facts right (roar_formal/roar/vocabulary.py).

``tests/roar/test_vocabulary.py`` checks the records against the framework signature (their
arity and argument sorts). This module checks the decoders on facts of real explored states:
the bundled jobs ``conflict``, ``survey`` (crashes: ``cep``, availability error contexts) and
``retry_bounded``, ``abstract_read.roar`` (a failed read: ``callfail``) and the sequential-
achievement specs with the monitor on (``mon_*`` facts, ``mtag_*`` tags; plans and ``kept``).

Each decoded fact is compared with an independent reading of the same fact: its printed text
(``program.show``), split into arguments, and named by this module's own table of the
families' arguments in the order ``framework.clf`` declares them (``ORDER``, written from the
framework's declarations and the monitor's documentation, not from the records). Every field of
the record must print as the argument of that name. On top of it, fields are checked by what
their name says their value is (an agent field holds one of the model's agents, a request field
a request, ...), so a decoder that swapped two arguments fails even where the table agreed.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import pytest

from roar_formal.clf.query import with_big_stack
from roar_formal.clf.terms import Const, Root
from roar_formal.explore.search import Budget, Explorer
from roar_formal.explore.system import Options
from roar_formal.roar import vocabulary as V
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.explore import PROGRESS_RULES, RoarSystem, sequential_pairs
from roar_formal.roar.functional import load_registry
from roar_formal.roar.spec import load_spec

from checker_cache import checker_result

from .printed import args_of

DATA = Path(__file__).resolve().parent / "data"

#: family or constructor -> its arguments, by name, in the declared order (framework.clf;
#: the monitor's facts as roar/explore.py documents them)
ORDER = {
    # facts of framework.clf
    "contains": "cell value",
    "rq": "request agent cst emitter kind",
    "rs": "request state",
    "ecf": "request ec",
    "hs": "request phase ec failed plan where",
    "mask": "agent entries",
    "abortreq": "request",
    "cres": "request at",
    "act": "inst request task recipe owned",
    "chk": "inst request recipe failed",
    "ctl": "inst mode code locals",
    "rstat": "inst pause",
    "owns": "inst request forwarded",
    "rdone": "request recipe reason",
    "pending": "fn args dest",
    "return": "value dest",
    "callfail": "dest",
    "cep": "agent epoch",
    # the sequential-achievement monitor's facts
    "mon_in": "request pair",
    "mon_cmd": "dest pair",
    "mon_b": "pair",
    "mon_plan": "plan request cst tasks current",
    "mon_got": "site inst",
    "mon_undone": "a b",
    # terms
    "vcons": "head tail",
    "vpair": "first second",
    "m_call": "dest site",
    "ccons": "site rest",
    "k_cst": "cst ec",
    "mtag_site": "site inst",
    "mtag_task": "plan task",
}

#: family or constructor -> the vocabulary's decoder of it (each named decoder, by hand)
DECODERS = {
    "contains": V.contains, "rq": V.rq, "rs": V.rs, "ecf": V.ecf, "hs": V.hs, "mask": V.mask,
    "abortreq": V.abortreq, "cres": V.cres, "act": V.act, "chk": V.chk, "ctl": V.ctl, "rstat": V.rstat,
    "owns": V.owns, "rdone": V.rdone, "pending": V.pending, "return": V.return_, "callfail": V.callfail,
    "cep": V.cep, "mon_in": V.mon_in, "mon_cmd": V.mon_cmd, "mon_b": V.mon_b, "mon_plan": V.mon_plan,
    "mon_got": V.mon_got, "mon_undone": V.mon_undone, "vcons": V.cons, "vpair": V.vpair, "m_call": V.m_call,
    "ccons": V.ccons, "k_cst": V.k_cst, "mtag_site": V.tag_site, "mtag_task": V.tag_task,
}

#: decoded by the robot-backed explorer's own states only (robot/explore.py), not explored here
NOT_HERE = {V.RB_RUN, V.RB_SLEEP}

_PARAM = r"#\d+"


def _is(pattern: str):
    rx = re.compile(pattern)
    return lambda text, model: rx.fullmatch(text) is not None


def _in(table: str, *also: str):
    return lambda text, model: text in getattr(model, table) or text in also


def _site(text: str, model) -> bool:
    """A statement's site of the model, or one of the framework's own (s_pdone, s_end, s_done)."""
    return text in model.sites or re.fullmatch(r"s_[a-z]+", text) is not None


#: field name (or ``kind.field``, first) -> what its printed value must be (by what the name
#: says), on the compiled model
MEANS = {
    "request": _is(rf"r\w*{_PARAM}"),
    "at": _is(rf"r\w*{_PARAM}"),
    "inst": _is(rf"(i\w*{_PARAM}|i_start)"),
    "emitter": _is(rf"(i\w*{_PARAM}|itop|irel|i_start)"),
    "dest": _is(rf"d\w*{_PARAM}"),
    "plan": _is(rf"plan{_PARAM}"),
    "agent": _in("agents"),
    "cst": _in("csts"),
    "task": _in("tasks"),
    "recipe": _in("recipes"),
    "cell": _in("cells"),
    "fn": _in("functions"),
    "site": _site,
    "a": _in("sites"),
    "b": _in("sites", V.MTAG_END),
    "state": _is(r"s_\w+"),
    "phase": _is(r"h_\w+( .*)?"),
    "kind": _is(r"k_\w+"),
    "reason": _is(r"k_\w+( .*)?"),
    "mode": _is(r"m_\w+( .*)?"),
    "pause": _is(r"go|pz .*"),
    "forwarded": _is(r"tt|ff"),
    "current": _is(r"tt|ff"),
    "owned": _is(r"z|s .*"),
    "hs.failed": _is(r"vnil|vcons .*"),
    "chk.failed": _is(r"\d+"),
    "epoch": _is(r"t_ep\d+"),
    "pair": _is(r"mtag_(site|task) .*"),
    "tail": _is(r"vnil|vcons .*"),
    "rest": _is(r"cnil|ccons .*"),
    "entries": _is(r"vnil|vcons .*"),
    "tasks": _is(r"vcons \(vtsk .*"),
    "hs.plan": _is(r"vnil|vcons .*"),
    "hs.where": _is(r"vnone|vsome .*"),
}


def _any(text: str, model) -> bool:
    return True


def _unparen(text: str) -> str:
    """A printed argument without its enclosing parentheses (an argument of several words)."""
    if text.startswith("(") and text.endswith(")"):
        depth = 0
        for i, ch in enumerate(text):
            depth += (ch == "(") - (ch == ")")
            if depth == 0 and i < len(text) - 1:
                return text   # '(a) (b)': not one parenthesised group
        return text[1:-1]
    return text


def _name(t):
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None


def _subterms(t):
    stack = [t]
    while stack:
        x = stack.pop()
        if type(x) is Root:
            yield x
            stack.extend(x.args)


def _explored_monitor(spec: str, request: str, kept: bool):
    def go():
        model = compile_spec(load_spec(DATA / spec), request, registry=load_registry(DATA / "seq_tools.py"),
                             functional="abstract")
        program = model.program()
        start = program.start_context(next(d for d in program.sig.directives
                                           if type(d).__name__ == "ExecDirective").start)
        system = RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES, fairness="agent"),
                            sequential_pairs(model, kept=kept))
        ex = Explorer(system)
        g = ex.run(Budget(max_states=20_000))
        assert g.complete
        return model, program, [ex.states[s] for s in range(g.n_states)]
    return with_big_stack(go)


def _explored_plain(spec: str, request: str, functional: str):
    def go():
        model = compile_spec(load_spec(DATA / spec), request, registry=load_registry(DATA / functional),
                             functional="abstract")
        program = model.program()
        start = program.start_context(next(d for d in program.sig.directives
                                           if type(d).__name__ == "ExecDirective").start)
        ex = Explorer(RoarSystem(model, start, Options(progress_rules=PROGRESS_RULES)))
        g = ex.run(Budget(max_states=20_000))
        assert g.complete
        return model, program, [ex.states[s] for s in range(g.n_states)]
    return with_big_stack(go)


def _job(name: str):
    res = checker_result(name)
    model, _start, explorer = res.roar
    return model, res.program, [explorer.states[s] for s in range(res.graph.n_states)]


PER_KIND = 400   # distinct facts (terms) kept per family and source


@lru_cache(maxsize=None)
def samples() -> dict:
    """family or constructor -> [(model, program, fact or term)], distinct ones from every source."""
    sources = [
        _job("conflict.toml"),
        _job("survey.toml"),
        _job("retry_bounded.toml"),
        _explored_plain("abstract_read.roar", "loco::arrived == true", "abstract_read.py"),
        _explored_monitor("seq_plan.roar", "arm::holding == true", False),
        _explored_monitor("seq_later_pair.roar", "cell::done == true", False),
        _explored_monitor("seq_kept.roar", "cell::done == true", True),
        _explored_monitor("seq_kept_late.roar", "cell::done == true", True),
    ]
    out: dict = {}
    for model, program, states in sources:
        seen: dict = {}
        for ctx in states:
            for _m, f, _n in ctx.facts():
                for t in _subterms(f):
                    k = _name(t)
                    if k in ORDER and t.args and len(seen.setdefault(k, set())) < PER_KIND and t not in seen[k]:
                        seen[k].add(t)
                        out.setdefault(k, []).append((model, program, t))
    return out


def disagreements(kind: str, decoder, items) -> list[str]:
    """Where ``decoder``'s records disagree with the printed facts (empty: they agree)."""
    names = ORDER[kind].split()
    bad = []
    for model, program, t in items:
        printed = program.show(t)
        head, args = printed.split(" ", 1)[0], [_unparen(a) for a in args_of(printed)]
        rec = decoder(t)
        if head != kind or len(args) != len(names):
            bad.append(f"{printed}: not a {kind} fact of {len(names)} arguments")
            continue
        if tuple(rec._fields) != tuple(names):
            bad.append(f"{type(rec).__name__}{rec._fields}: the arguments of {kind} are {names}")
            continue
        for name, text in zip(names, args):
            got = _unparen(program.show(getattr(rec, name)))
            if got != text:
                bad.append(f"{printed}: .{name} is {got!r}, the printed fact has {text!r}")
            elif not MEANS.get(f"{kind}.{name}", MEANS.get(name, _any))(got, model):
                bad.append(f"{printed}: .{name} is {got!r}, not what a {name} is")
    return bad


def test_every_decoder_is_read_here():
    # a record added to the vocabulary needs a line in ORDER and DECODERS
    known = set(V.FACTS) | set(V.EXPLORER_FAMILIES) | set(V.EXPLORER_TERMS) | set(V.TERMS)
    assert set(DECODERS) | NOT_HERE == known
    assert set(ORDER) == set(DECODERS)


@pytest.mark.parametrize("kind", sorted(DECODERS))
def test_decoders_agree_with_the_printed_facts(kind):
    items = samples().get(kind, [])
    assert items, f"no {kind} fact in the explored states: the decoder was not exercised"
    decoder = DECODERS[kind]
    rec = decoder(items[0][2])
    assert type(rec) is {**V.FACTS, **V.EXPLORER_FAMILIES, **V.EXPLORER_TERMS, **V.TERMS}[kind]
    assert V.decode(items[0][2]) == rec and type(V.decode(items[0][2])) is type(rec)
    bad = disagreements(kind, decoder, items)
    assert not bad, f"{len(bad)} of {len(items)} {kind} facts:\n" + "\n".join(bad[:10])


def test_the_monitor_reaches_every_tag_and_flag():
    # the sources exercise what the monitor reads: both tags (as a mon_b's subtree), an undone
    # flag at a later statement and one at the recipe's end
    s = samples()
    shown = {k: {p.show(t) for _m, p, t in s[k]} for k in ("mon_undone", "mon_b")}
    assert any(x.endswith(" " + V.MTAG_END) for x in shown["mon_undone"])
    assert any(not x.endswith(" " + V.MTAG_END) for x in shown["mon_undone"])
    assert {x.split(" ", 2)[1].lstrip("(") for x in shown["mon_b"]} == {V.MTAG_SITE, V.MTAG_TASK}


def test_a_decoder_reading_the_wrong_argument_is_caught():
    # the comparison can fail: a decoder of rq that swaps the agent and the constraint, and one
    # of mon_plan that swaps the request and the plan, disagree with the printed facts
    s = samples()

    def swapped_rq(f):
        q = V.rq(f)
        return q._replace(agent=q.cst, cst=q.agent)

    def swapped_plan(f):
        p = V.mon_plan(f)
        return p._replace(plan=p.request, request=p.plan)

    assert disagreements("rq", swapped_rq, s["rq"])
    assert disagreements("mon_plan", swapped_plan, s["mon_plan"])
    assert disagreements("ctl", V.act, s["ctl"])                 # another family's record
    assert not disagreements("rq", V.rq, s["rq"][:5])
