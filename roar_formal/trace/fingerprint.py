"""Fingerprints of the sources a trace was recorded on.

A counterexample's header records the SHA-256 of every file its model was
built from: the ``.clf`` program, or the files of a ROAR spec and its
functional-layer module. ``replay`` rebuilds the model from what the user
names on the command line (never from a path inside the trace, see
docs/trust.md) and compares fingerprints, so replaying on other sources than
the ones explored is refused (``--force`` overrides) rather than misread.

The fingerprint depends on the files' bytes and their roles, not on where
they are: a checkout in another folder has the same fingerprint.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Iterable

from ..errors import RoarError

ALGORITHM = "sha256"


def file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fingerprint(entries: Iterable[tuple[str, str, Path]]) -> dict:
    """``{"sha256": ..., "files": {name: sha256}}`` over (role, name, path) entries; the total
    hashes the sorted (role, file hash) pairs, so names and folders do not count."""
    files: dict[str, str] = {}
    pairs = []
    for role, name, path in entries:
        digest = file_digest(path)
        files[f"{role}:{name}"] = digest
        pairs.append([role, digest])
    total = hashlib.sha256(json.dumps(sorted(pairs)).encode()).hexdigest()
    return {ALGORITHM: total, "files": files}


def clf_fingerprint(model: Path) -> dict:
    return fingerprint([("model", Path(model).name, Path(model))])


def differences(recorded: dict, given: dict) -> list[str]:
    """What differs between two fingerprints, file by file, for a message."""
    rec = recorded.get("files") if isinstance(recorded.get("files"), dict) else {}
    giv = given.get("files", {})
    rec_hashes, giv_hashes = set(map(str, rec.values())), set(giv.values())
    out = []
    for role in sorted({str(k).split(":", 1)[0] for k in list(rec) + list(giv)}):
        new = [k.split(":", 1)[1] for k, h in sorted(giv.items()) if k.startswith(role + ":") and h not in rec_hashes]
        old = [str(k).split(":", 1)[1] for k, h in sorted(rec.items())
               if str(k).startswith(role + ":") and str(h) not in giv_hashes]
        if len(new) == 1 and len(old) == 1:
            out.append(f"{role} file {new[0]} differs from the recorded {json.dumps(old[0])}")
            continue
        if new:
            out.append(f"{role} files not in the recorded model (new or changed): {', '.join(new)}")
        if old:
            out.append(f"recorded {role} files missing or changed here: {', '.join(json.dumps(x) for x in old)}")
    return out


def check_fingerprint(path, header: dict, given: dict, force: bool, notes: list[str]) -> None:
    """Refuse (unless ``force``) a trace whose recorded fingerprint is not ``given``'s; note
    in ``notes`` what could not be confirmed or was overridden."""
    recorded = header.get("fingerprint")
    if not isinstance(recorded, dict) or not isinstance(recorded.get(ALGORITHM), str):
        notes.append("the trace records no fingerprint of its model's sources: it cannot be confirmed that "
                     "--model is the model it was recorded on")
        return
    if recorded[ALGORITHM] == given[ALGORITHM]:
        return
    what = differences(recorded, given) or ["the files differ"]
    rec_fn = [k.split(":", 1)[1] for k in (recorded.get("files") or {}) if str(k).startswith("functional:")]
    if rec_fn and not any(k.startswith("functional:") for k in given["files"]):
        what.append(f"the trace was recorded with the functional-layer module {shown(rec_fn[0])}: if it is one "
                    "you trust, name it with --functional")
    if not force:
        raise RoarError(f"{path}: the model given with --model is not the one the trace was recorded on "
                        f"(its fingerprint is {given[ALGORITHM][:12]}; the trace records "
                        f"{shown(recorded[ALGORITHM][:12])}, quoted as read)", None,
                        what + ["pass --force to replay it on this model anyway"])
    notes.append("replaying on a model other than the recorded one (--force): " + "; ".join(what))


def shown(value) -> str:
    """A value read from a trace, quoted for a message (control characters escaped)."""
    return json.dumps(value, ensure_ascii=True) if isinstance(value, str) else json.dumps(str(value))
