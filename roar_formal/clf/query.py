"""Running a program's directives: ``#query``, ``#exec`` and ``#trace``, with Celf's meaning.

Output is a list of plain lines (the CLI colours them); a directive whose
outcome differs from what it declares (solution count, exact step count)
raises :class:`QueryError` after printing what happened.
"""

from __future__ import annotations

import sys
import threading
from dataclasses import dataclass, field
from typing import Callable, Optional

from ..errors import QueryError, RoarError
from .backward import Backward, SearchLimit, show_proof
from .builtins import BuiltinError
from .context import Context
from .printer import show as _show
from .program import Program
from .rules import AFF, LIN, PERS
from .signature import ExecDirective, QueryDirective
from .terms import zonk


def _b(x) -> str:
    return "*" if x == "*" else str(x)


def show_context(ctx: Context) -> list[str]:
    """The context, one hypothesis a line, in a stable order (facts sorted by text)."""
    lines = []
    imp = ctx.implicit

    def show(t):
        return _show(t, implicit=imp)

    for mode, t, n in ctx.facts():
        prefix = {LIN: "", AFF: "@", PERS: "!"}[mode]
        text = prefix + show(t)
        lines.extend([text] * n)
    for mode, t in ctx.open:  # facts holding logic variables, with their values so far
        prefix = {LIN: "", AFF: "@", PERS: "!"}[mode]
        lines.append(prefix + show(zonk(t)))
    for r in ctx.rules.values():
        prefix = {LIN: "", AFF: "@", PERS: "!"}[r.mode]
        lines.append(prefix + "(" + show(zonk(r.source)) + ")")
    for mode, t in ctx.inert:
        prefix = {LIN: "", AFF: "@", PERS: "!"}[mode]
        lines.append(prefix + show(t))
    return sorted(lines)


@dataclass
class DirectiveResult:
    kind: str
    ok: bool
    lines: list[str] = field(default_factory=list)
    solutions: int = 0
    steps: int = 0
    final: Optional[Context] = None
    answers: list[dict[str, str]] = field(default_factory=list)


def run_query(program: Program, q: QueryDirective, seed: int = 0, emit: Callable[[str], None] = print,
              fair: bool = False, proofs: bool = False) -> DirectiveResult:
    """Run ``#query d e l a A`` as Celf does: up to ``a`` attempts, each looking for ``l``
    solutions; the query succeeds as soon as one attempt finds ``e`` of them. A query with
    ``l = 0`` or ``a = 0`` is ignored."""
    res = DirectiveResult("query", True)
    program = program.at(q.prefix)
    show = program.show
    head = f"Query ({_b(q.depth)}, {_b(q.expected)}, {_b(q.look)}, {_b(q.attempts)}) {show(q.goal)}."
    emit(head)
    if q.look == 0 or q.attempts == 0:
        emit("Ignoring query")  # Celf's words: nothing is run, nothing checked
        return res
    attempts = 1 if q.attempts == "*" else q.attempts
    look = None if q.look == "*" else q.look
    depth = None if q.depth == "*" else q.depth
    counts = []
    for attempt in range(attempts):
        if attempts > 1:
            emit(f"Iteration {attempt + 1}")
        bw = Backward(program, seed=seed + attempt, monad_depth=depth, fair=fair)
        bw.proofs = proofs
        count = 0
        try:
            for pf in bw.solve(q.goal):
                count += 1
                emit(f"Solution: {show_proof(pf) if proofs else '_'}")
                answer = {}
                for name, x in q.logic_vars:
                    v = zonk(x)
                    answer[name] = show(v)
                    emit(f" #{name} = {answer[name]}")
                res.answers.append(answer)
                if look is not None and count >= look:
                    break
        except SearchLimit as exc:
            raise QueryError(f"query aborted: {exc}", q.pos) from None
        except BuiltinError as exc:
            raise BuiltinError(exc.message, exc.pos or q.pos, exc.notes) from None
        res.solutions += count
        counts.append(count)
        if q.expected == "*":
            continue  # as Celf: no expectation, so every attempt is made and no verdict printed
        if count == q.expected:
            emit("Query ok.")
            return res
    if q.expected == "*":
        return res
    res.ok = False
    emit("Query failed")  # Celf's words
    found = counts[0] if len(counts) == 1 else "/".join(str(c) for c in counts)
    tries = "" if len(counts) == 1 else f" in any of {len(counts)} attempts (found {found})"
    if tries:
        raise QueryError(f"query failed: expected {q.expected} solution{'s' if q.expected != 1 else ''}"
                         f"{tries}", q.pos)
    raise QueryError(f"query failed: expected {q.expected} solution{'s' if q.expected != 1 else ''}, "
                     f"found {found}", q.pos)


