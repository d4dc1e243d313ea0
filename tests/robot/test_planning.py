"""Tests for roar_formal.robot.planning: grid, inflation, A*, shortcutting, pure pursuit."""

from __future__ import annotations

import math
import pickle
import time

import networkx as nx
import numpy as np
import pytest

from roar_formal.robot.planning import (OccupancyGrid, PurePursuit, astar, inflate, plan_path, polyline_length,
                                        segment_cells, wheel_speeds)

RES = 0.1
RADIUS = 0.2


def room(w=6.0, h=4.0, t=0.1, **extra):
    g = {"bounds": (0.0, 0.0, w, h),
         "walls": [((0, 0), (w, 0), t), ((w, 0), (w, h), t), ((w, h), (0, h), t), ((0, h), (0, 0), t)],
         "boxes": [], "circles": [], "doors": [], "patches": [], "objects": [], "robot": None, "ptu": None}
    for k, v in extra.items():
        g[k] = list(g.get(k) or []) + list(v) if isinstance(v, list) else v
    return g


def blocked_of(grid, radius=RADIUS):
    return inflate(grid.occupied(), radius, grid.resolution)


def assert_path_clear(grid, path, radius=RADIUS, skip_first_leg=False):
    """Every point sampled densely along the polyline lies in a free cell of the inflated grid."""
    blk = blocked_of(grid, radius)
    legs = list(zip(path, path[1:]))
    if skip_first_leg:
        legs = legs[1:]
    for a, b in legs:
        n = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / (RES / 20)) + 1)
        for t in np.linspace(0.0, 1.0, n):
            x, y = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
            i, j = grid.cell(x, y)
            assert grid.inside(x, y), (x, y)
            assert not blk[i, j], f"({x:.3f}, {y:.3f}) in inflated cell {(i, j)} on leg {a}->{b}"


# ---------------------------------------------------------------------------
# grid


def test_cell_centre_inside_roundtrip():
    g = OccupancyGrid((-1.0, 2.0, 3.0, 4.0), 0.1)
    assert g.shape == (20, 40)
    assert g.cell(-1.0, 2.0) == (0, 0)
    assert g.cell(2.99, 3.99) == (19, 39)
    i, j = g.cell(0.43, 3.17)
    assert (i, j) == (11, 14)
    cx, cy = g.centre(i, j)
    assert cx == pytest.approx(0.45) and cy == pytest.approx(3.15)
    assert g.inside(0.0, 3.0) and not g.inside(3.01, 3.0) and not g.inside(0.0, 1.99)


def test_from_geometry_walls_and_doors():
    geo = room(doors=[{"name": "shut", "from": (2.0, 0.0), "to": (2.0, 4.0), "thickness": 0.05, "open": False},
                      {"name": "ajar", "from": (4.0, 0.0), "to": (4.0, 4.0), "thickness": 0.05, "open": True}],
               boxes=[(1.0, 2.0, 0.4, 0.4, 0.0)], circles=[(5.0, 2.0, 0.3)],
               objects=[{"name": "crate", "kind": "box", "x": 3.0, "y": 1.0, "angle": 0.0, "w": 0.4, "h": 0.4}])
    g = OccupancyGrid.from_geometry(geo, RES)
    occ = g.occupied()
    assert g.known().all()
    for y in np.arange(0.25, 3.8, 0.1):
        assert occ[g.cell(2.0, y)], f"closed door not occupied at y={y}"
        assert not occ[g.cell(4.3, y)]
    # the open door's line is free away from the outer walls
    assert not occ[g.cell(4.0, 2.0)] and not occ[g.cell(4.02, 1.0)]
    assert occ[g.cell(3.0, 0.01)] and occ[g.cell(0.01, 2.0)] and occ[g.cell(5.99, 3.0)]
    assert occ[g.cell(1.0, 2.0)] and occ[g.cell(5.0, 2.0)] and occ[g.cell(5.25, 2.0)]
    assert not occ[g.cell(1.0, 2.5)] and not occ[g.cell(5.0, 2.6)]
    assert not occ[g.cell(3.0, 1.0)], "movable objects are free by default"
    assert OccupancyGrid.from_geometry(geo, RES, objects=True).occupied()[g.cell(3.0, 1.0)]


