"""Check a trace's task tree against the axioms and the declared constraints.

The trace is a finite structure: it fixes kinds, parents, send times and the
handling (and perhaps achievement) intervals; the achievement intervals of
goals are usually not observed. A trace conforms when some values for what it
leaves open satisfy every axiom. The checker

1. evaluates each axiom's own Z3 formula at the instances that matter (each
   message, each parent-child edge, each declared constraint); the
   definitional axioms (active, completed, scheduable, achieving, desc, childOf
   after sending) hold by construction of this interpretation;
2. applies the proved theorem ``seq_ach_subtrees`` to each declared SeqAch at
   its critical pair (the last command to end under m1, the first to start
   under m2), which names the messages and times when sequencing fails;
3. hands the instances that depend on unobserved values to Z3, and turns each
   unsat core into a violation naming the instances that cannot hold together.

Times a trace never reached (a message not yet started or ended) lie after
its last time: a trace prefix is judged on what it has already shown.
"""

from __future__ import annotations

import copy
import time
from bisect import bisect_right
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Optional

import z3

from ..errors import Pos, RoarError
from .axioms import BY_NAME as AXIOMS
from .difference import DifferenceSystem, NotDifference, atoms as difference_atoms
from .evaluate import LATE, UNKNOWN, compile_formula, compile_residual
from .explain import describe, false_atoms, show_value
from .tasktree import Message, Problem, TaskTree, build_tree
from .theorems import BY_NAME as OBLIGATIONS
from .trace_events import Event, read_events
from .vocabulary import Vocabulary, vocabulary

MAX_CORES = 25


@dataclass(frozen=True)
class Violation:
    """A way the trace breaks the theory: the rule, the messages, and why."""

    rule: str
    source: str
    messages: tuple[str, ...]
    explanation: str
    lines: tuple[int, ...] = ()


@dataclass
class CheckReport:
    tree: TaskTree
    violations: list[Violation]
    instances: int = 0
    residual: int = 0
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)   # what the check took on trust, or left out

    @property
    def ok(self) -> bool:
        return not self.violations


# --- which instances of which axioms a trace is checked on -----------------------------

Instances = Callable[[TaskTree, Fraction], Iterator[tuple]]


def _each_message(tree: TaskTree, after: Fraction) -> Iterator[tuple]:
    return ((m,) for m in tree.messages)


def _each_edge(tree: TaskTree, after: Fraction) -> Iterator[tuple]:
    return ((p.id, c.id, after) for p, c in tree.edges())


def _each_declared(relation: str) -> Instances:
    def instances(tree: TaskTree, after: Fraction) -> Iterator[tuple]:
        return ((d.m1, d.m2, after) for d in tree.declared if d.relation == relation)

    return instances


GROUNDED: dict[str, Instances] = {
    "a1_sent_by_parent": _each_edge,
    "a2_interval": _each_message,
    "a4_dispatch": _each_message,
    "a5_precedes": _each_declared("precedes"),
    "a6_interval": _each_message,
    "a7_command": _each_message,
    "a7_goal": _each_message,
    "a8_nesting": _each_edge,
    "q_leaf": _each_edge,
    "d_seq_ach": _each_declared("seq_ach"),
    "d_delay_planning": _each_declared("delay_planning"),
}
BY_CONSTRUCTION = ("a1_child", "a1_one_parent", "a1_sender", "a2_active", "a3_completed", "a4_scheduable", "a6_achieving",
                   "d_desc_child", "d_desc_step", "d_desc_unfold")


@dataclass
class _Compiled:
    """A formula with fresh constants for its variables, compiled for evaluation."""

    name: str
    source: str
    params: list[z3.ExprRef]
    formula: z3.BoolRef
    run: Callable  # three-valued evaluation
    partial: Optional[Callable] = None  # the part left open, as a Z3 constraint


