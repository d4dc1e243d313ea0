"""A job's symmetry reduction: the verified symmetries it uses (explore/symmetry.py for
.clf models, roar/symmetry.py for specs), the properties it refuses, what the report says."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from ..clf.context import Context
from ..clf.program import Program
from ..errors import RoarError
from ..explore.graph import StateGraph
from .jobs import Job
from ..explore.symmetry import discover_clf


@dataclass
class SymmetryUse:
    """The symmetries a job's search uses: the group (identity first) and the report's sentence."""

    group: list
    note: str


def symmetric(system, sym: Optional[SymmetryUse]):
    """``system``, its states keyed up to the symmetries when the job found some."""
    if sym is None or len(sym.group) < 2:
        return system
    from ..explore.symmetry import SymmetricSystem
    return SymmetricSystem(system, sym.group, sym.note)


def mark_symmetry(sym: Optional[SymmetryUse], verdicts: dict, graph: StateGraph) -> None:
    if sym is None:
        return
    quotient = len(sym.group) > 1
    for v in verdicts.values():
        v.message += (f" ({sym.note}; {graph.n_states:,} states of the quotient)" if quotient else f" ({sym.note})")
        v.details["symmetry"] = sym.note
        v.details["symmetry_order"] = len(sym.group)


def _symmetry_where(job: Job):
    return job.symmetry_at, ("symmetry = true" if job.symmetry_at is not None else "--symmetry")


def _refuse_named(job: Job, named, permuted: str) -> None:
    """Refuse the job's patterns and spec predicates that name a constant or agent the group moves:
    a property that tells the images of a state apart is not decided by the quotient."""
    where, opt = _symmetry_where(job)
    props = job.props
    for text, pos in props.never if "invariant" in props.check else ():
        hit = named(text)
        if hit:
            raise RoarError(f"{opt}: the invariant pattern {text!r} names {hit[0]}, one of the {permuted} symmetry "
                            f"reduction interchanges: the quotient cannot tell its states apart; check it without "
                            f"symmetry", pos)
    if props.accept and named(props.accept):
        raise RoarError(f"{opt}: the [deadlock] accept pattern names {named(props.accept)[0]}, one of the {permuted} "
                        f"symmetry reduction interchanges; check it without symmetry", where)
    formulas = (props.spec_never + props.spec_always) if "invariant" in props.check else []
    formulas += [f for n, f in props.temporal.items() if n in props.check]
    for f in formulas:
        hit = named(f.text)
        if hit:
            raise RoarError(f"{opt}: property {f.text!r} names agent {hit[0]}, one of the {permuted} symmetry "
                            f"reduction interchanges: the quotient keeps one state of each set of states that differ "
                            f"only by exchanging them, so it cannot decide a property that tells them apart; check it "
                            f"without symmetry", f.at(hit[1]) or where)
    if "incompatible-tasks" in props.check and props.incompatible_pairs:
        for pair in props.incompatible_pairs:
            for text, pos in pair:
                hit = named(text)
                if hit:
                    raise RoarError(f"{opt}: incompatible-tasks names {text!r}, of agent {hit[0]}, one of the "
                                    f"{permuted} symmetry reduction interchanges; check it without symmetry", pos)


def clf_symmetry(job: Job, program: Program, start: Context) -> SymmetryUse:
    """The interchangeable constants of a .clf model (explore/symmetry.py, discover_clf), verified."""
    import re
    from ..explore.symmetry import close_group, factorial_order, MAX_ORDER, transpositions, verify
    blocks, notes = discover_clf(program, start)
    gens = transpositions(blocks)
    for g in gens:   # (discover_clf verified them; a group is used only once each generator passes)
        chk = verify(program.sig, start, g)
        if not chk.ok:
            raise RoarError(f"symmetry reduction: a candidate symmetry failed verification: {chk.reason}")
        g.rules = chk.rules
    if factorial_order(len(b) for b in blocks) > MAX_ORDER:
        close_group(gens)   # refuses, with the message
    group = close_group(gens)
    if len(group) > 1:
        names = [[m[""] for m in b] for b in blocks]
        k = sum(len(b) for b in names)
        note = (f"symmetry: {k} constants interchangeable ({'; '.join(', '.join(b) for b in names)}), "
                f"group of order {len(group):,}")
        moved = {m for b in names for m in b}

        def named(text: str):
            for w in re.finditer(r"[A-Za-z_][A-Za-z0-9_']*", text):
                if w.group(0) in moved:
                    return w.group(0), w.start() + 1
            return None
        _refuse_named(job, named, "constants")
    else:
        why = "; ".join(notes) if notes else "no two constants of one type are mentioned by no rule"
        note = f"symmetry: none found ({why}); the search is the plain one"
    return SymmetryUse(group, note)


def roar_symmetry(job: Job, model, start: Context) -> SymmetryUse:
    """The interchangeable agents of a compiled spec (roar/symmetry.py), verified on the model."""
    from ..roar.symmetry import discover, names_permuted
    sym = discover(model, start)
    if sym.order > 1:
        _refuse_named(job, lambda text: names_permuted(sym, text), "agents")
    return SymmetryUse(sym.group, sym.note())