def test_thin_diagonal_wall_has_no_gaps():
    geo = room(walls=[((1.0, 0.3), (4.7, 3.1), 0.01)])
    g = OccupancyGrid.from_geometry(geo, RES)
    for t in np.linspace(0, 1, 400):
        x, y = 1.0 + t * 3.7, 0.3 + t * 2.8
        assert g.occupied()[g.cell(x, y)]
    assert plan_path(g, (0.5, 3.0), (5.0, 0.5), 0.0) is not None  # around the end
    g8 = OccupancyGrid.from_geometry(room(walls=[((1.0, 0.0), (5.0, 4.0), 0.01)]), RES)
    assert plan_path(g8, (0.5, 3.0), (5.0, 0.5), 0.0) is None        # point robot cannot slip through


def _square_room_scan(pose, lo, hi, n=720, max_range=8.0):
    """Exact ranges inside the axis-aligned square [lo, hi]^2 (walls are the square's sides)."""
    x, y, th = pose
    scan = []
    for k in range(n):
        a = 2 * math.pi * k / n
        c, s = math.cos(th + a), math.sin(th + a)
        ts = []
        if c > 1e-12:
            ts.append((hi - x) / c)
        if c < -1e-12:
            ts.append((lo - x) / c)
        if s > 1e-12:
            ts.append((hi - y) / s)
        if s < -1e-12:
            ts.append((lo - y) / s)
        r = min(ts)
        scan.append((a, r if r < max_range else None))
    return scan


def test_update_square_room_walls_occupied_inside_free():
    g = OccupancyGrid((0.0, 0.0, 6.0, 6.0), RES)
    lo, hi = 1.05, 4.95            # cell centres, so hits are not on cell borders
    pose = (2.7, 3.2, 0.4)
    g.update(pose, _square_room_scan(pose, lo, hi), max_range=8.0)
    occ, known, free = g.occupied(), g.known(), g.free()
    a, b = g.cell(lo, lo)[0], g.cell(hi, hi)[0]
    assert (a, b) == (10, 49)
    for k in range(a + 1, b):      # the four sides, corners excepted
        assert occ[a, k] and occ[b, k] and occ[k, a] and occ[k, b], k
    assert free[a + 1:b, a + 1:b].all()
    assert not occ[a + 1:b, a + 1:b].any()
    assert not known[:a, :].any() and not known[b + 1:, :].any()
    assert not known[:, :a].any() and not known[:, b + 1:].any()
    # a second scan from elsewhere keeps the picture; log-odds stay clamped
    pose2 = (4.0, 1.8, -2.0)
    for _ in range(20):
        g.update(pose2, _square_room_scan(pose2, lo, hi), max_range=8.0)
    assert g.occupied()[a, 30] and g.free()[30, 30]
    assert g.log_odds.max() <= OccupancyGrid.L_MAX and g.log_odds.min() >= OccupancyGrid.L_MIN


def test_update_none_ranges_free_up_to_max_range():
    g = OccupancyGrid((0.0, 0.0, 4.0, 4.0), RES)
    g.update((2.0, 2.0, 0.0), [(2 * math.pi * k / 180, None) for k in range(180)], max_range=1.0)
    assert not g.occupied().any()
    assert g.free()[g.cell(2.0, 2.0)] and g.free()[g.cell(2.9, 2.0)] and g.free()[g.cell(2.0, 1.15)]
    assert not g.known()[g.cell(3.3, 2.0)] and not g.known()[g.cell(2.8, 2.8)]
    # a range at or above max_range is "nothing hit" too
    g2 = OccupancyGrid((0.0, 0.0, 4.0, 4.0), RES)
    g2.update((2.0, 2.0, 0.0), [(0.0, 1.0), (0.5, 5.0)], max_range=1.0)
    assert not g2.occupied().any()


def test_floor_plan_plus_one_scan_shows_new_obstacle():
    """A from_geometry grid used as a prior: one scan marks an unmapped obstacle and keeps the walls."""
    plan = OccupancyGrid.from_geometry(room(), RES)
    g = plan.copy()
    pose = (2.0, 2.0, 0.0)
    # one ray hits an obstacle at x = 3.55 that the plan does not have; the others reach the outer walls
    scan = [(0.0, 1.55), (math.pi, 1.95), (math.pi / 2, 1.95), (-math.pi / 2, 1.95)]
    assert not plan.occupied()[g.cell(3.55, 2.0)]
    g.update(pose, scan, max_range=5.0)
    assert g.occupied()[g.cell(3.55, 2.0)]
    assert g.occupied()[g.cell(0.02, 2.0)] and g.occupied()[g.cell(2.0, 3.98)]
    assert g.free()[g.cell(3.0, 2.0)] and g.free()[g.cell(2.0, 2.0)]
    assert plan_path(g, (2.0, 2.0), (5.0, 2.0), RADIUS) != plan_path(plan, (2.0, 2.0), (5.0, 2.0), RADIUS)
    assert OccupancyGrid.PRIOR_FREE + OccupancyGrid.L_OCC > OccupancyGrid.OCC_THRESHOLD


