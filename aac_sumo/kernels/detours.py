"""Compiled loops of the detour planner (:mod:`aac_sumo.coordination.detour`): the distance field, its
costs, the cheapest grid path (A*) and its shortcut. They release Python's lock (``nogil``), so that
the detours of one period are planned on several threads.
"""

from __future__ import annotations

import heapq
import math

import numba
import numpy as np

from aac_sumo.kernels.geometry import point_rect_distance


@numba.njit(cache=True, nogil=True)
def grid_path(cost, start, goal):
    """Cheapest 8-connected path of cells from ``start`` to ``goal`` (row, column) over the cell
    costs ``cost`` (rows, columns) [per cell side], each at least 1 (inf: blocked); a step's
    cost is its length in cell sides times the mean of its two cells' costs (A* with the octile
    distance, admissible since every cost is at least 1). Returns the flat cell indices (K,)
    from start to goal, empty when the goal cannot be reached."""
    rows, cols = cost.shape
    n = rows * cols
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    s, t = start[0] * cols + start[1], goal[0] * cols + goal[1]
    g[s] = 0.0
    heap = [(0.0, s)]
    diag = math.sqrt(2.0)
    while len(heap):
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == t:
            break
        closed[u] = True
        ur, uc = u // cols, u % cols
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                if dr == 0 and dc == 0:
                    continue
                vr, vc = ur + dr, uc + dc
                if vr < 0 or vr >= rows or vc < 0 or vc >= cols:
                    continue
                v = vr * cols + vc
                if closed[v] or not math.isfinite(cost[vr, vc]):
                    continue
                step = (diag if dr != 0 and dc != 0 else 1.0) * 0.5 * (cost[ur, uc] + cost[vr, vc])
                if g[u] + step < g[v]:
                    g[v] = g[u] + step
                    parent[v] = u
                    ar, ac = abs(vr - goal[0]), abs(vc - goal[1])
                    h = max(ar, ac) + (diag - 1.0) * min(ar, ac)
                    heapq.heappush(heap, (g[v] + h, v))
    if not math.isfinite(g[t]):
        return np.empty(0, dtype=np.int64)
    k, u = 1, t
    while u != s:
        u = parent[u]
        k += 1
    out = np.empty(k, dtype=np.int64)
    u = t
    for i in range(k - 1, -1, -1):
        out[i] = u
        u = parent[u]
    return out


@numba.njit(cache=True)
def _rect_distance(px, py, rect, c, s):
    """Distance [m] from the point (``px``, ``py``) to the rectangle ``rect`` ``[cx, cy, length,
    width, heading]`` whose heading has cosine ``c`` and sine ``s`` (0 inside)."""
    return max(point_rect_distance(px, py, rect[0], rect[1], c, s, rect[2], rect[3]), 0.0)


@numba.njit(cache=True, nogil=True)
def distance_field(lo, cell, rows, cols, rects, reach):
    """Distance [m] from the centre of each cell (``rows``, ``cols``) of the grid whose first cell
    centre is ``lo`` (2,) [m] and whose side is ``cell`` [m] to the nearest of ``rects`` (m, 5),
    for the cells within ``reach`` [m] of a rectangle's enclosing disc (the window of each
    rectangle, whole cells; inf elsewhere). Each value is
    :func:`aac_sumo.geometry.rect_distances` of the cell centre over the rectangles whose
    window holds it."""
    dist = np.full((rows, cols), np.inf)
    for k in range(len(rects)):
        rect = rects[k]
        c, s = math.cos(rect[4]), math.sin(rect[4])
        r = 0.5 * math.hypot(rect[2], rect[3]) + reach
        c0 = max(int(math.floor((rect[0] - r - lo[0]) / cell)), 0)
        r0 = max(int(math.floor((rect[1] - r - lo[1]) / cell)), 0)
        c1 = min(int(math.ceil((rect[0] + r - lo[0]) / cell)) + 1, cols)
        r1 = min(int(math.ceil((rect[1] + r - lo[1]) / cell)) + 1, rows)
        for row in range(r0, r1):
            py = lo[1] + cell * row
            for col in range(c0, c1):
                d = _rect_distance(lo[0] + cell * col, py, rect, c, s)
                if d < dist[row, col]:
                    dist[row, col] = d
    return dist


