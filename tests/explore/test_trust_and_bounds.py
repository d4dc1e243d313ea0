"""Traces are data (replay never runs what a trace names), search budgets are bounded and
checked (memory often, time while grounding, invalid budgets refused), and trace files
are written atomically with their temporary files cleaned up."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from roar_formal.cli import main
from roar_formal.clf.query import with_big_stack
from roar_formal.errors import RoarError
from roar_formal.verify.check import run_job, save_counterexample
from roar_formal.verify.jobs import MIN_MEMORY_MB, load_job
from roar_formal.explore.search import MemoryWatch, current_rss_mb, rss_mb
from roar_formal.trace.format import read_trace, remove_stale_temporaries, write_atomic
from roar_formal.verify.replay import replay

from repo import ROOT
DL = ROOT / "models" / "philosophers" / "dl.clf"
MUTUAL = ROOT / "models" / "faulty" / "mutual_make.roar"


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text).lstrip(), encoding="utf-8")
    return path


def clf_trace(tmp_path) -> Path:
    """A deadlock counterexample of the 5 dining philosophers, saved by check."""
    res = run_job(load_job(ROOT / "checker" / "philosophers_dl5.toml"))
    return save_counterexample(res, "deadlock", tmp_path / "traces")


# ------------------------------------------------------------------ 1. traces are data

EVIL = """
from pathlib import Path
Path({marker!r}).write_text("ran")
raise SystemExit("the functional-layer module named by a trace ran")
"""


def _evil_trace(tmp_path: Path, **header) -> tuple[Path, Path]:
    """A trace whose header names a spec and a functional-layer module that writes a marker."""
    marker = tmp_path / "MARKER"
    evil = write(tmp_path, "evil.py", EVIL.format(marker=str(marker)))
    write(tmp_path, "evil.roar", "this is not even a spec\n")
    head = {"trace": "roar-formal", "version": 1, "kind": "counterexample", "property": "deadlock",
            "spec": str(tmp_path / "evil.roar"), "functional": str(evil), "request": "arm::started == true",
            **header}
    trace = tmp_path / "evil.deadlock.jsonl"
    step = {"step": 1, "rule": "start", "group": "g", "consumed": [], "produced": [], "event": None, "loop": False}
    trace.write_text(json.dumps(head) + "\n" + json.dumps(step) + "\n")
    return trace, marker


def test_replay_never_runs_the_module_a_trace_names(tmp_path, capsys):
    trace, marker = _evil_trace(tmp_path)
    with pytest.raises(RoarError) as e:
        replay(trace)
    assert not marker.exists()
    text = e.value.format()
    assert "pass --model SPEC" in text and "never opens, imports or runs" in text
    assert str(tmp_path / "evil.roar") in text  # the path it names, as a hint only

    # through the command line: exit 2, the same explanation, still nothing run
    with pytest.raises(SystemExit) as e:
        main(["replay", str(trace)])
    assert e.value.code == 2
    err = capsys.readouterr().err.replace("\n", " ")
    assert "replay needs the model on the command line: pass --model SPEC" in err and "Traceback" not in err
    assert not marker.exists()


def test_with_a_model_the_trace_named_module_is_still_not_run(tmp_path):
    """--model names the spec; its own functional-layer module (next to it) is the one used,
    whatever the header says, and a foreign fingerprint is refused before anything is imported."""
    trace, marker = _evil_trace(tmp_path, fingerprint={"sha256": "0" * 64, "files": {"spec:evil.roar": "1" * 64}})
    with pytest.raises(RoarError) as e:
        with_big_stack(replay, trace, None, MUTUAL)
    assert "not the one the trace was recorded on" in e.value.message
    # both fingerprints, the trace's quoted as read (it is the untrusted one)
    assert re.search(r"its fingerprint is [0-9a-f]{12}; the trace records \"000000000000\", quoted as read",
                     e.value.message)
    assert any("--force" in n for n in e.value.notes)
    with pytest.raises(RoarError) as e:  # forced: replayed on mutual_make, whose first step differs
        with_big_stack(lambda: replay(trace, None, MUTUAL, force=True))
    assert "cannot be replayed" in e.value.message
    assert not marker.exists()


def test_a_header_model_path_is_not_opened_either(tmp_path):
    trace = tmp_path / "t.jsonl"
    trace.write_text(json.dumps({"trace": "roar-formal", "version": 1, "kind": "counterexample",
                                 "model": "/etc/passwd", "start": 1}) + "\n")
    with pytest.raises(RoarError) as e:
        replay(trace)
    assert "pass --model" in e.value.message and '"/etc/passwd"' in e.value.format()


@pytest.mark.parametrize("start", ["1", 0, -2, 1.5, True, [1]])
def test_a_malformed_start_is_a_located_error(tmp_path, start):
    trace = tmp_path / "t.jsonl"
    trace.write_text(json.dumps({"trace": "roar-formal", "version": 1, "start": start}) + "\n")
    with pytest.raises(RoarError) as e:
        replay(trace, model=DL)
    assert e.value.pos is not None and e.value.pos.line == 1 and '"start"' in e.value.message


def test_check_records_a_fingerprint_and_replay_compares_it(tmp_path):
    trace = clf_trace(tmp_path)
    header, _ = read_trace(trace)
    fp = header["fingerprint"]
    assert len(fp["sha256"]) == 64 and list(fp["files"]) == ["model:dl.clf"]
    assert with_big_stack(lambda: replay(trace, model=DL)).steps == 5
    # a copy elsewhere with the same bytes: the same fingerprint
    same = tmp_path / "elsewhere" / "renamed.clf"
    same.parent.mkdir()
    same.write_bytes(DL.read_bytes())
    assert with_big_stack(lambda: replay(trace, model=same)).notes == []
    # changed sources: refused, then replayed with --force (and said so)
    changed = tmp_path / "dl_changed.clf"
    changed.write_text(DL.read_text() + "\n% a comment changes the fingerprint\n")
    with pytest.raises(RoarError) as e:
        replay(trace, model=changed)
    assert "not the one the trace was recorded on" in e.value.message
    assert any("dl_changed.clf differs from the recorded" in n for n in e.value.notes)
    res = with_big_stack(lambda: replay(trace, model=changed, force=True))
    assert res.steps == 5 and any("--force" in n for n in res.notes)


def test_roar_counterexample_replays_on_the_spec_given(tmp_path, capsys):
    res = run_job(load_job(ROOT / "checker" / "mutual_make.toml"))
    trace = save_counterexample(res, "deadlock", tmp_path)
    header, steps = read_trace(trace)
    assert set(header["fingerprint"]["files"]) == {"spec:mutual_make.roar"}
    with pytest.raises(SystemExit) as e:
        main(["replay", str(trace), "--model", str(MUTUAL)])
    assert e.value.code == 0
    assert f"replayed {len(steps)} steps" in capsys.readouterr().out
    with pytest.raises(SystemExit) as e:
        main(["replay", str(trace), "--model", str(MUTUAL.with_name("mutual_make_fixed.roar"))])
    assert e.value.code == 2
    assert "not the one the trace was recorded on" in capsys.readouterr().err


def test_trace_text_is_not_printed_as_is(tmp_path, capsys):
    """What replay prints comes from the engine; what it quotes from a trace is escaped."""
    trace = clf_trace(tmp_path)
    lines = trace.read_text().splitlines()
    rec = json.loads(lines[1])
    rec["group"] = "\x1b[2J[bold]:100:"
    lines[1] = json.dumps(rec)
    trace.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["replay", str(trace), "--model", str(DL)])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and ":100:" not in out and "[p" in out  # the engine's group, e.g. [p1]


# ------------------------------------------------------------------ 2. budgets in job files

BOUNDS = 'model = "{model}"\n[bounds]\n{key} = {value}\n[expect]\ndeadlock = "violated"\n'


@pytest.mark.parametrize("key,value", [
    ("max_states", "-1"), ("max_states", "0"), ("max_states", "2.5"), ("max_states", "nan"),
    ("max_seconds", "-1"), ("max_seconds", "0"), ("max_seconds", "nan"), ("max_seconds", "inf"),
    ("max_seconds", "-inf"), ("max_seconds", "true"), ("max_seconds", '"10"'), ("max_seconds", "1e300"),
    ("max_memory_mb", "-100"), ("max_memory_mb", "nan"), ("max_memory_mb", "1"), ("max_memory_mb", "100.5"),
])
def test_invalid_budgets_are_refused_at_their_value(tmp_path, capsys, key, value):
    job = write(tmp_path, "j.toml", BOUNDS.format(model=DL, key=key, value=value))
    with pytest.raises(RoarError) as e:
        load_job(job)
    pos = e.value.pos
    assert (pos.file, pos.line, pos.col) == (str(job), 3, len(f"{key} = ") + 1)
    assert e.value.message.startswith(f"[bounds] {key} must be ")
    assert e.value.message.endswith("not " + {"1e300": "1e+300"}.get(value, value))
    with pytest.raises(SystemExit) as e:
        main(["check", str(job), "--no-traces"])
    assert e.value.code == 2
    assert f"{job}:3:{len(key) + 4}: [bounds] {key}" in capsys.readouterr().err.replace("\n", "")


def test_valid_budgets_are_read():
    job = load_job(ROOT / "checker" / "philosophers_dl5.toml")
    assert job.budget.max_states is None or job.budget.max_states >= 1
    assert MIN_MEMORY_MB <= 64


# ------------------------------------------------------------------ 3. time while grounding

COUNTER = """
nat : type.  z : nat.  s : nat -> nat.
c : nat -> type.
inc : c N -o {c (s N)}.
#exec * c z.
"""


@pytest.mark.parametrize("backend", ["auto", "ground"])
def test_the_time_budget_holds_while_grounding(tmp_path, backend):
    """Grounding this 4-line counter never ends (one new fact a round, each round over all
    facts); before, ``max_seconds = 2`` gave no answer in 60 s."""
    write(tmp_path, "count.clf", COUNTER)
    job = write(tmp_path, "j.toml", f'model = "count.clf"\nbackend = "{backend}"\n[bounds]\nmax_seconds = 2\n'
                                    '[expect]\ndeadlock = "holds"\n')
    t = time.perf_counter()
    res = run_job(load_job(job))
    took = time.perf_counter() - t
    assert took < 10, took
    v = res.verdicts["deadlock"]
    assert v.status == "incomplete" and "time budget of 2 s reached while grounding" in v.message
    assert not res.graph.complete and res.backend == "ground"


# ------------------------------------------------------------------ 4. memory

# The peak is VmHWM (this process's own high-water mark): ru_maxrss would also count the
# parent's resident size at the fork (Linux keeps it across exec).
MEMORY_RUN = textwrap.dedent("""
    import re, sys
    from pathlib import Path
    from roar_formal.cli import main
    try:
        main(sys.argv[1:])
    except SystemExit as e:
        code = e.code
    hwm = re.search(r"VmHWM:\\s+(\\d+) kB", Path("/proc/self/status").read_text()).group(1)
    sys.stderr.write("PEAK %s %s\\n" % (hwm, code))