def _compile_axiom(name: str, v: Vocabulary) -> _Compiled:
    q = AXIOMS[name].build(v)
    params = [z3.Const(f"{q.var_name(i)}!{i}", q.var_sort(i)) for i in range(q.num_vars())]
    body = z3.substitute_vars(q.body(), *reversed(params))
    return _Compiled(name, AXIOMS[name].source, params, body, compile_formula(body, params),
                     compile_residual(body, params, lambda value: _lift(v, value)))


def _compile_theorem(name: str, v: Vocabulary) -> _Compiled:
    ob = OBLIGATIONS[name]
    w = {n: (z3.Real(f"{n}!w") if n == "t" else z3.Const(f"{n}!w", v.msg)) for n in ob.witnesses}
    hyp, concl = ob.claim(v, w)
    formula = z3.Implies(hyp, concl)
    params = [w[n] for n in ob.witnesses]
    return _Compiled(name, f"theorem {name}", params, formula, compile_formula(formula, params))


# --- the trace as an interpretation of the vocabulary -----------------------------------

class _Interpretation:
    """Values of the vocabulary's symbols on one task tree."""

    def __init__(self, tree: TaskTree, v: Vocabulary):
        self.tree, self.v = tree, v
        self.declared = {(d.relation, d.m1, d.m2) for d in tree.declared}
        self.consts: dict[str, z3.ExprRef] = {}
        self.unknowns: dict[str, z3.ArithRef] = {}
        self.late: dict[str, str] = {}  # unknown name -> message
        self.asserting = False  # precedes is its axiom-5 definition, unless a declaration asserts it

    def asserting_declarations(self) -> "_Interpretation":
        """The same interpretation (sharing its unknowns) where declared precedes pairs hold:
        axiom 5 on a declared pair then checks the declaration against the times."""
        view = copy.copy(self)
        view.asserting = True
        return view

    def time(self, field_name: str, m: Message) -> Any:
        value = getattr(m, field_name)
        if value is not None:
            return value
        if field_name == "end" or (field_name == "start" and m.end is None):
            return LATE
        return UNKNOWN

    def desc(self, a: str, m: str, t: Fraction) -> bool:
        if not self.tree.is_desc(a, m):
            return False
        return all(t > self.tree.messages[x].sent for x in self.tree.path(a, m)[1:])

    def lookup(self, name: str, args: tuple) -> Any:
        ms = self.tree.messages
        if name == "kind":
            return ms[args[0]].kind
        if name in ("sent", "start", "end", "ach.start", "ach.end"):
            return self.time(name.replace(".", "_"), ms[args[0]])
        if name == "childOf":
            p, c, t = args
            return ms[c].parent == p and t > ms[c].sent
        if name == "send":
            p, c, t = args
            return ms[c].parent == p and t == ms[c].sent
        if name in ("SeqAch", "DelayPlanning"):
            relation = "seq_ach" if name == "SeqAch" else "delay_planning"
            return (relation, args[0], args[1]) in self.declared
        if name == "precedes":
            m1, m2, _ = args
            if self.asserting and ("precedes", m1, m2) in self.declared:
                return True
            end, start = self.time("end", ms[m1]), self.time("start", ms[m2])
            if end is UNKNOWN or start is UNKNOWN or (end is LATE and start is LATE):
                return UNKNOWN
            return start is LATE or (end is not LATE and end <= start)
        if name == "desc":
            return self.desc(*args)
        raise ValueError(f"the trace does not interpret {name}")

    # Z3 terms for the residual constraints

    def const(self, m: str) -> z3.ExprRef:
        if m not in self.consts:
            self.consts[m] = z3.Const(m, self.v.msg)
        return self.consts[m]

    def z3_value(self, value: Any) -> z3.ExprRef:
        if isinstance(value, str):
            return self.const(value)
        return z3.RealVal(str(value))

    def symbolic(self, name: str, args: tuple) -> Any:
        """The value of a ground application, or a Z3 variable standing for it when unknown."""
        value = self.lookup(name, args)
        if value is not UNKNOWN and value is not LATE:
            return value
        key = f"{name}({args[0]})" if len(args) == 1 else f"{name}{args}"
        if key not in self.unknowns:
            self.unknowns[key] = z3.Real(key)
            if value is LATE:
                self.late[key] = args[0]
        return self.unknowns[key]


