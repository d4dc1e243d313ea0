"""``roar-verify prove``, ``tca-check`` and ``tca-simulate``: the TCA logic from the command line."""

from __future__ import annotations

import json
import random
import sys
from pathlib import Path
from typing import Optional

import typer
from rich.table import Table
from rich.text import Text

from .console import make_console
from ..errors import RoarError

#: the largest value ``tca-simulate --size NAME=N`` accepts (the unrolled tree is bounded too:
#: ``unroll.MAX_MESSAGES``)
MAX_SIZE = 100_000

STATUS_STYLE = {"proved": "green", "consistent": "green", "refuted": "yellow", "inconsistent": "red",
                "unknown": "red", "vacuous": "red"}


def _obligations(models: list[Path]):
    """Every obligation: the axiom set's, then each model's claims (metric ones as model/claim pairs)."""
    from ..tca.model import load_model
    from ..tca.theorems import OBLIGATIONS
    from ..tca.window import claim_obligation

    rows = [(ob.name, ob, None) for ob in OBLIGATIONS]
    for path in models:
        model = load_model(path)
        for claim in model.claims:
            name = f"{model.name}:{claim.name}"
            rows.append((name, None, (model, claim)) if claim.metric else (name, claim_obligation(model, claim), None))
    return rows


def _select(rows, names: list[str]):
    known = {name for name, _, _ in rows}
    unknown = [n for n in names if n not in known]
    if unknown:
        import difflib
        close = [m for n in unknown for m in difflib.get_close_matches(n, sorted(known), n=1, cutoff=0.6)]
        hint = f" (did you mean {', '.join(repr(m) for m in close)}?)" if close else ""
        raise RoarError(f"no obligation named {', '.join(unknown)}{hint}; `roar-verify prove --list` lists them")
    return [r for r in rows if not names or r[0] in names]


def _list_table(rows) -> Table:
    table = Table(title="TCA obligations")
    for col in ("obligation", "expected", "statement"):
        table.add_column(col, overflow="fold")
    for name, ob, metric in rows:
        if ob is not None:
            table.add_row(name, ob.expect, ob.statement)
        else:
            model, claim = metric
            table.add_row(name, "proved", f"{claim.says or claim.holds} iff {claim.bound}")
    return table


def _countermodel_table(name: str, cm) -> Table:
    from ..tca.countermodel import RELATION_LABEL, format_number

    title = f"countermodel for {name}" + (f" at t = {format_number(cm.time)}" if cm.time is not None else "")
    table = Table(title=title, title_justify="left")
    for col in ("message", "kind", "sent", "start", "end", "ach.start", "ach.end"):
        table.add_column(col)
    for r in cm.rows:
        times = [format_number(r.times[k]) if r.times[k] is not None else "-"
                 for k in ("sent", "start", "end", "ach_start", "ach_end")]
        table.add_row(r.label, r.kind, *times)
    relations = [f"{RELATION_LABEL[rel]}: " + ", ".join(f"({a}, {b})" for a, b in pairs)
                 for rel, pairs in cm.relations.items() if pairs]
    table.caption = "; ".join(relations)
    table.caption_justify = "left"
    return table


def _countermodel_reading(name: str, outcome) -> Text:
    """What a countermodel shows, in a sentence: why a refutation is an answer."""
    ob = outcome.obligation
    cm = outcome.countermodel
    at = f" at t = {cm.time}" if cm.time is not None else ""
    ranks = " Only the order of the times matters (any times in that order would do)." if ob.order_only else ""
    return Text(f"{name} is refuted, its claim does not follow from the axioms ({ob.statement}). The countermodel is "
                f"a task tree that satisfies every axiom and the claim's hypotheses, but not its conclusion: each "
                f"message is an element of the model (the claim's names for it in parentheses), with its kind and "
                f"its intervals; the relations under the table are those that hold{at}.{ranks}")