""")


def _toggles(n: int) -> str:
    bits = " ".join(f"b{i} : bit." for i in range(n))
    start = " * ".join(f"off b{i}" for i in range(n))
    return f"bit : type. {bits}\noff : bit -> type. on : bit -> type.\nflip : off B -o {{on B}}.\n#exec * {start}.\n"


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="reads the resident size from /proc")
@pytest.mark.parametrize("backend", ["general", "ground"])
def test_memory_budget_of_100_mb_holds(tmp_path, backend):
    """22 independent switches: 4 million states, about 2.3 GB with the ground backend
    (more with the general one). Before, memory was checked every 1,024 states (the general
    backend) or once a level (the ground one), against the process's peak, so the search
    went hundreds of MB past its budget."""
    write(tmp_path, "toggles.clf", _toggles(22))
    job = write(tmp_path, "j.toml", f'model = "toggles.clf"\nbackend = "{backend}"\n'
                                    '[bounds]\nmax_memory_mb = 100\nmax_seconds = 300\n[expect]\ndeadlock = "violated"\n')
    out = subprocess.run([sys.executable, "-c", MEMORY_RUN, "check", str(job), "--json", "--no-traces"],
                         capture_output=True, text=True, timeout=600)
    peak_kb = int(out.stderr.rsplit("PEAK ", 1)[1].split()[0])
    doc = json.loads(out.stdout)
    v = doc[0]["verdicts"]["deadlock"]
    assert v["status"] == "incomplete" and "memory budget of 100 MiB reached" in v["message"], v
    assert doc[0]["states"] > 1000
    assert peak_kb / 1024 <= 100 * 1.05, f"peak {peak_kb / 1024:.1f} MiB against a budget of 100 MiB"


def test_memory_watch_reads_often_near_the_budget():
    now = current_rss_mb()
    # the same figure the kernel gives in /proc/self/status (read independently), and never above the peak
    status = {k: v for k, _, v in (ln.partition(":") for ln in open("/proc/self/status", encoding="ascii"))}
    assert abs(now - int(status["VmRSS"].split()[0]) / 1024) < 16
    assert now <= rss_mb() + 1
    far = MemoryWatch(now + 10_000)
    assert not far.over(0) and far.next_at > 1  # far from the budget: reads seldom
    near = MemoryWatch(now + 1)
    near.over(0)
    import mmap
    # grows 8 MiB past a budget 1 MiB away: fresh pages from the kernel (a bytearray may reuse
    # memory the process freed earlier, which is resident already)
    blob = mmap.mmap(-1, 8 << 20)
    for off in range(0, 8 << 20, 4096):
        blob[off] = 1
    assert any(near.over(u) for u in range(1, 400))
    assert MemoryWatch(None).over(10 ** 9) is False


# ------------------------------------------------------------------ 5. temporary files

WRITER = textwrap.dedent("""
    import os, sys, time
    from roar_formal.cli import _exit_cleanly_on_sigterm
    from roar_formal.trace import format
    if sys.argv[2] == "handler":
        _exit_cleanly_on_sigterm()
    def hang(*a):
        sys.stdout.write("writing\\n"); sys.stdout.flush()
        time.sleep(60)
    format.os.replace = hang
    format.write_atomic(sys.argv[1], "x" * 100000)
