"""Mapping, path planning and path following for the reference robot (numpy only).

* :class:`OccupancyGrid` - a log-odds grid updated from range scans, or built
  exactly from the world geometry (the ground truth a planner may be given).
* :func:`inflate` and :func:`plan_path` - A* on the grid grown by the robot
  radius, so a path of cell centres is a path of collision-free robot centres.
* :class:`PurePursuit` and :func:`wheel_speeds` - follow the planned polyline
  with a differential-drive robot.

Everything is deterministic: integer ray traversal, a heap with explicit
tie-breaks, no randomness and no clock. All objects are plain data and pickle,
because they are part of a robot snapshot.

Index convention: arrays are ``[i, j]`` with ``i`` the row (y) and ``j`` the
column (x); cell ``(i, j)`` covers ``x0 + j*res <= x < x0 + (j+1)*res`` and
``y0 + i*res <= y < y0 + (i+1)*res``.
"""

from __future__ import annotations

import heapq
import math
from typing import Iterable, Iterator, Sequence

import numpy as np

SQRT2 = math.sqrt(2.0)

Point = tuple[float, float]


# ---------------------------------------------------------------------------
# occupancy grid


class OccupancyGrid:
    """A log-odds occupancy grid over ``bounds`` (rows = y, columns = x).

    Log-odds rather than probabilities so that repeated scans add up and a
    single stray reading cannot flip a well-observed cell; values are clamped
    to ``[L_MIN, L_MAX]`` so the map can still change when the world does
    (a door opening).
    """

    L_OCC = 0.85      # added to a cell a ray ends in
    L_FREE = -0.4     # added to a cell a ray passes through
    L_MIN = -4.0
    L_MAX = 4.0
    OCC_THRESHOLD = 0.5   # occupied above this log-odds (p ~ 0.62): one hit suffices
    KNOWN_EPS = 1e-3
    # from_geometry's values: fixed structure is certain, free floor only mildly so,
    # so that one scan hit on a floor-plan grid shows a new obstacle (a closed door)
    PRIOR_OCC = L_MAX
    PRIOR_FREE = -0.3

    def __init__(self, bounds: Sequence[float] = (0.0, 0.0, 1.0, 1.0), resolution: float = 0.1):
        x0, y0, x1, y1 = (float(b) for b in bounds)
        if not (resolution > 0) or not (x1 > x0) or not (y1 > y0):
            raise ValueError(f"bad grid: bounds {bounds}, resolution {resolution}")
        self.bounds = (x0, y0, x1, y1)
        self.resolution = float(resolution)
        # the grid covers the bounds, rounded up to whole cells
        self.nx = max(1, int(math.ceil((x1 - x0) / self.resolution - 1e-9)))
        self.ny = max(1, int(math.ceil((y1 - y0) / self.resolution - 1e-9)))
        self.log_odds = np.zeros((self.ny, self.nx), dtype=np.float32)

    # -- geometry of the cells
    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nx)

    @property
    def origin(self) -> Point:
        return (self.bounds[0], self.bounds[1])

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the cells, the ``imshow`` extent."""
        x0, y0 = self.origin
        return (x0, x0 + self.nx * self.resolution, y0, y0 + self.ny * self.resolution)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """The (row, column) holding (x, y); may lie outside the grid (see :meth:`inside`)."""
        return (int(math.floor((y - self.bounds[1]) / self.resolution)),
                int(math.floor((x - self.bounds[0]) / self.resolution)))

    def centre(self, i: int, j: int) -> Point:
        return (self.bounds[0] + (j + 0.5) * self.resolution, self.bounds[1] + (i + 0.5) * self.resolution)

    def inside(self, x: float, y: float) -> bool:
        i, j = self.cell(x, y)
        return 0 <= i < self.ny and 0 <= j < self.nx

    # -- classification
    def occupied(self) -> np.ndarray:
        return self.log_odds > self.OCC_THRESHOLD

    def free(self) -> np.ndarray:
        """Observed and more likely free than occupied (one ray through it suffices)."""
        return self.log_odds < -self.KNOWN_EPS

    def known(self) -> np.ndarray:
        return np.abs(self.log_odds) > self.KNOWN_EPS

    def probability(self) -> np.ndarray:
        """Occupancy probability per cell (0.5 where unknown), for drawing."""
        return 1.0 - 1.0 / (1.0 + np.exp(self.log_odds.astype(np.float64)))

    def copy(self) -> "OccupancyGrid":
        g = OccupancyGrid.__new__(OccupancyGrid)
        g.__dict__.update(self.__dict__)
        g.log_odds = self.log_odds.copy()
        return g

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, OccupancyGrid) and self.bounds == other.bounds
                and self.resolution == other.resolution and np.array_equal(self.log_odds, other.log_odds))

    __hash__ = None  # type: ignore[assignment]  # mutable

    def __repr__(self) -> str:
        return (f"OccupancyGrid(bounds={self.bounds}, resolution={self.resolution}, "
                f"occupied={int(self.occupied().sum())}, known={int(self.known().sum())})")

    # -- scan update
    def update(self, pose: Sequence[float], scan: Iterable[tuple[float, float | None]], max_range: float) -> None:
        """Integrate one range scan taken at ``pose = (x, y, theta)``.

        ``scan`` holds ``(angle relative to theta, range or None)``; None (or a
        range >= ``max_range``) means nothing was hit, so the ray is free up to
        ``max_range``. Each ray is traversed with integer DDA from the robot's
        cell; within one scan a cell is counted once, and a cell some ray hit
        is not also cleared by another ray grazing it.
        """
        x, y, th = (float(v) for v in pose)
        res = self.resolution
        ox, oy = self.origin
        i0, j0 = self.cell(x, y)
        ends_i: list[int] = []
        ends_j: list[int] = []
        hits: list[bool] = []
        for ang, rng in scan:
            hit = rng is not None and math.isfinite(rng) and rng < max_range
            r = max(0.0, float(rng)) if hit else float(max_range)
            a = th + float(ang)
            ex, ey = x + r * math.cos(a), y + r * math.sin(a)
            ends_i.append(int(math.floor((ey - oy) / res)))
            ends_j.append(int(math.floor((ex - ox) / res)))
            hits.append(hit)
        if not hits:
            return
        ei = np.asarray(ends_i, dtype=np.int64)
        ej = np.asarray(ends_j, dtype=np.int64)
        hit = np.asarray(hits, dtype=bool)
        di, dj = ei - i0, ej - j0
        n = np.maximum(np.abs(di), np.abs(dj))
        # free cells: k = 0 .. n-1 on a hit ray (the end cell is the obstacle), 0 .. n otherwise
        count = np.where(hit, n, n + 1)
        ray = np.repeat(np.arange(len(n)), count)
        start = np.cumsum(count) - count
        k = np.arange(int(count.sum()), dtype=np.int64) - np.repeat(start, count)
        nn = np.maximum(n[ray], 1)
        # symmetric integer DDA: round(k * d / n) with exact floor arithmetic
        fi = i0 + (2 * k * di[ray] + nn) // (2 * nn)
        fj = j0 + (2 * k * dj[ray] + nn) // (2 * nn)
        free_flat = self._flat_inside(fi, fj)
        occ_flat = self._flat_inside(ei[hit], ej[hit])
        free_flat = np.setdiff1d(free_flat, occ_flat)
        flat = self.log_odds.reshape(-1)
        flat[free_flat] += np.float32(self.L_FREE)
        flat[occ_flat] += np.float32(self.L_OCC)
        np.clip(self.log_odds, self.L_MIN, self.L_MAX, out=self.log_odds)

    def _flat_inside(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        ok = (i >= 0) & (i < self.ny) & (j >= 0) & (j < self.nx)
        return np.unique(i[ok] * self.nx + j[ok])

    # -- ground truth
    @classmethod
    def from_geometry(cls, geometry: dict, resolution: float = 0.1, *, objects: bool = False) -> "OccupancyGrid":
        """The exact map of a world: walls, boxes, circles and closed doors occupied, the rest free.

        A cell is occupied when the shape comes within half a cell of its
        centre or a wall's centre line crosses it, so walls thinner than a
        cell still leave no gaps. Movable
        ``objects`` are free unless ``objects=True`` (the planner is not told
        about things the robot may push).

        Occupied cells get ``PRIOR_OCC`` (certain) and free cells ``PRIOR_FREE``
        (mild): used as a floor plan that scans are added to, a single hit
        (``PRIOR_FREE + L_OCC > OCC_THRESHOLD``) marks an obstacle the plan
        does not know, while a ray grazing a wall does not clear it.
        """
        g = cls(geometry["bounds"], resolution)
        occ = np.zeros(g.shape, dtype=bool)
        half = 0.5 * g.resolution
        for (a, b, t) in geometry.get("walls", ()):
            g._mark_segment(occ, a, b, 0.5 * float(t) + half)
        for door in geometry.get("doors", ()):
            if not door.get("open", False):
                g._mark_segment(occ, door["from"], door["to"], 0.5 * float(door.get("thickness", 0.0)) + half)
        for (cx, cy, w, h, ang) in geometry.get("boxes", ()):
            g._mark_box(occ, cx, cy, w, h, ang, half)
        for (cx, cy, r) in geometry.get("circles", ()):
            g._mark_circle(occ, cx, cy, r, half)
        if objects:
            for o in geometry.get("objects", ()):
                if o.get("kind") == "circle":
                    g._mark_circle(occ, o["x"], o["y"], o["r"], half)
                else:
                    g._mark_box(occ, o["x"], o["y"], o["w"], o["h"], o.get("angle", 0.0), half)
        g.log_odds[:] = np.where(occ, cls.PRIOR_OCC, cls.PRIOR_FREE).astype(np.float32)
        return g

    def _window(self, xmin: float, ymin: float, xmax: float, ymax: float):
        """Cell-centre coordinates of the sub-grid covering a box (None when empty)."""
        i0, j0 = self.cell(xmin, ymin)
        i1, j1 = self.cell(xmax, ymax)
        i0, j0 = max(i0, 0), max(j0, 0)
        i1, j1 = min(i1, self.ny - 1), min(j1, self.nx - 1)
        if i0 > i1 or j0 > j1:
            return None
        ox, oy = self.origin
        ys = oy + (np.arange(i0, i1 + 1) + 0.5) * self.resolution
        xs = ox + (np.arange(j0, j1 + 1) + 0.5) * self.resolution
        X, Y = np.meshgrid(xs, ys)
        return (slice(i0, i1 + 1), slice(j0, j1 + 1)), X, Y

    def _mark_segment(self, occ: np.ndarray, a, b, reach: float) -> None:
        (ax, ay), (bx, by) = (float(a[0]), float(a[1])), (float(b[0]), float(b[1]))
        w = self._window(min(ax, bx) - reach, min(ay, by) - reach, max(ax, bx) + reach, max(ay, by) + reach)
        if w is None:
            return
        sl, X, Y = w
        dx, dy = bx - ax, by - ay
        L2 = dx * dx + dy * dy
        t = np.zeros_like(X) if L2 == 0 else np.clip(((X - ax) * dx + (Y - ay) * dy) / L2, 0.0, 1.0)
        d = np.hypot(X - (ax + t * dx), Y - (ay + t * dy))
        occ[sl] |= d <= reach + 1e-9
        # plus every cell the centre line crosses, so a thin diagonal wall has no diagonal gaps
        ox, oy = self.origin
        r = self.resolution
        for i, j in segment_cells((ax - ox) / r, (ay - oy) / r, (bx - ox) / r, (by - oy) / r):
            if 0 <= i < self.ny and 0 <= j < self.nx:
                occ[i, j] = True

    def _mark_box(self, occ: np.ndarray, cx, cy, w, h, ang, half: float) -> None:
        cx, cy, w, h, ang = (float(v) for v in (cx, cy, w, h, ang))
        R = 0.5 * math.hypot(w, h) + half
        win = self._window(cx - R, cy - R, cx + R, cy + R)
        if win is None:
            return
        sl, X, Y = win
        c, s = math.cos(ang), math.sin(ang)
        lx = (X - cx) * c + (Y - cy) * s
        ly = -(X - cx) * s + (Y - cy) * c
        d = np.hypot(np.maximum(np.abs(lx) - 0.5 * w, 0.0), np.maximum(np.abs(ly) - 0.5 * h, 0.0))
        occ[sl] |= d <= half + 1e-9

    def _mark_circle(self, occ: np.ndarray, cx, cy, r, half: float) -> None:
        cx, cy, r = float(cx), float(cy), float(r)
        R = r + half
        win = self._window(cx - R, cy - R, cx + R, cy + R)
        if win is None:
            return
        sl, X, Y = win
        occ[sl] |= np.hypot(X - cx, Y - cy) - r <= half + 1e-9


# ---------------------------------------------------------------------------
# inflation and A*


def _disc_offsets(radius_m: float, resolution: float) -> np.ndarray:
    """Structuring element: offsets whose cell *square* comes closer than ``radius_m`` to the centre.

    Measuring to the obstacle cell's square rather than its centre is what
    makes a gap narrower than the robot blocked; a centre-to-centre disc
    would let the robot through gaps up to one cell too narrow.
    """
    r = float(radius_m) / float(resolution)
    n = int(math.ceil(r + 0.5))
    d = np.arange(-n, n + 1)
    DI, DJ = np.meshgrid(d, d, indexing="ij")
    gi = np.maximum(np.abs(DI) - 0.5, 0.0)
    gj = np.maximum(np.abs(DJ) - 0.5, 0.0)
    return gi * gi + gj * gj < r * r - 1e-12


def inflate(occ_bool: np.ndarray, radius_m: float, resolution: float) -> np.ndarray:
    """Obstacles grown by the robot radius, so the robot is a point on the result."""
    occ = np.asarray(occ_bool, dtype=bool)
    if radius_m <= 0 or not occ.any():
        return occ.copy()
    # dilation as an OR of shifted copies (numpy only; scipy.ndimage costs ~0.4 s to import)
    disc = _disc_offsets(radius_m, resolution)
    n = disc.shape[0] // 2
    ny, nx = occ.shape
    pad = np.zeros((ny + 2 * n, nx + 2 * n), dtype=bool)
    pad[n:n + ny, n:n + nx] = occ
    out = np.zeros_like(occ)
    for di, dj in zip(*np.nonzero(disc)):
        out |= pad[di:di + ny, dj:dj + nx]
    return out


def astar(blocked: np.ndarray, start: tuple[int, int], goal: tuple[int, int]
          ) -> tuple[list[tuple[int, int]], float] | None:
    """Shortest 8-connected cell path (cost in cells: 1 straight, sqrt 2 diagonal), or None.

    A diagonal step needs both cells it squeezes between free (no corner
    cutting), so a robot centre moving along the path never touches a blocked
    cell. The octile heuristic is consistent, so the first expansion of the
    goal is optimal; ties on f prefer the deeper node (larger g), then the
    earlier push, which makes the result independent of anything but input.
    """
    blk = np.asarray(blocked, dtype=bool)
    ny, nx = blk.shape
    (si, sj), (gi, gj) = start, goal
    if not (0 <= si < ny and 0 <= sj < nx and 0 <= gi < ny and 0 <= gj < nx):
        return None
    if blk[si, sj] or blk[gi, gj]:
        return None
    W = nx + 2
    pad = np.ones((ny + 2, W), dtype=np.uint8)
    pad[1:-1, 1:-1] = blk
    free = (pad == 0).ravel().tolist()
    N = len(free)
    s = (si + 1) * W + sj + 1
    t = (gi + 1) * W + gj + 1
    tr, tc = divmod(t, W)
    straight = (1, -1, W, -W)
    diagonal = ((W + 1, W, 1), (W - 1, W, -1), (-W + 1, -W, 1), (-W - 1, -W, -1))
    INF = math.inf
    g = [INF] * N
    parent = [-1] * N
    closed = bytearray(N)
    g[s] = 0.0
    k = 0

    def h(p: int) -> float:
        r, c = divmod(p, W)
        dr, dc = abs(r - tr), abs(c - tc)
        return dr + dc + (SQRT2 - 2.0) * (dr if dr < dc else dc)

    heap = [(h(s), -0.0, 0, s)]
    push, pop = heapq.heappush, heapq.heappop
    while heap:
        _, _, _, p = pop(heap)
        if closed[p]:
            continue
        if p == t:
            break
        closed[p] = 1
        gp = g[p]
        for d in straight:
            q = p + d
            if free[q] and not closed[q]:
                gq = gp + 1.0
                if gq < g[q]:
                    g[q] = gq
                    parent[q] = p
                    k += 1
                    push(heap, (gq + h(q), -gq, k, q))
        for d, a, b in diagonal:
            q = p + d
            if free[q] and not closed[q] and free[p + a] and free[p + b]:
                gq = gp + SQRT2
                if gq < g[q]:
                    g[q] = gq
                    parent[q] = p
                    k += 1
                    push(heap, (gq + h(q), -gq, k, q))
    else:
        return None
    cells = []
    p = t
    while p != -1:
        r, c = divmod(p, W)
        cells.append((r - 1, c - 1))
        p = parent[p]
    cells.reverse()
    return cells, g[t]


def segment_cells(u0: float, v0: float, u1: float, v1: float) -> list[tuple[int, int]]:
    """Every cell (row, column) a segment in cell units touches (supercover DDA).

    When the segment passes exactly through a cell corner both side cells are
    included, so "all these cells are free" implies every point of the
    segment lies in a free cell.
    """
    return list(iter_segment_cells(u0, v0, u1, v1))


def iter_segment_cells(u0: float, v0: float, u1: float, v1: float) -> Iterator[tuple[int, int]]:
    """:func:`segment_cells` lazily, so a line-of-sight test stops at the first blocked cell."""
    j, i = math.floor(u0), math.floor(v0)
    je, ie = math.floor(u1), math.floor(v1)
    du, dv = u1 - u0, v1 - v0
    sj = 1 if du > 0 else -1
    si = 1 if dv > 0 else -1
    if du != 0:
        tmu = ((j + 1 - u0) if du > 0 else (u0 - j)) / abs(du)
        tdu = 1.0 / abs(du)
    else:
        tmu, tdu = math.inf, math.inf
    if dv != 0:
        tmv = ((i + 1 - v0) if dv > 0 else (v0 - i)) / abs(dv)
        tdv = 1.0 / abs(dv)
    else:
        tmv, tdv = math.inf, math.inf
    yield (i, j)
    limit = abs(je - j) + abs(ie - i) + 4
    eps = 1e-9
    while (i, j) != (ie, je) and limit > 0:
        limit -= 1
        if abs(tmu - tmv) <= eps:
            if tmu > 1.0 + eps:
                break
            yield (i, j + sj)
            yield (i + si, j)
            i += si
            j += sj
            tmu += tdu
            tmv += tdv
        elif tmu < tmv:
            if tmu > 1.0 + eps:
                break
            j += sj
            tmu += tdu
        else:
            if tmv > 1.0 + eps:
                break
            i += si
            tmv += tdv
        yield (i, j)


def _line_free(rows: list[bytes], origin: Point, res: float, a: Point, b: Point) -> bool:
    """True when every cell the segment a-b touches exists and is free (``rows[i][j] == 0``)."""
    ny, nx = len(rows), len(rows[0])
    ox, oy = origin
    for i, j in iter_segment_cells((a[0] - ox) / res, (a[1] - oy) / res, (b[0] - ox) / res, (b[1] - oy) / res):
        if not (0 <= i < ny and 0 <= j < nx) or rows[i][j]:
            return False
    return True


def _drop_collinear(pts: list[Point], tol: float = 1e-9) -> list[Point]:
    """Remove repeated points and points lying on the line through their neighbours."""
    out: list[Point] = []
    for p in pts:
        if out and abs(p[0] - out[-1][0]) <= tol and abs(p[1] - out[-1][1]) <= tol:
            continue
        while len(out) >= 2:
            (ax, ay), (bx, by) = out[-2], out[-1]
            cross = (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax)
            dot = (bx - ax) * (p[0] - bx) + (by - ay) * (p[1] - by)
            if abs(cross) <= tol and dot >= 0:   # b lies between a and p on a straight run
                out.pop()
            else:
                break
        out.append(p)
    return out


def polyline_length(pts: Sequence[Sequence[float]]) -> float:
    return float(sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(pts, pts[1:])))


def plan_path(grid_or_bool, start_xy: Sequence[float], goal_xy: Sequence[float], robot_radius: float,
              resolution: float | None = None, unknown_is_free: bool = True, *,
              origin: Sequence[float] = (0.0, 0.0), clearance: float = 0.0) -> list[Point] | None:
    """A collision-free polyline for a disc robot from ``start_xy`` to ``goal_xy``, or None.

    ``grid_or_bool`` is an :class:`OccupancyGrid` (unknown cells count as free
    unless ``unknown_is_free=False``) or a bool array of occupied cells, then
    with ``resolution`` and ``origin`` (the world position of cell (0, 0)'s
    corner). The path is A* over the inflated grid, with collinear points
    removed and then shortcut where the straight line stays in free cells;
    it starts at ``start_xy`` and ends exactly at ``goal_xy``. A start inside
    the inflation (robot brushing a wall) is moved to the nearest free cell
    within the robot radius; a blocked goal gives None.

    ``clearance`` (m) is room wanted beyond the radius where there is some: the path is planned
    with obstacles grown by ``robot_radius + clearance`` first, and only where that finds none
    (a gap narrower than that) with the radius alone. Why: a shortest path brushes every
    obstacle it passes at exactly the radius, where a follower's safety stop (which keeps a
    margin) halts the robot.
    """
    if isinstance(grid_or_bool, OccupancyGrid):
        grid = grid_or_bool
        occ = grid.occupied()
        if not unknown_is_free:
            occ = occ | ~grid.known()
        res = grid.resolution if resolution is None else float(resolution)
        if res != grid.resolution:
            raise ValueError("resolution differs from the grid's")
        org = grid.origin
    else:
        occ = np.asarray(grid_or_bool, dtype=bool)
        if resolution is None:
            raise ValueError("plan_path on a bool array needs a resolution")
        res = float(resolution)
        org = (float(origin[0]), float(origin[1]))
    if clearance > 0:
        roomy = _plan_on(occ, res, org, start_xy, goal_xy, robot_radius + clearance)
        if roomy is not None:
            return roomy
    return _plan_on(occ, res, org, start_xy, goal_xy, robot_radius)


def _plan_on(occ: np.ndarray, res: float, org: Point, start_xy, goal_xy, robot_radius: float) -> list[Point] | None:
    """:func:`plan_path` on a bool grid for a disc of ``robot_radius``."""
    blocked = inflate(occ, robot_radius, res)
    ny, nx = blocked.shape
    sx, sy = float(start_xy[0]), float(start_xy[1])
    gx, gy = float(goal_xy[0]), float(goal_xy[1])

    def cell(x: float, y: float) -> tuple[int, int]:
        return (int(math.floor((y - org[1]) / res)), int(math.floor((x - org[0]) / res)))

    def centre(i: int, j: int) -> Point:
        return (org[0] + (j + 0.5) * res, org[1] + (i + 0.5) * res)

    def ok(c: tuple[int, int]) -> bool:
        return 0 <= c[0] < ny and 0 <= c[1] < nx and not blocked[c]

    sc, gc = cell(sx, sy), cell(gx, gy)
    if not ok(gc):
        return None
    displaced = False
    if not ok(sc):
        sc = _nearest_free(blocked, sc, (sx, sy), robot_radius + res, res, centre)
        if sc is None:
            return None
        displaced = True
    if not _connected(blocked, sc, gc):   # no path at all: say so without searching the whole region
        return None
    found = astar(blocked, sc, gc)
    if found is None:
        return None
    cells, _ = found
    raw = [(sx, sy)] + _drop_collinear([centre(i, j) for i, j in cells]) + [(gx, gy)]
    raw = _drop_collinear(raw)
    # greedy shortcut: from each anchor jump to the farthest point in line of sight;
    # a displaced start keeps its first leg (it starts inside the inflation by definition)
    rows = [bytes(r) for r in blocked.astype(np.uint8)]
    out = [raw[0]]
    a = 0
    if displaced and len(raw) > 1:
        out.append(raw[1])
        a = 1
    while a < len(raw) - 1:
        nxt = a + 1
        for b in range(len(raw) - 1, a + 1, -1):
            if _line_free(rows, org, res, raw[a], raw[b]):
                nxt = b
                break
        out.append(raw[nxt])
        a = nxt
    return _drop_collinear(out)


def _connected(blocked: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Are cells ``a`` and ``b`` in one 8-connected region of free cells? (A necessary condition
    for an A* path, which moves 8-connected without cutting corners; labelling is ~100x cheaper
    than an A* search that has to exhaust a region to fail.)"""
    from scipy import ndimage
    labels, _n = ndimage.label(~blocked, structure=np.ones((3, 3), dtype=bool))
    return labels[a] != 0 and labels[a] == labels[b]


