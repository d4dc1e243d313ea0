"""Hash-consed terms and types of CLF.

Why hash-consing: two structurally equal ground terms are the same Python
object, so equality and hashing are O(1) (identity), facts in a context can be
indexed by their arguments cheaply, and a unary numeral of depth 40,000 costs
nothing to compare. Bound variables are de Bruijn indices; every node records
``maxb`` (how many enclosing binders it reaches through: 0 means closed) and
whether it contains logic variables (``evars``) or pattern slots (``metas``),
so substitution skips closed subterms without walking them.

Terms: ``Root(head, args)`` (head a :class:`Const`, :class:`Param`,
:class:`BVar`, :class:`EVar`, :class:`Meta` or :class:`Lit`) and ``Lam(body)``.
A literal of the built-in domain (a number or a string) is ``Root(Lit(...), ())``:
interned by value, so ``3.0`` and ``3`` are the same term.
Types: ``Root`` with a family head (atoms), ``Pi``, ``Imp`` (``->``, ``-o``,
``-@``), ``With``, ``Top``, ``Monad``; positive types ``Tensor``, ``One``,
``Exists``, ``Bang``, ``Aff``; kinds ``Type`` (and ``Pi``/``Imp`` over it).
"""

from __future__ import annotations

import itertools
from decimal import Decimal
from fractions import Fraction

# ---------------------------------------------------------------- heads


class Head:
    __slots__ = ()


class Const(Head):
    """A signature constant or type family (interned by name)."""

    __slots__ = ("name",)
    _table: dict[str, "Const"] = {}

    def __new__(cls, name: str) -> "Const":
        c = cls._table.get(name)
        if c is None:
            c = object.__new__(cls)
            c.name = name
            cls._table[name] = c
        return c

    def __repr__(self) -> str:
        return self.name


class Lit(Head):
    """A literal of the built-in domain: an exact rational number or a string.

    Interned by (kind, value), so two literals are the same head exactly when
    they denote the same value (``Fraction(3) == Fraction("3.0")``), and a
    literal term ``Root(lit, ())`` is hash-consed like any constant. ``family``
    is the literal's type (``number`` or ``string``), ``text`` its printed form.
    """

    __slots__ = ("value", "family", "text")
    _table: dict[tuple, "Lit"] = {}

    def __new__(cls, value, family: "Const", text: str) -> "Lit":
        key = (family.name, value)
        c = cls._table.get(key)
        if c is None:
            c = object.__new__(cls)
            c.value = value
            c.family = family
            c.text = text
            cls._table[key] = c
        return c

    def __repr__(self) -> str:
        return self.text


_param_ids = itertools.count(1)


def next_param_id() -> int:
    """The id the next fresh name or logic variable will get (read by taking it and restarting
    the counter there: O(1), unlike parsing the counter's repr)."""
    global _param_ids
    n = next(_param_ids)
    _param_ids = itertools.count(n)
    return n


def skip_param_ids(n: int) -> None:
    """Skip the next ``n`` ids: those a proof search whose answer is memoised would have taken,
    so the fresh names made afterwards (and printed in traces) are numbered as without the memo."""
    global _param_ids
    if n:
        _param_ids = itertools.count(next(_param_ids) + n)


class Param(Head):
    """A fresh name (``Exists`` in the monad, ``Pi`` in a goal). Unique by identity.

    ``id`` grows monotonically: a logic variable may only be instantiated with
    terms whose parameters are older than itself (scope check).
    """

    __slots__ = ("id", "hint")

    def __init__(self, hint: str = "x"):
        self.id = next(_param_ids)
        self.hint = hint

    def __repr__(self) -> str:
        return f"{self.hint}!{self.id}"


