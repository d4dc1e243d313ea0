"""Tests for roar_formal.robot.draw: valid, deterministic, atomic PNGs that show what they should."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from roar_formal.errors import RoarError
from roar_formal.robot import draw
from roar_formal.robot.planning import OccupancyGrid, plan_path

WALL_FROM, WALL_TO = (6.0, 0.5), (6.0, 4.0)


def geometry():
    return {
        "bounds": (0.0, 0.0, 12.0, 6.0),
        "walls": [((0, 0), (12, 0), 0.1), ((12, 0), (12, 6), 0.1), ((12, 6), (0, 6), 0.1), ((0, 6), (0, 0), 0.1),
                  (WALL_FROM, WALL_TO, 0.15)],
        "boxes": [(3.0, 4.0, 1.0, 0.6, 0.4)],
        "circles": [(9.0, 2.0, 0.4)],
        "doors": [{"name": "d1", "from": (6.0, 4.0), "to": (6.0, 5.0), "thickness": 0.08, "open": False},
                  {"name": "d2", "from": (6.0, 5.0), "to": (6.0, 6.0), "thickness": 0.08, "open": True}],
        "patches": [(1.0, 0.5, 3.0, 2.0, 0.3)],
        "objects": [{"name": "crate", "kind": "box", "x": 8.0, "y": 4.5, "angle": 0.2, "w": 0.5, "h": 0.4},
                    {"name": "ball", "kind": "circle", "x": 10.5, "y": 4.5, "r": 0.2}],
        "robot": {"x": 10.0, "y": 1.0, "theta": 0.5, "radius": 0.2},
        "ptu": {"x": 10.0, "y": 1.0, "angle_rad": 1.2},
    }


def run_inputs():
    geo = geometry()
    grid = OccupancyGrid.from_geometry(geo, 0.1)
    plan = plan_path(grid, (1.0, 1.0), (10.0, 1.0), 0.2)
    assert plan is not None
    driven = [(0.1 * k, 1.0 + 9.0 * k / 50, 1.0 + 0.8 * math.sin(k / 8), 0.0) for k in range(51)]
    events = [(0.5 * k, driven[k * 3][1], driven[k * 3][2], f"event number {k} with a rather long description")
              for k in range(15)]
    return dict(grid=grid, planned=[("plan", plan), ("replan", plan[::-1])], driven=driven, events=events,
                marks=[(7.0, 1.5, "step 12 failed")], title="a run")


def rgb(img, x_px, y_px):
    """Pixel at display coordinates (origin bottom-left) of an image read by imread (origin top-left)."""
    h = img.shape[0]
    return img[h - 1 - int(round(y_px)), int(round(x_px)), :3]


def test_draw_run_valid_png_of_expected_size(tmp_path):
    import matplotlib.image as mpimg
    out = tmp_path / "sub" / "run.png"
    draw.draw_run(out, geometry(), **run_inputs())
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(out)
    assert img.shape[:2] == (500, 800)
    draw.draw_run(tmp_path / "small.png", geometry(), size=(4, 3))
    assert mpimg.imread(tmp_path / "small.png").shape[:2] == (300, 400)
    assert sorted(p.name for p in out.parent.iterdir()) == ["run.png"]


def test_draw_run_is_byte_identical(tmp_path):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    draw.draw_run(a, geometry(), **run_inputs())
    draw.draw_run(b, geometry(), **run_inputs())
    assert a.read_bytes() == b.read_bytes()
    assert b"Software" not in a.read_bytes() and b"matplotlib" not in a.read_bytes()


def test_draw_run_identical_across_processes(tmp_path):
    a = tmp_path / "a.png"
    draw.draw_run(a, geometry(), **run_inputs())
    code = ("import sys, matplotlib; matplotlib.rcParams['lines.linewidth'] = 7;"
            "from tests.robot.test_draw import geometry, run_inputs;"
            "from roar_formal.robot.draw import draw_run;"
            "draw_run(sys.argv[1], geometry(), **run_inputs())")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    subprocess.run([sys.executable, "-c", code, str(tmp_path / "b.png")], check=True, cwd=root)
    assert a.read_bytes() == (tmp_path / "b.png").read_bytes()


def test_wall_pixels_dark_and_trajectory_colour_present(tmp_path):
    import matplotlib.image as mpimg
    from matplotlib.colors import to_rgb
    inputs = run_inputs()
    inputs.pop("grid")                       # keep the background white so the wall stands out
    out = tmp_path / "run.png"
    draw.draw_run(out, geometry(), **inputs)
    img = mpimg.imread(out)
    fig, ax = draw.render_run(geometry(), **inputs)
    fig.canvas.draw()
    for t in np.linspace(0.3, 0.95, 15):      # above where the driven line crosses the wall
        x = WALL_FROM[0] + t * (WALL_TO[0] - WALL_FROM[0])
        y = WALL_FROM[1] + t * (WALL_TO[1] - WALL_FROM[1])
        px, py = ax.transData.transform((x, y))
        assert rgb(img, px, py).max() < 0.3, f"wall not dark at ({x}, {y})"
    # background away from everything is light
    px, py = ax.transData.transform((4.5, 5.5))
    assert rgb(img, px, py).min() > 0.8
    # the driven line's colour is in the picture, along the line
    target = np.array(to_rgb(draw.DRIVEN))
    close = np.abs(img[:, :, :3] - target).max(axis=2) < 0.05
    assert close.sum() > 200
    _, x, y, _ = inputs["driven"][20]
    px, py = ax.transData.transform((x, y))
    h = img.shape[0]
    r, c = h - 1 - int(round(py)), int(round(px))
    assert close[r - 2:r + 3, c - 2:c + 3].any()
    # the failure mark is red
    px, py = ax.transData.transform((7.0, 1.5))
    red = rgb(img, px, py)
    assert red[0] > 0.7 and red[1] < 0.4 and red[2] < 0.4


def test_grid_drawn_underneath(tmp_path):
    import matplotlib.image as mpimg
    g = OccupancyGrid((0.0, 0.0, 12.0, 6.0), 0.1)
    g.log_odds[:, 60:] = 4.0                 # right half occupied
    geo = {"bounds": (0.0, 0.0, 12.0, 6.0)}
    out = tmp_path / "grid.png"
    draw.draw_run(out, geo, grid=g)
    img = mpimg.imread(out)
    fig, ax = draw.render_run(geo, grid=g)
    fig.canvas.draw()
    left = rgb(img, *ax.transData.transform((3.0, 3.0)))
    right = rgb(img, *ax.transData.transform((9.0, 3.0)))
    assert right.mean() < left.mean() - 0.3


def test_minimal_geometry(tmp_path):
    draw.draw_run(tmp_path / "m.png", {"bounds": (0, 0, 2, 1), "ptu": None, "robot": None})
    assert (tmp_path / "m.png").exists()


def test_unwritable_path_raises_and_leaves_nothing(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(RoarError, match="cannot write"):
        draw.draw_run(blocker / "run.png", geometry())
    # the target is a directory: the temporary file is made, the rename fails, the temp is removed
    target = tmp_path / "out.png"
    target.mkdir()
    (target / "keep").write_text("x")
    with pytest.raises(RoarError, match=r"out\.png: cannot write"):
        draw.draw_run(target, geometry())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "out.png"]
    assert sorted(p.name for p in target.iterdir()) == ["keep"]


def test_failed_write_keeps_earlier_file(tmp_path, monkeypatch):
    out = tmp_path / "run.png"
    draw.draw_run(out, geometry())
    before = out.read_bytes()

    def boom(src, dst):
        raise OSError(28, "No space left on device")
    import roar_formal.trace.format as trace_format   # the project's one atomic writer
    monkeypatch.setattr(trace_format.os, "replace", boom)
    with pytest.raises(RoarError, match="cannot write"):
        draw.draw_run(out, geometry(), title="new")
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["run.png"]


def test_draw_ptu(tmp_path):
    import matplotlib.image as mpimg
    t = [0.1 * k for k in range(100)]
    ang = [200 * math.sin(k / 20) for k in range(100)]
    tgt = [180.0 if k < 50 else -180.0 for k in range(100)]
    a, b = tmp_path / "p1.png", tmp_path / "p2.png"
    draw.draw_ptu(a, t, ang, tgt, limits=(-270, 270), title="pan")
    draw.draw_ptu(b, t, ang, tgt, limits=(-270, 270), title="pan")
    assert a.read_bytes() == b.read_bytes()
    assert mpimg.imread(a).shape[:2] == (300, 600)
    draw.draw_ptu(tmp_path / "p3.png", t, ang)
    with pytest.raises(RoarError):
        draw.draw_ptu(a / "x.png", t, ang)


def test_import_is_cheap():
    code = "import sys, roar_formal.robot.draw; print('matplotlib' in sys.modules)"
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, cwd=root)
    assert out.stdout.strip() == "False"
