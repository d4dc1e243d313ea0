"""Discharge obligations with Z3: proofs over an unbounded message sort,
countermodels over small finite ones.

A proof is an ``unsat`` answer for the assumptions plus the negated claim on
fresh witnesses, over an uninterpreted sort, so it holds in every structure.
Z3's model search with quantifiers is unreliable over an unbounded sort, so
refutations and consistency look for a model over ``N`` messages for growing
``N``; any model found is a real one. Neither answer within the limits gives
``unknown``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Optional

import z3

from .axioms import formulas
from .countermodel import Countermodel, read_countermodel
from .theorems import Obligation
from .vocabulary import Vocabulary, vocabulary

PROOF_TIMEOUT_MS = 3000
# Model searches are bounded by Z3's resource limit (a count of its own steps), not by the
# clock: a search stopped by the clock stops at a point that depends on the machine's load,
# and the next attempt of the portfolio then finds another countermodel. With a fixed seed
# and a step bound, ``prove`` prints the same countermodels on every run. The clock bounds
# stay as a safety net far above what the step bounds take.
MODEL_RLIMIT = 6_000_000
READABLE_RLIMIT = 4_000_000
MODEL_TIMEOUT_MS = 60_000
READABLE_TIMEOUT_MS = 60_000
SEED = 0
EXTRA_DOMAIN = 3  # finite domains tried: witnesses .. witnesses + EXTRA_DOMAIN


@dataclass
class Outcome:
    """What the prover found for one obligation."""

    obligation: Obligation
    status: str  # proved | refuted | consistent | inconsistent | vacuous | unknown
    seconds: float
    countermodel: Optional[Countermodel] = None
    reason: str = ""
    details: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.status == self.obligation.expect


def _witnesses(ob: Obligation, v: Vocabulary) -> dict[str, z3.ExprRef]:
    return {n: (z3.Real(n) if n == "t" else v.msg_const(n)) for n in ob.witnesses}


def _solver(timeout_ms: int) -> z3.Solver:
    s = z3.Solver()
    s.set("timeout", timeout_ms)
    s.set("random_seed", SEED)
    s.set("smt.macro_finder", True)
    return s


def _problem(ob: Obligation, v: Vocabulary, track: bool = False) -> tuple[z3.Solver, dict[str, z3.ExprRef]]:
    """A solver holding the assumptions and the hypothesis with the negated conclusion.

    Over a finite sort, model-based instantiation alone decides the message
    quantifiers; pattern matching there only loops on desc's unfolding."""
    s = _solver(PROOF_TIMEOUT_MS if not v.finite else MODEL_TIMEOUT_MS)
    if v.finite:
        s.set("smt.ematching", False)
        s.set("rlimit", MODEL_RLIMIT)
    named = formulas(ob.assumptions, v)
    named.update({a.name: a.build(v) for a in ob.added})
    for name, formula in named.items():
        if track:
            s.assert_and_track(formula, z3.Bool(f"assume:{name}"))
        else:
            s.add(formula)
    w = _witnesses(ob, v)
    hyp, concl = ob.claim(v, w)
    s.add(hyp)
    if concl is not None:
        s.add(z3.Not(concl))
    return s, w


def _try_proof(ob: Obligation) -> Optional[str]:
    s, _ = _problem(ob, vocabulary())
    answer = s.check()
    if answer == z3.unsat:
        return "unsat"
    return "sat" if answer == z3.sat else s.reason_unknown()


def _readable(v: Vocabulary, w: dict[str, z3.ExprRef]) -> list[z3.BoolRef]:
    """Presentation preferences (a model meeting them is still a model):
    distinct witnesses and no message its own child."""
    msgs = [c for n, c in w.items() if n != "t"]
    prefs = [z3.Distinct(*msgs)] if len(msgs) > 1 else []
    if "t" in w:
        t = w["t"]
        for i in range(v.msg.num_constructors()):
            e = v.msg.constructor(i)()
            prefs.append(z3.ForAll([t], z3.Not(v.child_of(e, e, t))))
    return prefs


