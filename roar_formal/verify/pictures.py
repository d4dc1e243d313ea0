"""Pictures of counterexamples: a message sequence chart (PNG, SVG) and the state graph (DOT).

The chart is drawn from :func:`~roar_formal.verify.report.counterexample_report`, so it
shows what the text shows: one lifeline per agent, each constraint sent as an arrow
from its sender to the agent that handles it, state changes, primitive calls and
variable changes as notes, and, at a deadlock, the wait-for cycle as red arrows.
Output is deterministic (no dates or software names, a fixed SVG hash salt), so a
picture in the docs or a CI artifact changes only when the counterexample does.
"""

from __future__ import annotations

import io
from typing import Optional
from pathlib import Path

from ..errors import RoarError
from ..trace.format import write_atomic_bytes
from .report import counterexample_report
from .results import safe_name

#: the largest graph written as DOT: beyond it a drawing is unreadable and slow to lay out
DOT_MAX_STATES = 3000
#: the most rows a chart draws; the rest is summarised in one note
CHART_MAX_ROWS = 400
_NOTE_CHARS = 44
_SPACING = 3.2


def _short(text: str, n: int = _NOTE_CHARS) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


def _rows(rep: dict) -> tuple[list[str], list[tuple]]:
    """The agents, in order of appearance, and the chart's rows: ('arrow', a, b, label),
    ('note', agent, text, colour), ('cycle',) where a lasso's cycle starts."""
    agents: list[str] = []

    def see(a):
        if a and a not in agents:
            agents.append(a)

    rows: list[tuple] = []
    reqs = rep.get("requests") or {}
    roar = rep.get("final") is not None and "facts" not in rep["final"]
    for s in rep["steps"]:
        if s["loop"] and not any(r[0] == "cycle" for r in rows):
            rows.append(("cycle",))
        if not roar:
            see(s["group"])
            rows.append(("note", s["group"], f"{s['step']}. {s['rule']}", "#eeeeee"))
            continue
        for ev in s["events"]:
            if ev["kind"] == "write":
                continue
            see(ev["agent"])
            if ev["kind"] == "sent" and ev.get("request") in reqs:
                target = reqs[ev["request"]]["agent"]
                see(target)
                label = f"{s['step']}. {ev.get('rkind', 'make')} {ev['request']}: {reqs[ev['request']]['constraint']}"
                rows.append(("arrow", ev["agent"], target, label))
            else:
                colour = {"state": "#e3ecfa", "primitive-start": "#fff3cf", "primitive-end": "#fff3cf"}.get(
                    ev["kind"], "#eeeeee")
                text = ev["text"]
                if ev["kind"] == "state" and ev.get("request"):   # the constraint is on the arrow that sent it
                    text = f"{ev['request']} {ev.get('from') or 'new'} -> {ev['to']}"
                rows.append(("note", ev["agent"], f"{s['step']}. {text}", colour))
        for ch in s["changes"]:
            see(ch["agent"])
            change = f"{ch['var']}: {ch['old']} -> {ch['new']}" if ch.get("old") is not None \
                else f"{ch['var']} = {ch['new']}"
            rows.append(("note", ch["agent"], f"{s['step']}. {change}", "#e4f5e0"))
    if roar:
        for a in rep["final"]:
            see(a)
    dl = rep.get("deadlock")
    if dl:
        for b in dl["blocked"]:
            on = f"make {b['on']}" if b.get("on") else (b.get("text") or b["status"]).split(": until")[0]
            rows.append(("note", b["agent"], f"blocked: {b['task']}.{b['recipe']} in {on}", "#fbdada"))
    if len(rows) > CHART_MAX_ROWS:
        n = len(rows) - CHART_MAX_ROWS
        rows = rows[:CHART_MAX_ROWS] + [("note", agents[0], f"... {n} more rows (see the text report)", "#ffffff")]
    return agents, rows


def sequence_chart(res, prop: str):
    """The message sequence chart of the counterexample of ``prop``: (fig, ax, artists).

    ``artists`` names what a test or a caller may check: ``lifelines`` and ``heads`` (per
    agent), ``arrows`` ([(sender, target, label, artist)]), ``notes`` (text artists),
    ``cycle`` ([(a, b, artist)], the deadlock's wait-for cycle) and ``cycle_label``."""
    rep = counterexample_report(res, prop)
    v = res.verdicts[prop]
    return chart_of_report(rep, f"{res.job.name}: {prop} {v.status} ({v.counterexample.kind} of "
                                f"{v.counterexample.length()} steps)", f"{res.job.name}: the {prop} counterexample")