def _lift(v: Vocabulary, value: Any) -> z3.ExprRef:
    if isinstance(value, bool):
        return z3.BoolVal(value)
    if isinstance(value, str):
        return v.kinds[value]  # the only strings compared against unknowns are kinds
    return z3.RealVal(str(value))


def _lines_of(tree: TaskTree, messages: Iterable[str]) -> tuple[int, ...]:
    return tuple(sorted({line for m in messages for line in tree.messages[m].lines.values()}))


def _ground_violation(c: _Compiled, values: tuple, interp: _Interpretation) -> Violation:
    msgs = tuple(dict.fromkeys(x for x in values if isinstance(x, str)))
    atoms = false_atoms(c.formula, interp, c.params, values)
    why = f"{AXIOMS[c.name].summary}; fails: " + "; ".join(atoms)
    return Violation(c.name, c.source, msgs, why, _lines_of(interp.tree, msgs))


# --- the checker --------------------------------------------------------------------------

class _Checker:
    def __init__(self, tree: TaskTree, v: Vocabulary):
        self.tree, self.v = tree, v
        self.interp = _Interpretation(tree, v)
        self.asserting = self.interp.asserting_declarations()
        self.after = tree.horizon + 1
        self.violations: list[Violation] = []
        self.pending: list[tuple[_Compiled, tuple, z3.BoolRef]] = []
        self.instances = 0
        self.sequencing_failed: set[tuple[str, str]] = set()

    def ground(self) -> None:
        for name, instances in GROUNDED.items():
            c = _compile_axiom(name, self.v)
            interp = self.asserting if name == "a5_precedes" else self.interp
            for values in instances(self.tree, self.after):
                self.instances += 1
                verdict = c.run(values, interp.lookup)
                if verdict is False:
                    self.violations.append(_ground_violation(c, values, interp))
                elif verdict is UNKNOWN:
                    self.pending.append((c, values, c.partial(values, interp.symbolic)))

    def sequencing(self) -> None:
        """Theorem ``seq_ach_subtrees`` at each declared SeqAch's critical pair."""
        c = _compile_theorem("seq_ach_subtrees", self.v)
        for d in self.tree.declared:
            if d.relation != "seq_ach":
                continue
            pair = self._critical_pair(d.m1, d.m2)
            if pair is None:
                continue
            values = (d.m1, d.m2, pair[0].id, pair[1].id, self.after)
            self.instances += 1
            if c.run(values, self.interp.lookup) is False:
                self.sequencing_failed.add((d.m1, d.m2))
                self.violations.append(self._sequencing_violation(d, *pair))

    def _critical_pair(self, m1: str, m2: str) -> Optional[tuple[Message, Message]]:
        firsts = [m for m in self.tree.subtree(m1) if m.executes]
        seconds = [m for m in self.tree.subtree(m2) if m.executes]
        if not firsts or not seconds:
            return None
        late = _late_key(self.interp, "end")
        return max(firsts, key=late), min(seconds, key=_late_key(self.interp, "start"))

    def _sequencing_violation(self, d, last: Message, first: Message) -> Violation:
        tree, interp = self.tree, self.interp
        ends = sorted(_late_key(interp, "end")(m) for m in tree.subtree(d.m1) if m.executes)
        starts = [_late_key(interp, "start")(m) for m in tree.subtree(d.m2) if m.executes]
        overlapping = sum(len(ends) - bisect_right(ends, s) for s in starts)
        path1 = " > ".join(tree.path(d.m1, last.id))
        path2 = " > ".join(tree.path(d.m2, first.id))
        end = interp.time("end", last)
        ends = f"ends at {show_value(end)}" if end is not LATE else "has not ended when the trace stops"
        texts = [f"{m}: {c}" for m in (d.m1, d.m2)
                 if (c := getattr(tree.messages.get(m), "constraint", None))]   # as the spec wrote them
        said = f" ({'; '.join(texts)})" if texts else ""
        header = " (the trace's header)" if d.pos.line == 1 and str(d.pos.file).endswith(".jsonl") else ""
        why = (f"SeqAch({d.m1}, {d.m2}){said} declared at line {d.pos.line}{header}: {last.kind} {last.id}{_named(last)} ({path1}) "
               f"{ends}, after {first.kind} {first.id}{_named(first)} ({path2}) starts at "
               f"{show_value(interp.time('start', first))}; {overlapping} pair(s) of commands/monitors overlap")
        msgs = (d.m1, d.m2, last.id, first.id)
        lines = (d.pos.line,) + _lines_of(tree, msgs[2:])
        return Violation("seq_ach", "theorem seq_ach_subtrees", msgs, why, tuple(dict.fromkeys(lines)))

    def solve(self) -> None:
        """Decide the instances that depend on unobserved values; one violation per conflict.

        The open constraints are difference constraints (difference.py): a negative cycle of
        their graph is a minimal conflict, found in time and memory about linear in the
        trace. Anything outside that fragment goes to Z3 with core minimisation."""
        if not self.pending:
            return
        labels: dict[str, tuple[str, Callable[[], str], tuple[str, ...]]] = {}  # label -> (rule, text, messages)
        constraints: list[tuple[str, Any]] = []
        for i, (c, values, constraint) in enumerate(self.pending):
            msgs = tuple(dict.fromkeys(x for x in values if isinstance(x, str)))
            labels[f"i{i}"] = (c.name, describe(c.name, values, constraint), msgs)
            constraints.append((f"i{i}", constraint))
        for key, m in self.interp.late.items():
            text = f"{key} lies after the trace's last time {show_value(self.tree.horizon)}"
            labels[f"late:{key}"] = ("late", lambda text=text: text, (m,))
            constraints.append((f"late:{key}", self.interp.unknowns[key] > z3.RealVal(str(self.tree.horizon))))
        try:
            system = DifferenceSystem()
            for label, constraint in constraints:
                system.add(label, difference_atoms(constraint))
        except NotDifference:
            return self._solve_with_z3(constraints, labels)
        for _ in range(MAX_CORES):
            core = system.conflict()
            if core is None:
                return
            self._report_core([labels[k] for k in sorted(core)])
            system.drop(self._to_drop(core, labels))

    @staticmethod
    def _to_drop(core, labels) -> str:
        """Which instance of a conflict to set aside before looking for the next: a declaration if any."""
        return next((k for k in sorted(core) if labels[k][0] in ("d_seq_ach", "d_delay_planning", "a5_precedes")),
                    min(core))

    def _solve_with_z3(self, constraints, labels) -> None:
        s = z3.Solver()
        s.set("core.minimize", True)
        active = []
        for label, constraint in constraints:
            b = z3.Bool(label)
            s.add(z3.Implies(b, constraint))
            active.append(b)
        for _ in range(MAX_CORES):
            if s.check(*active) != z3.unsat:
                return
            core = {str(x) for x in s.unsat_core()}
            self._report_core([labels[k] for k in sorted(core)])
            drop = self._to_drop(core, labels)
            active = [a for a in active if str(a) != drop]

    def _report_core(self, parts: list[tuple[str, str, tuple[str, ...]]]) -> None:
        parts = sorted(parts, key=lambda p: p[0] not in ("d_seq_ach", "d_delay_planning", "a5_precedes"))
        declared = [p for p in parts if p[0] == "d_seq_ach"]
        if declared and all(tuple(p[2][:2]) in self.sequencing_failed for p in declared):
            return  # already explained by the sequencing rule
        msgs = tuple(dict.fromkeys(m for p in parts for m in p[2]))
        why = "these cannot all hold together: " + "; ".join(p[1]() for p in parts)
        rules = sorted({p[0] for p in parts if p[0] != "late"})
        self.violations.append(Violation("+".join(rules) or "late", "axioms together", msgs, why,
                                         _lines_of(self.tree, msgs)))