def test_grid_copy_and_pickle():
    g = OccupancyGrid.from_geometry(room(), RES)
    h = g.copy()
    h.log_odds[5, 5] = 3.0
    assert g.log_odds[5, 5] != 3.0
    assert pickle.loads(pickle.dumps(g)) == g and pickle.loads(pickle.dumps(h)) != g


# ---------------------------------------------------------------------------
# inflation and planning


def test_inflation_blocks_narrow_gap():
    def with_gap(gap):
        lo, hi = 2.0 - gap / 2, 2.0 + gap / 2
        return room(walls=[((3.0, 0.0), (3.0, lo), 0.1), ((3.0, hi), (3.0, 4.0), 0.1)])
    narrow = OccupancyGrid.from_geometry(with_gap(0.35), RES)     # free opening < 0.4 m robot diameter
    assert not narrow.occupied()[narrow.cell(3.0, 2.0)]
    assert plan_path(narrow, (1.0, 2.0), (5.0, 2.0), RADIUS) is None
    # the rasterised opening is 2 cells; a robot well under one cell wide still passes
    assert plan_path(narrow, (1.0, 2.0), (5.0, 2.0), 0.05) is not None
    wide = OccupancyGrid.from_geometry(with_gap(0.8), RES)
    p = plan_path(wide, (1.0, 2.0), (5.0, 2.0), RADIUS)
    assert p is not None
    assert_path_clear(wide, p)


def test_inflation_disc():
    occ = np.zeros((21, 21), dtype=bool)
    occ[10, 10] = True
    blk = inflate(occ, 0.2, 0.1)
    assert blk[10, 12] and blk[12, 10] and blk[11, 12] and not blk[10, 13] and not blk[12, 12]
    assert (blk == blk.T).all() and (blk == blk[::-1, ::-1]).all()
    assert (inflate(occ, 0.0, 0.1) == occ).all()


def test_plans_around_box():
    geo = room(boxes=[(3.0, 2.0, 1.0, 2.4, 0.2)])
    g = OccupancyGrid.from_geometry(geo, RES)
    start, goal = (1.0, 2.0), (5.0, 2.1)
    p = plan_path(g, start, goal, RADIUS)
    assert p is not None and p[0] == start and p[-1] == goal
    assert len(p) >= 3
    assert polyline_length(p) > math.dist(start, goal) + 0.5
    assert_path_clear(g, p)
    assert plan_path(g, start, goal, RADIUS) == p    # deterministic


def test_no_path_when_wall_closes_map():
    g = OccupancyGrid.from_geometry(room(walls=[((3.0, 0.0), (3.0, 4.0), 0.05)]), RES)
    assert plan_path(g, (1.0, 2.0), (5.0, 2.0), RADIUS) is None
    assert plan_path(g, (1.0, 2.0), (2.0, 3.0), RADIUS) is not None


def test_goal_blocked_or_outside_gives_none():
    g = OccupancyGrid.from_geometry(room(boxes=[(3.0, 2.0, 1.0, 1.0, 0.0)]), RES)
    assert plan_path(g, (1.0, 2.0), (3.0, 2.0), RADIUS) is None
    assert plan_path(g, (1.0, 2.0), (3.0, 2.62), RADIUS) is None     # inside the inflation
    assert plan_path(g, (1.0, 2.0), (7.0, 2.0), RADIUS) is None


def test_start_inside_inflation_is_displaced():
    g = OccupancyGrid.from_geometry(room(), RES)
    start = (0.22, 2.0)                      # brushing the left wall
    assert blocked_of(g)[g.cell(*start)]
    p = plan_path(g, start, (4.0, 3.0), RADIUS)
    assert p is not None and p[0] == start and p[-1] == (4.0, 3.0)
    assert math.dist(p[0], p[1]) <= RADIUS + RES
    assert_path_clear(g, p, skip_first_leg=True)


