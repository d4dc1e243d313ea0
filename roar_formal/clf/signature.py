"""Signatures and type reconstruction: surface syntax to checked, internal CLF.

LF-style checking with unification: free upper-case variables of a declaration
and unsolved implicit arguments of the constants it uses become implicit
``Pi`` binders in front of it (as in Twelf and Celf); every use of a constant
then receives fresh logic variables for its implicit arguments. Positive
types on the left of an arrow are curried away (``A * B -o C`` is
``A -o B -o C``, ``Exists x. A -o C`` is ``Pi x. A -o C``, ``!A -o C`` is
``A -> C``). Anything the engine does not support is refused with a message
that names the construct.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from ..errors import Pos, TypeError_, UnsupportedError
from . import surface as S
from .parser import parse_program
from .builtins import BUILTIN_FAMILIES, BUILTIN_TYPES, BUILTINS, is_builtin, kind_of
from .printer import show
from .terms import (NUMBER, STRING, Aff, Bang, BVar, Const, EVar, Exists, Imp, Lam, Monad, Node, One, Param, Pi, Root,
                    Tensor, Top, Type, TypeNode, With, abstract, apply, deref, free_evars, num_term, param_term,
                    string_term, subst, subst1, zonk)
from .unify import Unifier


class ModeError(TypeError_):
    """A clause that is not well-moded for its family's ``#mode`` declaration (Celf's "mode error")."""


@dataclass
class ConstInfo:
    """A declared constant or type family with its reconstructed classifier."""

    name: str
    const: Const
    classifier: Node  # closed kind (families) or type (constants), implicit Pis first
    implicit: int
    is_family: bool
    pos: Pos
    definition: Optional[Node] = None
    builtin: bool = False  # predeclared by the built-in domain of numbers and strings
    proof: bool = False  # a definition by a proof term (lambdas, monadic lets): type-checked, kept opaque


_BUILTIN_POS = Pos("<built-in>", 1, 1)
#: the predeclared families of the built-in domain (``number``, ``string``, tests, functions)
BUILTIN_INFOS: dict[str, ConstInfo] = {
    c.name: ConstInfo(c.name, c, Type(), 0, True, _BUILTIN_POS, builtin=True) for c in BUILTIN_TYPES}
BUILTIN_INFOS.update({
    b.name: ConstInfo(b.name, b.const, kind_of(b), 0, True, _BUILTIN_POS, builtin=True) for b in BUILTINS.values()})


@dataclass
class QueryDirective:
    pos: Pos
    depth: object
    expected: object
    look: object
    attempts: object
    goal: Node
    logic_vars: list  # (name, EVar) in order of first occurrence
    prefix: int = -1  # how many declarations precede it (it sees only those); -1: all
    bounds_pos: tuple = ()  # the positions of d, e, l, a (Celf's checks of the bounds are located there)


@dataclass
class ExecDirective:
    pos: Pos
    steps: object
    start: Node
    trace: bool
    prefix: int = -1  # how many declarations precede it (it sees only those); -1: all


@dataclass
class Signature:
    """Constants in declaration order, plus the directives in program order.

    ``consts`` holds the program's own declarations; the families of the built-in
    domain are predeclared in every signature and found through :meth:`lookup`."""

    consts: dict[str, ConstInfo] = field(default_factory=dict)
    directives: list = field(default_factory=list)
    modes: dict[str, tuple] = field(default_factory=dict)
    implicit_modes: dict[str, tuple] = field(default_factory=dict)  # from ``#mode p {+} ...``
    file: str = "<input>"

    def lookup(self, name: str) -> Optional[ConstInfo]:
        info = self.consts.get(name)
        return info if info is not None else BUILTIN_INFOS.get(name)


_LAM_MARK = {"linear": "", "affine": "@", "persistent": "!"}


def _is_kind(e: S.Expr) -> bool:
    while True:
        if isinstance(e, S.TypeKw):
            return True
        if isinstance(e, S.Pi):
            e = e.body
        elif isinstance(e, S.Arrow) and e.op == "->":
            e = e.right
        else:
            return False


def _is_upper(name: str) -> bool:
    return name[:1].isupper()


class Elaborator:
    """Elaborates one program item at a time into a :class:`Signature`."""

    def __init__(self, sig: Signature, strict: bool = False):
        self.sig = sig
        # Celf's typing of persistent functions: `\x.` is a linear lambda and `L a` a linear
        # application, so a persistent function is written `\!x. M` and applied as `L !a`
        # when L is a bound variable (constants and upper-case variables take `a` as `!a`)
        self.strict = strict
        self.proof = False
        self.usage: dict = {}
        # implicit-argument counts of the constants declared so far (how messages print terms)
        self.implicit = {info.const: info.implicit for info in sig.consts.values()}

    # ------------------------------------------------------------ entry points
    def declare(self, d: S.Decl) -> ConstInfo:
        if is_builtin(d.name):
            raise TypeError_(f"'{d.name}' is reserved by the built-in domain of numbers and strings "
                             "(it is predeclared in every program)", d.pos)
        if d.name in self.sig.consts:
            prev = self.sig.consts[d.name]
            raise TypeError_(f"'{d.name}' is already declared (at {prev.pos})", d.pos)
        self._begin()
        is_family = _is_kind(d.classifier)
        if is_family:
            cls = self.kind(d.classifier)
        else:
            cls = self.neg(d.classifier)
        definition = None
        proof = False
        if d.definition is not None:
            if is_family:
                _refuse_proof_terms(d.definition)
                if not isinstance(d.classifier, S.TypeKw):
                    raise UnsupportedError("type abbreviations with arguments are not supported", d.pos)
                definition = self.neg(d.definition)
            elif _is_proof_type(cls) or _has_proof_syntax(d.definition):
                # a proof term (Celf's objects: linear lambdas, {let {p} = M in E}, [M, N], ...):
                # type-checked with Celf's typing and linearity, then kept as an opaque constant
                proof = True
                self.proof = True
                try:
                    self.check(d.definition, cls)
                finally:
                    self.proof = False
                definition = Root(Const(d.name), ())
            else:
                definition = self.check(d.definition, cls)
        self._solve_postponed(d.pos)
        if not is_family:
            _refuse_builtin_conclusion(cls, d.name, d.pos)
        cls, n, definition = self._generalise(cls, d.pos, definition if not proof else None)
        if proof:
            definition = Root(Const(d.name), ())
        info = ConstInfo(d.name, Const(d.name), cls, n, is_family, d.pos, definition, proof=proof)
        self.sig.consts[d.name] = info
        self.implicit[info.const] = n
        return info

    def query(self, q: S.Query) -> QueryDirective:
        self._begin()
        goal = self.neg(q.goal)
        self._solve_postponed(q.pos)
        goal = zonk(goal)
        named = [(n, x) for n, x in self.free.items()]
        return QueryDirective(q.pos, q.depth, q.expected, q.look, q.attempts, goal, named, len(self.sig.consts),
                              bounds_pos=q.bounds_pos)

    def exec_(self, e: S.Exec) -> ExecDirective:
        self._begin()
        start = self.pos(e.start)
        self._solve_postponed(e.pos)
        if self.free:
            name = next(iter(self.free))
            raise TypeError_(f"unbound variable '{name}' in the start context of #exec", e.pos)
        start = zonk(start)
        left = free_evars(start)
        if left:
            raise TypeError_("the start context of #exec has parts that cannot be inferred", e.pos)
        return ExecDirective(e.pos, e.steps, start, e.trace, len(self.sig.consts))

    # ------------------------------------------------------------ state
    def _begin(self) -> None:
        self.proof = False  # checking a proof term (a definition's body): linear objects allowed
        self.usage: dict = {}  # proof variable (Param) -> [mode, times used], for linearity
        self.u = Unifier()
        self.free: dict[str, Root] = {}  # implicit (free upper-case) variables
        self.bound: list[tuple[str, Param]] = []
        self.ptype: dict[Param, Node] = {}
        self.evars: list[EVar] = []  # every logic variable made for this item
        self.binder_pos: dict = {}    # the type variable of an untyped binder -> where the binder is

    def _evar(self, name: str, ty: Optional[Node], scope_of: Optional[EVar] = None) -> EVar:
        x = EVar(name, ty)
        if scope_of is not None:
            x.scope = scope_of.scope
        self.evars.append(x)
        return x

    def _unify(self, a: Node, b: Node, pos: Pos, what: str) -> None:
        if not self.u.unify(a, b):
            raise TypeError_(f"type mismatch in {what}", pos, self._mismatch(a, b))

    def _mismatch(self, want: Node, got: Node) -> list[str]:
        """The notes of a type mismatch: both types, and what ``T`` is when one of them is it."""
        notes = [f"expected: {self._show(want)}", f"found:    {self._show(got)}"]
        if any(type(zonk(t)) is Top for t in (want, got)):
            notes.append("'T' is CLF's top type (the unit of &), never a variable (and CLF has no type "
                         "variables: index by a type of type codes, e.g. 'tp : type.')")
        return notes

    def _show(self, t: Node) -> str:
        names = [n for n, _ in self.bound]
        return show(zonk(t) if not t.maxp else zonk(self._close(t)), names, implicit=self.implicit)

    def _close(self, t: Node) -> Node:
        return abstract(zonk(t), [p for _, p in self.bound]) if self.bound else t

    def _solve_postponed(self, pos: Pos) -> None:
        if not self.u.solved():
            a, b = self.u.postponed[0]
            raise TypeError_(
                "cannot solve a unification constraint outside the higher-order pattern fragment",
                pos,
                [f"{self._show(a)}  =  {self._show(b)}"],
            )

    def _open(self, name: str, ty: Node) -> Param:
        p = Param(name)
        self.bound.append((name, p))
        self.ptype[p] = ty
        return p

    def _close_binder(self, p: Param, body: Node) -> Node:
        """Leave the scope of ``p``: unsolved variables inside may no longer mention it."""
        self.bound.pop()
        for x in free_evars(body):
            if x.scope > p.id:
                x.scope = p.id
        return abstract(body, [p])

    def _generalise(self, cls: Node, pos: Pos, definition: Optional[Node]):
        """Abstract unsolved logic variables as implicit Pi binders, dependencies first."""
        cls = zonk(cls)
        pending = free_evars(cls)
        if definition is not None:
            definition = zonk(definition)
            extra = [x for x in free_evars(definition) if x not in pending]
            if extra:
                raise TypeError_("the definition has parts that cannot be inferred", pos)
        # close over types of the variables too, and order by dependency
        order: list[EVar] = []
        seen: set = set()

        def visit(x: EVar, chain: tuple) -> None:
            if x in seen:
                return
            if x in chain:
                raise TypeError_("circular dependency between implicit arguments", pos)
            if x.ty is None:
                raise TypeError_(f"cannot infer the type of '{self._name_of(x)}'", self.binder_pos.get(x, pos))
            ty = zonk(x.ty)
            x.ty = ty
            for y in free_evars(ty):
                visit(y, chain + (x,))
            seen.add(x)
            order.append(x)

        for x in sorted(pending, key=lambda e: e.uid):
            visit(x, ())
        for x in order:
            if isinstance(x.ty, Root) and type(x.ty.head) is EVar:
                raise TypeError_(f"cannot infer the type of '{self._name_of(x)}'", self.binder_pos.get(x, pos))
            if isinstance(x.ty, TypeNode) and type(x.ty) is Type and x.name.startswith("ty_"):
                # the unknown type of a binder or variable that nothing in the declaration constrains
                name = x.name[3:]
                raise TypeError_(f"cannot infer the type of '{name}': nothing in the declaration tells it; write "
                                 f"it ('{name}:A', as in 'Exists {name}:A.' or 'Pi {name}:A.')",
                                 self.binder_pos.get(x, pos))
            if isinstance(x.ty, TypeNode) and type(x.ty) is Type:
                raise TypeError_(f"'{self._name_of(x)}' would have to be a type; CLF has no type variables "
                                 "(declare a type of type codes, e.g. 'tp : type.', and index by it)", pos)
        params = []
        types = []
        for x in order:
            types.append(abstract(zonk(x.ty), params) if params else zonk(x.ty))
            p = Param(x.name)
            params.append(p)
            x.ref = param_term(p)
        body = abstract(zonk(cls), params) if params else cls
        if definition is not None and params:
            definition = abstract(zonk(definition), params)
        for x, ty in zip(reversed(order), reversed(types)):
            body = Pi(x.name, ty, body)
        if body.evars:
            raise TypeError_("internal: unsolved variables remain after generalisation", pos)
        return body, len(order), definition

    def _name_of(self, x: EVar) -> str:
        for n, r in self.free.items():
            if r.head is x:
                return n
        return x.name

    # ------------------------------------------------------------ kinds
    def kind(self, e: S.Expr) -> Node:
        if isinstance(e, S.TypeKw):
            return Type()
        if isinstance(e, S.Pi):
            dom = self.neg(e.ty) if e.ty is not None else self._type_evar(e.var, e.pos)
            p = self._open(e.var, dom)
            body = self.kind(e.body)
            return Pi(e.var, dom, self._close_binder(p, body))
        if isinstance(e, S.Arrow) and e.op == "->":
            dom = self.neg(e.left)
            return Imp("!", dom, self.kind(e.right))
        raise TypeError_("expected a kind (ending in 'type')", e.pos)

    def _type_evar(self, name: str, pos: Optional[Pos] = None) -> Root:
        """The unknown type of an untyped binder (``Exists x.``, ``Pi x.``) written at ``pos``."""
        x = self._evar(f"ty_{name}", Type())
        if pos is not None:
            self.binder_pos[x] = pos
        return Root(x, ())

    # ------------------------------------------------------------ negative types
    def neg(self, e: S.Expr) -> Node:
        """An asynchronous (negative) type."""
        if isinstance(e, S.Pi):
            dom = self.neg(e.ty) if e.ty is not None else self._type_evar(e.var, e.pos)
            p = self._open(e.var, dom)
            body = self.neg(e.body)
            return Pi(e.var, dom, self._close_binder(p, body))
        if isinstance(e, S.Arrow):
            mode = {"->": "!", "-o": "1", "-@": "@"}[e.op]
            return self._left(e.left, mode, lambda: self.neg(e.right))
        if isinstance(e, S.With):
            return With(self.neg(e.left), self.neg(e.right))
        if isinstance(e, S.Monad):
            return Monad(self.pos(e.body))
        if isinstance(e, S.Id) and e.name == "T" and not self._is_bound("T") and "T" not in self.sig.consts:
            return Top()
        if isinstance(e, (S.Id, S.App)):
            return self.atom(e)
        if isinstance(e, (S.Tensor, S.Exists, S.Bang, S.Affine, S.One)):
            raise TypeError_(
                f"a positive type ({_describe(e)}) may only appear inside {{ }} or on the left of an arrow", e.pos)
        if isinstance(e, S.TypeKw):
            raise TypeError_("'type' is a kind, not a type", e.pos)
        raise TypeError_(f"expected a type, found {_describe(e)}", e.pos)

    def _left(self, e: S.Expr, mode: str, k):
        """Curry a positive premise ``e`` in front of the body built by ``k``."""
        if isinstance(e, S.Tensor):
            return self._left(e.left, mode, lambda: self._left(e.right, mode, k))
        if isinstance(e, S.One):
            return k()
        if isinstance(e, S.Exists):
            dom = self.neg(e.ty) if e.ty is not None else self._type_evar(e.var, e.pos)
            p = self._open(e.var, dom)
            body = self._left(e.body, mode, k)
            return Pi(e.var, dom, self._close_binder(p, body))
        if isinstance(e, S.Bang):
            return self._left(e.body, "!", k)
        if isinstance(e, S.Affine):
            return self._left(e.body, "@" if mode != "!" else "!", k)
        dom = self.neg(e)
        return Imp(mode, dom, k())

    def _is_bound(self, name: str) -> bool:
        return any(n == name for n, _ in self.bound)

    # ------------------------------------------------------------ positive types
    def pos(self, e: S.Expr) -> Node:
        """A synchronous (positive) type."""
        if isinstance(e, S.Tensor):
            return Tensor(self.pos(e.left), self.pos(e.right))
        if isinstance(e, S.One):
            return One()
        if isinstance(e, S.Exists):
            dom = self.neg(e.ty) if e.ty is not None else self._type_evar(e.var, e.pos)
            p = self._open(e.var, dom)
            body = self.pos(e.body)
            return Exists(e.var, dom, self._close_binder(p, body))
        if isinstance(e, S.Bang):
            return Bang(self._fact(e.body))
        if isinstance(e, S.Affine):
            return Aff(self._fact(e.body))
        return self._fact(e)

    def _fact(self, e: S.Expr) -> Node:
        """A negative type in a positive one: a fact or a rule of a monad or a start context,
        which may not conclude in a built-in family (the engine decides those)."""
        ty = self.neg(e)
        fam = _builtin_conclusion(ty)
        if fam is not None:
            raise TypeError_(
                f"the built-in family '{fam.name}' cannot be a fact or the conclusion of a rule in a monad "
                "or a start context: it is decided by the engine, and may only be a premise", e.pos)
        return ty

    # ------------------------------------------------------------ atoms
    def atom(self, e: S.Expr) -> Node:
        head, args = _spine(e)
        if not isinstance(head, S.Id):
            raise TypeError_(f"expected a type family at the head of an atomic type, found {_describe(head)}", head.pos)
        info = self.sig.lookup(head.name)
        if info is None:
            if self._is_bound(head.name) or _is_upper(head.name):
                raise TypeError_(f"'{head.name}' is a variable, not a type family (CLF has no type variables)", head.pos)
            raise TypeError_(f"unknown type family '{head.name}'", head.pos)
        if not info.is_family:
            raise TypeError_(f"'{head.name}' is a constant, not a type family", head.pos)
        if info.definition is not None:
            if args:
                raise TypeError_(f"type abbreviation '{head.name}' takes no arguments", args[0][0].pos)
            return info.definition
        term, k = self._instantiate(info)
        given = 0
        for arg, mark in args:
            k = deref(k)
            if isinstance(k, Pi):
                a = self.check(arg, k.dom)
                term = apply(term, (a,))
                k = subst1(k.body, a)
            elif isinstance(k, Imp):
                a = self.check(arg, k.dom)
                term = apply(term, (a,))
                k = k.body
            else:
                explicit = _arity(info.classifier) - info.implicit
                raise TypeError_(
                    f"type family '{head.name}' takes {explicit} argument{'s' if explicit != 1 else ''}, "
                    f"given {len(args)}", arg.pos)
            given += 1
        if not isinstance(deref(k), Type):
            explicit = _arity(info.classifier) - info.implicit
            raise TypeError_(
                f"type family '{head.name}' takes {explicit} argument{'s' if explicit != 1 else ''}, given {given}",
                e.pos)
        return term

    def _instantiate(self, info: ConstInfo) -> tuple[Node, Node]:
        term, ty, _ = self._instantiate_all(info)
        return term, ty

    def _instantiate_all(self, info: ConstInfo) -> tuple[Node, Node, list]:
        """The constant applied to fresh logic variables for its implicit arguments,
        the rest of its type, and those variables."""
        term: Node = Root(info.const, ())
        ty = info.classifier
        xs = []
        for _ in range(info.implicit):
            x = Root(self._evar(ty.hint, ty.dom), ())
            xs.append(x)
            term = apply(term, (x,))
            ty = subst1(ty.body, x)
        return term, ty, xs

    # ------------------------------------------------------------ objects
    def infer(self, e: S.Expr) -> tuple[Node, Node]:
        if isinstance(e, S.Id):
            for n, p in reversed(self.bound):
                if n == e.name:
                    use = self.usage.get(p)
                    if use is not None:
                        use[1] += 1
                    return param_term(p), self.ptype[p]
            info = self.sig.lookup(e.name)
            if info is not None:
                if info.is_family:
                    raise TypeError_(f"type family '{e.name}' used as a term", e.pos)
                term, ty, xs = self._instantiate_all(info)
                if info.definition is not None and not info.proof:
                    return (subst(info.definition, list(reversed(xs))) if xs else info.definition), ty
                return term, ty
            if _is_upper(e.name) or e.name.startswith("_"):
                r = self.free.get(e.name)
                if r is None:
                    x = self._evar(e.name, None)
                    x.scope = 0  # a free variable is bound outside everything in the declaration
                    tyv = self._evar(f"ty_{e.name}", Type(), scope_of=x)
                    x.ty = Root(tyv, ())
                    r = Root(x, ())
                    self.free[e.name] = r
                return r, r.head.ty
            raise TypeError_(f"unknown constant '{e.name}'", e.pos)
        if isinstance(e, S.App):
            f, fty = self.infer(e.fn)
            fty = deref(fty)
            if isinstance(fty, Root) and type(fty.head) is EVar:
                fx = fty.head
                a_ty = Root(self._evar("dom", Type(), scope_of=fx), ())
                b_ty = Root(self._evar("cod", Type(), scope_of=fx), ())
                self._unify(fty, Imp("!", a_ty, b_ty), e.pos, "an application")
                fty = deref(fty)
            if self.strict and e.mark is None and (isinstance(fty, Pi) or (isinstance(fty, Imp) and fty.mode == "!")):
                head, _ = _spine(e)
                if isinstance(head, S.Id) and self._is_bound(head.name):
                    raise TypeError_(
                        f"'{head.name}' is a bound variable of a persistent function type, applied to a linear "
                        f"argument: Celf writes the application '{head.name} !...'", e.arg.pos,
                        [f"type of '{head.name}' here: {self._show(fty)}"])
            if isinstance(fty, Pi):
                a = self.check(e.arg, fty.dom)
                return apply(f, (a,)), subst1(fty.body, a)
            if isinstance(fty, Imp):
                if fty.mode != "!" and not self.proof:
                    raise UnsupportedError(
                        "linear or affine function objects as index terms are not supported "
                        f"(applying a term of type {self._show(fty)})", e.pos)
                if self.proof:
                    a = self._proof_arg(e, fty)
                else:
                    a = self.check(e.arg, fty.dom)
                return apply(f, (a,)), fty.body
            raise TypeError_(f"{_describe(e.fn)} is applied to an argument but its type is not a function type",
                             e.pos, [f"type: {self._show(fty)}"])
        if isinstance(e, S.Annot):
            ty = self.neg(e.ty)
            return self.check(e.term, ty), ty
        if isinstance(e, S.Num):
            return num_term(e.value), Root(NUMBER, ())
        if isinstance(e, S.One):  # `1` where a term is expected: the number one
            return num_term(1), Root(NUMBER, ())
        if isinstance(e, S.Str):
            return string_term(e.value), Root(STRING, ())
        if isinstance(e, S.Underscore):
            tyv = Root(self._evar("ty", Type()), ())
            return Root(self._evar("_", tyv), ()), tyv
        if isinstance(e, S.Lam):
            if e.ty is not None:
                dom = self._lam_annotation(e)
                if self.strict and e.mode != "persistent":
                    raise TypeError_(
                        f"the lambda '\\{_LAM_MARK[e.mode]}{e.var}:...' is {e.mode}; where its type is not given "
                        f"from outside only a persistent lambda '\\!{e.var}:!A. M' can be an index term", e.pos)
                p = self._open(e.var, dom)
                body, bty = self.infer(e.body)
                bty = zonk(bty)
                self.bound.pop()
                return Lam(abstract(body, [p])), Pi(e.var, dom, abstract(bty, [p]))
            raise TypeError_("cannot infer the type of this lambda here; annotate it as (\\x. M : A -> B)", e.pos)
        if isinstance(e, (S.Pair, S.Proj)):
            raise UnsupportedError(f"{_describe(e)} as an index term is not supported", e.pos)
        if isinstance(e, (S.Let, S.Tuple, S.PatLam)):
            raise UnsupportedError(f"monadic proof terms as input are not supported ({_describe(e)})", e.pos)
        raise TypeError_(f"expected a term, found {_describe(e)}", e.pos)

    def _lam_annotation(self, e: S.Lam) -> Node:
        """The domain given by a lambda's annotation: `\\x:A`, `\\!x:!A`, `\\@x:@A` (Celf's shapes)."""
        ty = e.ty
        want = {"persistent": S.Bang, "affine": S.Affine}.get(e.mode)
        if want is not None and isinstance(ty, want):
            return self.neg(ty.body)
        if isinstance(ty, (S.Bang, S.Affine)):
            mark = "!" if isinstance(ty, S.Bang) else "@"
            raise TypeError_(f"the pattern '{_LAM_MARK[e.mode]}{e.var}' of this lambda does not match its type "
                             f"'{mark}...'; write '\\{mark}{e.var}:{mark}A'", ty.pos)
        if want is not None and self.strict:
            mark = _LAM_MARK[e.mode]
            raise TypeError_(f"the pattern '{mark}{e.var}' needs a type '{mark}A' (Celf: '\\{mark}{e.var}:{mark}A. M')",
                             ty.pos)
        return self.neg(ty)

    # ------------------------------------------------------------ proof terms (Celf's objects)
    def _linear_uses(self) -> dict:
        return {p: u[1] for p, u in self.usage.items() if u[0] != "persistent"}

    def _no_linear(self, before: dict, pos: Pos, what: str) -> None:
        """A persistent position (`!N`, the argument of `->`) may use no linear or affine variable."""
        for p, n in self._linear_uses().items():
            if n != before.get(p, 0):
                raise TypeError_(f"{what} uses the {self.usage[p][0]} variable '{self._pname(p)}', "
                                 "which a persistent position may not use", pos)

    def _pname(self, p: Param) -> str:
        for n, q in self.bound:
            if q is p:
                return n
        return p.hint

    def _proof_arg(self, e: S.App, fty: Imp) -> Node:
        """The argument of an application in a proof term: `M N` for `-o`, `M @N` for `-@`,
        `M !N` (or a plain argument of a constant) for `->`, with the linearity Celf checks."""
        want = {"1": None, "@": "@", "!": "!"}[fty.mode]
        if e.mark is not None and e.mark != want:
            kind = {"1": "a linear '-o'", "@": "an affine '-@'", "!": "a persistent '->'"}[fty.mode]
            raise TypeError_(f"the argument is marked '{e.mark}' but the function takes {kind} argument", e.arg.pos,
                             [f"function type: {self._show(fty)}"])
        before = self._linear_uses()
        a = self.check(e.arg, fty.dom)
        if fty.mode == "!":
            self._no_linear(before, e.arg.pos, "the argument of a persistent function")
        elif fty.mode == "@":
            for p, n in self._linear_uses().items():
                if n != before.get(p, 0) and self.usage[p][0] == "linear":
                    raise TypeError_(f"the argument of an affine function uses the linear variable "
                                     f"'{self._pname(p)}'", e.arg.pos)
        return a

    def _bind_proof_var(self, name: str, ty: Node, mode: str) -> Param:
        p = self._open(name, ty)
        self.usage[p] = [mode, 0]
        return p

    def _release(self, params: list, pos: Pos) -> None:
        """Leave the scope of proof variables: a linear one must have been used exactly once,
        an affine one at most once (Celf's linearity check)."""
        for p in reversed(params):
            mode, n = self.usage.pop(p)
            name = self._pname(p)
            if mode == "linear" and n != 1:
                raise TypeError_(f"linearity: the linear variable '{name}' is used {n} times "
                                 "(exactly once is required)", pos)
            if mode == "affine" and n > 1:
                raise TypeError_(f"linearity: the affine variable '{name}' is used {n} times "
                                 "(at most once is allowed)", pos)
            idx = max(i for i, (_n, q) in enumerate(self.bound) if q is p)
            del self.bound[idx]

    def _check_proof_lam(self, e: S.Expr, ty: Node) -> Node:
        """``\\x. M`` against ``A -o B``, ``\\@x. M`` against ``A -@ B``, ``\\!x. M`` against ``A -> B``
        or ``Pi x:A. B``; ``\\[p, q]. M`` and ``\\1. M`` against the curried premises."""
        if isinstance(e, S.PatLam):
            pat = e.pattern
            if isinstance(pat, S.POne):
                return self.check(e.body, ty)
            if isinstance(pat, S.PTuple):
                body = e.body
                for item in reversed(pat.items):
                    if isinstance(item, S.PVar):
                        body = S.Lam(item.pos, item.name, body, item.mode)
                    else:
                        body = S.PatLam(item.pos, item, None, body)
                return self.check(body, ty)
            raise TypeError_("this lambda pattern does not match the type", e.pos, [f"type: {self._show(ty)}"])
        mode = {"!": "persistent", "1": "linear", "@": "affine"}[ty.mode] if isinstance(ty, Imp) else "persistent"
        if e.mode != mode:
            mark = _LAM_MARK[mode]
            raise TypeError_(f"a {e.mode} lambda '\\{_LAM_MARK[e.mode]}{e.var}.' is given where a {mode} function is "
                             f"expected: Celf writes '\\{mark}{e.var}. ...'", e.pos,
                             [f"expected: {self._show(ty)}"])
        if e.ty is not None:
            self._unify(ty.dom, self._lam_annotation(e), e.ty.pos, "the type of a lambda's variable")
        p = self._bind_proof_var(e.var, ty.dom, mode)
        if isinstance(ty, Pi):
            body_ty = subst1(ty.body, param_term(p))
        else:
            body_ty = ty.body
        body = self.check(e.body, body_ty)
        self._release([p], e.pos)
        self.bound.append((e.var, p))  # _close_binder pops it again
        return Lam(self._close_binder(p, body))

    def _check_monad(self, e: S.Expr, s: Node) -> Node:
        """The inside of ``{E}`` against the positive type ``S``: lets, then a monadic object."""
        if isinstance(e, S.Let):
            m, mty = self.infer(e.value)
            mty = deref(mty)
            if not isinstance(mty, Monad):
                raise TypeError_("the right-hand side of 'let {p} = M' must have a monadic type {S}", e.value.pos,
                                 [f"type: {self._show(mty)}"])
            params = self._bind_pattern(e.pattern, mty.body)
            self._check_monad(e.body, s)
            self._release(params, e.pos)
            return Root(Const("{let}"), ())
        return self._check_mon_obj(e, s)

    def _bind_pattern(self, pat: S.Expr, s: Node) -> list:
        """Bind a let pattern against the positive type it destructures: ``[p, q]`` for
        ``S1 * S2``, ``[!x, p]`` for ``Exists x:A. S``, ``1``, ``!x`` for ``!A``, ``@x`` for
        ``@A``, ``x`` for a linear type."""
        s = deref(s)
        if isinstance(pat, S.PTuple) and len(pat.items) > 2:
            pat = S.PTuple(pat.pos, (pat.items[0], S.PTuple(pat.items[1].pos, pat.items[1:])))
        if isinstance(s, Tensor):
            if not isinstance(pat, S.PTuple):
                raise TypeError_(f"the pattern does not match the type {self._show(s)} (Celf's pattern: [p, q])",
                                 pat.pos)
            left = self._bind_pattern(pat.items[0], s.left)
            return left + self._bind_pattern(pat.items[1], s.right)
        if isinstance(s, One):
            if not isinstance(pat, S.POne):
                raise TypeError_("the pattern does not match the type 1 (Celf's pattern: 1)", pat.pos)
            return []
        if isinstance(s, Exists):
            if not isinstance(pat, S.PTuple):
                raise TypeError_(f"the pattern does not match the type {self._show(s)} (Celf's pattern: [!x, p])",
                                 pat.pos)
            first = pat.items[0]
            if not isinstance(first, S.PVar) or first.mode == "affine":
                raise TypeError_("the witness of an Exists is bound by a pattern '!x'", first.pos)
            p = self._bind_proof_var(first.name, s.dom, "persistent")
            return [p] + self._bind_pattern(pat.items[1], subst1(s.body, param_term(p)))
        want = "persistent" if isinstance(s, Bang) else "affine" if isinstance(s, Aff) else "linear"
        body = s.body if isinstance(s, (Bang, Aff)) else s
        if isinstance(pat, S.PVar) and pat.mode == want:
            return [self._bind_proof_var(pat.name, body, want)]
        shape = {"persistent": "!x", "affine": "@x", "linear": "x"}[want]
        raise TypeError_(f"the pattern does not match the type {self._show(s)} (Celf's pattern: {shape})", pat.pos)

    def _check_mon_obj(self, e: S.Expr, s: Node) -> Node:
        """A monadic object against a positive type: ``[M, N]``, ``1``, ``!M``, ``@M``, ``[!N, M]``."""
        s = deref(s)
        if isinstance(e, S.Tuple) and len(e.items) > 2:
            e = S.Tuple(e.pos, (e.items[0], S.Tuple(e.items[1].pos, e.items[1:])))
        if isinstance(s, Tensor):
            if not isinstance(e, S.Tuple):
                raise TypeError_(f"expected a monadic object [M, N] of type {self._show(s)}", e.pos)
            self._check_mon_obj(e.items[0], s.left)
            return self._check_mon_obj(e.items[1], s.right)
        if isinstance(s, One):
            if not isinstance(e, S.One):
                raise TypeError_("expected the monadic object 1", e.pos)
            return Root(Const("{1}"), ())
        if isinstance(s, Exists):
            if not isinstance(e, S.Tuple):
                raise TypeError_(f"expected a monadic object [!N, M] of type {self._show(s)}", e.pos)
            w = e.items[0].body if isinstance(e.items[0], S.Bang) else e.items[0]
            before = self._linear_uses()
            n = self.check(w, s.dom)
            self._no_linear(before, w.pos, "the witness of an Exists")
            return self._check_mon_obj(e.items[1], subst1(s.body, n))
        if isinstance(s, Bang):
            if not isinstance(e, S.Bang):
                raise TypeError_(f"expected a monadic object !M of type {self._show(s)}", e.pos)
            before = self._linear_uses()
            self.check(e.body, s.body)
            self._no_linear(before, e.pos, "'!M'")
            return Root(Const("{!}"), ())
        if isinstance(s, Aff):
            if not isinstance(e, S.Affine):
                raise TypeError_(f"expected a monadic object @M of type {self._show(s)}", e.pos)
            return self.check(e.body, s.body, "the monadic object")
        return self.check(e, s, "the monadic object")

    def _check_pair(self, e: S.Pair, ty: With) -> Node:
        """``<M, N>`` against ``A & B``: both halves use the same linear variables."""
        start = self._linear_uses()
        self.check(e.left, ty.left)
        after_left = self._linear_uses()
        for p, n in start.items():
            self.usage[p][1] = n
        self.check(e.right, ty.right)
        if self._linear_uses() != after_left:
            raise TypeError_("the two halves of '<M, N>' must use the same linear variables", e.pos)
        return Root(Const("<>"), ())

    def check(self, e: S.Expr, ty: Node, role: str = "the argument") -> Node:
        """Check ``e`` against ``ty``; ``role`` names what ``e`` is in a type mismatch."""
        ty = deref(ty)
        if self.proof:
            if isinstance(e, (S.Lam, S.PatLam)) and isinstance(ty, (Pi, Imp)):
                return self._check_proof_lam(e, ty)
            if isinstance(ty, Monad):
                if not isinstance(e, S.Monad):
                    m, got = self.infer(e)
                    self._unify(ty, got, e.pos, "a monadic term")
                    return m
                return self._check_monad(e.body, ty.body)
            if isinstance(ty, With) and isinstance(e, S.Pair):
                return self._check_pair(e, ty)
            if isinstance(e, (S.Let, S.Tuple, S.Monad, S.Pair)):
                raise TypeError_(f"{_describe(e)} is given where a term of type {self._show(ty)} is expected", e.pos)
        if isinstance(e, S.Lam) and (e.ty is not None and isinstance(deref(ty), (Pi, Imp))):
            dom = self._lam_annotation(e)
            self._unify(deref(ty).dom, dom, e.ty.pos, "the type of a lambda's variable")
            e = S.Lam(e.pos, e.var, e.body, e.mode, None)
        if isinstance(e, S.Lam) and e.ty is None:
            if self.strict and e.mode != "persistent" and isinstance(ty, Pi) or (
                    self.strict and e.mode != "persistent" and isinstance(ty, Imp) and ty.mode == "!"):
                raise TypeError_(
                    f"a {e.mode} lambda '\\{_LAM_MARK[e.mode]}{e.var}.' is given where a persistent function is "
                    f"expected: Celf writes '\\!{e.var}. ...'", e.pos, [f"expected: {self._show(ty)}"])
            if isinstance(ty, Root) and type(ty.head) is EVar:
                fx = ty.head
                a_ty = Root(self._evar("dom", Type(), scope_of=fx), ())
                b_ty = Root(self._evar("cod", Type(), scope_of=fx), ())
                self._unify(ty, Imp("!", a_ty, b_ty), e.pos, "a lambda")
                ty = deref(ty)
            if isinstance(ty, Pi):
                p = self._open(e.var, ty.dom)
                body = self.check(e.body, subst1(ty.body, param_term(p)))
                return Lam(self._close_binder(p, body))
            if isinstance(ty, Imp):
                if ty.mode != "!":
                    raise UnsupportedError("linear or affine lambdas as index terms are not supported", e.pos)
                p = self._open(e.var, ty.dom)
                body = self.check(e.body, ty.body)
                return Lam(self._close_binder(p, body))
            raise TypeError_("a lambda is given where a term of a non-function type is expected", e.pos,
                             [f"expected: {self._show(ty)}"])
        if isinstance(e, S.Underscore):
            return Root(self._evar("_", ty), ())
        term, got = self.infer(e)
        if not self.u.unify(ty, got):
            # name the argument by its text: "_describe" would only say "an application"
            what = _describe(e) if isinstance(e, S.Id) else f"'{self._show(term)}'"
            raise TypeError_(f"type mismatch in {role} {what}", e.pos, self._mismatch(ty, got))
        return term


def _is_proof_type(ty: Node) -> bool:
    """Is a definition of this type a proof term (its type mentions a monad, a linear or affine
    implication, ``&`` or ``T``) rather than an index term?"""
    stack = [ty]
    while stack:
        t = stack.pop()
        tt = type(t)
        if tt is Monad or tt is With or tt is Top or (tt is Imp and t.mode != "!"):
            return True
        if tt is Pi or tt is Imp:
            stack.append(t.body)
    return False


def _has_proof_syntax(e: S.Expr) -> bool:
    stack = [e]
    while stack:
        x = stack.pop()
        if isinstance(x, (S.Monad, S.Let, S.Tuple, S.PatLam, S.Pair)):
            return True
        for v in vars(x).values():
            if isinstance(v, S.Node):
                stack.append(v)
    return False


def _refuse_proof_terms(e: S.Expr) -> None:
    """Monadic proof terms are read but not checked: refuse them where they occur."""
    stack = [e]
    while stack:
        x = stack.pop()
        if isinstance(x, (S.Monad, S.Let, S.Tuple, S.PatLam)):
            what = {S.Monad: "a monadic object '{...}'", S.Let: "'let {p} = M in E'",
                    S.Tuple: "a tuple '[M, N]'", S.PatLam: "a lambda with a pattern"}[type(x)]
            raise UnsupportedError(f"monadic proof terms as input are not supported ({what} in a definition)",
                                   x.pos)
        for v in vars(x).values():
            if isinstance(v, S.Node):
                stack.append(v)
            elif isinstance(v, tuple):
                stack.extend(i for i in v if isinstance(i, S.Node))


def _builtin_conclusion(ty: Node) -> Optional[Const]:
    """The built-in family a negative type concludes in (either half of an ``&``), if any."""
    stack = [ty]
    while stack:
        t = stack.pop()
        tt = type(t)
        if tt is Pi or tt is Imp:
            stack.append(t.body)
        elif tt is With:
            stack.extend((t.left, t.right))
        elif tt is Root and t.head in BUILTIN_FAMILIES:
            return t.head
    return None


def _refuse_builtin_conclusion(cls: Node, name: str, pos: Pos) -> None:
    fam = _builtin_conclusion(cls)
    if fam is None:
        return
    if fam in BUILTIN_TYPES:
        raise TypeError_(f"'{name}' cannot be declared of type {fam.name}: the elements of the built-in "
                         "types number and string are their literals only", pos)
    raise TypeError_(f"'{name}' would be a clause of the built-in family '{fam.name}', which the engine "
                     "decides itself: no declaration may conclude in a built-in family", pos)


def _spine(e: S.Expr):
    args = []
    while isinstance(e, S.App):
        args.append((e.arg, e.mark))
        e = e.fn
    args.reverse()
    return e, args


def _arity(k: Node) -> int:
    n = 0
    while isinstance(k, (Pi, Imp)):
        n += 1
        k = k.body
    return n


def _describe(e: S.Expr) -> str:
    names = {
        S.Id: lambda e: f"'{e.name}'", S.TypeKw: lambda e: "'type'", S.One: lambda e: "'1'",
        S.Underscore: lambda e: "'_'", S.App: lambda e: "an application", S.Lam: lambda e: "a lambda",
        S.Pi: lambda e: "a Pi type", S.Exists: lambda e: "an Exists type", S.Arrow: lambda e: f"an implication '{e.op}'",
        S.Tensor: lambda e: "a tensor '*'", S.With: lambda e: "a conjunction '&'", S.Bang: lambda e: "'!'",
        S.Affine: lambda e: "'@'", S.Monad: lambda e: "a monad '{...}'", S.Pair: lambda e: "a pair '<M, N>'",
        S.Proj: lambda e: "a projection", S.Annot: lambda e: "an annotation",
        S.Num: lambda e: f"the number literal '{e.text or e.value}'",
        S.Str: lambda e: "a string literal",
        S.Let: lambda e: "'let {p} = M in E'", S.Tuple: lambda e: "a tuple '[M, N]'",
        S.PatLam: lambda e: "a lambda with a pattern",
    }
    return names.get(type(e), lambda e: type(e).__name__)(e)


def _declare_mode(sig: Signature, item: S.Mode) -> None:
    info = sig.lookup(item.family)
    if info is None or not info.is_family:
        raise TypeError_(f"#mode names '{item.family}', which is not a declared type family", item.pos)
    explicit = _arity(info.classifier) - info.implicit
    if len(item.modes) != explicit:
        raise TypeError_(f"#mode for '{item.family}' gives {len(item.modes)} modes for {explicit} arguments",
                         item.pos)
    if item.implicit is not None and len(item.implicit) != info.implicit:
        raise TypeError_(f"#mode for '{item.family}' gives {len(item.implicit)} modes in braces for "
                         f"{info.implicit} implicit argument{'s' if info.implicit != 1 else ''}", item.pos)
    sig.modes[item.family] = item.modes
    if item.implicit is not None:
        sig.implicit_modes[item.family] = item.implicit


def _vars_of(t: Node, depth: int, acc: set, lam: int = 0) -> None:
    """The outer binders (numbered from the outside, 0 first) that a term mentions."""
    if not t.maxb:
        return
    tt = type(t)
    if tt is Root:
        h = t.head
        if type(h) is BVar and h.index >= lam:
            acc.add(depth - 1 - (h.index - lam))
        for a in t.args:
            _vars_of(a, depth, acc, lam)
    elif tt is Lam:
        _vars_of(t.body, depth, acc, lam + 1)
    elif isinstance(t, TypeNode):
        for f in type(t).fields:
            v = getattr(t, f)
            if isinstance(v, Node):
                _vars_of(v, depth, acc, lam + (1 if isinstance(t, (Pi, Exists)) and f == "body" else 0))


def _modes_of(sig: Signature, fam: Const) -> Optional[tuple]:
    """The mode of every argument of a moded family, implicit ones first ('*': not checked)."""
    modes = sig.modes.get(fam.name)
    if modes is None:
        return None
    info = sig.lookup(fam.name)
    implicit = sig.implicit_modes.get(fam.name) or _implicit_modes(info, modes)
    return tuple(implicit) + tuple(modes)


def _implicit_modes(info: ConstInfo, modes: tuple) -> tuple:
    """The modes of a family's implicit arguments that ``#mode`` leaves out, inferred as Twelf and
    Celf infer them: input when the argument occurs in the type of an input argument, else
    output when it occurs in the type of an output one, else unchecked ('*')."""
    n = info.implicit
    if not n:
        return ()
    ins: set = set()
    outs: set = set()
    t, depth, k = info.classifier, 0, 0
    while isinstance(t, (Pi, Imp)):
        if depth + (1 if isinstance(t, Pi) else 0) > n or isinstance(t, Imp):   # an explicit argument
            if k < len(modes):
                _vars_of(t.dom, depth, ins if modes[k] == "+" else outs if modes[k] == "-" else set())
            k += 1
        if isinstance(t, Pi):
            depth += 1
        t = t.body
    return tuple("+" if i in ins else "-" if i in outs else "*" for i in range(n))


def mode_check(sig: Signature, info: ConstInfo) -> None:
    """Celf's mode check of a backward clause ``Pi xs. A1 -> ... -> p ts`` for a moded family.

    The variables in the head's input (``+``) arguments are ground when the clause is
    used; each premise (solved innermost first, as proof search does) needs its inputs
    ground and makes its outputs ground; at the end every variable of the head's
    output (``-``) arguments must be ground."""
    ty = info.classifier
    names: list[str] = []
    premises: list[tuple[Node, int]] = []
    while True:
        tt = type(ty)
        if tt is Pi:
            names.append(ty.hint)
            ty = ty.body
        elif tt is Imp:
            premises.append((ty.dom, len(names)))
            ty = ty.body
        else:
            break
    if type(ty) is not Root or not isinstance(ty.head, Const):
        return
    modes = _modes_of(sig, ty.head)
    if modes is None:
        return
    depth = len(names)
    known: set = set()
    for m, a in zip(modes, ty.args):
        if m == "+":
            _vars_of(a, depth, known)
    fam = ty.head.name
    shown = " ".join(sig.modes[fam])
    for prem, d in reversed(premises):
        pm = _modes_of(sig, prem.head) if type(prem) is Root and isinstance(prem.head, Const) else None
        if pm is None:
            _vars_of(prem, d, known)
            continue
        for k, (m, a) in enumerate(zip(pm, prem.args)):
            if m != "+":
                continue
            need: set = set()
            _vars_of(a, d, need)
            missing = sorted(need - known)
            if missing:
                raise ModeError(
                    f"mode error: {names[missing[0]]} not necessarily ground (an input of the premise "
                    f"'{prem.head.name}' in '{info.name}')", info.pos,
                    [f"#mode {prem.head.name} {' '.join(sig.modes[prem.head.name])}"])
        for m, a in zip(pm, prem.args):
            if m != "+":
                _vars_of(a, d, known)
    for k, (m, a) in enumerate(zip(modes, ty.args)):
        if m not in ("-", "-D"):
            continue
        need = set()
        _vars_of(a, depth, need)
        missing = sorted(need - known)
        if missing:
            raise ModeError(f"mode error: {names[missing[0]]} not necessarily ground (an output of '{info.name}')",
                            info.pos, [f"#mode {fam} {shown}"])


def elaborate_steps(program: S.Program, sig: Optional[Signature] = None, strict: bool = False):
    """Check a parsed program one item at a time, as Celf does, yielding the signature
    after each item together with the directive it made (or None)."""
    sig = sig if sig is not None else Signature(file=program.file)
    el = Elaborator(sig, strict)
    for item in program.items:
        directive = None
        if isinstance(item, S.Decl):
            info = el.declare(item)
            if sig.modes and not info.is_family and info.definition is None:
                mode_check(sig, info)
        elif isinstance(item, S.Query):
            directive = el.query(item)
            sig.directives.append(directive)
        elif isinstance(item, S.Exec):
            directive = el.exec_(item)
            sig.directives.append(directive)
        elif isinstance(item, S.Mode):
            _declare_mode(sig, item)
        yield sig, directive


def extend_signature(base: Signature, items, file: str = "<extension>", failed: Optional[list] = None) -> Signature:
    """A copy of ``base`` extended with ``items``: syntax trees (declarations and directives, as a
    compiler builds them) or CLF text, checked one item at a time (positions in errors of text
    refer to the text alone). ``base`` is not changed. ``failed``, when given, gets the item that
    did not check (an error names the item, whatever positions its nodes have)."""
    sig = Signature(dict(base.consts), list(base.directives), dict(base.modes), dict(base.implicit_modes), file)
    program = parse_program(items, file) if isinstance(items, str) else S.Program(file, tuple(items))
    done = 0
    try:
        for _ in elaborate_steps(program, sig):
            done += 1
    except Exception:
        if failed is not None and done < len(program.items):
            failed.append(program.items[done])
        raise
    return sig


def elaborate(program: S.Program, strict: bool = False) -> Signature:
    """Check every item of a parsed program, in order; the first error stops.

    ``strict``: Celf's typing of persistent functions (``\\!x.`` lambdas, ``L !a``
    applications of bound variables); the library default accepts ``\\x.`` and
    ``L a`` for them too, which the ROAR framework signature relies on."""
    sig = Signature(file=program.file)
    for _ in elaborate_steps(program, sig, strict):
        pass
    return sig