# Z3's model search over quantifiers swings widely with its random seed and
# arithmetic solver; a few short tries with different settings beat one long one.
PORTFOLIO = ({"random_seed": SEED}, {"random_seed": SEED + 1, "smt.arith.solver": 2}, {"random_seed": SEED + 2})


def _attempt(ob: Obligation, size: int, readable: bool, settings: dict) -> Optional[Countermodel]:
    v = vocabulary(size)
    s, w = _problem(ob, v)
    for key, value in settings.items():
        s.set(key, value)
    if readable:
        s.add(*_readable(v, w))
        s.set("timeout", READABLE_TIMEOUT_MS)
        s.set("rlimit", READABLE_RLIMIT)
    if s.check() == z3.sat:
        return read_countermodel(s.model(), v, w, ob.order_only)
    return None


def find_model(ob: Obligation) -> Optional[Countermodel]:
    """A finite model of the assumptions, hypothesis and negated conclusion, if
    one exists over a few messages; readable models are tried first."""
    low = max(1, sum(1 for n in ob.witnesses if n != "t"))
    sizes = range(low, low + EXTRA_DOMAIN + 1)
    for readable, settings in [(True, PORTFOLIO[0])] + [(False, p) for p in PORTFOLIO]:
        for size in sizes:
            found = _attempt(ob, size, readable, settings)
            if found is not None:
                return found
    return None


def prove(ob: Obligation) -> Outcome:
    """Try the claim both ways (proof first unless a model is expected)."""
    began = time.perf_counter()
    wants_model = ob.expect in ("refuted", "consistent")
    model = find_model(ob) if wants_model else None
    proof = None if model else _try_proof(ob)
    if model is None and proof != "unsat" and not wants_model:
        model = find_model(ob)
    seconds = time.perf_counter() - began
    if model is not None:
        return Outcome(ob, "consistent" if ob.is_consistency else "refuted", seconds, model)
    if proof == "unsat":
        if ob.check_vacuity and not ob.is_consistency:
            return _vacuity(ob, began)
        return Outcome(ob, "inconsistent" if ob.is_consistency else "proved", seconds)
    return Outcome(ob, "unknown", seconds, reason=proof or "no model up to the domain bound")


def hypotheses_only(ob: Obligation) -> Obligation:
    """The obligation's assumptions and hypotheses, without its conclusion: consistent exactly
    when the claim is not proved vacuously."""
    def claim(v: Vocabulary, w):
        return ob.claim(v, w)[0], None

    return replace(ob, name=f"{ob.name} (hypotheses)", expect="consistent", claim=claim, check_vacuity=False)


def _vacuity(ob: Obligation, began: float) -> Outcome:
    """A proved claim whose hypotheses have a model is proved; one whose hypotheses contradict
    the axioms is vacuous (every claim follows), and not what anyone expects."""
    hyp = hypotheses_only(ob)
    if find_model(hyp) is not None:
        return Outcome(ob, "proved", time.perf_counter() - began)
    if _try_proof(hyp) == "unsat":
        return Outcome(ob, "vacuous", time.perf_counter() - began,
                       reason="proved only vacuously: the model's facts about the claim's messages (their kinds, "
                              "who sent whom, the declared constraints) contradict the axioms, so every claim "
                              "follows from them; look for constraints that cannot hold together")
    return Outcome(ob, "unknown", time.perf_counter() - began,
                   reason="proved, but no model of its hypotheses was found to show the proof is not vacuous")


def unsat_core(ob: Obligation) -> Optional[list[str]]:
    """The assumptions Z3 used in a proof of ``ob`` (None if it is not proved)."""
    s, _ = _problem(ob, vocabulary(), track=True)
    if s.check() != z3.unsat:
        return None
    return sorted(str(c).removeprefix("assume:") for c in s.unsat_core())


def dependencies(ob: Obligation) -> Optional[list[str]]:
    """A minimal set of assumptions that still proves ``ob``: the unsat core,
    then each member dropped in turn if the rest still proves the claim."""
    core = unsat_core(ob)
    if core is None:
        return None
    needed = list(core)
    for name in list(needed):
        trial = [n for n in needed if n != name]
        if _try_proof(ob.with_assumptions(tuple(trial))) == "unsat":
            needed = trial
    return needed