def test_unknown_cells():
    g = OccupancyGrid((0.0, 0.0, 4.0, 4.0), RES)
    assert plan_path(g, (0.5, 0.5), (3.5, 3.5), RADIUS) == [(0.5, 0.5), (3.5, 3.5)]
    assert plan_path(g, (0.5, 0.5), (3.5, 3.5), RADIUS, unknown_is_free=False) is None


def test_bool_array_input_with_origin():
    g = OccupancyGrid.from_geometry({**room(boxes=[(3.0, 2.0, 1.0, 2.4, 0.0)]), "bounds": (10.0, 20.0, 16.0, 24.0)}, RES)
    # the same room shifted: a bool array with an origin plans the shifted path
    g0 = OccupancyGrid.from_geometry(room(boxes=[(3.0, 2.0, 1.0, 2.4, 0.0)]), RES)
    p0 = plan_path(g0, (1.0, 2.0), (5.0, 2.0), RADIUS)
    p1 = plan_path(g0.occupied(), (11.0, 22.0), (15.0, 22.0), RADIUS, resolution=RES, origin=(10.0, 20.0))
    assert p0 is not None and p1 is not None and len(p0) == len(p1)
    for a, b in zip(p0, p1):
        assert b[0] - 10.0 == pytest.approx(a[0]) and b[1] - 20.0 == pytest.approx(a[1])
    with pytest.raises(ValueError):
        plan_path(g0.occupied(), (1.0, 2.0), (5.0, 2.0), RADIUS)
    assert g.shape == g0.shape


def _random_world(seed, w=6.0, h=4.0):
    rng = np.random.default_rng(seed)
    boxes = [(float(rng.uniform(1.0, w - 1.0)), float(rng.uniform(0.5, h - 0.5)), float(rng.uniform(0.2, 1.2)),
              float(rng.uniform(0.2, 1.2)), float(rng.uniform(0, math.pi))) for _ in range(6)]
    circles = [(float(rng.uniform(1.0, w - 1.0)), float(rng.uniform(0.5, h - 0.5)), float(rng.uniform(0.1, 0.4)))
               for _ in range(3)]
    return OccupancyGrid.from_geometry(room(w, h, boxes=boxes, circles=circles), RES)


def _dijkstra_cost(blocked, s, t):
    """Independent oracle: networkx Dijkstra on the same 8-connected grid without corner cutting."""
    ny, nx_ = blocked.shape
    G = nx.Graph()
    free = lambda i, j: 0 <= i < ny and 0 <= j < nx_ and not blocked[i, j]
    for i in range(ny):
        for j in range(nx_):
            if not free(i, j):
                continue
            G.add_node((i, j))
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                a, b = i + di, j + dj
                if not free(a, b):
                    continue
                if di and dj:
                    if not (free(i + di, j) and free(i, j + dj)):
                        continue
                    G.add_edge((i, j), (a, b), weight=math.sqrt(2))
                else:
                    G.add_edge((i, j), (a, b), weight=1.0)
    try:
        return nx.dijkstra_path_length(G, s, t)
    except (nx.NetworkXNoPath, nx.NodeNotFound):
        return None


@pytest.mark.parametrize("seed", range(10))
def test_astar_matches_dijkstra_and_shortcut_is_no_longer(seed):
    g = _random_world(seed)
    blk = blocked_of(g)
    free_pts = [(x, y) for x in (0.5, 0.8, 5.2, 5.5) for y in (0.5, 1.0, 2.0, 3.0, 3.5) if not blk[g.cell(x, y)]]
    start = min(free_pts, key=lambda p: (p[0], p[1]))
    goal = max(free_pts, key=lambda p: (p[0], p[1]))
    s, t = g.cell(*start), g.cell(*goal)
    found = astar(blk, s, t)
    oracle = _dijkstra_cost(blk, s, t)
    if oracle is None:
        assert found is None and plan_path(g, start, goal, RADIUS) is None
        return
    cells, cost = found
    assert cost == pytest.approx(oracle, abs=1e-9)
    assert cells[0] == s and cells[-1] == t
    steps = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(cells, cells[1:])]
    assert sum(steps) == pytest.approx(cost) and all(st in (1.0, math.sqrt(2)) for st in steps)
    raw = [start] + [g.centre(i, j) for i, j in cells] + [goal]
    p = plan_path(g, start, goal, RADIUS)
    assert p is not None and p[0] == start and p[-1] == goal
    assert polyline_length(p) <= polyline_length(raw) + 1e-9
    assert_path_clear(g, p)


