"""Output files a command writes are checked before any work: none may overwrite an input.

A user who types ``--trace tri.py`` for ``--trace tri.jsonl`` must not lose the functional
module, nor two options naming one path leave only the last one written. :func:`check_outputs`
is called with every output of a command and every file it reads (the spec, the files it
imports, its functional-layer module, a scenario, a trace)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Optional

from .errors import RoarError


def check_outputs(outputs: Iterable[tuple[str, Optional[Path]]], inputs: Iterable[Optional[Path]]) -> None:
    """Refuse an output (``(option, path)``; None: not asked for) that is an input of the command,
    a folder, under a file or a folder that cannot be written, or named by two options. Missing
    folders on the way are fine: writing the output makes them."""
    reads = {Path(p).resolve() for p in inputs if p is not None}
    folders = [r for r in reads if r.is_dir()]   # a hyper spec's folder: every file in it is read
    taken: dict[Path, str] = {}
    for option, path in outputs:
        if path is None:
            continue
        path = Path(path)
        if path.exists() and path.is_dir():
            raise RoarError(f"{option} {path}: cannot write: it is a folder (expected a file path)")
        where = path.resolve()
        if where in reads:
            raise RoarError(f"{option} {path}: is an input of this command; refusing to overwrite it")
        inside = next((d for d in folders if read_by_spec_folder(d, where, False)), None)
        if inside is not None:
            raise RoarError(f"{option} {path}: is inside {inside}, a folder this command reads as its input (a "
                            "hyper spec's): a file written there would be read as part of it; write it elsewhere")
        if where in taken:
            raise RoarError(f"{option} {path}: {taken[where]} writes the same file; give each output its own path")
        taken[where] = option
        parent = path.parent if str(path.parent) else Path(".")
        while not parent.exists() and parent != parent.parent:   # missing folders are made when written
            parent = parent.parent
        if not parent.is_dir():
            raise RoarError(f"{option} {path}: {parent} is not a folder")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise RoarError(f"{option} {path}: {parent} is not writable")


def read_by_spec_folder(folder: Path, where: Path, is_folder: bool) -> bool:
    """Would a file at ``where`` (every file in it, when ``is_folder``) be read as part of the hyper
    spec in ``folder``? Its agents' ``.ability`` files are, and every file of an agent's folder
    (``folder/AGENT/...``: its tasks and recipes); other files at the top (a README, a compiled
    program) are not."""
    if folder not in where.parents:
        return False
    parts = where.relative_to(folder).parts
    if (folder / (parts[0] + ".ability")).is_file() and (len(parts) > 1 or is_folder):
        return True
    return len(parts) == 1 and not is_folder and where.suffix == ".ability"
