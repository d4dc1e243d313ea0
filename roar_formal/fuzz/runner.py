"""Run one fuzzing case: ``roar-verify`` in-process, in a forked child, within a time bound.

The child is a fork of the calling process (the toolkit is imported already, so a case
costs what the command costs), writes the case's files into a fresh folder, changes to
it, calls :func:`roar_formal.cli.main` with the case's arguments and reports the exit
status; the parent waits at most ``timeout`` seconds and kills it after (a hang). Memory
is bounded in the child (``RLIMIT_AS``), so an input that tries to allocate without limit
ends as an error rather than taking the machine.
"""

from __future__ import annotations

import os
import re
import select
import shutil
import signal
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from .mutate import Case

#: exit statuses a user may see: verdicts as expected, a verdict differs, bad input, incomplete search
ALLOWED = {0, 1, 2, 4}
_LOCATED = re.compile(r":\d+:\d+:")


@dataclass
class Outcome:
    """What a case did: ``status`` (exit code, or None on a hang or a crash) and its output."""

    case: Case
    status: int | None
    stdout: str
    stderr: str
    seconds: float
    hang: bool = False
    signal: int | None = None

    @property
    def internal_error(self) -> bool:
        """An exit code outside {0, 1, 2, 4}, "internal error" printed, or a child killed by a signal."""
        return (not self.hang and (self.status not in ALLOWED or self.signal is not None
                                   or "internal error" in self.stderr or "Traceback" in self.stderr))

    @property
    def unlocated(self) -> bool:
        """The input had an error the oracle can locate, but the message names no ``file:line:col``."""
        if not self.case.expect_location or self.status != 2:
            return False
        return not any(_LOCATED.search(line) and self.case.target in line for line in self.stderr.splitlines())

    @property
    def verdict(self) -> str:
        if self.hang:
            return "hang"
        if self.internal_error:
            return "internal-error"
        if self.unlocated:
            return "unlocated"
        return f"exit-{self.status}"

    def first_error_line(self) -> str:
        for line in (self.stderr + "\n" + self.stdout).splitlines():
            if "error" in line:
                return line.strip()[:300]
        return (self.stderr.strip().splitlines() or [""])[0][:300]


def warm_up() -> None:
    """Run one command of each kind in this process, output discarded, so that the parsers and
    caches every forked case needs are built once, here, rather than in every child."""
    import contextlib
    import io

    from ..cli import main
    from .mutate import REQUESTS, ROOT
    cmds = [["compile", ROOT / "models/faulty/mutual_make.roar", "-r", REQUESTS["mutual_make.roar"]],
            ["check", ROOT / "models/clf/counter.clf", "--max-states", "40", "--no-traces"],
            ["check", ROOT / "checker/mutual_make.toml", "--max-states", "40", "--no-traces"],
            ["tca-check", ROOT / "models/ambler/traces/walk.jsonl"],
            ["tca-simulate", ROOT / "models/ambler/ambler.toml", "--out", "out.jsonl"],
            ["simulate", ROOT / "models/door_nav.roar", "-s", ROOT / "models/scenarios/door.toml", "-r",
             REQUESTS["door_nav.roar"], "--max-steps", "20"]]
    here = os.getcwd()
    folder = tempfile.mkdtemp(prefix="roar-fuzz-warm-")
    sigterm = signal.getsignal(signal.SIGTERM)   # main() installs its own; this process keeps the caller's
    try:
        os.chdir(folder)
        for argv in cmds:
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                try:
                    main([str(a) for a in argv])
                except SystemExit:
                    pass
    finally:
        os.chdir(here)
        shutil.rmtree(folder, ignore_errors=True)
        try:
            signal.signal(signal.SIGTERM, sigterm)
        except (ValueError, TypeError):   # not the main thread, or a handler set outside Python
            pass


def _materialise(case: Case, folder: Path) -> None:
    for name, data in case.files.items():
        p = folder / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
    for name, what in case.special.items():
        p = folder / name
        if what == "dir":
            p.mkdir()
        elif what == "fifo":
            os.mkfifo(p)
        elif what == "readonly-dir":
            p.mkdir()
            os.chmod(p, 0o500)


def _child(case: Case, folder: Path, out_fd: int, err_fd: int, status_w: int, memory_mb: int) -> None:
    code = 99
    try:
        import resource
        if memory_mb:
            resource.setrlimit(resource.RLIMIT_AS, (memory_mb << 20, memory_mb << 20))
        os.dup2(out_fd, 1)
        os.dup2(err_fd, 2)
        os.chdir(folder)
        import sys
        sys.stdout = open(1, "w", closefd=False)
        sys.stderr = open(2, "w", closefd=False)
        os.environ.update({"NO_COLOR": "1", "COLUMNS": "200"})
        for var in ("FORCE_COLOR", "ROAR_DEBUG", "TTY_COMPATIBLE", "TTY_INTERACTIVE"):
            os.environ.pop(var, None)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        from ..cli import main
        try:
            main([str(a) for a in case.argv])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException as exc:   # noqa: BLE001 - escaped the CLI's own handler: a bug
            print(f"internal error (escaped main): {type(exc).__name__}: {exc}", file=sys.stderr)
            code = 98
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        except BaseException:   # noqa: BLE001
            pass
    finally:
        try:
            os.write(status_w, str(code).encode())
        finally:
            os._exit(0)


def run_case(case: Case, timeout: float = 20.0, memory_mb: int = 6144) -> Outcome:
    """Run ``case`` in a forked child; kill it after ``timeout`` seconds (a hang)."""
    folder = Path(tempfile.mkdtemp(prefix="roar-fuzz-"))
    try:
        _materialise(case, folder)
        out = tempfile.TemporaryFile()
        err = tempfile.TemporaryFile()
        status_r, status_w = os.pipe()
        began = time.monotonic()
        pid = os.fork()
        if pid == 0:   # pragma: no cover - the child
            os.close(status_r)
            _child(case, folder, out.fileno(), err.fileno(), status_w, memory_mb)
        os.close(status_w)
        hang = False
        sig = None
        data = b""
        deadline = began + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                hang = True
                os.kill(pid, signal.SIGKILL)
                break
            r, _, _ = select.select([status_r], [], [], min(left, 0.5))
            if r:
                chunk = os.read(status_r, 64)
                if not chunk:
                    break
                data += chunk
        _, wstatus = os.waitpid(pid, 0)
        os.close(status_r)
        seconds = time.monotonic() - began
        if os.WIFSIGNALED(wstatus) and not hang:
            sig = os.WTERMSIG(wstatus)
        status = int(data) if data and not hang else None
        out.seek(0)
        err.seek(0)
        stdout = out.read(200_000).decode("utf-8", errors="replace")
        stderr = err.read(200_000).decode("utf-8", errors="replace")
        out.close()
        err.close()
        return Outcome(case, status, stdout, stderr, seconds, hang=hang, signal=sig)
    finally:
        for p in folder.rglob("*"):
            try:
                if p.is_dir() and not p.is_symlink():
                    os.chmod(p, 0o700)
            except OSError:
                pass
        shutil.rmtree(folder, ignore_errors=True)