def test_segment_cells_cover_every_point():
    rng = np.random.default_rng(7)
    segs = [tuple(rng.uniform(-3, 3, 4)) for _ in range(200)]
    segs += [(0.5, 0.5, 3.5, 3.5), (0.5, 2.5, 3.5, -0.5), (1.0, 1.0, 4.0, 1.0), (2.0, 0.3, 2.0, -4.2)]
    for u0, v0, u1, v1 in segs:
        cells = set(segment_cells(u0, v0, u1, v1))
        for t in np.linspace(0, 1, 300):
            u, v = u0 + t * (u1 - u0), v0 + t * (v1 - v0)
            assert (math.floor(v), math.floor(u)) in cells
    # exact diagonal through corners includes both side cells
    assert {(0, 1), (1, 0)} <= set(segment_cells(0.5, 0.5, 1.5, 1.5))


def test_planning_time_12_by_6():
    geo = room(12.0, 6.0, walls=[((4.0, 0.0), (4.0, 4.5), 0.1), ((8.0, 6.0), (8.0, 1.5), 0.1)],
               boxes=[(2.0, 3.0, 1.0, 0.6, 0.3), (10.0, 4.0, 0.8, 0.8, 0.0)], circles=[(6.0, 2.0, 0.4)])
    g = OccupancyGrid.from_geometry(geo, RES)
    plan_path(g, (0.5, 0.5), (11.5, 0.5), RADIUS)
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        p = plan_path(g, (0.5, 0.5), (11.5, 0.5), RADIUS)
        best = min(best, time.perf_counter() - t0)
    assert p is not None
    assert_path_clear(g, p)
    assert best < 0.25       # ~7 ms measured; generous for a loaded machine


# ---------------------------------------------------------------------------
# following


def _dist_to_path(p, path):
    best = math.inf
    for a, b in zip(path, path[1:]):
        dx, dy = b[0] - a[0], b[1] - a[1]
        t = max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)))
        best = min(best, math.hypot(a[0] + t * dx - p[0], a[1] + t * dy - p[1]))
    return best


def _drive(pp, pose, dt=0.05, steps=2000):
    x, y, th = pose
    poses = [pose]
    for _ in range(steps):
        if pp.done((x, y, th)):
            break
        v, w = pp.command((x, y, th))
        x += v * math.cos(th) * dt
        y += v * math.sin(th) * dt
        th += w * dt
        poses.append((x, y, th))
    return poses


def test_pure_pursuit_follows_l_path():
    path = [(0.0, 0.0), (3.0, 0.0), (3.0, 2.0)]
    pp = PurePursuit(path)
    poses = _drive(pp, (0.0, 0.0, 0.0))
    x, y, _ = poses[-1]
    assert pp.done(poses[-1]) and math.hypot(x - 3.0, y - 2.0) <= 0.1
    assert max(_dist_to_path(p, path) for p in poses) <= 0.3
    assert pp.progress == 1 and pp.remaining(poses[-1]) < 0.15
    assert pp.command(poses[-1]) == (0.0, 0.0)


def test_pure_pursuit_offset_start_and_pickle():
    path = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    pp = PurePursuit(path, lookahead=0.4, speed=0.5)
    poses = _drive(pp, (0.1, -0.2, 0.3), steps=30)
    clone = pickle.loads(pickle.dumps(pp))
    assert clone.command(poses[-1]) == pp.command(poses[-1])
    rest = _drive(pp, poses[-1])
    assert pp.done(rest[-1])
    assert max(_dist_to_path(p, path) for p in poses + rest) <= 0.3
    # progress never went backwards and the remaining distance shrank
    assert pp.progress == 2


def test_pure_pursuit_turns_in_place_when_target_behind():
    pp = PurePursuit([(0.0, 0.0), (-2.0, 0.0)])
    v, w = pp.command((0.0, 0.0, 0.0))
    assert v == 0.0 and w != 0.0
    poses = _drive(pp, (0.0, 0.0, 0.0))
    assert pp.done(poses[-1])
    assert max(abs(p[1]) for p in poses) <= 0.3


def test_pure_pursuit_never_goes_backwards_along_path():
    # a hairpin: the return leg passes close to the start; progress must not jump to it or back
    path = [(0.0, 0.0), (2.0, 0.0), (2.0, 0.3), (0.0, 0.3)]
    pp = PurePursuit(path, lookahead=0.3)
    pp.command((0.2, 0.0, 0.0))
    assert pp.progress == 0
    seen = []
    for p in _drive(pp, (0.2, 0.0, 0.0)):
        seen.append(pp.progress)
    assert seen == sorted(seen)
    assert pp.progress == 2


