"""One matcher for both drivers (issue 12, item 7): committed choice takes the first match of a
template (``first_match``), the explorer every match (``all_matches``), and the first is the
first element of all of them. Checked step by step along committed-choice runs of the bundled
``.clf`` models and of a compiled ROAR spec: at every state of each run, for every forward
template and every live rule of the context, with candidates in bag order and rotated (the
scheduler's random choice of instances); and every match against the plain enumeration,
``find_matches``."""

from __future__ import annotations

import pytest

from roar_formal.clf.forward import all_matches, find_matches, first_match
from roar_formal.clf.program import Program
from roar_formal.clf.query import with_big_stack
from roar_formal.clf.signature import ExecDirective
from repo import ROOT

MODELS = ROOT / "models" / "clf"
STARTS = (0, 1, 3, 7)   # 0: bag order; the others rotate every candidate list
MAX_STEPS = 60


def _compare(program, ctx, prover) -> int:
    """Compare the two uses of the matcher on every template and live rule of ``ctx``; returns
    how many (template, start) pairs had a match."""
    if ctx.open:   # facts with logic variables: the general (unification) path matches those
        return 0
    jobs = [(t, [None] * t.nslots) for t in program.templates if t.forward]
    jobs += [(t, list(r.env)) for r in ctx.rules.values() for t in r.alts if t.forward]
    matched = 0
    for t, env in jobs:
        for start in STARTS:
            every = all_matches(ctx, t, list(env), prover, start=start)
            b = list(env)
            first = first_match(ctx, t, b, start, prover)
            if not every:
                assert first is None and b == env
                continue
            matched += 1
            bindings, consumed = every[0]
            assert first is not None, (t.name, start)
            assert (tuple(b), tuple(first)) == (bindings, consumed), (t.name, start)
            assert every[:1] == all_matches(ctx, t, list(env), prover, first_only=True, start=start)
            plain = []
            b2 = list(env)
            for c in find_matches(ctx, t, b2, start, prover, all_modes=True):
                plain.append((tuple(b2), tuple(c)))
            assert every == plain, (t.name, start)
    return matched


def _run_checked(program, start, seed: int) -> tuple[int, int]:
    ctx = program.start_context(start)
    prover = program.prover()
    counts = [0, 0]

    def on_step(step, c):
        counts[0] += 1
        counts[1] += _compare(program, c, prover)

    counts[1] += _compare(program, ctx, prover)
    program.run(ctx, MAX_STEPS, seed=seed, on_step=on_step)
    return counts[0], counts[1]


def _clf_starts():
    out = []
    for path in sorted(MODELS.glob("*.clf")):
        program = Program.from_file(path)
        execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
        for i, d in enumerate(execs):
            out.append(pytest.param(path, i, id=f"{path.stem}-{i + 1}"))
    return out


@pytest.mark.parametrize("path,i", _clf_starts())
def test_first_match_is_the_first_of_all_matches_along_clf_runs(path, i):
    def go():
        program = Program.from_file(path)
        d = [d for d in program.sig.directives if isinstance(d, ExecDirective)][i]
        total = 0
        for seed in (0, 1):
            _steps, matched = _run_checked(program.at(getattr(d, "prefix", -1)), d.start, seed)
            total += matched
        return total

    with_big_stack(go)


def test_first_match_is_the_first_of_all_matches_along_runs_of_a_compiled_spec():
    from roar_formal.roar.compile import compile_spec
    from roar_formal.roar.functional import functional_module, load_registry
    from roar_formal.roar.spec import load_spec

    spec = ROOT / "models" / "conflict.roar"

    def go():
        model = compile_spec(load_spec(spec), "mission::done == true",
                             registry=load_registry(functional_module(spec, None)), functional="abstract")
        program = model.program()
        d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        out = []
        for seed in (0, 1, 2):
            out.append(_run_checked(program, d.start, seed))
        return out

    runs = with_big_stack(go)
    assert all(steps > 10 and matched > steps for steps, matched in runs)