def chart_of_report(rep: dict, title: str, what: str):
    """The message sequence chart of a report in the form of :func:`counterexample_report`
    (a counterexample, a replayed trace, a run): (fig, ax, artists) as :func:`sequence_chart`."""
    from matplotlib.figure import Figure
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    agents, rows = _rows(rep)
    if not agents:
        raise RoarError(f"{what} has no step to draw")
    dl = rep.get("deadlock") or {}
    cycle = dl.get("cycle") or []
    n_rows = len(rows) + (3 if cycle else 0)
    x = {a: i * _SPACING for i, a in enumerate(agents)}
    width = max(6.0, 0.9 * _SPACING * len(agents) + 1.5)
    height = 1.6 + 0.3 * n_rows
    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.02, 0.02, 0.96, 0.96 - 0.5 / height))
    ax.set_axis_off()
    ax.set_xlim(-_SPACING / 2, x[agents[-1]] + _SPACING / 2)
    ax.set_ylim(-(n_rows + 0.5), 1.0)
    fig.suptitle(title, fontsize=10, y=1 - 0.15 / height)
    artists: dict = {"lifelines": {}, "heads": {}, "arrows": [], "notes": [], "cycle": [], "cycle_label": None}
    for a in agents:
        (line,) = ax.plot([x[a], x[a]], [0.3, -(n_rows + 0.3)], color="#555555", lw=1, ls="--", zorder=1,
                          gid=f"lifeline-{a}")
        artists["lifelines"][a] = line
        artists["heads"][a] = ax.text(x[a], 0.5, a, ha="center", va="center", fontsize=9, fontweight="bold",
                                      bbox={"boxstyle": "round,pad=0.3", "fc": "#dfe7f2", "ec": "#333333"},
                                      zorder=3)
    for k, row in enumerate(rows, 1):
        y = -k
        if row[0] == "cycle":
            ax.axhline(y, color="#c77c00", lw=1, ls=":")
            artists["notes"].append(ax.text(x[agents[0]] - _SPACING / 2 + 0.05, y + 0.12,
                                            "cycle (repeats forever)", fontsize=7, color="#c77c00"))
        elif row[0] == "arrow":
            _, a, b, label = row
            if a == b:
                ann = ax.annotate("", xy=(x[b] + 0.05, y - 0.15), xytext=(x[a] + 0.05, y + 0.15),
                                  arrowprops={"arrowstyle": "->", "connectionstyle": "arc3,rad=-1.2", "lw": 1.2})
                tx, ha = x[a] + 0.5, "left"
            else:
                ann = ax.annotate("", xy=(x[b], y), xytext=(x[a], y), arrowprops={"arrowstyle": "->", "lw": 1.2})
                tx, ha = (x[a] + x[b]) / 2, "center"
            t = ax.text(tx, y + 0.1, _short(label, 60), ha=ha, va="bottom", fontsize=7)
            artists["arrows"].append((a, b, label, ann))
            artists["notes"].append(t)
        else:
            _, a, text, colour = row
            artists["notes"].append(ax.text(x[a], y, _short(text), ha="center", va="center", fontsize=7, zorder=3,
                                            bbox={"boxstyle": "round,pad=0.2", "fc": colour, "ec": "#999999",
                                                  "lw": 0.5}))
    if cycle:
        y = -(len(rows) + 1.4)
        pairs = list(zip(cycle, cycle[1:] + cycle[:1]))
        for i, (a, b) in enumerate(pairs):
            off = 0.3 * (i - (len(pairs) - 1) / 2)
            if a == b:
                ann = ax.annotate("", xy=(x[a] + 0.05, y + off - 0.2), xytext=(x[a] + 0.05, y + off + 0.2),
                                  arrowprops={"arrowstyle": "-|>", "color": "#c00000", "lw": 2,
                                              "connectionstyle": "arc3,rad=-1.2"})
            else:
                ann = ax.annotate("", xy=(x[b], y + off), xytext=(x[a], y + off),
                                  arrowprops={"arrowstyle": "-|>", "color": "#c00000", "lw": 2,
                                              "connectionstyle": "arc3,rad=0.15"})
            ann.set_gid(f"wait-for-{a}-{b}")
            on = sorted({e["request"] for e in dl.get("wait_for", []) if e["from"] == a and e["to"] == b
                         and e["request"]})
            if a != b:
                ax.text((x[a] + x[b]) / 2, y + off + (0.32 if x[b] < x[a] else -0.32),
                        f"{a} waits for {b}" + (f" ({', '.join(on)})" if on else ""), ha="center", va="center",
                        fontsize=7, color="#c00000")
            artists["cycle"].append((a, b, ann))
        text = "deadlock: wait-for cycle " + " → ".join(cycle + [cycle[0]])
        artists["cycle_label"] = ax.text((x[agents[0]] + x[agents[-1]]) / 2, -(len(rows) + 2.9), text,
                                         ha="center", va="center", fontsize=9, color="#c00000", fontweight="bold")
    return fig, ax, artists


def render_chart(res, prop: str, fmt: str) -> bytes:
    """The chart as PNG or SVG bytes, identical for identical counterexamples."""
    return figure_bytes(sequence_chart(res, prop)[0], fmt)


def figure_bytes(fig, fmt: str) -> bytes:
    """A figure as PNG or SVG bytes, with no date or software stamp (identical figures, identical bytes)."""
    import matplotlib
    buf = io.BytesIO()
    meta = {"Software": None} if fmt == "png" else {"Date": None, "Creator": None}
    with matplotlib.rc_context({"svg.hashsalt": "roar-formal", "svg.fonttype": "path"}):
        fig.savefig(buf, format=fmt, metadata=meta)
    return buf.getvalue()


