"""The files a spec is made of: what its fingerprint hashes and what an output must never overwrite."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from ..trace.fingerprint import fingerprint
from .ast import walk

__all__ = ["spec_files", "spec_fingerprint"]


def spec_files(spec_ast) -> list[str]:
    """Every file one of the spec's nodes comes from (the spec and the files it imports)."""
    return sorted({n.pos.file for n in walk(spec_ast) if n.pos is not None and Path(n.pos.file).is_file()})


def spec_fingerprint(spec_path: Path, spec_ast, functional: Optional[Path]) -> dict:
    """The fingerprint (trace/fingerprint.py) of a loaded spec's files and of its
    functional-layer module, if any: a trace records it, replay compares it."""
    spec_path = Path(spec_path)
    base = spec_path if spec_path.is_dir() else spec_path.parent
    files = [Path(f) for f in spec_files(spec_ast)]
    if spec_path.is_file() and spec_path not in files:
        files.insert(0, spec_path)
    entries = []
    for f in files:
        try:
            name = str(f.resolve().relative_to(base.resolve()))
        except ValueError:
            name = f.name
        entries.append(("spec", name, f))
    if functional is not None:
        entries.append(("functional", Path(functional).name, Path(functional)))
    return fingerprint(entries)
