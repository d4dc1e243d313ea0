"""What a job explores: the model it names, loaded or compiled, its start state, and the
properties made into code (accepted final states, invariant patterns, spec-level checks)."""

from __future__ import annotations

from typing import Callable, Optional, Union

from ..clf.backward import Backward
from ..clf.context import Context
from ..clf.parser import parse_expr
from ..clf.forward import enabled_steps
from ..clf.program import Program
from ..clf.signature import Elaborator, ExecDirective, Signature, extend_signature
from ..errors import Pos, RoarError, did_you_mean
from .jobs import Job
from ..explore.system import Options


def load_model(job: Job) -> tuple[Program, Context]:
    program = Program.from_file(job.model)
    execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
    if not execs:
        raise RoarError(f"{job.model} has no #exec or #trace directive to start the search from", None)
    if job.start > len(execs):
        raise RoarError(f"'start = {job.start}' but {job.model.name} has only {len(execs)} #exec or #trace directive(s)",
                        job.start_at)
    refuse_open_heads(program)
    return program, program.start_context(execs[job.start - 1].start)


def refuse_open_heads(program: Program) -> None:
    """The explorer's states are ground: a rule with a Pi variable that only its head uses
    (``r : idle P -o {idle Q}``) would put a logic variable in the state, which no backend
    explores. Refused before the search, at the rule."""
    for t in program.templates:
        if t.forward and t.open_slots:
            names = [t.slot_names[s] if s < len(t.slot_names) else "?" for s in t.open_slots]
            info = program.sig.consts.get(t.name)
            raise RoarError(f"rule '{t.name}' uses variable{'s' if len(names) > 1 else ''} "
                            f"{', '.join(names)} only in its head (no premise binds "
                            f"{'them' if len(names) > 1 else 'it'}): firing it puts a logic variable in the state, and the explorer's states are ground "
                            "(bind it in a premise, or run the program with #exec or #query)",
                            info.pos if info is not None else None)


def inside(at: Optional[Pos], pos: Optional[Pos]) -> Optional[Pos]:
    """A position ``pos`` in a one-line text, as a position in the file where the text is
    written starting at ``at`` (None: where it is written is not known)."""
    if at is None:
        return pos
    if pos is None or pos.line != 1:
        return at
    return Pos(at.file, at.line, at.col + pos.col - 1)


def make_accept(program: Program, text: str, where: str, at: Optional[Pos] = None) -> Callable[[Context], bool]:
    """A final-state test from a positive CLF type: the context must match it exactly
    (every linear fact accounted for; affine ones may be left over). ``at``: where the text is
    written (an error inside it is reported there)."""
    try:
        expr = parse_expr(text, file=where)
        el = Elaborator(program.sig)
        el._begin()
        s = el.pos(expr)
        el._solve_postponed(expr.pos)
    except RoarError as e:
        if at is None:
            raise
        raise RoarError(f"accept pattern {text!r}: {e.message}", inside(at, e.pos), e.notes) from None
    for x in el.evars:
        x.scope = 1 << 62  # pattern variables may stand for fresh names

    def accept(ctx: Context) -> bool:
        # the pattern's variables are shared by every call: bindings made by one state's match
        # must be undone before the next state is tested
        bw = Backward(program)
        mark, hmark = bw.u.mark(), len(bw.htrail)
        try:
            return next(iter(bw._match_pos(s, ctx)), None) is not None
        finally:
            bw.undo(mark, hmark)

    return accept


