"""Reading printed CLF facts in the tests' independent enumerations (tests only)."""

from __future__ import annotations


def args_of(fact: str) -> list[str]:
    """The arguments of a printed fact (parenthesised ones kept whole)."""
    out, depth, cur = [], 0, ""
    for ch in fact.split(" ", 1)[1] if " " in fact else "":
        if ch == " " and depth == 0:
            out.append(cur)
            cur = ""
            continue
        depth += ch == "("
        depth -= ch == ")"
        cur += ch
    return out + ([cur] if cur else [])