""")


def _killed_writer(target: Path, how: int, handler: str) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-c", WRITER, str(target), handler], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "writing"
    p.send_signal(how)
    p.wait(timeout=30)
    return p


def _temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_sigterm_removes_the_temporary_file(tmp_path):
    target = tmp_path / "t.jsonl"
    p = _killed_writer(target, signal.SIGTERM, "handler")
    assert p.returncode == 128 + signal.SIGTERM
    assert _temporaries(tmp_path) == [] and not target.exists()


def test_a_killed_writers_temporary_file_is_removed_by_the_next_write(tmp_path):
    target = tmp_path / "t.jsonl"
    target.write_text("previous\n")
    p = _killed_writer(target, signal.SIGKILL, "none")
    assert p.returncode == -signal.SIGKILL
    (left,) = _temporaries(tmp_path)
    assert left.startswith(".t.jsonl.") and left.endswith(".tmp")
    assert target.read_text() == "previous\n"  # the earlier file is whole
    write_atomic(tmp_path / "other.jsonl", "new\n")  # any write in the folder cleans up
    assert _temporaries(tmp_path) == []
    # files that are not ours, and temporaries of live processes, stay
    mine = tmp_path / f".u.jsonl.{left.split('.')[3]}.{os.getpid()}-abcd1234.tmp"
    mine.write_text("in progress")
    (tmp_path / ".hidden").write_text("not ours")
    assert remove_stale_temporaries(tmp_path) == []
    assert mine.exists() and (tmp_path / ".hidden").exists()


def test_check_leaves_no_temporary_files(tmp_path):
    with pytest.raises(SystemExit):
        main(["check", str(ROOT / "checker" / "philosophers_dl5.toml"), "--traces", str(tmp_path)])
    assert [p.name for p in tmp_path.iterdir()] == ["philosophers-dl-5.deadlock.jsonl"]


def test_atomic_outputs_get_the_mode_a_plain_write_gives(tmp_path):
    """mkstemp makes private files; an output is readable as any file the user writes (umask), and a
    replaced file keeps its own mode."""
    import os
    import stat
    from roar_formal.trace.format import write_atomic, write_atomic_bytes
    old = os.umask(0o022)
    try:
        write_atomic(tmp_path / "a.jsonl", "x\n")
        write_atomic_bytes(tmp_path / "b.png", b"x")
        assert stat.S_IMODE((tmp_path / "a.jsonl").stat().st_mode) == 0o644
        assert stat.S_IMODE((tmp_path / "b.png").stat().st_mode) == 0o644
        os.chmod(tmp_path / "a.jsonl", 0o600)
        write_atomic(tmp_path / "a.jsonl", "y\n")
        assert stat.S_IMODE((tmp_path / "a.jsonl").stat().st_mode) == 0o600
        assert (tmp_path / "a.jsonl").read_text() == "y\n"
    finally:
        os.umask(old)
