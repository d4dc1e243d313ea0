"""Leveled random CLF programs, a generator shared by the tests of the partial-order reduction
and of canonical state keys (from the reduction's audit).

Every rule consumes a level token c_i and makes only lower levels, so every program terminates;
facts in all three modes, several copies, rules put in the context at depth (with `&`, in every
mode), fresh names, rules in the start state, persistent rules holding fresh names (whose
states' keys were not canonical before the keys broke ties by individualisation: two keys for
one state up to renaming).
"""

from __future__ import annotations

_DATA = ["p", "q", "r"]
_LEVELS = 4
_LEVELED_HEADER = ("k : type. k0 : k. k1 : k.\n" + "".join(f"{f} : k -> type.\n" for f in _DATA)
                   + "".join(f"c{i} : k -> type.\n" for i in range(_LEVELS)))


class _Leveled:
    def __init__(self, rnd):
        self.R, self.nv = rnd, 0

    def mode(self, lin=6, pers=2, aff=1) -> str:
        return self.R.choices(["", "!", "@"], weights=[lin, pers, aff])[0]

    def rule(self, lev: int, scope: list, top: bool) -> str:
        R = self.R
        newv: list = []

        def var() -> str:
            if top:
                v = R.choice(["X", "Y"])
            else:
                self.nv += 1
                v = f"y{self.nv}"
            if v not in newv and v not in scope:
                newv.append(v)
            return v
        prem = [f"c{lev} {var() if R.random() < 0.8 else R.choice(['k0', 'k1'] + scope)}"]
        for _ in range(R.choice([0, 1, 1, 2])):
            a = var() if R.random() < 0.4 else R.choice(["k0", "k1"] + scope + newv)
            prem.append(f"{self.mode()}{R.choice(_DATA)} {a}")
        R.shuffle(prem)
        body = " * ".join(prem) + " -o {" + self.head(lev, scope + newv) + "}"
        return body if top else "".join(f"Pi {v}:k. " for v in newv) + body

    def head(self, lev: int, scope: list) -> str:
        R = self.R
        fresh = []
        for _ in range(R.choice([0, 0, 1, 1, 2])):
            self.nv += 1
            fresh.append(f"n{self.nv}")
        sc = scope + fresh
        items = [f"{self.mode(6, 1, 1)}{R.choice(_DATA)} {R.choice(['k0', 'k1'] + sc)}"
                 for _ in range(R.choice([0, 1, 1, 2, 2]))]
        if lev > 0:
            for _ in range(R.choice([0, 1, 1, 2])):
                items.append(f"{'@' if R.random() < 0.15 else ''}c{R.randrange(lev)} {R.choice(['k0', 'k1'] + sc)}")
            if R.random() < 0.6:
                for _ in range(R.choice([1, 1, 2])):
                    j = R.randrange(lev)
                    alts = [self.rule(j, sc, False) for _ in range(R.choice([1, 1, 2]))]
                    t = f"({alts[0]})" if len(alts) == 1 else "(" + " & ".join(f"({x})" for x in alts) + ")"
                    items.append(R.choices(["", "@", "!"], weights=[8, 1, 1])[0] + t)
        txt = " * ".join(items)
        toks = set(txt.replace("(", " ").replace(")", " ").replace("{", " ").replace("}", " ").split())
        return "".join(f"Exists {n}:k. " for n in fresh if n in toks) + (txt or "1")

    def program(self) -> str:
        R = self.R
        levs = [R.randrange(1, _LEVELS) for _ in range(R.randint(2, 4))]
        rules = [f"r{i} : " + self.rule(lev, [], True) + "." for i, lev in enumerate(levs)]
        start = [f"{'@' if R.random() < 0.15 else ''}c{R.choice(levs)} {R.choice(['k0', 'k1'])}"
                 for _ in range(R.randint(2, 4))]
        start += [f"{self.mode(5, 2, 1)}{R.choice(_DATA)} {R.choice(['k0', 'k1'])}" for _ in range(R.randint(0, 4))]
        if R.random() < 0.3:
            start.append("(" + self.rule(R.randrange(1, _LEVELS), [], False) + ")")
        R.shuffle(start)
        return _LEVELED_HEADER + "".join(r + "\n" for r in rules) + "#exec * " + " * ".join(start) + ".\n"



def leveled_program(rnd) -> str:
    """A leveled program drawn with the random generator ``rnd``."""
    return _Leveled(rnd).program()