def _split_tensor(text: str) -> list[str]:
    """``A * B * C`` at parenthesis depth 0 -> [A, B, C]."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        if ch == "*" and depth == 0:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    parts.append(cur.strip())
    return [p for p in parts if p]


def make_never(program: Union[str, Signature], file: str, patterns: list) -> Callable[[Context], Optional[str]]:
    """Invariant patterns as rules that must never be enabled: pattern ``A * B`` is violated by
    a state exactly when ``A -o B -o {1}`` could fire there (a sub-multiset match, with
    upper-case names as pattern variables and ``!A`` for persistent facts). ``program`` is the
    program's text, or its elaborated signature (a compiled model's: extended, not re-read)."""
    rules = []
    for k, (pat, pos) in enumerate(patterns):
        parts = _split_tensor(pat)
        rules.append(f"never_{k} : " + " -o ".join(parts) + " -o {1}.")
    extra = "\n".join(rules) + "\n"
    try:
        prog = Program.from_text(program + "\n" + extra, file) if isinstance(program, str) else \
            Program(extend_signature(program, extra, file))
    except RoarError as exc:
        # the error is in a pattern: point at the property file
        k = next((i for i, r in enumerate(rules) if r.split(" :")[0] in exc.message), None)
        pat, pos = patterns[k] if k is not None else patterns[0]
        raise RoarError(f"invariant pattern {pat!r}: {exc.message}", pos) from None
    tpls = [t for t in prog.templates if t.name.startswith("never_")]
    prover = prog.prover()

    def bad(ctx: Context) -> Optional[str]:
        for t in tpls:
            if any(True for _ in enabled_steps([t], ctx, prover, first_only=True)):
                return f"a reachable state matches the forbidden pattern {patterns[int(t.name[6:])][0]!r}"
        return None

    bad.templates = tuple(tpls)  # the reduction keeps these rules in every stubborn set
    return bad


def spec_properties(job: Job, model):
    """The job's properties in the spec's terms, bound to its compiled model (roar/props.py)."""
    from ..roar.props import SpecChecks
    return SpecChecks(job.props, model)


def mark_defaults(props, verdicts: dict) -> None:
    """Say which properties a job checked by default (a job on a spec that names none)."""
    if getattr(props, "defaulted", False):
        for v in verdicts.values():
            if "(a default property)" not in v.message:
                v.message += " (a default property)"


def note_default_progress(props, verdicts: dict) -> None:
    """On a spec, a livelock that holds by the default progress (any request finishing) says so,
    and what that progress hides."""
    v = verdicts.get("livelock")
    if v is not None and v.status == "holds" and not props.progress and not props.spec_progress:
        v.message += (" (progress: any request of any agent finishing, as no [livelock] progress is given; a "
                      "retry whose sub-requests succeed counts as progress: to check that the job's request "
                      "finishes, give progress = [\"request R0 finished\"] in a property file, e.g. with "
                      "--properties FILE)")


def check_progress_rules(props, program, spec: bool) -> None:
    """Refuse a livelock progress rule name (or glob) that names no rule of the program: it would
    make no step progress, and the livelock verdict would silently be another property's."""
    if "livelock" not in props.check:
        return
    import fnmatch
    names = [t.name for t in program.templates]
    for pat in props.progress:
        if not any(fnmatch.fnmatchcase(n, pat) for n in names):
            where = f" ({', '.join(map(str, props.sources))})" if props.sources else ""
            what = ("neither a predicate in the spec's terms (such as 'request R0 finished' or 'gripper::busy == "
                    "false') nor the name of a rule of the compiled model") if spec else \
                f"not the name of a rule of the model, nor a pattern matching one{did_you_mean(pat, names)}"
            at = getattr(props, "progress_at", {}).get(pat)
            raise RoarError(f"livelock progress {pat!r}{'' if at else where} is {what}: it would make no step "
                            f"progress", at)


def roar_setup(job: Job, model) -> tuple:
    """(program, start context, options, sequential pairs) of a job on a compiled spec: weak
    fairness per agent, the property files' progress rules (or requests reaching a final state)."""
    from ..roar.explore import PROGRESS_RULES, job_sequence_pairs
    program = model.program()
    start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
    start = program.start_context(start_d.start)
    props = job.props
    check_progress_rules(props, program, spec=True)
    options = Options(progress_rules=tuple(props.progress) or PROGRESS_RULES, fairness="agent",
                      canonical=job.canonical)
    pairs = []
    if "sequential-achievement" in props.check:
        pairs = job_sequence_pairs(model, props.sequence_recipes, props.sequence_kept, str(job.path),
                                   getattr(props, "sequence_at", None))
    return program, start, options, pairs


def reduction_options(options: Options, props, never) -> None:
    """Partial-order reduction for every property the job checks (see reduction.py): an
    invariant's forbidden patterns stay in every stubborn set, the families a monitor or a
    Python-computed invariant reads make their rules visible, progress steps are visible."""
    from ..clf.terms import Const
    from ..roar.explore import EXCLUSIVE_WRITES_FAMILIES, MONITOR_FAMILIES
    options.reduction = True
    options.observers = tuple(never.templates) if never is not None else ()
    visible: set = set()
    if "sequential-achievement" in props.check:
        visible |= MONITOR_FAMILIES
    if "exclusive-writes" in props.check:
        visible |= EXCLUSIVE_WRITES_FAMILIES
    options.visible_families = frozenset(Const(f) for f in visible)
