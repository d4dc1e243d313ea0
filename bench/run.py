"""Run the benchmarks in ``bench/``: ``python bench/run.py [b1 b2 ...] [--repeats N] [--quick]``.

Every module ``bench/bN_*.py`` is a benchmark; it exposes ``NAME``, ``TITLE``
and ``run(repeats=..., quick=...) -> dict`` returning its measurements and
``tables`` (title, columns, rows of strings) to print. With no names, all of
them run, in order. Each result is written atomically (a temporary file, then
``os.replace``) to ``bench/results/NAME.json`` together with the machine and
the date. Benchmarks report; they never assert timings (the test suite does
not run them).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import importlib.util
import json
import os
import platform
import re
import sys
import tempfile
import time
from pathlib import Path

BENCH_DIR = Path(__file__).resolve().parent
ROOT = BENCH_DIR.parent
RESULTS_DIR = BENCH_DIR / "results"
_MODULE_RE = re.compile(r"^(b\d+)_\w+\.py$")

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def discover() -> dict[str, Path]:
    """Short name (``b1``) -> module file, in numeric order."""
    found = {}
    for p in BENCH_DIR.glob("b*_*.py"):
        m = _MODULE_RE.match(p.name)
        if m:
            found[m.group(1)] = p
    return dict(sorted(found.items(), key=lambda kv: int(kv[0][1:])))


def load(name: str, path: Path):
    mod_name = f"_roar_bench_{path.stem}"
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    spec = importlib.util.spec_from_file_location(mod_name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = mod
    spec.loader.exec_module(mod)
    return mod


def write_json_atomic(path: Path, data: dict) -> None:
    """Results go through the project's atomic writer (temporary file, then rename)."""
    from roar_formal.trace.format import write_atomic

    write_atomic(path, json.dumps(data, indent=2, sort_keys=False, default=str) + "\n")


def machine() -> dict:
    return {
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
    }


def print_tables(result: dict, console) -> None:
    from rich.table import Table

    for spec in result.get("tables", ()):
        table = Table(title=spec["title"], title_justify="left")
        for col in spec["columns"]:
            table.add_column(col, justify="right")
        for row in spec["rows"]:
            table.add_row(*[str(x) for x in row])
        console.print(table)
    for note in result.get("notes", ()):
        console.print(f"  [dim]{note}[/dim]")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="benchmarks to run (b1, b2, ...); default: all")
    ap.add_argument("--repeats", type=int, default=5, help="runs per configuration (medians are reported)")
    ap.add_argument("--quick", action="store_true", help="small sizes only (a smoke run)")
    ap.add_argument("--no-write", action="store_true", help="do not write bench/results/NAME.json")
    args = ap.parse_args(argv)

    from rich.console import Console

    console = Console(width=None if sys.stdout.isatty() else 150)
    available = discover()
    names = args.names or list(available)
    unknown = [n for n in names if n not in available]
    if unknown:
        console.print(f"[red]unknown benchmark(s): {', '.join(unknown)}; "
                      f"available: {', '.join(available)}[/red]")
        return 2
    for name in names:
        mod = load(name, available[name])
        console.print(f"[bold]{name}[/bold]: {getattr(mod, 'TITLE', name)}")
        t0 = time.perf_counter()
        result = mod.run(repeats=args.repeats, quick=args.quick)
        wall = time.perf_counter() - t0
        result = {
            **result,
            "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "machine": machine(),
            "quick": args.quick,
            "wall_s": wall,
        }
        print_tables(result, console)
        if not args.no_write:
            out = RESULTS_DIR / f"{name}.json"
            write_json_atomic(out, result)
            console.print(f"  [dim]wrote {out.relative_to(ROOT)} ({wall:.1f} s)[/dim]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
