"""Pictures of robot runs: the world, the map, planned and driven paths, events (PNG).

matplotlib is imported inside the functions, so importing this module costs
nothing for runs that draw nothing. Figures are built on a private Agg canvas
(no pyplot, no global figure state) under matplotlib's default style, and
saved without a software/date stamp, so the same inputs give byte-identical
files. Files are written atomically like traces: a reader never sees half a
PNG and a failed write leaves no temporary file behind.
"""

from __future__ import annotations

import io
import math
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Sequence

from ..trace.format import write_atomic_bytes

WALL = "#222222"
OBSTACLE = "#8c8c8c"
DOOR = "#8b4513"
PATCH = "#add8e6"
OBJECT = "#ff8c00"
ROBOT = "#444444"
DRIVEN = "#1f77b4"
MARK = "#d62728"
EVENT = "#555555"
PLANNED = ("#2ca02c", "#9467bd", "#17becf", "#e377c2", "#bcbd22", "#7f7f7f")
MAX_EVENTS = 12
EVENT_FONT = 6.5
DPI = 100


@contextmanager
def _style():
    """matplotlib's default style whatever the caller configured, for reproducible pictures."""
    import matplotlib
    with matplotlib.rc_context():
        matplotlib.rcdefaults()
        matplotlib.rcParams["svg.hashsalt"] = "roar-formal"
        matplotlib.rcParams["path.simplify"] = False
        yield


def _new_figure(size: Sequence[float], dpi: int):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(float(size[0]), float(size[1])), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig, path_png: str | Path) -> None:
    """Render ``fig`` to PNG (fixed pixel size, no metadata stamp) and write it atomically."""
    buf = io.BytesIO()
    with _style():
        fig.savefig(buf, format="png", dpi=fig.dpi, metadata={"Software": None})
    write_atomic_bytes(path_png, buf.getvalue())


# ---------------------------------------------------------------------------
# the world


def _thick_segment(a, b, thickness: float) -> list[tuple[float, float]]:
    """The rectangle a wall of ``thickness`` around segment a-b covers (a tiny square for a point)."""
    (ax, ay), (bx, by) = (float(a[0]), float(a[1])), (float(b[0]), float(b[1]))
    dx, dy = bx - ax, by - ay
    L = math.hypot(dx, dy)
    h = 0.5 * float(thickness)
    if L == 0:
        return [(ax - h, ay - h), (ax + h, ay - h), (ax + h, ay + h), (ax - h, ay + h)]
    nx, ny = -dy / L * h, dx / L * h
    return [(ax + nx, ay + ny), (bx + nx, by + ny), (bx - nx, by - ny), (ax - nx, ay - ny)]


def _box(cx, cy, w, h, ang) -> list[tuple[float, float]]:
    c, s = math.cos(float(ang)), math.sin(float(ang))
    out = []
    for lx, ly in ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)):
        out.append((float(cx) + lx * c - ly * s, float(cy) + lx * s + ly * c))
    return out


