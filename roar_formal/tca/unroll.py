"""Unroll a model into a concrete task tree: every repetition and chain
expanded to the model's sizes, every class constraint instantiated."""

from __future__ import annotations

import re
from collections import deque
from dataclasses import dataclass, field
from typing import Optional

from ..errors import RoarError
from .model import Model, Slot

#: the most messages an unrolled tree may have (simulating, checking and proving on it must stay
#: within memory: about 4 KB a message while simulating)
MAX_MESSAGES = 200_000

_INDEXED = re.compile(r"^(\w+)\[(k|k\+1)\]$")


@dataclass
class Node:
    """A message of the unrolled tree; ``slots`` maps a child name (``leg``, ``arc[2]``) to its id."""

    id: str
    cls: str
    kind: str
    parent: Optional[str]
    chain_pos: int = 1
    slots: dict[str, str] = field(default_factory=dict)


@dataclass
class Instance:
    model: Model
    nodes: dict[str, Node]
    root: str
    constraints: list[tuple[str, str, str]]  # (relation, first id, second id)

    def children(self, node_id: str) -> list[Node]:
        return [self.nodes[c] for c in self.nodes[node_id].slots.values()]

    def resolve(self, start: str, path: list[tuple[str, Optional[int]]]) -> Optional[str]:
        """Follow child names (with absolute indices for repeated children) from ``start``."""
        here: Optional[str] = start
        for name, index in path:
            key = f"{name}[{index}]" if index is not None else name
            here = self.nodes[here].slots.get(key) if here else None
        return here


def _child_id(parent: Node, slot: Slot, index: Optional[int], pos: int, root: str) -> str:
    prefix = "" if parent.id == root else parent.id + "."
    if slot.chain:  # the next link of a chain sits beside its predecessor: arc1.step2 after arc1.step1
        return re.sub(r"\d+$", "", parent.id) + str(pos)
    name = slot.name + (str(index) if index is not None else "")
    return prefix + name


def unroll(model: Model, sizes: Optional[dict[str, int]] = None, max_messages: int = MAX_MESSAGES) -> Instance:
    """The task tree the model's handlers build, with ``sizes`` overriding the model's.

    More than ``max_messages`` messages is an error (raised as soon as the count is passed,
    before the tree takes the memory)."""
    sizes = {**model.sizes, **(sizes or {})}
    root_cls = model.classes[model.root]
    root = Node(model.root.lower(), model.root, root_cls.kind, None)
    nodes = {root.id: root}
    constraints: list[tuple[str, str, str]] = []
    todo = deque([root])
    while todo:
        node = todo.popleft()
        cls = model.classes[node.cls]
        for slot in cls.slots:
            child_cls = model.classes[slot.cls]
            if slot.chain and node.chain_pos >= sizes[slot.chain]:
                continue
            count = sizes[slot.repeat] if slot.repeat else 1
            for i in range(1, count + 1):
                index = i if slot.repeat else None
                pos = node.chain_pos + 1 if slot.chain else 1
                cid = _child_id(node, slot, index, pos, root.id)
                if not slot.chain and any(s.chain for s in child_cls.slots):
                    cid += "1"  # the head of a chain is its first link
                child = Node(cid, slot.cls, child_cls.kind, node.id, pos)
                nodes[cid] = child
                if len(nodes) > max_messages:
                    shown = ", ".join(f"{k} = {v:,}" for k, v in sizes.items())
                    raise RoarError(f"{model.name}: with {shown} the task tree has more than {max_messages:,} "
                                    "messages; use smaller sizes")
                node.slots[f"{slot.name}[{i}]" if slot.repeat else slot.name] = cid
                todo.append(child)
        constraints.extend(_instantiate(cls.constraints, node, sizes, cls))
    return Instance(model, nodes, root.id, constraints)


def _instantiate(constraints, node: Node, sizes: dict[str, int], cls) -> list[tuple[str, str, str]]:
    out = []
    for c in constraints:
        repeated = [_INDEXED.match(r) for r in (c.first, c.second)]
        if any(repeated):
            name = next(m.group(1) for m in repeated if m)
            count = sizes[cls.slot(name).repeat]
            for k in range(1, count + 1):
                ids = [node.slots.get(_at(ref, k)) for ref in (c.first, c.second)]
                if all(ids):
                    out.append((c.relation, ids[0], ids[1]))
        else:
            ids = [node.slots.get(ref) for ref in (c.first, c.second)]
            if all(ids):
                out.append((c.relation, ids[0], ids[1]))
    return out


def _at(ref: str, k: int) -> str:
    m = _INDEXED.match(ref)
    if not m:
        return ref
    return f"{m.group(1)}[{k + 1 if m.group(2) == 'k+1' else k}]"