def _late_key(interp: _Interpretation, field_name: str) -> Callable[[Message], tuple]:
    def key(m: Message) -> tuple:
        value = interp.time(field_name, m)
        return (1, Fraction(0)) if value is LATE or value is UNKNOWN else (0, value)

    return key


def _problem_violation(p: Problem) -> Violation:
    return Violation("well_formed", "task tree", p.messages, p.message, (p.pos.line,))


def check_tree(tree: TaskTree, problems: Iterable[Problem] = ()) -> CheckReport:
    """Every violation of the axioms and declared constraints in ``tree``."""
    began = time.perf_counter()
    checker = _Checker(tree, vocabulary())
    checker.violations.extend(_problem_violation(p) for p in problems)
    checker.ground()
    checker.sequencing()
    checker.solve()
    return CheckReport(tree, checker.violations, checker.instances, len(checker.pending),
                       time.perf_counter() - began)


def check_events(events: Iterable[Event]) -> CheckReport:
    tree, problems = build_tree(events)
    return check_tree(tree, problems)


def read_task_tree(path) -> list[Event]:
    """The task-tree events of a trace: a trace of the project (``run``, ``simulate``, a ``check``
    counterexample) read as its ROAR task tree (roar_runs), plus any TCA event records in the file."""
    from ..trace.format import read_trace
    from .roar_runs import is_roar_trace, task_tree_events
    path = Path(path)
    from ..inputs import check_input_file
    check_input_file(path, Pos(str(path), 1, 1))
    try:
        with path.open(encoding="utf-8") as handle:
            first = handle.readline()
    except OSError as exc:
        raise RoarError(f"cannot read trace: {exc.strerror}", Pos(str(path), 1, 1)) from None
    except UnicodeDecodeError as exc:
        raise RoarError(f"trace is not UTF-8 text: {exc.reason}", Pos(str(path), 1, 1)) from None
    events = read_events(path)   # TCA records, wherever they are (they may share a ROAR trace)
    if '"roar-formal"' in first:
        header, steps = read_trace(path)
        if is_roar_trace(header):
            return task_tree_events(header, steps, str(path)) + events
    return events


