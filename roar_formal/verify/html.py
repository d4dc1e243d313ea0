"""``roar-verify check --html DIR``: one self-contained HTML report of a run of jobs.

The folder holds ``index.html`` (the summary table, then per job each verdict with its
counterexample in ROAR terms), ``charts/`` (the message sequence chart of each
counterexample as SVG, from :mod:`~roar_formal.verify.pictures`), ``traces/`` (a copy of
each saved counterexample trace, linked from the page) and ``report.json`` (the same data
as ``check --json``). The page is static: no script, no network access; the counterexample
text comes from :func:`~roar_formal.verify.report.counterexample_report`, the one source
the printed report, ``--json`` and the charts read. Every file is written atomically
(:func:`~roar_formal.trace.format.write_atomic_bytes`), ``index.html`` last, so a reader
never sees a page that links files not yet written.
"""

from __future__ import annotations

import json
from html import escape
from pathlib import Path

from ..errors import RoarError
from ..trace.format import write_atomic_bytes
from .report import counterexample_report, replay_command
from .results import safe_name

__all__ = ["write_html_report", "render_index"]

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em 2em; color: #222; background: #fff; }
h1 { font-size: 1.5em; } h2 { font-size: 1.25em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.05em; }
table { border-collapse: collapse; margin: 0.6em 0; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #eef2f7; }
.holds { color: #137a13; font-weight: bold; } .violated { color: #b00000; font-weight: bold; }
.incomplete { color: #a06a00; font-weight: bold; }
.ok { color: #137a13; } .unexpected { color: #b00000; font-weight: bold; }
.steps td.n { text-align: right; color: #666; } .loop { background: #fff6e0; }
.cycle { color: #b00000; font-weight: bold; }
img.chart { max-width: 100%; border: 1px solid #ddd; background: #fff; }
code, pre { font-family: ui-monospace, monospace; font-size: 0.92em; }
code.internal { color: #888; }
"""


def _status(status: str) -> str:
    return f'<span class="{escape(status)}">{escape(status)}</span>'


def _result_word(r) -> tuple[str, str]:
    if r.ok and not r.incomplete:
        return "as expected", "ok"
    if r.ok:
        return "incomplete", "incomplete"
    return "unexpected", "unexpected"


def _summary(results) -> list[str]:
    props = sorted({p for r in results for p in r.verdicts})
    out = ['<table id="summary"><tr><th>job</th>'
           + "".join(f"<th>{escape(p)}</th>" for p in props)
           + "<th>states</th><th>time</th><th>result</th></tr>"]
    for i, r in enumerate(results):
        cells = []
        for p in props:
            v = r.verdicts.get(p)
            if v is None:
                cells.append("<td>-</td>")
                continue
            want = r.job.expect.get(p)
            mark = "" if want is None or want == v.status else f" (want {escape(want)})"
            cells.append(f"<td>{_status(v.status)}{mark}</td>")
        word, cls = _result_word(r)
        out.append(f'<tr><td><a href="#job-{i}">{escape(r.job.name)}</a></td>{"".join(cells)}'
                   f'<td>{r.graph.n_states:,}</td><td>{r.seconds:.2f} s</td>'
                   f'<td class="{cls}">{word}</td></tr>')
    out.append("</table>")
    return out


def _steps(rep: dict, is_roar: bool) -> list[str]:
    out = ['<table class="steps"><tr><th>#</th><th>agent</th><th>what happened</th></tr>']
    hidden = 0
    # does the cycle (if any) have a step with a ROAR event? If not, its engine steps are shown
    loop_shown = any(s["loop"] and (s["changes"] or any(ev["kind"] != "write" for ev in s["events"]))
                     for s in rep["steps"])
    for s in rep["steps"]:
        cls = ' class="loop"' if s["loop"] else ""
        if not is_roar:
            out.append(f'<tr{cls}><td class="n">{s["step"]}</td><td>{escape(s["group"])}</td>'
                       f'<td><code>{escape(s["rule"])}</code></td></tr>')
            continue
        lines = [escape(ev["text"]) for ev in s["events"] if ev["kind"] != "write"]
        lines += [f"{escape(ch['var'])}: {escape(str(ch['old']))} &rarr; {escape(str(ch['new']))}"
                  for ch in s["changes"]]
        agents = [ev["agent"] for ev in s["events"] if ev["kind"] != "write"] + [ch["agent"] for ch in s["changes"]]
        agent = agents[0] if agents else s["group"]
        if not lines:
            # an engine step with no ROAR event: left out, as the text report leaves it out, unless
            # the cycle has nothing else to show
            if not (s["loop"] and not loop_shown):
                hidden += 1
                continue
            lines = [f'<code class="internal" title="engine step">{escape(s["rule"])}</code>']
        out.append(f'<tr{cls}><td class="n">{s["step"]}</td><td>{escape(agent)}</td>'
                   f'<td>{"<br>".join(lines)}</td></tr>')
    out.append("</table>")
    if hidden:
        out.append(f"<p>{hidden} engine step{'s' if hidden != 1 else ''} with no ROAR event "
                   f"{'are' if hidden != 1 else 'is'} not shown (the step numbers count them; "
                   "<code>roar-verify replay TRACE --verbose</code> shows every step).</p>")
    if any(s["loop"] for s in rep["steps"]):
        out.append("<p>Shaded steps form the cycle, which repeats forever.</p>")
    return out


def _final(rep: dict, shape: str) -> list[str]:
    final = rep.get("final")
    if final is None:
        return []
    head = "final state" if shape == "path" else "state where the cycle starts"
    if "facts" in final:
        return [f"<h4>{head}</h4>", "<pre>" + escape("\n".join(final["facts"])) + "</pre>"]
    out = [f"<h4>{head}</h4>", '<table class="final"><tr><th>agent</th><th>variables</th><th>requests</th>'
           "<th>activities</th></tr>"]
    for agent, row in final.items():
        vs = ", ".join(f"{k} = {val}" for k, val in sorted(row["variables"].items())) or "-"
        reqs = "<br>".join(escape(f"{r['request']} {r['constraint']}: {r['state']}") for r in row["requests"]) or "-"
        acts = []
        for a in row["activities"]:
            handles = f" (for {a['request']})" if a.get("request") else ""
            what = f": {a['text']}" if a.get("text") else ""
            acts.append(escape(f"{a['status']}: {a['task']}.{a['recipe']}{handles}{what}"))
        out.append(f"<tr><td>{escape(agent)}</td><td>{escape(vs)}</td><td>{reqs}</td>"
                   f"<td>{'<br>'.join(acts) or '-'}</td></tr>")
    out.append("</table>")
    dl = rep.get("deadlock")
    if dl is not None:
        if dl["cycle"]:
            cyc = dl["cycle"]
            out.append(f'<p class="cycle">wait-for cycle: {escape(" -> ".join(cyc + [cyc[0]]))}</p><ul>')
            for a, b in zip(cyc, cyc[1:] + cyc[:1]):
                why = "; ".join(e["why"] for e in dl["wait_for"] if e["from"] == a and e["to"] == b)
                whom = "its own variables" if a == b else escape(b)
                out.append(f"<li>{escape(a)} waits for {whom}: {escape(why)}</li>")
            out.append("</ul>")
        else:
            out.append('<p class="cycle">no wait-for cycle between agents: the blocked activities wait for no '
                       "agent</p>")
    return out


def render_index(results, charts: dict, traces: dict, title: str = "roar-verify check") -> str:
    """The page: ``charts`` and ``traces`` map (job index, property) to a path relative to the page."""
    body = [f"<h1>{escape(title)}</h1>"]
    n_bad = sum(1 for r in results if not r.ok)
    n_inc = sum(1 for r in results if r.ok and r.incomplete)
    body.append(f'<p id="overall">{len(results)} job{"s" if len(results) != 1 else ""}: '
                f'{len(results) - n_bad - n_inc} as expected, {n_bad} unexpected, {n_inc} incomplete.</p>')
    body += _summary(results)
    for i, r in enumerate(results):
        word, cls = _result_word(r)
        job = r.job
        model = job.spec if job.is_roar else job.model
        body.append(f'<section class="job" id="job-{i}"><h2>{escape(job.name)} '
                    f'<span class="{cls}">({word})</span></h2>')
        req = f", request <code>{escape(str(job.request))}</code>" if job.is_roar and job.request else ""
        body.append(f"<p>model <code>{escape(str(model))}</code>{req}; {r.graph.n_states:,} states, "
                    f"{r.graph.n_edges + r.graph.n_unrecorded:,} transitions, {r.seconds:.2f} s, backend {escape(str(r.backend))}.</p>")
        robot = getattr(r, "robot", None)
        if robot is not None:
            body.append(f"<p>robot: {escape(robot.describe())}</p>")
        for m in r.unexpected:
            body.append(f'<p class="unexpected">{escape(m)}</p>')
        for p, v in r.verdicts.items():
            want = job.expect.get(p)
            exp = f" (expected: {escape(want)})" if want else ""
            body.append(f'<div class="verdict" data-property="{escape(p)}" data-status="{escape(v.status)}">'
                        f"<h3>{escape(p)}: {_status(v.status)}{exp}</h3><p>{escape(v.message)}</p>")
            if v.counterexample is not None:
                rep = counterexample_report(r, p)
                chart = charts.get((i, p))
                if chart:
                    body.append(f'<p><img class="chart" src="{escape(chart)}" '
                                f'alt="message sequence chart of the {escape(p)} counterexample"></p>')
                body.append(f"<h4>counterexample ({escape(rep['shape'])}, {len(rep['steps'])} steps)</h4>")
                body += _steps(rep, getattr(r, "roar", None) is not None)
                body += _final(rep, rep["shape"])
                tr = traces.get((i, p))
                if tr:
                    body.append(f'<p>trace: <a class="trace" href="{escape(tr)}">{escape(tr)}</a> '
                                f"(<code>{escape(replay_command(job, tr))}</code>)</p>")
            body.append("</div>")
        body.append("</section>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{escape(title)}</title><link rel=\"stylesheet\" href=\"style.css\"></head>\n<body>\n"
            + "\n".join(body) + "\n</body></html>\n")


#: the file a report folder holds to say an --html report wrote it, listing the report's files
MARKER = ".roar-verify-report"


def check_report_folder(folder: Path, opt: str = "--html") -> list[str]:
    """Refuse a report folder that holds files no --html report wrote (a user's own files would be
    overwritten or mixed with the report's); the files an earlier report wrote there (listed in its
    marker), which the new report replaces."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    present = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    if not present:
        return []
    marker = folder / MARKER
    if not marker.is_file():
        shown = ", ".join(present[:3]) + (f" and {len(present) - 3} more" if len(present) > 3 else "")
        raise RoarError(f"{opt} {folder}: the folder holds files no report of roar-verify wrote ({shown}); "
                        "give a new or empty folder, or one an earlier --html report wrote (nothing of "
                        "yours is overwritten)")
    try:
        listed = [x for x in marker.read_text(encoding="utf-8").splitlines() if x]
    except (OSError, UnicodeDecodeError) as exc:
        raise RoarError(f"{opt} {marker}: cannot read it: {exc}") from None
    ours = {x for x in listed if not Path(x).is_absolute() and ".." not in Path(x).parts} | {MARKER}
    others = [x for x in present if x not in ours]
    if others:
        raise RoarError(f"{opt} {folder}: the folder holds files the earlier report there did not write "
                        f"({', '.join(others[:3])}{' ...' if len(others) > 3 else ''}); give a new or empty folder")
    return sorted(ours - {MARKER})


def write_html_report(folder: Path, results, json_docs: list, inputs: tuple = ()) -> Path:
    """Write the report into ``folder``; returns the path of ``index.html``.

    ``json_docs`` is what ``check --json`` prints for ``results`` (written as report.json).
    A file that is an input of the command is never overwritten; a folder holding files no report
    wrote is refused (:func:`check_report_folder`), and an earlier report's files the new one does
    not write again (charts and traces of verdicts that changed) are removed."""
    from .pictures import render_chart
    folder = Path(folder)
    earlier = check_report_folder(folder)
    inputs_resolved = {Path(x).resolve() for x in inputs}
    written: list[str] = []

    def put(rel: str, data: bytes) -> None:
        path = folder / rel
        if path.resolve() in inputs_resolved:
            raise RoarError(f"{path}: is an input of this command; not overwritten")
        if rel not in earlier:   # listed before it is written: a report stopped half-way is still ours
            _mark(sorted(set(earlier) | set(written) | {rel}))
        write_atomic_bytes(path, data)
        written.append(rel)

    def _mark(files: list) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        write_atomic_bytes(folder / MARKER, ("\n".join(files) + "\n").encode("utf-8"))

    charts: dict = {}
    traces: dict = {}
    for i, r in enumerate(results):
        for p, v in r.verdicts.items():
            if v.counterexample is None:
                continue
            stem = f"{i}-{safe_name(r, p)}"
            try:
                data = render_chart(r, p, "svg")
            except RoarError:   # nothing to draw (no step): the text report stands alone
                data = None
            if data is not None:
                put(f"charts/{stem}.svg", data)
                charts[(i, p)] = f"charts/{stem}.svg"
            saved = getattr(r, "saved", {}).get(p)
            if saved:
                try:
                    put(f"traces/{stem}.jsonl", Path(saved).read_bytes())
                except OSError as exc:
                    raise RoarError(f"{saved}: cannot read the saved trace: {exc.strerror or exc}") from None
                traces[(i, p)] = f"traces/{stem}.jsonl"
    put("style.css", _CSS.lstrip().encode("utf-8"))
    put("report.json", (json.dumps(json_docs, indent=2) + "\n").encode("utf-8"))
    put("index.html", render_index(results, charts, traces).encode("utf-8"))
    _mark(written)
    for rel in set(earlier) - set(written):   # the earlier report's, not this one's: stale
        try:
            (folder / rel).unlink()
        except OSError:
            pass
    return folder / "index.html"
