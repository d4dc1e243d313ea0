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


class MalformedQueryError(RoarError):
    """Bounds of ``#query d e l a`` that Celf refuses when the query is reached ("Malformed query
    (D,E,L,A)", a general error of the query in Celf's terms, after its type is checked)."""


def _plural(n, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def _nth(n: int) -> str:
    if n % 100 in (11, 12, 13):
        return f"{n}th"
    return f"{n}{ {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th') }"


def check_bounds(q: QueryDirective) -> None:
    """Celf's checks of ``#query d e l a``, in Celf's order (made after the query is printed and
    only when it is not ignored): more than one attempt must look for every solution (``l`` is
    ``*``), and the expected count must be below the number looked for (``e < l``: the search
    stops when it finds the ``l``-th solution, so ``e >= l`` could never be confirmed)."""
    where = list(q.bounds_pos) if len(q.bounds_pos) == 4 else [q.pos] * 4
    e, look, a = q.expected, q.look, q.attempts
    if a != "*" and a >= 2 and look != "*":
        raise MalformedQueryError(
            f"malformed query (D,E,L,A): A>1 and L<>*: {_plural(a, 'attempt')} must each look for every "
            f"solution, so the third bound must be '*', not {look} (Celf does not explore the monad's "
            "choices and backtracking together)", where[2])
    if e != "*" and look != "*" and e >= look:
        raise MalformedQueryError(
            f"malformed query (D,E,L,A): E>=L: it expects {_plural(e, 'solution')} and stops at the "
            f"{_nth(look)} it finds, so the count cannot be checked; look for one "
            f"more than expected (#query {_b(q.depth)} {e} {e + 1} {a} ...) or expect '*'", where[1])


def run_query(program: Program, q: QueryDirective, seed: int = 0, emit: Callable[[str], None] = print,
              fair: bool = False, proofs: bool = False) -> DirectiveResult:
    """Run ``#query d e l a A`` as Celf does: printed first; ignored when ``l = 0`` or ``a = 0``;
    malformed bounds refused (:func:`check_bounds`); then up to ``a`` attempts, each looking for
    ``l`` solutions (stopping at the ``l``-th), the query succeeding as soon as one attempt finds
    exactly ``e``. With ``proofs`` each solution prints its proof term (Celf's ``Solution: M``),
    otherwise ``Solution: _``."""
    res = DirectiveResult("query", True)
    program = program.at(q.prefix)
    show = program.show
    head = f"Query ({_b(q.depth)}, {_b(q.expected)}, {_b(q.look)}, {_b(q.attempts)}) {show(q.goal)}."
    emit(head)
    if q.look == 0 or q.attempts == 0:
        emit("Ignoring query")  # Celf's words: nothing is run, nothing checked
        return res
    check_bounds(q)
    attempts = 1 if q.attempts == "*" else q.attempts  # `*` is not read (Celf's grammar); built by hand: once
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
        except (SearchLimit, RecursionError) as exc:
            # raised after the handler: the error then keeps no traceback of the deep search (a
            # chain of nested generators that only the cyclic collector would free, slowly)
            aborted = str(exc) if isinstance(exc, SearchLimit) else "the proof search recursed too deeply"
        except BuiltinError as exc:
            raise BuiltinError(exc.message, exc.pos or q.pos, exc.notes) from None
        else:
            aborted = None
        if aborted is not None:
            raise QueryError(f"query aborted: {aborted} (after {_plural(count, 'solution')}): a depth-first search "
                             f"that does not end (Celf's would not either)? Order the clauses or premises so that "
                             f"it does", q.pos)
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
    expected = _plural(q.expected, "solution")
    if len(counts) > 1:
        raise QueryError(f"query failed: expected {expected} in any of {len(counts)} attempts (found {found})",
                         q.pos)
    if look is not None and found == look:
        raise QueryError(f"query failed: expected {expected}, found at least {found} (the search stops at "
                         f"the {_nth(look)})", q.pos)
    raise QueryError(f"query failed: expected {expected}, found {found}", q.pos)


def context_layout(ctx: Context, width: int = 80) -> list[str]:
    """The context as Celf prints it after ``#exec`` and at each step of ``#trace``: ``-- `` and
    the hypotheses separated by ``, ``, each its type followed by ``lin``, ``aff`` or ``pers``,
    continued on lines indented by three spaces past ``width`` columns; ``-- (nothing)`` when it
    is empty. Celf lists them in its context's order, this engine sorted by text (stable across
    seeds and runs)."""
    imp = ctx.implicit
    items = []
    for mode, t, n in ctx.facts():
        items.extend([f"{_show(t, implicit=imp)} {_MODE_WORD[mode]}"] * n)
    for mode, t in ctx.open:
        items.append(f"{_show(zonk(t), implicit=imp)} {_MODE_WORD[mode]}")
    for r in ctx.rules.values():
        items.append(f"{_show(zonk(r.source), implicit=imp)} {_MODE_WORD[r.mode]}")
    for mode, t in ctx.inert:
        items.append(f"{_show(t, implicit=imp)} {_MODE_WORD[mode]}")
    items.sort()
    if not items:
        return ["-- (nothing)"]
    lines, line = [], "--"
    for i, item in enumerate(items):
        piece = item + ("," if i < len(items) - 1 else "")
        if line.strip() not in ("--", "") and len(line) + 1 + len(piece) > width:
            lines.append(line)
            line = "  "
        line += " " + piece
    lines.append(line)
    return lines


_MODE_WORD = {LIN: "lin", AFF: "aff", PERS: "pers"}


def run_exec(program: Program, d: ExecDirective, seed: int = 0, emit: Callable[[str], None] = print,
             trace: bool = False, fair: bool = False, max_steps: Optional[int] = None) -> DirectiveResult:
    """Run ``#exec n S`` or ``#trace n S`` with Celf's output: ``Exec n S`` (``Trace n S``), the
    context (:func:`context_layout`; with ``#trace``, or ``trace``, also before the first step
    and after each one), then ``Success: k steps``, or ``Exec failed, expected n steps but only
    k taken`` (raising :class:`QueryError`, Celf's "query failed") when it quiesced early.
    ``max_steps`` bounds ``#exec *`` (which Celf runs until the program quiesces, for ever if it
    never does): past it the directive fails, saying the program had not quiesced."""
    kw = "Trace" if d.trace else "Exec"
    program = program.at(d.prefix)
    emit(f"{kw} {_b(d.steps)} {program.show(d.start)}")
    ctx = program.start_context(d.start)
    res = DirectiveResult("exec", True)
    show_each = d.trace or trace
    if show_each:
        for line in context_layout(ctx):
            emit(line)

    def on_step(step, c):
        if show_each:
            for line in context_layout(c):
                emit(line)
        res.steps += 1

    bound = None if d.steps == "*" else d.steps
    try:
        steps, quiescent = program.run(ctx, max_steps if bound is None else bound, seed=seed, fair=fair,
                                       on_step=on_step)
    except BuiltinError as exc:
        raise BuiltinError(exc.message, exc.pos or d.pos, exc.notes) from None
    except (SearchLimit, RecursionError) as exc:
        steps = None
        aborted = str(exc) if isinstance(exc, SearchLimit) else "the proof search recursed too deeply"
    if steps is None:   # (raised after the handler: see run_query)
        raise QueryError(f"#{kw.lower()} aborted after {res.steps} steps: a premise's {aborted} (a depth-first "
                         f"search that does not end?)", d.pos)
    res.steps = steps
    res.final = ctx
    if not show_each:
        for line in context_layout(ctx):  # Celf prints it on success; here also on failure
            emit(line)
    if bound is None and not quiescent:   # (only with max_steps: '*' runs to quiescence otherwise)
        res.ok = False
        emit(f"{kw} stopped after {steps} steps (--max-steps {max_steps}): the program had not quiesced")
        raise QueryError(f"#{kw.lower()} * did not quiesce within {max_steps} steps (--max-steps); Celf would "
                         "run it on, for ever if nothing ends it", d.pos)
    if bound is not None and steps < bound:
        res.ok = False
        emit(f"{kw} failed, expected {bound} steps but only {steps} taken")  # Celf's words
        raise QueryError(f"#{kw.lower()} expected exactly {bound} steps, but the program quiesced after {steps}",
                         d.pos)
    emit(f"Success: {steps} steps")  # Celf's words (also for 1)
    return res


def run_directives(program: Program, seed: int = 0, emit: Callable[[str], None] = print,
                   trace: bool = False, fair: bool = False, proofs: bool = False,
                   max_steps: Optional[int] = None) -> list[DirectiveResult]:
    """Run every directive in program order; the first failing one raises."""
    out = []
    for d in program.sig.directives:
        if isinstance(d, QueryDirective):
            out.append(run_query(program, d, seed, emit, fair, proofs))
        else:
            out.append(run_exec(program, d, seed, emit, trace, fair, max_steps))
    return out


def run_file(path, seed: int = 0, emit: Callable[[str], None] = print, trace: bool = False,
             fair: bool = False, proofs: bool = False, strict: bool = True,
             max_steps: Optional[int] = None) -> list[DirectiveResult]:
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
            out.append(run_exec(program, d, seed, emit, trace, fair, max_steps))
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
        # a daemon: when the caller is interrupted (Ctrl-C, SIGTERM unwinding as SystemExit), the
        # process exits without waiting for the search to end
        t = threading.Thread(target=target, daemon=True)
        t.start()
        t.join()
    finally:
        threading.stack_size(old_size)
        sys.setrecursionlimit(old_limit)
    if "error" in result:
        raise result["error"]
    return result.get("value")


__all__ = ["run_query", "run_exec", "check_bounds", "context_layout", "MalformedQueryError", "run_directives",
           "run_file", "show_context", "with_big_stack", "RoarError"]
