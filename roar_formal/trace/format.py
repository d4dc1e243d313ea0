"""The trace format shared by engine runs, robot runs and counterexamples: JSON Lines.

The first line is a header ``{"trace": "roar-formal", "version": 1, "kind": ..., ...}``;
each further line is one step::

    {"step": 3, "rule": "take_first", "group": "p2", "consumed": ["at0 p2", "fork p2"],
     "produced": ["at1 p2", "busy p2"], "event": null, "loop": false}

``event`` carries the ROAR-level meaning of a step (constraint sent, request
state change, recipe selected, primitive started or ended) when there is one.
``loop`` marks the steps of a lasso's repeating cycle. Files are written
atomically (a temporary file renamed over the target), so a reader never sees
half a trace and an interrupted write never destroys an earlier one.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Iterable, Iterator

from ..errors import Pos, RoarError

VERSION = 1


def write_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write_trace(path: str | Path, header: dict, steps: Iterable[dict]) -> None:
    lines = [json.dumps({"trace": "roar-formal", "version": VERSION, **header}, sort_keys=True)]
    for i, s in enumerate(steps, 1):
        rec = {"step": i, **s}
        lines.append(json.dumps(rec, sort_keys=True))
    write_atomic(path, "\n".join(lines) + "\n")


def read_trace(path: str | Path) -> tuple[dict, list[dict]]:
    """Read a trace; malformed lines are errors with their line number."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RoarError(f"cannot read {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RoarError(f"cannot read {path}: {exc}") from None
    header: dict | None = None
    steps: list[dict] = []
    for n, line in _lines(text):
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as exc:
            raise RoarError(f"not a JSON object: {exc.msg}", Pos(str(path), n, exc.colno)) from None
        if not isinstance(rec, dict):
            raise RoarError("expected a JSON object on each line", Pos(str(path), n, 1))
        if header is None:
            if rec.get("trace") != "roar-formal":
                raise RoarError('expected a trace header {"trace": "roar-formal", ...} on the first line',
                                Pos(str(path), n, 1))
            header = rec
            continue
        if "step" not in rec:
            raise RoarError("expected a step record with a \"step\" field", Pos(str(path), n, 1))
        steps.append(rec)
    if header is None:
        raise RoarError(f"{path} is empty: expected a roar-formal trace")
    return header, steps


def _lines(text: str) -> Iterator[tuple[int, str]]:
    for n, line in enumerate(text.splitlines(), 1):
        if line.strip():
            yield n, line