def run_exec(program: Program, d: ExecDirective, seed: int = 0, emit: Callable[[str], None] = print,
             trace: bool = False, fair: bool = False) -> DirectiveResult:
    kw = "Trace" if d.trace else "Exec"
    program = program.at(d.prefix)
    emit(f"{kw} ({_b(d.steps)}) {program.show(d.start)}.")
    ctx = program.start_context(d.start)
    res = DirectiveResult("exec", True)
    show_each = d.trace or trace

    def on_step(step, c):
        if show_each:
            emit(f"-- step {res.steps + 1}: {step.rule}")
            for line in show_context(c):
                emit(f"   {line}")
        res.steps += 1

    bound = None if d.steps == "*" else d.steps
    try:
        steps, quiescent = program.run(ctx, bound, seed=seed, fair=fair, on_step=on_step)
    except BuiltinError as exc:
        raise BuiltinError(exc.message, exc.pos or d.pos, exc.notes) from None
    res.steps = steps
    res.final = ctx
    emit(f"Final context after {steps} step{'s' if steps != 1 else ''}{' (quiescent)' if quiescent else ''}:")
    for line in show_context(ctx):
        emit(f"  {line}")
    if bound is not None and steps < bound:
        res.ok = False
        emit(f"{kw} error.")
        raise QueryError(f"#{kw.lower()} expected exactly {bound} steps, but the program quiesced after {steps}",
                         d.pos)
    emit(f"{kw} ok.")
    return res


def run_directives(program: Program, seed: int = 0, emit: Callable[[str], None] = print,
                   trace: bool = False, fair: bool = False, proofs: bool = False) -> list[DirectiveResult]:
    """Run every directive in program order; the first failing one raises."""
    out = []
    for d in program.sig.directives:
        if isinstance(d, QueryDirective):
            out.append(run_query(program, d, seed, emit, fair, proofs))
        else:
            out.append(run_exec(program, d, seed, emit, trace, fair))
    return out


def run_file(path, seed: int = 0, emit: Callable[[str], None] = print, trace: bool = False,
             fair: bool = False, proofs: bool = False, strict: bool = True) -> list[DirectiveResult]:
    """Check and run a Celf file the way Celf does: one item at a time, so each directive
    runs (and prints) before the declarations after it are checked, and sees only the
    declarations before it; the first error (parse, type, mode, or a failed directive) stops."""
    from .parser import parse_file
    from .signature import elaborate_steps

    parsed = parse_file(str(path))
    out = []
    program = None
    sig = None
    for sig, d in elaborate_steps(parsed, strict=strict):
        if d is None:
            continue
        if program is None or program._size != len(sig.consts):
            program = Program(sig)
        if isinstance(d, QueryDirective):
            out.append(run_query(program, d, seed, emit, fair, proofs))
        else:
            out.append(run_exec(program, d, seed, emit, trace, fair))
    if sig is not None and (program is None or program._size != len(sig.consts)):
        Program(sig)  # the rules after the last directive are compiled too (and refused if they must be)
    return out


def with_big_stack(fn, *args, **kwargs):
    """Run ``fn`` in a thread with a large stack: proof search and deep terms recurse."""
    result: dict = {}

    def target():
        try:
            result["value"] = fn(*args, **kwargs)
        except BaseException as exc:  # re-raised in the caller's thread
            result["error"] = exc

    old_limit = sys.getrecursionlimit()
    old_size = threading.stack_size()
    sys.setrecursionlimit(max(old_limit, 200_000))
    threading.stack_size(512 * 1024 * 1024)
    try:
        t = threading.Thread(target=target)
        t.start()
        t.join()
    finally:
        threading.stack_size(old_size)
        sys.setrecursionlimit(old_limit)
    if "error" in result:
        raise result["error"]
    return result.get("value")


__all__ = ["run_query", "run_exec", "run_directives", "run_file", "show_context", "with_big_stack", "RoarError"]