#: said of a ROAR trace checked as the file has it
AS_RECORDED = ("the task tree is read from the trace's own event fields and header pairs, as recorded; "
               "`--model SPEC` replays the trace on the spec and reads them from the model instead")


def check_trace(path, events: Optional[list[Event]] = None) -> CheckReport:
    """Read a trace and check it (``events``: its task-tree events, already read from a model's
    replay). A trace with no task-tree message is an error, not a pass: nothing was checked."""
    from ..inputs import check_input_file
    check_input_file(path, Pos(str(path), 1, 1))   # before any open: a FIFO would block it
    notes = []
    header = _roar_header(path)
    if events is None:
        events = read_task_tree(path)
        if header is not None:
            notes.append(AS_RECORDED)
        if header is not None and not header.get("seq_pairs"):
            notes.append("the trace header names no sequential-achievement pairs (\"seq_pairs\"): no SeqAch "
                         "between requests is checked")
    report = check_events(events)
    report.notes = notes + report.notes
    if not report.tree.messages:
        raise RoarError("the trace holds no task-tree message (no request, no primitive call, no "
                        "constraint_sent record): there is nothing to check", Pos(str(path), 1, 1))
    return report


def _roar_header(path) -> Optional[dict]:
    """The header of a ROAR trace (None: a file of TCA records only): its first line alone (the
    whole file is read, with its errors located, by :func:`read_task_tree`)."""
    import json
    from .roar_runs import is_roar_trace
    try:
        with Path(path).open(encoding="utf-8") as handle:
            header = json.loads(handle.readline())
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return None
    return header if isinstance(header, dict) and is_roar_trace(header) else None


def _named(m: Message) -> str:
    """What a message is, as the trace names it (`` 'jaw::press()' by jaw``), for a violation's text."""
    what = f" '{m.constraint}'" if m.constraint else ""
    return what + (f" by {m.agent}" if m.agent and m.constraint and "::" not in m.constraint else "")
