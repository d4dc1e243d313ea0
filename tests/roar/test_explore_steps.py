"""The explorer's enabled steps on a compiled ROAR model (models/conflict.roar), against
the plain enumeration: ``find_matches`` over every template of the compiled program,
every premise proved afresh (the premise memo emptied first). Same steps, in the same
order, at each of the first 700 states of a breadth-first search, and successors whose
indexes are those of a copy made by re-adding every fact."""

from __future__ import annotations

from collections import deque

from roar_formal.clf.forward import multiset_key, enabled_steps, find_matches
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.signature import ExecDirective
from roar_formal.clf.state import canonical_key
from roar_formal.roar.functional import functional_module, load_registry
from roar_formal.roar.compile import compile_spec
from roar_formal.roar.spec import load_spec
from repo import ROOT

MODELS = ROOT / "models"


def _reference_steps(program, ctx) -> list:
    program.__dict__.pop("_premise_memo", None)
    prover = program.prover()
    seen: set = set()
    out = []
    for t in program.templates:
        if not t.forward:
            continue
        b = [None] * t.nslots
        for consumed in find_matches(ctx, t, b, -1, prover, all_modes=True):
            key = (id(t), tuple(b), multiset_key(consumed))
            if key not in seen:
                seen.add(key)
                out.append((t.name, tuple(b), tuple(consumed)))
    return out


def _bags(ctx) -> tuple:
    index = {f: list(b.items) for f, b in ctx.index.items() if b.items}
    by_arg = {f: [{a: list(b.items) for a, b in d.items()} for d in per] for f, per in ctx.by_arg.items()
              if any(per)}
    return index, by_arg


def _readded(ctx):
    from roar_formal.clf.context import Context
    c = Context()
    for mode, t, n in ctx.facts():
        for _ in range(n):
            c.add_fact(t, mode)
    return c


def test_enabled_steps_of_conflict_states_are_the_plain_ones():
    spec = MODELS / "conflict.roar"
    model = compile_spec(load_spec(spec), "mission::done == true",
                         registry=load_registry(functional_module(spec, None)), functional="abstract")
    program = model.program()
    start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))

    def go():
        start = program.start_context(start_d.start)
        queue = deque([start])
        seen = {canonical_key(start)}
        expanded = 0
        while queue and expanded < 700:
            ctx = queue.popleft()
            expanded += 1
            fast = [(c.rule, c.bindings, c.consumed) for c in enabled_steps(program.templates, ctx, program.prover())]
            assert fast == _reference_steps(program, ctx)
            assert _bags(ctx.copy()) == _bags(_readded(ctx))
            for choice in program.steps(ctx):
                nxt, _ = program.successor(ctx, choice)
                k = canonical_key(nxt)
                if k not in seen:
                    seen.add(k)
                    queue.append(nxt)
        assert expanded == 700  # past state 651, the first whose steps' order follows a bag's order

    with_big_stack(go)