def register(app: typer.Typer) -> None:
    @app.command("prove")
    def prove_command(
        theorems: Optional[list[str]] = typer.Argument(None, help="Obligations to run (default: all)."),
        list_only: bool = typer.Option(False, "--list", help="List the obligations and stop."),
        model: Optional[list[Path]] = typer.Option(None, "--model", help="Also prove a model's claims (TOML)."),
        deps: bool = typer.Option(False, "--deps", help="Show the axioms each proof needs (minimal set)."),
    ) -> None:
        """Prove the TCA axiom set's theorems (and a model's claims); exit 1 if any result is not the expected one."""
        from ..tca.metric import metric_outcome
        from ..tca.prover import dependencies, prove

        console = make_console()
        every = _obligations(list(model or []))
        rows = _select(every, list(theorems or []))
        left = [name for name, _ob, _m in every if ":" in name and all(name != r[0] for r in rows)]
        if theorems and model and left:   # --model given, but the names chosen leave its claims out
            console.print(f"note: {len(left)} claim(s) of --model not run, since obligations were named "
                          f"({', '.join(left[:4])}{', ...' if len(left) > 4 else ''}); name them too, or name none "
                          "to run everything")
        if list_only:
            console.print(_list_table(rows))
            return
        table = Table(title="TCA proof obligations")
        for col in ("obligation", "expected", "result", "time (s)"):
            table.add_column(col, overflow="fold")
        if deps:
            table.add_column("uses", overflow="fold")
        outcomes, failed = [], 0
        for name, ob, metric in rows:
            outcome = prove(ob) if ob is not None else metric_outcome(*metric)
            outcomes.append((name, outcome))
            ok = outcome.ok
            failed += not ok
            style = STATUS_STYLE[outcome.status] if ok else "bold red"
            cells = [name, outcome.obligation.expect, Text(outcome.status, style=style), f"{outcome.seconds:.3f}"]
            if deps:
                used = dependencies(ob) if ob is not None and outcome.status == "proved" else None
                cells.append(", ".join(used) if used else "")
            table.add_row(*cells)
        console.print(table)
        for name, outcome in outcomes:
            if outcome.countermodel is not None and not outcome.obligation.is_consistency:
                console.print(_countermodel_reading(name, outcome))
                console.print(_countermodel_table(name, outcome.countermodel))
            if outcome.reason:
                console.print(f"{name}: {outcome.reason}")
            for line in outcome.details:
                console.print(f"  {line}")
        if failed:
            console.print(f"{failed} obligation(s) did not come out as expected", style="bold red")
            raise typer.Exit(1)

    @app.command("tca-check")
    def tca_check(
        trace: Path = typer.Argument(..., help="A JSON Lines trace (engine run, robot run or counterexample)."),
        as_json: bool = typer.Option(False, "--json", help="Print the result as JSON (the same fields as the table)."),
        model: Optional[Path] = typer.Option(None, "--model", help="Replay the trace on this spec first and read "
                                             "the task tree from the model, not from the trace's own fields."),
        functional: Optional[Path] = typer.Option(None, "--functional",
                                                  help="With --model: this functional-layer module."),
        force: bool = typer.Option(False, "--force", help="With --model: replay even if the spec's sources differ "
                                   "from those the trace records."),
    ) -> None:
        """Check a trace's task tree against the TCA axioms and its declared constraints; exit 1 on violations.

        Without --model the task tree is the trace's own record of its events (a trace is data:
        an edited one checks as edited); with --model SPEC the trace is replayed on the spec and
        its events and sequential-achievement pairs are the model's.
        """
        from ..tca.check import check_trace

        console = make_console()
        if model is None and (functional is not None or force):
            raise RoarError("--functional and --force go with --model SPEC")
        events = None
        if model is not None:
            from ..clf.query import with_big_stack
            from ..verify.replay import model_task_tree
            events = with_big_stack(lambda: model_task_tree(trace, model, functional=functional, force=force))
        report = check_trace(trace, events)
        tree = report.tree
        if as_json:
            doc = {"trace": str(trace), "ok": report.ok, "messages": len(tree.messages),
                   "task_tree_from": "model" if model is not None else "trace", "notes": report.notes,
                   "declared": len(tree.declared), "instances": report.instances, "residual": report.residual,
                   "seconds": round(report.seconds, 6),
                   "violations": [{"rule": v.rule, "from": v.source, "messages": list(dict.fromkeys(v.messages)),
                                   "trace_lines": list(v.lines), "explanation": v.explanation}
                                  for v in report.violations]}
            sys.stdout.write(json.dumps(doc, indent=2) + "\n")
            if not report.ok:
                raise typer.Exit(1)
            return
        console.print(f"{trace}: {len(tree.messages)} messages, {len(tree.declared)} declared constraints, "
                      f"{report.instances} axiom instances ({report.residual} left open, decided by the constraint solver), "
                      f"{report.seconds:.3f} s")
        for note in report.notes:
            console.print(f"note: {note}")
        if report.ok:
            console.print("no violations", style="green")
            return
        table = Table(title=f"{len(report.violations)} violation(s)")
        for col in ("#", "rule", "from", "messages", "trace lines"):
            table.add_column(col, overflow="fold")
        for i, v in enumerate(report.violations, start=1):
            table.add_row(str(i), v.rule, v.source, ", ".join(dict.fromkeys(v.messages)),
                          ", ".join(map(str, v.lines[:10])) + (" ..." if len(v.lines) > 10 else ""))
        console.print(table)
        for i, v in enumerate(report.violations, start=1):
            console.print(f"{i}. {v.explanation}")
        raise typer.Exit(1)

    @app.command("tca-simulate")
    def tca_simulate(
        model: Path = typer.Argument(..., help="A task-tree model (TOML)."),
        out: Optional[Path] = typer.Option(None, "--out", help="Write the trace here (default: stdout)."),
        size: Optional[list[str]] = typer.Option(None, "--size", help="Override a size, e.g. --size arcs=3."),
        seed: int = typer.Option(0, "--seed", help="Seed for the durations drawn within bounds."),
        no_achievement: bool = typer.Option(False, "--no-achievement", help="Leave goals' achievement out."),
    ) -> None:
        """Run a model under TCA's eager dispatching and write the run as a JSON Lines trace."""
        from ..tca.model import load_model
        from ..tca.schedule import sample_timing, simulate
        from ..tca.trace_events import dumps
        from ..tca.unroll import unroll

        from ..trace.format import write_atomic

        loaded = load_model(model)
        sizes = {}
        for item in size or []:
            key, _, value = item.partition("=")
            value = value.strip()
            if key not in loaded.sizes or not (value.isascii() and value.isdigit()) or len(value) > 6 \
                    or not 1 <= int(value) <= MAX_SIZE:
                raise RoarError(f"--size {item}: expected NAME=N with NAME one of {', '.join(loaded.sizes)} "
                                f"and N from 1 to {MAX_SIZE:,}")
            sizes[key] = int(value)
        inst = unroll(loaded, sizes)
        text = dumps(simulate(inst, sample_timing(inst, random.Random(seed)), achievement=not no_achievement))
        if out is None:
            typer.echo(text, nl=False)
        else:
            # through a temporary file: a failed or interrupted write leaves the previous output whole
            try:
                write_atomic(out, text)
            except OSError as exc:
                raise RoarError(f"{out}: cannot write: {exc.strerror or exc}") from None