def test_pure_pursuit_slows_near_goal():
    pp = PurePursuit([(0.0, 0.0), (5.0, 0.0)], speed=0.5)
    v_far, _ = pp.command((1.0, 0.0, 0.0))
    v_near, _ = pp.command((4.7, 0.0, 0.0))
    assert v_far == pytest.approx(0.5) and 0 < v_near < v_far
    assert PurePursuit([(1.0, 1.0)]).done((1.05, 1.0, 0.0))
    assert PurePursuit([(0.0, 0.0), (5.0, 0.0)]).remaining((1.0, 0.2, 0.0)) == pytest.approx(4.0)


def test_wheel_speeds():
    left, right = wheel_speeds(0.5, 0.0, 0.3, 0.05, 20.0)
    assert left == pytest.approx(10.0) and right == pytest.approx(10.0)
    left, right = wheel_speeds(0.0, 1.0, 0.3, 0.05, 20.0)
    assert left == pytest.approx(-3.0) and right == pytest.approx(3.0)
    left, right = wheel_speeds(1.0, 2.0, 0.3, 0.05, 10.0)   # 14, 26 rad/s unscaled
    assert max(abs(left), abs(right)) == pytest.approx(10.0)
    assert left / right == pytest.approx(14.0 / 26.0)



@pytest.mark.parametrize("cx, cy, r", [(5.0, 3.0, 0.1), (5.03, 3.07, 0.15), (6.0, 2.95, 0.3)])
def test_the_base_passes_a_lone_pillar_without_its_safety_stop(tmp_path, cx, cy, r):
    """A shortest path brushes a pillar at the robot's radius, where the follower's safety stop
    (radius + 5 cm) halted the base until it gave up (every time, whatever the pillar); the
    robot plans with room beyond the stop's margin where there is room."""
    from roar_formal.robot.robot import Robot
    from roar_formal.robot.scenario import load_scenario
    from repo import ROOT
    text = (ROOT / "models/scenarios/clear.toml").read_text()
    head, robot = text.split("# a table", 1)[0], "[robot]" + text.split("[robot]", 1)[1]
    scen = tmp_path / "pillar.toml"
    scen.write_text(f"{head}[[obstacle]]\ncircle = [{cx}, {cy}, {r}]\n\n{robot}")
    sc = load_scenario(scen)

    def drive(path):
        rb = Robot(sc)
        rb.follow(path)
        waited = 0
        while rb.follow_state in ("following", "waiting") and rb.time < 60:
            rb.step()
            waited += rb.follow_state == "waiting"
        return rb.follow_state, waited

    rb = Robot(sc)
    x, y, _ = rb.world.base.odometry
    tight = plan_path(rb.known_grid(), (x, y), (10.5, 3.0), sc.robot.radius, resolution=rb.resolution,
                      origin=rb.floor_plan.origin)
    assert drive(tight)[0] == "blocked"           # the old plan: the stop halts the base for good
    assert drive(rb.plan_to((10.5, 3.0))) == ("arrived", 0)


def test_clearance_gives_way_in_a_gap_too_narrow_for_it():
    """A gap wide enough for the robot but not for the room wanted is planned as without clearance."""
    lo, hi = 2.0 - 0.4, 2.0 + 0.4
    gap = OccupancyGrid.from_geometry(room(walls=[((3.0, 0.0), (3.0, lo), 0.1), ((3.0, hi), (3.0, 4.0), 0.1)]), RES)
    assert plan_path(gap, (1.0, 2.0), (5.0, 2.0), RADIUS + 0.05 + RES) is None
    through = plan_path(gap, (1.0, 2.0), (5.0, 2.0), RADIUS, clearance=0.05 + RES)
    assert through is not None and through == plan_path(gap, (1.0, 2.0), (5.0, 2.0), RADIUS)
    # in the open, the room is kept: the path is the one planned for the wider disc
    g = OccupancyGrid.from_geometry(room(circles=[(3.0, 2.0, 0.15)]), RES)
    assert plan_path(g, (1.0, 2.05), (5.0, 2.05), RADIUS, clearance=0.15) == \
        plan_path(g, (1.0, 2.05), (5.0, 2.05), RADIUS + 0.15)
