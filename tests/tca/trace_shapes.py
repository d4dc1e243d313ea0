"""Task-tree trace shapes shared by the TCA tests and benchmark B5 (``bench/b5_tca.py``)."""

from __future__ import annotations

import json
import random


def deep_chain(n: int, declarations: int, seed: int = 0) -> str:
    """A chain of n goals, each sent and handled inside its parent, achievement never observed;
    random declarations between them, most of which contradict the nesting (conflicts as long
    as the chain: the shape that made the SMT core minimisation quadratic). JSON Lines text."""
    rng = random.Random(seed)
    out = []
    for i in range(n):
        out.append({"event": "constraint_sent", "time": 2 * i, "msg": f"m{i}", "kind": "goal",
                    "parent": f"m{i - 1}" if i else None})
        out.append({"event": "started", "time": 2 * i + 1, "msg": f"m{i}"})
    for i in reversed(range(n)):
        out.append({"event": "ended", "time": 4 * n - i, "msg": f"m{i}"})
    for _ in range(declarations):
        a, b = rng.randrange(n), rng.randrange(n)
        out.append({"event": rng.choice(["seq_ach", "delay_planning", "precedes"]), "m1": f"m{a}", "m2": f"m{b}"})
    return "".join(json.dumps(r) + "\n" for r in out)