def _draw_world(ax, geometry: dict) -> None:
    from matplotlib.patches import Circle, Polygon, Rectangle
    x0, y0, x1, y1 = (float(v) for v in geometry["bounds"])
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="#bbbbbb", linewidth=0.8, zorder=1))
    for (px0, py0, px1, py1, mu) in geometry.get("patches", ()):
        ax.add_patch(Rectangle((min(px0, px1), min(py0, py1)), abs(px1 - px0), abs(py1 - py0),
                               facecolor=PATCH, edgecolor="none", alpha=0.6, zorder=2))
        ax.text((px0 + px1) / 2, (py0 + py1) / 2, f"\u03bc={float(mu):g}", ha="center", va="center",
                fontsize=7, color="#1f4e79", zorder=2)
    for (a, b, t) in geometry.get("walls", ()):
        ax.add_patch(Polygon(_thick_segment(a, b, t), closed=True, facecolor=WALL, edgecolor=WALL,
                             linewidth=1.0, zorder=4))
    for (cx, cy, w, h, ang) in geometry.get("boxes", ()):
        ax.add_patch(Polygon(_box(cx, cy, w, h, ang), closed=True, facecolor=OBSTACLE, edgecolor="#555555",
                             linewidth=0.8, zorder=4))
    for (cx, cy, r) in geometry.get("circles", ()):
        ax.add_patch(Circle((cx, cy), r, facecolor=OBSTACLE, edgecolor="#555555", linewidth=0.8, zorder=4))
    for door in geometry.get("doors", ()):
        poly = _thick_segment(door["from"], door["to"], max(float(door.get("thickness", 0.05)), 0.02))
        if door.get("open", False):
            ax.add_patch(Polygon(poly, closed=True, fill=False, edgecolor=DOOR, linestyle="--",
                                 linewidth=1.0, zorder=4))
        else:
            ax.add_patch(Polygon(poly, closed=True, facecolor=DOOR, edgecolor=DOOR, linewidth=1.0, zorder=4))
        mx = (door["from"][0] + door["to"][0]) / 2
        my = (door["from"][1] + door["to"][1]) / 2
        ax.text(mx, my, f" {door.get('name', '')}", fontsize=7, color=DOOR, ha="left", va="center", zorder=6)
    for o in geometry.get("objects", ()):
        if o.get("kind") == "circle":
            ax.add_patch(Circle((o["x"], o["y"]), o["r"], facecolor=OBJECT, edgecolor="#a65c00",
                                linewidth=0.8, zorder=5))
        else:
            ax.add_patch(Polygon(_box(o["x"], o["y"], o["w"], o["h"], o.get("angle", 0.0)), closed=True,
                                 facecolor=OBJECT, edgecolor="#a65c00", linewidth=0.8, zorder=5))
        ax.text(o["x"], o["y"], str(o.get("name", "")), fontsize=7, ha="center", va="center", zorder=6)
    robot = geometry.get("robot")
    if robot:
        x, y, th = float(robot["x"]), float(robot["y"]), float(robot.get("theta", 0.0))
        r = float(robot.get("radius", 0.2))
        ax.add_patch(Circle((x, y), r, facecolor="#dddddd", edgecolor=ROBOT, linewidth=1.2, alpha=0.9,
                            zorder=7, label="robot"))
        ax.plot([x, x + r * math.cos(th)], [y, y + r * math.sin(th)], color=ROBOT, linewidth=1.5, zorder=8)
    ptu = geometry.get("ptu")
    if ptu:
        x, y, a = float(ptu["x"]), float(ptu["y"]), float(ptu.get("angle_rad", 0.0))
        s = 0.15
        tip = (x + s * math.cos(a), y + s * math.sin(a))
        left = (x + 0.5 * s * math.cos(a + 2.5), y + 0.5 * s * math.sin(a + 2.5))
        right = (x + 0.5 * s * math.cos(a - 2.5), y + 0.5 * s * math.sin(a - 2.5))
        ax.add_patch(Polygon([tip, left, right], closed=True, facecolor="#000000", edgecolor="#000000",
                             linewidth=0.5, zorder=9))


def _grid_shade(grid):
    """Grey level per cell: free white, unknown light, suspected mid, occupied dark by confidence.

    Drawn by state rather than raw probability because a floor-plan grid's
    free cells sit only mildly below p = 0.5, which would make free floor
    and unexplored floor look alike.
    """
    import numpy as np
    lo = grid.log_odds.astype(np.float64)
    occ, known = grid.occupied(), grid.known()
    conf = np.clip(lo / grid.L_MAX, 0.0, 1.0)
    return np.where(~known, 0.2, np.where(lo < 0, 0.0, np.where(occ, 0.6 + 0.4 * conf, 0.4)))


def _short(text: str, n: int = 42) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= n else text[:n - 1] + "\u2026"


