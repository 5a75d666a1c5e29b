"""Compiled loop of the time to collision (:mod:`aac_sumo.metrics`): the swept gap of two footprints
along their relative velocity.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _half_extent(rect, nx, ny):
    """Half the length [m] of rectangle row ``rect`` ``[cx, cy, length, width, heading]``
    projected on the unit axis ``(nx, ny)``."""
    c, s = math.cos(rect[4]), math.sin(rect[4])
    return 0.5 * rect[2] * abs(c * nx + s * ny) + 0.5 * rect[3] * abs(-s * nx + c * ny)


@numba.njit(cache=True)
def sweep_gap(a, b, dx, dy):
    """How far [m] rectangle row ``a`` ``[cx, cy, length, width, heading]`` can translate along
    the unit direction ``(dx, dy)`` before its footprint touches rectangle row ``b``'s: 0 when
    they already touch or overlap, inf when it never does.

    Exact for any orientations: ``a`` shifted by ``s (dx, dy)`` meets ``b`` exactly when their
    projections overlap on each of the four edge normals of the two rectangles (the separating
    axis theorem; these are the edge normals of their Minkowski difference), and on each axis
    that holds for an interval of ``s``; the gap is the least ``s >= 0`` in all four intervals."""
    lo, hi = 0.0, np.inf
    for axis in range(4):
        h = a[4] if axis < 2 else b[4]
        if axis % 2 == 0:
            nx, ny = math.cos(h), math.sin(h)
        else:
            nx, ny = -math.sin(h), math.cos(h)
        sep = (b[0] - a[0]) * nx + (b[1] - a[1]) * ny  # centre of b relative to a's, on this axis
        reach = _half_extent(a, nx, ny) + _half_extent(b, nx, ny)
        rate = dx * nx + dy * ny
        if abs(rate) < 1e-12:  # moving parallel to this axis's lines: the overlap never changes
            if abs(sep) > reach:
                return np.inf
            continue
        s1, s2 = (sep - reach) / rate, (sep + reach) / rate
        lo, hi = max(lo, min(s1, s2)), min(hi, max(s1, s2))
        if lo > hi:
            return np.inf
    return lo


@numba.njit(cache=True)
def _pair_time(rows, velocity, radius, i, j):
    """The time to collision [s] of robot ``i`` with ``j`` as :func:`times_to_collision` counts
    it (inf when it does not count), for a pair that passed its cheap tests there (the closing
    velocity points ahead of ``i``; ``j`` not well off the sweep's line nor behind it);
    ``radius``: each row's half diagonal [m]."""
    wx, wy = velocity[i, 0] - velocity[j, 0], velocity[i, 1] - velocity[j, 1]
    dx, dy = rows[j, 0] - rows[i, 0], rows[j, 1] - rows[i, 1]
    reach = radius[i] + radius[j] + 1e-9
    closing = math.hypot(wx, wy)
    if closing <= 1e-6:
        return np.inf
    ux, uy = wx / closing, wy / closing
    # each footprint lies within its half diagonal of its centre: farther off the line of the
    # sweep, or behind it, the two never touch
    if abs(dx * uy - dy * ux) > reach or dx * ux + dy * uy < -reach:
        return np.inf
    return sweep_gap(rows[i], rows[j], ux, uy) / closing


@numba.njit(cache=True)
def _half_diagonals(rows):
    out = np.empty(rows.shape[0])
    for k in range(rows.shape[0]):
        out[k] = 0.5 * math.hypot(rows[k, 2], rows[k, 3])
    return out


@numba.njit(cache=True, parallel=True)
def times_to_collision(rows, velocity, n):
    """Per robot i < n, the least time to collision [s] with the others: footprint rows ``rows``
    (M, 5) ``[cx, cy, length, width, heading]`` and velocities ``velocity`` (M, 2) [m/s] of
    everything, the first n being the robots themselves. For each other j, the closing
    velocity is ``w = velocity[i] - velocity[j]``; j counts when ``w`` points ahead of robot i
    (positive along its heading, so i is the one driving into j) and i's footprint, translated
    along ``w``, touches j's: TTC = :func:`sweep_gap` along ``w`` / ``|w|``. inf when nothing
    counts."""
    radius = _half_diagonals(rows)
    m = rows.shape[0]
    cx, cy = np.ascontiguousarray(rows[:, 0]), np.ascontiguousarray(rows[:, 1])
    vx, vy = np.ascontiguousarray(velocity[:, 0]), np.ascontiguousarray(velocity[:, 1])
    out = np.full(n, np.inf)
    for i in numba.prange(n):  # each robot's least time alone: the same numbers on any number of threads
        hx, hy = math.cos(rows[i, 4]), math.sin(rows[i, 4])
        # first, without branches (a loop the compiler can vectorise), the pairs that can count:
        # the closing velocity points ahead of i, and, without a root or a division, j is not
        # off the sweep's line or behind it by a millionth more than _pair_time's exact test asks
        passing = np.empty(m, dtype=np.bool_)
        for j in range(m):
            wx, wy = vx[i] - vx[j], vy[i] - vy[j]
            dx, dy = cx[j] - cx[i], cy[j] - cy[i]
            loose = ((radius[i] + radius[j] + 1e-9) * (1.0 + 1e-6) + 1e-6) ** 2 * (wx * wx + wy * wy)
            across, along = dx * wy - dy * wx, dx * wx + dy * wy
            passing[j] = (wx * hx + wy * hy > 1e-6) & (across * across <= loose) & ((along >= 0.0) | (along * along <= loose))
        for j in range(m):
            if passing[j] and j != i:
                out[i] = min(out[i], _pair_time(rows, velocity, radius, i, j))
    return out