class CanonParam(Param):
    """Canonical names used when states are compared up to renaming."""

    __slots__ = ("index",)
    _table: dict[int, "CanonParam"] = {}

    def __new__(cls, index: int) -> "CanonParam":
        p = cls._table.get(index)
        if p is None:
            p = object.__new__(cls)
            p.id = -1 - index  # older than everything: in scope of every logic variable
            p.hint = f"#{index}"
            p.index = index
            cls._table[index] = p
        return p

    def __init__(self, index: int):  # noqa: D401 - state set in __new__
        pass

    def __repr__(self) -> str:
        return self.hint


class BVar(Head):
    """De Bruijn index (0 = innermost binder)."""

    __slots__ = ("index",)
    _table: dict[int, "BVar"] = {}

    def __new__(cls, index: int) -> "BVar":
        b = cls._table.get(index)
        if b is None:
            b = object.__new__(cls)
            b.index = index
            cls._table[index] = b
        return b

    def __repr__(self) -> str:
        return f"^{self.index}"


class Meta(Head):
    """Pattern slot ``i`` of a compiled rule: bound by matching, read by instantiation."""

    __slots__ = ("index",)
    _table: dict[int, "Meta"] = {}

    def __new__(cls, index: int) -> "Meta":
        m = cls._table.get(index)
        if m is None:
            m = object.__new__(cls)
            m.index = index
            cls._table[index] = m
        return m

    def __repr__(self) -> str:
        return f"?{self.index}"


_evar_ids = itertools.count(1)


class EVar(Head):
    """A logic (unification) variable with a mutable binding, undone through a trail."""

    __slots__ = ("ref", "name", "scope", "ty", "uid")

    def __init__(self, name: str = "X", ty=None):
        self.ref = None
        self.name = name
        self.scope = next(_param_ids)  # params with a smaller id are in scope
        self.ty = ty
        self.uid = next(_evar_ids)

    def __repr__(self) -> str:
        return f"?{self.name}{self.uid}"


# ---------------------------------------------------------------- nodes


class Node:
    __slots__ = ("maxb", "evars", "metas", "maxp", "__weakref__")


#: the hash-consing tables of roots: a head alone -> its root without arguments (a constant, a
#: fresh name); a head -> {arguments -> root} (no (head, arguments) pair made or kept per root)
_atoms: dict = {}
_by_head: dict = {}


class Root(Node):
    """``head arg1 ... argn`` in beta-normal form (the head is never a lambda)."""

    __slots__ = ("head", "args")

    def __new__(cls, head: Head, args: tuple = ()) -> "Root":
        if args:
            table = _by_head.get(head)
            if table is not None:
                r = table.get(args)
                if r is not None:
                    return r
        else:
            r = _atoms.get(head)
            if r is not None:
                return r
        r = object.__new__(cls)
        r.head = head
        r.args = args
        maxb = head.index + 1 if type(head) is BVar else 0
        ev = type(head) is EVar
        me = type(head) is Meta
        maxp = head.id if isinstance(head, Param) and head.id > 0 else 0
        for a in args:
            if a.maxb > maxb:
                maxb = a.maxb
            if a.maxp > maxp:
                maxp = a.maxp
            if a.evars:
                ev = True
            if a.metas:
                me = True
        r.maxb = maxb
        r.evars = ev
        r.metas = me
        r.maxp = maxp
        if not ev:  # nodes with logic variables are short-lived: do not pin them
            if args:
                table = _by_head.get(head)
                if table is None:
                    table = _by_head[head] = {}
                table[args] = r
            else:
                _atoms[head] = r
        return r

    def __repr__(self) -> str:
        return show(self)


_lams: dict = {}


class Lam(Node):
    """``\\x. body``; construction eta-contracts, so every term is eta-short and
    structurally equal terms are identical (matching stays syntactic)."""

    __slots__ = ("body",)

    def __new__(cls, body: Node) -> "Lam":
        r = _lams.get(body)
        if r is not None:
            return r
        if type(body) is Root and body.args:
            last = body.args[-1]
            h = body.head
            if (type(last) is Root and not last.args and last.head is _BV0
                    and h is not _BV0 and not any(_mentions_below(a, 1) for a in body.args[:-1])):
                return shift(Root(h, body.args[:-1]), -1)
        r = object.__new__(cls)
        r.body = body
        r.maxb = body.maxb - 1 if body.maxb > 0 else 0
        r.evars = body.evars
        r.metas = body.metas
        r.maxp = body.maxp
        if not r.evars:
            _lams[body] = r
        return r

    def __repr__(self) -> str:
        return show(self)