@numba.njit(cache=True, nogil=True)
def band_costs(dist, hard, clearance, penalty):
    """Cell costs (rows, cols) from the distances ``dist`` [m] to the nearest footprint: 1 at
    ``clearance`` or beyond, rising linearly to ``1 + penalty`` at ``hard``, inf (blocked) below
    ``hard``."""
    out = np.empty(dist.shape)
    scale = max(clearance - hard, 1e-9)
    for r in range(dist.shape[0]):
        for c in range(dist.shape[1]):
            d = dist[r, c]
            out[r, c] = np.inf if d < hard else 1.0 + penalty * min(max((clearance - d) / scale, 0.0), 1.0)
    return out


@numba.njit(cache=True, nogil=True)
def shortcut(path, kept, rects, hard, cell, samples):
    """Indices (J,) of the corners of ``path`` (K, 2) [m] it needs: from each kept point on, the
    farthest later point up to which the straight segment, sampled ``samples`` times per ``cell``
    [m], keeps from ``rects`` (m, 5) at least the smallest of ``kept`` (K,) [m] over the same
    stretch, at least ``hard``, less half a cell. The first and the last point are always kept."""
    m, last = len(rects), len(path) - 1
    cos, sin, radius = np.empty(m), np.empty(m), np.empty(m)
    for k in range(m):
        cos[k], sin[k] = math.cos(rects[k, 4]), math.sin(rects[k, 4])
        radius[k] = 0.5 * math.hypot(rects[k, 2], rects[k, 3])  # each rectangle lies within this of its centre
    near = np.empty(m, dtype=np.int64)
    out = [0]
    i = 0
    while i < last:
        j = i + 1
        low = min(kept[i], kept[i + 1])
        while j < last:
            low = min(low, kept[j + 1])
            need = max(low, hard) - 0.5 * cell
            ax, ay = path[i, 0], path[i, 1]
            ux, uy = path[j + 1, 0] - ax, path[j + 1, 1] - ay
            length = math.hypot(ux, uy)
            scale = max(length * length, 1e-12)
            count = 0
            for k in range(m):  # only these can be closer than need
                along = min(max(((rects[k, 0] - ax) * ux + (rects[k, 1] - ay) * uy) / scale, 0.0), 1.0)
                if math.hypot(ax + along * ux - rects[k, 0], ay + along * uy - rects[k, 1]) < need + radius[k]:
                    near[count] = k
                    count += 1
            blocked = False
            if count > 0:
                n = max(2, int(math.ceil(samples * length / cell)) + 1)
                step = 1.0 / (n - 1)
                for q in range(n):
                    t = 1.0 if q == n - 1 else q * step
                    px, py = ax + t * ux, ay + t * uy
                    for e in range(count):
                        k = near[e]
                        if _rect_distance(px, py, rects[k], cos[k], sin[k]) < need:
                            blocked = True
                            break
                    if blocked:
                        break
            if blocked:
                break
            j += 1
        out.append(j)
        i = j
    return np.array(out)


@numba.njit(cache=True, nogil=True)
def rects_within(points, rects, reach):
    """Whether each of ``rects`` (m, 5) comes closer than ``reach`` [m] to one of ``points`` (k,
    2) [m] (by :func:`aac_sumo.geometry.rect_distances`), (m,)."""
    out = np.zeros(len(rects), dtype=np.bool_)
    if len(points) == 0:
        return out
    x_lo, x_hi = points[:, 0].min(), points[:, 0].max()
    y_lo, y_hi = points[:, 1].min(), points[:, 1].max()
    walked = np.zeros(len(points))  # distance along the points, one to the next [m]
    for p in range(1, len(points)):
        walked[p] = walked[p - 1] + math.hypot(points[p, 0] - points[p - 1, 0], points[p, 1] - points[p - 1, 1])
    for k in range(len(rects)):
        # a rectangle lies within its half diagonal of its centre: one that far beyond the points' box is out of reach
        far = reach + 0.5 * math.hypot(rects[k, 2], rects[k, 3]) + 1e-9
        outside = math.hypot(max(x_lo - rects[k, 0], rects[k, 0] - x_hi, 0.0), max(y_lo - rects[k, 1], rects[k, 1] - y_hi, 0.0))
        if outside > far:
            continue
        c, s = math.cos(rects[k, 4]), math.sin(rects[k, 4])
        p = 0
        while p < len(points):
            centre = math.hypot(points[p, 0] - rects[k, 0], points[p, 1] - rects[k, 1])
            if centre > far:  # the points within (centre - far) of it along the way are out of reach too
                p = max(p + 1, np.searchsorted(walked, walked[p] + (centre - far), side="left"))
                continue
            if _rect_distance(points[p, 0], points[p, 1], rects[k], c, s) < reach:
                out[k] = True
                break
            p += 1
    return out
