"""The trace format shared by engine runs, robot runs and counterexamples: JSON Lines.

The first line is a header ``{"trace": "roar-formal", "version": 1, "kind": ..., ...}``;
each further line is one step::

    {"step": 3, "rule": "take_first", "group": "p2", "consumed": ["at0 p2", "fork p2"],
     "produced": ["at1 p2", "busy p2"], "event": null, "loop": false}

``event`` carries the ROAR-level meaning of a step (constraint sent, request
state change, recipe selected, primitive started or ended) when there is one.
``loop`` marks the steps of a lasso's repeating cycle. Files are written
atomically (a temporary file renamed over the target), so a reader never sees
half a trace and an interrupted write never destroys an earlier one (nor leaves its
temporary file behind for long: see :func:`write_atomic`).
"""

from __future__ import annotations

import json
import os
import re
import socket
import tempfile
from pathlib import Path
from typing import Iterable, Iterator, Optional

from ..errors import Pos, RoarError, json_message

VERSION = 1

#: the kinds of a ROAR event (a step's ``event``; ``several`` holds a step's list of them): the
#: narrator writes only these (roar/run.py), and a reader refuses any other
ROAR_EVENT_KINDS = frozenset({"sent", "state", "tasks", "recipe", "recipe-end", "recipe-stop", "primitive-start",
                              "primitive-end", "write", "pause", "resume", "abort", "conflict", "calling-context",
                              "crash", "crash-plan", "back",
                              "robot"})   # (a step of the robot in a lockstep run: testing/stateful.py)


def write_atomic_bytes(path: str | Path, data: bytes) -> None:
    """:func:`write_atomic` for bytes (pictures), with an unwritable path as a located error."""
    path = Path(path)
    try:
        _write_atomic(path, data)
    except OSError as exc:
        raise RoarError(f"{path}: cannot write: {exc.strerror or exc}") from None


def write_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (see :func:`_write_atomic`)."""
    _write_atomic(Path(path), text.encode("utf-8"))


def _umask() -> int:
    """The process's umask (read by setting it and putting it back: there is no getter)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder.

    The temporary file is ``.NAME.HOST.PID-<random>.tmp``: removed if the write fails or is
    interrupted (an exception, Ctrl-C, or SIGTERM through the command line's handler); one
    left behind by a killed process (SIGKILL, power loss) is removed by the next write in the
    same folder on the same host, once its process is gone."""
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{_HOST}.{os.getpid()}-", suffix=".tmp", dir=path.parent)
    try:
        # mkstemp makes the file private (0600); an output gets the mode a plain open would give it
        mode = 0o666 & ~_umask()
        if path.exists():
            mode = path.stat().st_mode & 0o7777   # replacing a file keeps its mode
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


_HOST = re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname() or "host")[:40]
_TEMPORARY = re.compile(r"^\..+\.(?P<host>[A-Za-z0-9-]+)\.(?P<pid>\d+)-[A-Za-z0-9_]+\.tmp$")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True  # someone else's process, or no way to tell: keep its file
    return True


def remove_stale_temporaries(folder: str | Path) -> list[Path]:
    """Remove the temporary files of :func:`write_atomic` in ``folder`` whose writer, a process
    of this host, no longer runs; returns them."""
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        m = _TEMPORARY.match(name)
        if m is None or m.group("host") != _HOST or _alive(int(m.group("pid"))):
            continue
        try:
            os.unlink(Path(folder) / name)
            removed.append(Path(folder) / name)
        except OSError:
            pass
    return removed


def write_trace(path: str | Path, header: dict, steps: Iterable[dict]) -> None:
    lines = [json.dumps({"trace": "roar-formal", "version": VERSION, **header}, sort_keys=True)]
    for i, s in enumerate(steps, 1):
        rec = {"step": i, **s}
        lines.append(json.dumps(rec, sort_keys=True))
    write_atomic(path, "\n".join(lines) + "\n")


#: the kinds of trace the project writes, whose steps are numbered in the order they were taken
#: (a hand-written TCA event trace may interleave its events' numbers with others')
NUMBERED_KINDS = ("roar-run", "roar-robot-run", "counterexample")


def read_trace(path: str | Path, lines: Optional[list[int]] = None) -> tuple[dict, list[dict]]:
    """Read a trace; malformed lines are errors with their line number. ``lines``, if given, is
    filled with each step record's line number (for errors found later, at a step)."""
    path = Path(path)
    from ..inputs import check_input_file
    check_input_file(path)
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
            raise RoarError(f"not a JSON object: {json_message(exc)}", Pos(str(path), n, exc.colno)) from None
        except RecursionError:
            raise RoarError("not a JSON object: nested too deeply", Pos(str(path), n, 1)) from None
        except ValueError as exc:   # e.g. an integer beyond Python's int-string limit
            raise RoarError(f"not a JSON object: {exc}", Pos(str(path), n, 1)) from None
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
        k = rec["step"]
        if (header.get("kind") in NUMBERED_KINDS and type(k) is int and steps and type(steps[-1]["step"]) is int
                and k <= steps[-1]["step"]):
            # the steps of a run or a counterexample are numbered in the order they were taken: a
            # trace with two steps swapped or renumbered is not the run it claims to be, even where
            # the swapped order would be another run of the model
            raise RoarError(f"step {k} comes after step {steps[-1]['step']}: the steps of a trace are numbered "
                            "in increasing order (the order they were taken)", Pos(str(path), n, 1))
        steps.append(rec)
        if lines is not None:
            lines.append(n)
    if header is None:
        raise RoarError(f"{path} is empty: expected a roar-formal trace")
    return header, steps


def _lines(text: str) -> Iterator[tuple[int, str]]:
    for n, line in enumerate(text.splitlines(), 1):
        if line.strip():
            yield n, line