def _nearest_free(blocked, sc, p: Point, reach: float, res: float, centre):
    n = int(math.ceil(reach / res)) + 1
    ny, nx = blocked.shape
    best = None
    for i in range(max(0, sc[0] - n), min(ny, sc[0] + n + 1)):
        for j in range(max(0, sc[1] - n), min(nx, sc[1] + n + 1)):
            if blocked[i, j]:
                continue
            cx, cy = centre(i, j)
            d = math.hypot(cx - p[0], cy - p[1])
            if d <= reach and (best is None or (d, i, j) < best):
                best = (d, i, j)
    return None if best is None else (best[1], best[2])


# ---------------------------------------------------------------------------
# path following


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class PurePursuit:
    """Pure-pursuit follower of a polyline for a unicycle / differential-drive robot.

    The robot's progress along the path only moves forward: the projection is
    searched on the segments from :attr:`progress` on, within a window a few
    lookaheads long, so a path that doubles back near itself cannot make the
    follower skip ahead or fall back. The target is the point ``lookahead``
    further along the path than that projection.
    """

    def __init__(self, path: Sequence[Sequence[float]], lookahead: float = 0.4, speed: float = 0.5,
                 goal_tolerance: float = 0.1, max_omega: float = 2.0, turn_exit_deg: float = 45.0):
        pts: list[Point] = []
        for p in path:
            q = (float(p[0]), float(p[1]))
            if not pts or q != pts[-1]:
                pts.append(q)
        if not pts:
            raise ValueError("PurePursuit needs a non-empty path")
        self.path = pts
        self.lookahead = float(lookahead)
        self.speed = float(speed)
        self.goal_tolerance = float(goal_tolerance)
        self.max_omega = float(max_omega)
        self.turn_exit = math.radians(turn_exit_deg)
        self.cum = [0.0]
        for a, b in zip(pts, pts[1:]):
            self.cum.append(self.cum[-1] + math.hypot(b[0] - a[0], b[1] - a[1]))
        self.length = self.cum[-1]
        self.progress = 0           # index of the segment the robot is on
        self.s = 0.0                # arc length of the robot's projection, never decreasing
        self.turning = False        # rotating in place (hysteresis: until |alpha| < turn_exit)

    @property
    def goal(self) -> Point:
        return self.path[-1]

    def _project(self, x: float, y: float) -> tuple[int, float]:
        """(segment index, arc length) of the nearest path point ahead of the progress."""
        if len(self.path) == 1:
            return 0, 0.0
        window = self.s + 3.0 * self.lookahead
        best = None
        for k in range(self.progress, len(self.path) - 1):
            if self.cum[k] > window and best is not None:
                break
            (ax, ay), (bx, by) = self.path[k], self.path[k + 1]
            dx, dy = bx - ax, by - ay
            L = self.cum[k + 1] - self.cum[k]
            t = min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / (L * L)))
            d = math.hypot(ax + t * dx - x, ay + t * dy - y)
            if best is None or d < best[0]:
                best = (d, k, self.cum[k] + t * L)
        _, k, s = best
        if s < self.s:              # never backwards along the path
            s = self.s
            k = max(k, self.progress)
        return k, s

    def _point_at(self, s: float) -> Point:
        if s >= self.length:
            return self.path[-1]
        k = max(self.progress, 0)
        while k < len(self.path) - 2 and self.cum[k + 1] < s:
            k += 1
        (ax, ay), (bx, by) = self.path[k], self.path[k + 1]
        L = self.cum[k + 1] - self.cum[k]
        t = 0.0 if L == 0 else (s - self.cum[k]) / L
        return (ax + t * (bx - ax), ay + t * (by - ay))

    def done(self, pose: Sequence[float]) -> bool:
        gx, gy = self.path[-1]
        return math.hypot(float(pose[0]) - gx, float(pose[1]) - gy) <= self.goal_tolerance

    def remaining(self, pose: Sequence[float]) -> float:
        """Distance along the path from the robot's projection to the goal (does not advance progress)."""
        _, s = self._project(float(pose[0]), float(pose[1]))
        return max(0.0, self.length - s)

    def command(self, pose: Sequence[float]) -> tuple[float, float]:
        """(v, omega) for the robot at ``pose = (x, y, theta)``; (0, 0) once done."""
        x, y, th = (float(v) for v in pose)
        if self.done(pose):
            self.turning = False
            return (0.0, 0.0)
        k, s = self._project(x, y)
        self.progress, self.s = k, s
        tx, ty = self._point_at(s + self.lookahead)
        dx, dy = tx - x, ty - y
        dist = math.hypot(dx, dy)
        if dist < 1e-9:
            return (0.0, 0.0)
        alpha = _wrap(math.atan2(dy, dx) - th)
        if abs(alpha) > math.pi / 2:
            self.turning = True
        elif abs(alpha) < self.turn_exit:
            self.turning = False
        if self.turning:
            # target behind: turn on the spot, proportional but capped
            omega = max(-self.max_omega, min(self.max_omega, 2.0 * alpha))
            return (0.0, omega)
        to_goal = max(self.length - s, math.hypot(self.path[-1][0] - x, self.path[-1][1] - y))
        v = self.speed * min(1.0, max(0.25, to_goal / (2.0 * self.lookahead)))
        # the arc through the target: curvature 2 sin(alpha) / distance to it
        kappa = 2.0 * math.sin(alpha) / max(dist, 1e-6)
        omega = v * kappa
        if abs(omega) > self.max_omega:
            v *= self.max_omega / abs(omega)     # keep the curvature, slow down
            omega = math.copysign(self.max_omega, omega)
        return (v, omega)


def wheel_speeds(v: float, omega: float, wheel_base: float, wheel_radius: float,
                 max_wheel_speed: float) -> tuple[float, float]:
    """(left, right) wheel speeds in rad/s; both scaled down together so the path curvature is kept."""
    half = 0.5 * float(wheel_base)
    left = (float(v) - float(omega) * half) / float(wheel_radius)
    right = (float(v) + float(omega) * half) / float(wheel_radius)
    m = max(abs(left), abs(right))
    if m > max_wheel_speed > 0:
        f = float(max_wheel_speed) / m
        left, right = left * f, right * f
    elif max_wheel_speed <= 0:
        return (0.0, 0.0)
    return (left, right)
