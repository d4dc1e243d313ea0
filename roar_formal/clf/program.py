"""A loaded CLF program: checked signature, forward templates, backward clauses.

This is the library entry point: ``Program.from_file(path)`` parses,
reconstructs types and compiles; ``program.start_context(S)`` builds a
context; ``program.run(ctx, ...)`` runs committed choice; ``program.steps(ctx)``
and ``program.successor(ctx, choice)`` are the explorer's view.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from .backward import Backward, head_families, memo_answer, prove_premise
from .terms import skip_param_ids
from .builtins import BUILTIN_FAMILIES
from .context import Context
from .forward import Choice, Run, Step, enabled_steps, load_positive, successor
from .parser import parse_file, parse_program
from .rules import Template, compile_rule
from .signature import Signature, elaborate
from .terms import Const, Imp, Monad, Node, Pi, With


def _ends_in_monad(ty: Node) -> bool:
    while True:
        t = type(ty)
        if t is Pi or t is Imp:
            ty = ty.body
        elif t is With:
            return _ends_in_monad(ty.left) or _ends_in_monad(ty.right)
        else:
            return t is Monad


class Program:
    """A checked, compiled CLF signature with its directives."""

    def __init__(self, sig: Signature, upto: Optional[int] = None):
        self.sig = sig
        infos = list(sig.consts.values())
        if upto is not None and 0 <= upto < len(infos):
            infos = infos[:upto]  # a directive sees only the declarations before it
        self._size = len(infos)
        self._prefixes: dict[int, "Program"] = {}
        self.clauses: dict[Const, list[tuple[str, Node]]] = {}
        for info in infos:
            if info.is_family or info.definition is not None:
                continue
            for fam in head_families(info.classifier):
                self.clauses.setdefault(fam, []).append((info.name, info.classifier))
        # families whose goals proof search decides: those with clauses, and the built-in ones
        self.backward_families = frozenset(self.clauses) | BUILTIN_FAMILIES
        self.templates: list[Template] = []
        self.rule_names: list[str] = []
        for info in infos:
            if info.is_family or info.definition is not None:
                continue
            if _ends_in_monad(info.classifier):
                self.templates.extend(compile_rule(info.name, info.classifier, info.pos, self.backward_families))
                self.rule_names.append(info.name)
        self._ctx_cache: dict = {}
        self.implicit = {info.const: info.implicit for info in sig.consts.values()}

    def at(self, prefix: int) -> "Program":
        """The program of the first ``prefix`` declarations (Celf checks and runs a file one
        declaration at a time, so a directive sees only what is declared before it);
        ``self`` when that is every declaration (or ``prefix`` is -1)."""
        if prefix < 0 or prefix >= self._size:
            return self
        p = self._prefixes.get(prefix)
        if p is None:
            p = self._prefixes[prefix] = Program(self.sig, prefix)
        return p

    def premise_families(self, fam) -> tuple:
        """``fam`` and every family a proof of a ``fam`` goal may need a fact of: the premises of
        its clauses, transitively (so a backward-proved premise of a forward rule sees the
        persistent facts of those families in the context). Cached; ``fam`` first."""
        cache = self.__dict__.setdefault("_premise_fams", {})
        out = cache.get(fam)
        if out is None:
            from .backward import premise_atoms
            seen = [fam]
            todo = [fam]
            while todo:
                f = todo.pop()
                for _name, ty in self.clauses.get(f, ()):
                    for g in sorted(premise_atoms(ty), key=lambda c: c.name):
                        if g not in seen:
                            seen.append(g)
                            todo.append(g)
            out = cache[fam] = tuple(seen)
        return out

    def indexed_clauses(self, fam) -> list:
        """The clauses of ``fam`` with their head skeletons (backward.clause_skeleton), cached."""
        cache = self.__dict__.setdefault("_indexed", {})
        out = cache.get(fam)
        if out is None:
            from .backward import clause_skeleton
            out = cache[fam] = [(name, ty, clause_skeleton(ty)) for name, ty in self.clauses.get(fam, ())]
        return out

    # ---------------------------------------------------------- loading
    @classmethod
    def from_file(cls, path: str | Path) -> "Program":
        return cls(elaborate(parse_file(str(path))))

    @classmethod
    def from_text(cls, text: str, file: str = "<input>") -> "Program":
        return cls(elaborate(parse_program(text, file)))

    # ---------------------------------------------------------- contexts
    def compile_context_rule(self, name: str, ty: Node) -> list[Template]:
        """Templates for a rule that lives in a context (cached per type)."""
        alts = self._ctx_cache.get(ty)
        if alts is None:
            alts = compile_rule(name, ty, None, self.backward_families)
            self._ctx_cache[ty] = alts
        return alts

    def start_context(self, s: Node) -> Context:
        """A context holding the closed positive type ``s``."""
        ctx = Context()
        ctx.implicit = self.implicit
        load_positive(ctx, s, self.compile_context_rule)
        return ctx

    def show(self, t: Node) -> str:
        """Print a term or type of this program (implicit arguments hidden)."""
        from .printer import show
        return show(t, implicit=self.implicit)

    def prover(self, bw: Optional[Backward] = None):
        """The callback forward matching uses for premises solved by proof search."""
        return _Prover(bw or Backward(self))

    # ---------------------------------------------------------- running
    def run(self, ctx: Context, max_steps: Optional[int] = None, seed: Optional[int] = 0,
            fair: bool = False, on_step=None) -> tuple[int, bool]:
        """Committed choice in place; returns (steps taken, quiescent)."""
        r = Run(self.templates, ctx, seed=seed, fair=fair, prover=self.prover(), on_step=on_step)
        q = r.run(max_steps)
        return r.steps, q

    def steps(self, ctx: Context) -> list[Choice]:
        """Every enabled step of ``ctx`` (explorer API). The explorer's states are ground: a
        context holding logic variables (open facts) is refused."""
        if ctx.open:
            from ..errors import UnsupportedError
            raise UnsupportedError("exploring a state whose facts hold logic variables is not supported "
                                   "(a rule with a Pi variable only in its head, or a query's logic variable); "
                                   "#query and #exec run such programs")
        return list(enabled_steps(self.templates, ctx, self.prover()))

    def successor(self, ctx: Context, choice: Choice) -> tuple[Context, Step]:
        return successor(ctx, choice)


class _Prover:
    """The callback forward matching uses for premises solved by proof search; ``bw`` is the
    proof search it runs (whose unifier the general matching path also uses)."""

    __slots__ = ("bw",)

    def __init__(self, bw: Backward):
        self.bw = bw

    def __call__(self, ctx, tpl, p, b, trail, consumed=()):
        return prove_premise(self.bw, ctx, tpl, p, b, trail, consumed)

    def quick(self, ctx, p, b):
        """The memoised answer of a premise, if any (see :func:`memo_answer`), its skipped
        ids taken as :func:`prove_premise` takes them: the matcher then needs no generator."""
        hit = memo_answer(self.bw, ctx, p, b)
        if hit is not None:
            skip_param_ids(b.count(None) + hit[1])
        return hit