def render_run(geometry: dict, *, grid=None, planned: Iterable = (), driven: Iterable = (),
               events: Iterable = (), marks: Iterable = (), title: str | None = None,
               size: Sequence[float] = (8, 5), dpi: int = DPI):
    """Build the run figure and return ``(fig, ax)`` without saving (tests map data to pixels with it)."""
    planned = [(str(label), [(float(p[0]), float(p[1])) for p in pts]) for label, pts in planned]
    driven = [tuple(float(v) for v in d[:4]) for d in driven]
    events = [(float(e[0]), float(e[1]), float(e[2]), str(e[3])) for e in events]
    marks = [(float(m[0]), float(m[1]), str(m[2]) if len(m) > 2 else "") for m in marks]
    with _style():
        fig = _new_figure(size, dpi)
        # the map on the left; a column on the right for the legend and the event list
        ax = fig.add_axes((0.07, 0.1, 0.64, 0.82))
        x0, y0, x1, y1 = (float(v) for v in geometry["bounds"])
        if grid is not None:
            ax.imshow(_grid_shade(grid), origin="lower", extent=grid.extent, cmap="Greys", vmin=0.0, vmax=1.0,
                      interpolation="nearest", alpha=0.8, zorder=0)
        _draw_world(ax, geometry)
        for n, (label, pts) in enumerate(planned):
            if pts:
                xs, ys = zip(*pts)
                ax.plot(xs, ys, linestyle="--", linewidth=1.4, color=PLANNED[n % len(PLANNED)], label=label,
                        zorder=10)
        if driven:
            xs = [d[1] for d in driven]
            ys = [d[2] for d in driven]
            ax.plot(xs, ys, linestyle="-", linewidth=1.8, color=DRIVEN, label="driven", zorder=11)
            ax.plot(xs[:1], ys[:1], marker="o", markersize=6, color=DRIVEN, linestyle="none", zorder=12,
                    label="start")
            ax.plot(xs[-1:], ys[-1:], marker="s", markersize=6, color=DRIVEN, linestyle="none", zorder=12,
                    label="end")
        shown = events[:MAX_EVENTS]
        for n, (t, x, y, text) in enumerate(shown, 1):
            ax.plot([x], [y], marker="o", markersize=4, color=EVENT, linestyle="none", zorder=13)
            ax.annotate(str(n), (x, y), xytext=(3, 3), textcoords="offset points", fontsize=7, color=EVENT,
                        zorder=13)
        for n, (x, y, text) in enumerate(marks):
            ax.plot([x], [y], marker="X", markersize=11, color=MARK, linestyle="none", zorder=14,
                    label="failure" if n == 0 else None)
            if text:
                ax.annotate(_short(text, 30), (x, y), xytext=(6, -10), textcoords="offset points", fontsize=7,
                            color=MARK, zorder=14)
        if shown:
            # monospace glyphs are ~0.6 em wide: cut lines to the column's width
            width = int(0.26 * float(size[0]) * 72.0 / (0.6 * EVENT_FONT))
            lines = [_short(f"{n}. t={t:.2f}s {text}", width) for n, (t, _, _, text) in enumerate(shown, 1)]
            if len(events) > MAX_EVENTS:
                lines.append(f"... (+{len(events) - MAX_EVENTS} more)")
            fig.text(0.735, 0.55, "\n".join(lines), fontsize=EVENT_FONT, va="top", ha="left", family="monospace")
        mx = 0.02 * max(x1 - x0, y1 - y0)
        ax.set_xlim(x0 - mx, x1 + mx)
        ax.set_ylim(y0 - mx, y1 + mx)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if title:
            ax.set_title(title, fontsize=10)
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            fig.legend(handles, labels, loc="upper left", bbox_to_anchor=(0.73, 0.93), fontsize=7, frameon=False)
    return fig, ax


def draw_run(path_png: str | Path, geometry: dict, *, grid=None, planned: Iterable = (), driven: Iterable = (),
             events: Iterable = (), marks: Iterable = (), title: str | None = None,
             size: Sequence[float] = (8, 5), dpi: int = DPI) -> None:
    """Draw a run over its world (see :func:`render_run`) and write it to ``path_png`` atomically."""
    fig, _ = render_run(geometry, grid=grid, planned=planned, driven=driven, events=events, marks=marks,
                        title=title, size=size, dpi=dpi)
    save_png(fig, path_png)


# ---------------------------------------------------------------------------
# the pan-tilt unit


def render_ptu(times: Sequence[float], angles_deg: Sequence[float], targets_deg: Sequence[float] | None = None,
               limits: Sequence[float] | None = None, title: str | None = None,
               size: Sequence[float] = (6, 3), dpi: int = DPI):
    """Pan angle over time, with commanded targets (steps) and the cable limits; returns ``(fig, ax)``."""
    times = [float(t) for t in times]
    with _style():
        fig = _new_figure(size, dpi)
        ax = fig.add_axes((0.12, 0.17, 0.84, 0.7))
        ax.plot(times, [float(a) for a in angles_deg], color=DRIVEN, linewidth=1.5, label="pan")
        if targets_deg is not None:
            ax.step(times, [float(a) for a in targets_deg], where="post", color=PLANNED[0], linestyle="--",
                    linewidth=1.2, label="target")
        if limits is not None:
            lo, hi = (float(v) for v in limits)
            for n, v in enumerate((lo, hi)):
                ax.axhline(v, color=MARK, linestyle=":", linewidth=1.2, label="limit" if n == 0 else None)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("pan [deg]")
        if title:
            ax.set_title(title, fontsize=10)
        ax.legend(loc="upper left", fontsize=7)
    return fig, ax


def draw_ptu(path_png: str | Path, times: Sequence[float], angles_deg: Sequence[float],
             targets_deg: Sequence[float] | None = None, limits: Sequence[float] | None = None,
             title: str | None = None) -> None:
    """Plot the pan angle over time (the cable-wrap scenario) and write it atomically."""
    fig, _ = render_ptu(times, angles_deg, targets_deg, limits, title)
    save_png(fig, path_png)