_types: dict = {}


class TypeNode(Node):
    """Base of the non-atomic types and kinds; interned by (class, fields)."""

    __slots__ = ()
    fields: tuple[str, ...] = ()

    def __repr__(self) -> str:
        return show(self)


def _mk(cls, *vals, binder_field: str | None = None):
    key = (cls, vals)
    n = _types.get(key)
    if n is not None:
        return n
    n = object.__new__(cls)
    maxb = maxp = 0
    ev = me = False
    for f, v in zip(cls.fields, vals):
        object.__setattr__(n, f, v)
        if isinstance(v, Node):
            if v.maxp > maxp:
                maxp = v.maxp
            b = v.maxb - 1 if (f == binder_field and v.maxb > 0) else v.maxb
            if b > maxb:
                maxb = b
            ev = ev or v.evars
            me = me or v.metas
    n.maxb = maxb
    n.evars = ev
    n.metas = me
    n.maxp = maxp
    if not ev:
        _types[key] = n
    return n


class Type(TypeNode):
    """The kind ``type``."""

    __slots__ = ()

    def __new__(cls):
        return _mk(cls)


class Top(TypeNode):
    __slots__ = ()

    def __new__(cls):
        return _mk(cls)


class One(TypeNode):
    __slots__ = ()

    def __new__(cls):
        return _mk(cls)


class Pi(TypeNode):
    """``Pi x:A. B`` (B under one binder). ``hint`` is the bound name, for printing."""

    __slots__ = ("hint", "dom", "body")
    fields = ("hint", "dom", "body")

    def __new__(cls, hint: str, dom: Node, body: Node):
        return _mk(cls, hint, dom, body, binder_field="body")


class Imp(TypeNode):
    """Non-dependent implication; ``mode`` is ``'!'`` (->), ``'1'`` (-o) or ``'@'`` (-@)."""

    __slots__ = ("mode", "dom", "body")
    fields = ("mode", "dom", "body")

    def __new__(cls, mode: str, dom: Node, body: Node):
        return _mk(cls, mode, dom, body)


class With(TypeNode):
    __slots__ = ("left", "right")
    fields = ("left", "right")

    def __new__(cls, left: Node, right: Node):
        return _mk(cls, left, right)


class Monad(TypeNode):
    __slots__ = ("body",)
    fields = ("body",)

    def __new__(cls, body: Node):
        return _mk(cls, body)


class Tensor(TypeNode):
    __slots__ = ("left", "right")
    fields = ("left", "right")

    def __new__(cls, left: Node, right: Node):
        return _mk(cls, left, right)


class Exists(TypeNode):
    """``Exists x:A. S`` (S under one binder)."""

    __slots__ = ("hint", "dom", "body")
    fields = ("hint", "dom", "body")

    def __new__(cls, hint: str, dom: Node, body: Node):
        return _mk(cls, hint, dom, body, binder_field="body")


class Bang(TypeNode):
    __slots__ = ("body",)
    fields = ("body",)

    def __new__(cls, body: Node):
        return _mk(cls, body)


class Aff(TypeNode):
    __slots__ = ("body",)
    fields = ("body",)

    def __new__(cls, body: Node):
        return _mk(cls, body)


BINDERS = (Pi, Exists)
_BV0 = BVar(0)

# ---------------------------------------------------------------- helpers


def const(name: str, *args: Node) -> Root:
    return Root(Const(name), tuple(args))


def bvar(i: int) -> Root:
    return Root(BVar(i), ())


def param_term(p: Param) -> Root:
    return Root(p, ())


# ---------------------------------------------------------------- literals

NUMBER = Const("number")
STRING = Const("string")


