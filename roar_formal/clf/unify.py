"""Higher-order pattern unification (Miller's fragment) with occurs and scope checks.

Binders are opened with fresh parameters (locally nameless), so a flexible
term is a logic variable applied to parameters; in the pattern fragment those
parameters are distinct and younger than the variable, and the unique most
general solution abstracts them. Equations outside the fragment are postponed
and retried after every binding; what is left at the end is reported by the
caller. Bindings are recorded on a trail so backtracking can undo them.
"""

from __future__ import annotations

from .terms import (BINDERS, EVar, Lam, Node, Param, Root, TypeNode, abstract, apply, deref,
                    param_term, subst1)


class Unifier:
    """Unification state: the trail of bindings and the postponed equations."""

    __slots__ = ("trail", "postponed")

    def __init__(self) -> None:
        self.trail: list = []
        # a tuple, replaced rather than changed: a mark keeps the one it saw, and undoing restores
        # it whole (a retry that solved an equation under a binding undone must not lose it)
        self.postponed: tuple = ()

    # -- trail ---------------------------------------------------------
    def mark(self) -> tuple:
        return len(self.trail), self.postponed

    def undo(self, mark: tuple) -> None:
        n, postponed = mark
        trail = self.trail
        while len(trail) > n:
            entry = trail.pop()
            if type(entry) is EVar:
                entry.ref = None
            else:  # (evar, old scope)
                entry[0].scope = entry[1]
        self.postponed = postponed

    def bind(self, x: EVar, val: Node) -> None:
        x.ref = val
        self.trail.append(x)

    # -- unification ---------------------------------------------------
    def unify(self, a: Node, b: Node) -> bool:
        """Unify, then retry postponed equations that a binding may have unlocked."""
        n_before = len(self.trail)
        if not self._unify(a, b):
            return False
        if self.postponed and len(self.trail) > n_before:
            return self._retry()
        return True

    def solved(self) -> bool:
        """True when no postponed equation remains."""
        return not self.postponed or (self._retry() and not self.postponed)

    def _retry(self) -> bool:
        progress = True
        while progress and self.postponed:
            progress = False
            eqs, self.postponed = self.postponed, ()
            before = len(self.trail)
            for a, b in eqs:
                if not self._unify(a, b):
                    return False
            progress = len(self.trail) > before
        return True

    def _unify(self, a: Node, b: Node) -> bool:
        stack = [(a, b)]
        while stack:
            a, b = stack.pop()
            if a is b:
                continue
            a = deref(a)
            b = deref(b)
            if a is b:
                continue
            ta, tb = type(a), type(b)
            if ta is Lam or tb is Lam:
                p = param_term(Param("u"))
                a2 = subst1(a.body, p) if ta is Lam else apply(a, (p,))
                b2 = subst1(b.body, p) if tb is Lam else apply(b, (p,))
                stack.append((a2, b2))
                continue
            if ta is Root and tb is Root:
                ha, hb = a.head, b.head
                fa, fb = type(ha) is EVar, type(hb) is EVar
                if fa and fb:
                    if not self._flex_flex(a, b):
                        return False
                    continue
                if fa:
                    if not self._flex_rigid(a, b):
                        return False
                    continue
                if fb:
                    if not self._flex_rigid(b, a):
                        return False
                    continue
                if ha is not hb or len(a.args) != len(b.args):
                    return False
                stack.extend(zip(a.args, b.args))
                continue
            if ta is Root and type(a.head) is EVar:
                if not self._flex_rigid(a, b):
                    return False
                continue
            if tb is Root and type(b.head) is EVar:
                if not self._flex_rigid(b, a):
                    return False
                continue
            if ta is not tb or ta is Root or tb is Root:
                return False
            # structural types
            for f in ta.fields:
                va, vb = getattr(a, f), getattr(b, f)
                if isinstance(va, Node):
                    if f == "body" and ta in BINDERS:
                        p = param_term(Param("u"))
                        stack.append((subst1(va, p), subst1(vb, p)))
                    else:
                        stack.append((va, vb))
                elif f != "hint" and va != vb:
                    return False
        return True

    # -- flexible cases ------------------------------------------------
    def _pattern_params(self, x: EVar, args: tuple) -> list | None:
        """The parameters of a pattern spine, or None if outside the fragment."""
        ps = []
        for a in args:
            a = deref(a)
            if type(a) is not Root or a.args or not isinstance(a.head, Param):
                return None
            p = a.head
            if p.id < x.scope or p in ps:  # in scope already, or repeated
                return None
            ps.append(p)
        return ps

    def _flex_rigid(self, flex: Root, other: Node) -> bool:
        x = flex.head
        ps = self._pattern_params(x, flex.args)
        if ps is None:
            self.postponed += ((flex, other),)
            return True
        ok = self._check(x, other, set(ps))
        if ok is None:
            self.postponed += ((flex, other),)
            return True
        if not ok:
            return False
        val = abstract(other, ps) if ps else other
        for _ in ps:
            val = Lam(val)
        self.bind(x, val)
        return True

    def _flex_flex(self, a: Root, b: Root) -> bool:
        x, y = a.head, b.head
        if x is y:
            if len(a.args) == len(b.args) and all(deref(s) is deref(t) for s, t in zip(a.args, b.args)):
                return True
            self.postponed += ((a, b),)
            return True
        pa = self._pattern_params(x, a.args)
        if pa is not None and not b.args and y.scope <= x.scope:
            return self._flex_rigid(a, b)
        pb = self._pattern_params(y, b.args)
        if pb is not None and not a.args and x.scope <= y.scope:
            return self._flex_rigid(b, a)
        if pa is not None:
            return self._flex_rigid(a, b)
        if pb is not None:
            return self._flex_rigid(b, a)
        self.postponed += ((a, b),)
        return True

    def _check(self, x: EVar, t: Node, allowed: set) -> bool | None:
        """Occurs and scope check of ``t`` as a value for ``x``.

        True: fine. False: impossible (occurs, or a parameter out of scope in a
        rigid position). None: undecided (would need pruning); postpone.
        """
        if not t.evars and t.maxp < x.scope:
            return True
        stack = [t]
        seen: set = set()
        while stack:
            s = stack.pop()
            if s in seen or (not s.evars and s.maxp < x.scope):
                continue
            seen.add(s)
            ts = type(s)
            if ts is Root:
                h = s.head
                if type(h) is EVar:
                    if h.ref is not None:
                        stack.append(apply(h.ref, s.args))
                        continue
                    if h is x:
                        return False
                    if h.scope > x.scope:
                        if s.args:
                            return None
                        # restrict y's scope to x's (trailed)
                        self.trail.append((h, h.scope))
                        h.scope = x.scope
                    stack.extend(s.args)
                    continue
                if isinstance(h, Param) and h.id >= x.scope and h not in allowed:
                    return False
                stack.extend(s.args)
            elif ts is Lam:
                stack.append(s.body)
            elif isinstance(s, TypeNode):
                stack.extend(v for v in (getattr(s, f) for f in ts.fields) if isinstance(v, Node))
        return True


def unify(a: Node, b: Node) -> bool:
    """One-shot unification (bindings are kept; no backtracking)."""
    u = Unifier()
    return u.unify(a, b) and u.solved()