def state_graph_dot(res, prop: str, max_states: int = DOT_MAX_STATES) -> str:
    """The explored state graph in DOT, the counterexample's path in red (a lasso's cycle too)."""
    g = res.graph
    if g.n_states > max_states:
        raise RoarError(f"{res.job.name}: the state graph has {g.n_states:,} states; --dot draws at most "
                        f"{max_states:,} (a larger drawing is unreadable): lower the job's bounds or draw a "
                        "smaller model")
    v = res.verdicts[prop]
    cx = v.counterexample
    on_path = set(cx.prefix) | set(cx.cycle) if cx is not None else set()
    marked = {int(g.src[e]) for e in on_path} | {int(g.dst[e]) for e in on_path}
    lines = [f"digraph {_q(safe_name(res, prop))} {{", "  rankdir=TB;",
             '  node [shape=circle, fontsize=9, width=0.3, fixedsize=false];', "  edge [fontsize=7];"]
    final = cx.final_state if cx is not None else None
    for s in range(g.n_states):
        attrs = [f"label={_q(str(s))}"]
        if s == 0:
            attrs.append("shape=doublecircle")
        if s in marked:
            attrs += ['color="#c00000"', "penwidth=2"]
        if s == final and cx.kind == "path":
            attrs += ["style=filled", 'fillcolor="#fbdada"']
        if not g.expanded[s]:
            attrs.append("style=dashed")
        lines.append(f"  s{s} [{', '.join(attrs)}];")
    for e in range(g.n_edges):
        label = f"{g.groups.names[int(g.group[e])]}: {g.labels.names[int(g.label[e])]}"
        attrs = [f"label={_q(label)}"]
        if e in on_path:
            attrs += ['color="#c00000"', "penwidth=2.5", 'fontcolor="#c00000"']
        lines.append(f"  s{int(g.src[e])} -> s{int(g.dst[e])} [{', '.join(attrs)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def write_pictures(res, png: Path | None, svg: Path | None, dot: Path | None, inputs: tuple = ()) -> dict:
    """One file per property with a counterexample in each folder given; {prop: [paths, or notes
    (str) saying why a DOT file was not written]}.
    A file that is an input of the command is never overwritten."""
    out: dict = {}
    inputs_resolved = {Path(x).resolve() for x in inputs}
    for p, v in res.verdicts.items():
        if v.counterexample is None:
            continue
        stem = safe_name(res, p)
        for folder, fmt in ((png, "png"), (svg, "svg"), (dot, "dot")):
            if folder is None:
                continue
            path = Path(folder) / f"{stem}.{fmt}"
            if path.resolve() in inputs_resolved:
                raise RoarError(f"{path}: is an input of this command; not overwritten")
            if fmt == "dot":
                try:
                    data = state_graph_dot(res, p).encode("utf-8")
                except RoarError as exc:   # too large: the other pictures and jobs still go on
                    out.setdefault(p, []).append(f"no DOT file: {exc.message}")
                    continue
            else:
                data = render_chart(res, p, fmt)
            write_atomic_bytes(path, data)
            out.setdefault(p, []).append(path)
        robot = getattr(res, "robot", None)
        if robot is not None and png is not None:   # robot-backed: the trajectory as well
            path = Path(png) / f"{stem}.robot.png"
            if path.resolve() in inputs_resolved:
                raise RoarError(f"{path}: is an input of this command; not overwritten")
            robot.draw_counterexample(res, p, path)
            out.setdefault(p, []).append(path)
    return out


def check_output_folder(folder: Path, option: str, inputs: list[Path]) -> None:
    """Refuse, before any work, a folder that cannot take the pictures (a file, unwritable, an input)."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise RoarError(f"{option} {folder}: not a folder")
    for parent in [folder, *folder.parents]:
        if parent.exists():
            if not parent.is_dir():
                raise RoarError(f"{option} {folder}: {parent} is not a folder")
            import os
            if not os.access(parent, os.W_OK | os.X_OK):
                raise RoarError(f"{option} {folder}: {parent} is not writable")
            break
    resolved = {Path(p).resolve() for p in inputs}
    if folder.resolve() in resolved:
        raise RoarError(f"{option} {folder}: is an input of this command")
    from ..outputs import read_by_spec_folder
    inside = next((d for d in resolved if d.is_dir() and read_by_spec_folder(d, folder.resolve(), True)), None)
    if inside is not None:
        raise RoarError(f"{option} {folder}: is inside {inside}, a folder this command reads as its input (a hyper "
                        "spec's): files written there would be read as part of it; write them elsewhere")


def write_chart(rep: dict, title: str, what: str, png: Optional[Path], svg: Optional[Path]) -> list[Path]:
    """Draw the chart of a report into the PNG and SVG files asked for (atomically)."""
    out = []
    if png is None and svg is None:
        return out
    fig = chart_of_report(rep, title, what)[0]
    for path, fmt in ((png, "png"), (svg, "svg")):
        if path is not None:
            write_atomic_bytes(path, figure_bytes(fig, fmt))
            out.append(Path(path))
    return out