def format_number(q: Fraction) -> str:
    """``5``, ``-1`` for integers; the shortest exact decimal (``0.1``, ``-2.5``) when
    the denominator has no prime factor but 2 and 5; ``1/3`` otherwise (not re-readable)."""
    n, d = q.numerator, q.denominator
    if d == 1:
        return str(n)
    twos = fives = 0
    r = d
    while r % 2 == 0:
        r //= 2
        twos += 1
    while r % 5 == 0:
        r //= 5
        fives += 1
    if r != 1:
        return f"{n}/{d}"
    k = max(twos, fives)
    digits = str(abs(n) * 10 ** k // d).rjust(k + 1, "0")
    return ("-" if n < 0 else "") + digits[:-k] + "." + digits[-k:]


_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\r": "\\r", "\t": "\\t"}


def format_string(s: str) -> str:
    """A string literal as written: quoted, with backslash, double quote, newline,
    carriage return and tab escaped (``\\\\``, ``\\"``, ``\\n``, ``\\r``, ``\\t``)."""
    return '"' + "".join(_ESCAPES.get(c, c) for c in s) + '"'


def to_fraction(x) -> Fraction:
    """An exact rational from an int, Fraction, Decimal or numeric string (``"2.5"``, ``"1/3"``).
    Floats are refused: they are not exact."""
    if isinstance(x, bool) or isinstance(x, float):
        raise TypeError(f"a number literal needs an exact value (int, Fraction, Decimal or str), not {x!r}")
    if isinstance(x, Fraction):
        return x
    if isinstance(x, (int, Decimal)):
        return Fraction(x)
    if isinstance(x, str):
        try:
            return Fraction(x.strip())
        except (ValueError, ZeroDivisionError):
            raise ValueError(f"not a number: {x!r}") from None
    raise TypeError(f"a number literal needs an int, Fraction, Decimal or str, not {type(x).__name__}")


_lits = Lit._table


def num_term(x) -> "Root":
    """The literal term of type ``number`` for ``x`` (int, Fraction, Decimal or str)."""
    q = x if type(x) is Fraction else to_fraction(x)
    lit = _lits.get(("number", q))
    if lit is None:
        lit = Lit(q, NUMBER, format_number(q))
    return Root(lit, ())


def string_term(s: str) -> "Root":
    """The literal term of type ``string`` for ``s``."""
    if not isinstance(s, str):
        raise TypeError(f"a string literal needs a str, not {type(s).__name__}")
    lit = _lits.get(("string", s))
    if lit is None:
        lit = Lit(s, STRING, format_string(s))
    return Root(lit, ())


def num_value(t: Node):
    """The value of a number literal (a Fraction), or None when ``t`` is not one
    (logic variables are followed)."""
    t = deref(t)
    if type(t) is Root and type(t.head) is Lit and t.head.family is NUMBER:
        return t.head.value
    return None


def string_value(t: Node):
    """The value of a string literal (a str), or None when ``t`` is not one."""
    t = deref(t)
    if type(t) is Root and type(t.head) is Lit and t.head.family is STRING:
        return t.head.value
    return None


def deref(t: Node) -> Node:
    """Follow instantiated logic variables at the head (one level, repeatedly)."""
    while type(t) is Root and type(t.head) is EVar and t.head.ref is not None:
        t = apply(t.head.ref, t.args)
    return t


def apply(f: Node, args: tuple) -> Node:
    """Beta-normal application ``f args`` (hereditary substitution)."""
    if not args:
        return f
    if type(f) is Root:
        return Root(f.head, f.args + tuple(args))
    if type(f) is Lam:
        # substitute all leading lambdas at once
        n = 0
        body = f
        while n < len(args) and type(body) is Lam:
            body = body.body
            n += 1
        res = subst(body, list(reversed(args[:n])))
        return apply(res, tuple(args[n:]))
    raise TypeError(f"cannot apply {f!r}")


def shift(t: Node, by: int, cutoff: int = 0) -> Node:
    """Raise loose de Bruijn indices >= cutoff by ``by``."""
    if by == 0 or t.maxb <= cutoff:
        return t
    return map_bvars(t, cutoff, lambda i, depth: bvar(i + by))


def subst(t: Node, vals: list, depth: int = 0) -> Node:
    """Replace indices depth..depth+len(vals)-1 by ``vals`` (vals[0] for index ``depth``)
    and lower the indices above; values are closed or shifted as needed."""
    n = len(vals)
    if t.maxb <= depth or n == 0:
        return t
    memo: dict = {}

    def go(t: Node, d: int) -> Node:
        if t.maxb <= d:
            return t
        key = (t, d)
        r = memo.get(key)
        if r is not None:
            return r
        tt = type(t)
        if tt is Root:
            args = tuple(go(a, d) for a in t.args)
            h = t.head
            if type(h) is BVar and h.index >= d:
                i = h.index - d
                if i < n:
                    v = vals[i]
                    if d and v.maxb:
                        v = shift(v, d)
                    r = apply(v, args)
                else:
                    r = Root(BVar(h.index - n), args)
            else:
                r = Root(h, args)
        elif tt is Lam:
            r = Lam(go(t.body, d + 1))
        else:
            r = _map_type(t, d, go)
        memo[key] = r
        return r

    return go(t, depth)


def subst1(body: Node, val: Node) -> Node:
    """Instantiate the binder of ``body`` with ``val``."""
    return subst(body, [val])


def _map_type(t: TypeNode, d: int, go) -> Node:
    cls = type(t)
    vals = []
    for f in cls.fields:
        v = getattr(t, f)
        if isinstance(v, Node):
            v = go(v, d + 1 if (f == "body" and cls in BINDERS) else d)
        vals.append(v)
    return cls(*vals)


def map_bvars(t: Node, cutoff: int, fn) -> Node:
    memo: dict = {}

    def go(t: Node, d: int) -> Node:
        if t.maxb <= d:
            return t
        key = (t, d)
        r = memo.get(key)
        if r is not None:
            return r
        tt = type(t)
        if tt is Root:
            args = tuple(go(a, d) for a in t.args)
            h = t.head
            if type(h) is BVar and h.index >= d:
                r = apply(fn(h.index, d), args)
            else:
                r = Root(h, args)
        elif tt is Lam:
            r = Lam(go(t.body, d + 1))
        else:
            r = _map_type(t, d, go)
        memo[key] = r
        return r

    return go(t, cutoff)


def abstract(t: Node, params: list, depth: int = 0) -> Node:
    """Replace the parameters (head objects) by de Bruijn indices: the last one
    in ``params`` becomes index ``depth`` (innermost)."""
    pos = {p: len(params) - 1 - i for i, p in enumerate(params)}
    n = len(params)
    memo: dict = {}

    def go(t: Node, d: int) -> Node:
        key = (t, d)
        r = memo.get(key)
        if r is not None:
            return r
        tt = type(t)
        if tt is Root:
            h = t.head
            if type(h) is EVar and h.ref is not None:
                r = go(deref(t), d)
            else:
                args = tuple(go(a, d) for a in t.args)
                if h in pos:
                    h = BVar(pos[h] + d)
                elif type(h) is BVar and h.index >= d:
                    h = BVar(h.index + n)
                r = Root(h, args)
        elif tt is Lam:
            r = Lam(go(t.body, d + 1))
        else:
            r = _map_type(t, d, go)
        memo[key] = r
        return r

    return go(t, depth)


def zonk(t: Node) -> Node:
    """Replace instantiated logic variables by their values, everywhere."""
    if not t.evars:
        return t
    memo: dict = {}

    def go(t: Node) -> Node:
        if not t.evars:
            return t
        r = memo.get(t)
        if r is not None:
            return r
        tt = type(t)
        if tt is Root:
            h = t.head
            if type(h) is EVar and h.ref is not None:
                r = go(apply(h.ref, t.args))
            else:
                r = Root(h, tuple(go(a) for a in t.args))
        elif tt is Lam:
            r = Lam(go(t.body))
        else:
            r = type(t)(*[go(v) if isinstance(v, Node) else v for v in (getattr(t, f) for f in type(t).fields)])
        memo[t] = r
        return r

    return go(t)


def free_evars(t: Node) -> list[EVar]:
    """Unsolved logic variables of ``t`` in order of first occurrence."""
    out: dict[EVar, None] = {}
    stack = [t]
    seen: set = set()
    while stack:
        x = stack.pop()
        if not x.evars or x in seen:
            continue
        seen.add(x)
        tx = type(x)
        if tx is Root:
            h = x.head
            if type(h) is EVar:
                if h.ref is not None:
                    stack.append(apply(h.ref, x.args))
                    continue
                out[h] = None
                if h.ty is not None:
                    stack.append(h.ty)
            stack.extend(reversed(x.args))
        elif tx is Lam:
            stack.append(x.body)
        else:
            stack.extend(v for v in reversed([getattr(x, f) for f in tx.fields]) if isinstance(v, Node))
    return list(out)


def params_of(t: Node, acc: dict) -> dict:
    """Add every fresh parameter of ``t`` to ``acc`` (in order of discovery); canonical
    names are not counted. Iterative, and closed-over-parameters subterms are skipped."""
    stack = [t]
    while stack:
        x = stack.pop()
        if not x.maxp:
            continue
        tx = type(x)
        if tx is Root:
            h = x.head
            if isinstance(h, Param) and h.id > 0:
                acc.setdefault(h, None)
            stack.extend(x.args)
        elif tx is Lam:
            stack.append(x.body)
        else:
            stack.extend(v for v in (getattr(x, f) for f in type(x).fields) if isinstance(v, Node))
    return acc


def _mentions_below(t: Node, k: int) -> bool:
    """Does ``t`` mention a loose index < k?"""
    stack = [(t, 0)]
    while stack:
        x, d = stack.pop()
        if x.maxb <= d:
            continue
        tx = type(x)
        if tx is Root:
            if type(x.head) is BVar and d <= x.head.index < d + k:
                return True
            stack.extend((a, d) for a in x.args)
        elif tx is Lam:
            stack.append((x.body, d + 1))
        else:
            for f in tx.fields:
                v = getattr(x, f)
                if isinstance(v, Node):
                    stack.append((v, d + 1 if (f == "body" and tx in BINDERS) else d))
    return False


# ====================================================================== printing
# Terms and types in Celf's concrete syntax (printer.py offers these to the other modules).
# Implicit arguments (reconstructed by elaboration) are hidden, as Celf hides them. Literals of
# the built-in domain print as written (``5``, ``-2.5``, ``"a\\"b"``); a rational that is not a
# finite decimal prints as ``1/3``, which does not read back. Printing is iterative over argument
# spines so that a unary numeral of depth 40,000 prints without hitting Python's recursion limit.

#: no implicit arguments hidden (a term printed outside any program shows every argument)
_NO_IMPLICIT: dict = {}

_IMP = {"!": "->", "1": "-o", "@": "-@"}

# precedence levels: higher binds tighter
_P_BINDER, _P_ARROW, _P_TENSOR, _P_PREFIX, _P_APP, _P_ATOM = 0, 1, 2, 3, 4, 5


def show(t: Node, names: list[str] | None = None, show_implicit: bool = False,
         implicit: dict | None = None) -> str:
    """Render a term or type; ``names`` are the bound names, innermost last.

    ``implicit`` is a program's table of implicit-argument counts (``Program.implicit``;
    ``Program.show`` passes it): the arguments it counts are hidden. Without it every
    argument prints. There is no process-wide table: constants are interned by name, and two
    programs may declare one name with different implicit arguments (a table of the latest
    declarations made a run's facts print differently once another program was loaded).
    """
    out: list[str] = []
    _render(t, list(names or []), _P_BINDER, out, show_implicit, _NO_IMPLICIT if implicit is None else implicit)
    return "".join(out)


def _head_name(h, names: list[str]) -> str:
    if type(h) is Const:
        return h.name
    if type(h) is Lit:
        return h.text  # 5, -2.5, 1/3 (not re-readable), "a\"b"
    if type(h) is BVar:
        i = len(names) - 1 - h.index
        return names[i] if 0 <= i < len(names) else f"^{h.index}"
    if isinstance(h, CanonParam):
        return h.hint
    if isinstance(h, Param):
        # a fresh name prints as hint#id: never an identifier, so a trace can tell it apart
        return f"{h.hint}#{h.id}" if not h.hint.startswith("#") else h.hint
    if type(h) is EVar:
        return h.name
    if type(h) is Meta:
        return f"?{h.index}"
    return repr(h)


def _fresh(names: list[str], hint: str = "x") -> str:
    base = hint or "x"
    if base not in names:
        return base
    k = 1
    while f"{base}{k}" in names:
        k += 1
    return f"{base}{k}"


def _render(t: Node, names: list[str], prec: int, out: list[str], imp: bool, table: dict) -> None:
    # work stack of either strings or (node, names, prec) items
    stack: list = [(t, names, prec)]
    while stack:
        item = stack.pop()
        if type(item) is str:
            out.append(item)
            continue
        t, names, prec = item
        tt = type(t)
        if tt is Root:
            h = t.head
            if type(h) is EVar and h.ref is not None:
                stack.append((apply(h.ref, t.args), names, prec))
                continue
            args = t.args
            if not imp and type(h) is Const:
                args = args[table.get(h, 0):]
            hn = _head_name(h, names)
            if not args:
                out.append(hn)
                continue
            paren = prec > _P_APP
            parts: list = []
            if paren:
                parts.append("(")
            parts.append(hn)
            for a in args:
                parts.append(" ")
                parts.append((a, names, _P_ATOM))
            if paren:
                parts.append(")")
            stack.extend(reversed(parts))
        elif tt is Lam:
            # (a lambda in a term is a persistent function: the engine refuses linear and affine
            # lambdas as index terms, and Celf writes a persistent one '\!x.')
            v = _fresh(names, "x")
            paren = prec > _P_BINDER
            parts = (["("] if paren else []) + [f"\\!{v}. ", (t.body, names + [v], _P_BINDER)] + ([")"] if paren else [])
            stack.extend(reversed(parts))
        else:
            stack.extend(reversed(_type_parts(t, names, prec)))


def _type_parts(t: Node, names: list[str], prec: int) -> list:
    tt = type(t)
    if tt is Type:
        return ["type"]
    if tt is Top:
        return ["T"]
    if tt is One:
        return ["1"]
    if tt in (Pi, Exists):
        v = _fresh(names, t.hint)
        kw = "Pi" if tt is Pi else "Exists"
        parts = [f"{kw} {v}: ", (t.dom, names, _P_ARROW), ". ", (t.body, names + [v], _P_BINDER)]
        return _wrap(parts, prec > _P_BINDER)
    if tt is Imp:
        parts = [(t.dom, names, _P_TENSOR), f" {_IMP[t.mode]} ", (t.body, names, _P_ARROW)]
        return _wrap(parts, prec > _P_ARROW)
    if tt in (Tensor, With):
        op = " * " if tt is Tensor else " & "
        parts = [(t.left, names, _P_PREFIX), op, (t.right, names, _P_TENSOR)]
        return _wrap(parts, prec > _P_TENSOR)
    if tt in (Bang, Aff):
        parts = ["!" if tt is Bang else "@", (t.body, names, _P_ATOM)]
        return _wrap(parts, prec > _P_PREFIX)
    if tt is Monad:
        return ["{", (t.body, names, _P_BINDER), "}"]
    return [repr(t)]


def _wrap(parts: list, paren: bool) -> list:
    return ["("] + parts + [")"] if paren else parts
