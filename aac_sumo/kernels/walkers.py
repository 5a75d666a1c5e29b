"""Compiled loop of the walkers' part of the exact check: the loop form of
:meth:`aac_sumo.coordination.walker_reach.WalkerReach.slack`, pinned to its numpy form (the code
it replaced) in ``tests/test_walker_reach.py``.

Units: m, s; footprint rows ``[cx, cy, length, width, heading]``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aac_sumo.kernels.geometry import point_rect_distance


@numba.njit(cache=True)
def walker_slack(rows, cos_h, sin_h, centres, velocities, radius, growth, delay, dt, far, step):
    """Least gap [m] between the course's footprints ``rows`` (K, 5) (heading cosines and sines
    ``cos_h``, ``sin_h`` (K,)) and the walkers' regions at the same moments, row k at ``k * dt``:
    walker j's at t is the segment from ``centres[j]`` to ``centres[j] + velocities[j] t`` while
    t < ``delay[j]`` [s], else the disc of ``growth[j] t`` round ``centres[j]``, either grown by
    ``radius[j]``. Per walker a lower bound from the centres; the walkers it leaves below ``far``
    are measured on their segments, sampled every at most ``step`` [m] and taken half a spacing
    nearer."""
    k_count, m = rows.shape[0], centres.shape[0]
    speed = np.empty(m)
    for j in range(m):
        speed[j] = math.hypot(velocities[j, 0], velocities[j, 1])
    best_far, longest, any_near = np.inf, 0.0, False
    near = np.zeros(m, dtype=np.bool_)
    t_last = (k_count - 1) * dt
    for j in range(m):
        bound = np.inf
        for k in range(k_count):
            t = k * dt
            extent = (speed[j] * t if t < delay[j] else growth[j] * t) + radius[j]
            apart = math.hypot(rows[k, 0] - centres[j, 0], rows[k, 1] - centres[j, 1])
            bound = min(bound, apart - 0.5 * math.hypot(rows[k, 2], rows[k, 3]) - extent)
        if bound < far:
            near[j], any_near = True, True
            longest = max(longest, speed[j] * t_last)
        else:
            best_far = min(best_far, bound)
    if not any_near:
        return best_far
    count = int(math.ceil(longest / step)) + 1
    du = 1.0 / (count - 1) if count > 1 else 0.0
    best = np.inf
    for j in range(m):
        if not near[j]:
            continue
        for k in range(k_count):
            t = k * dt
            walked = t if t < delay[j] else 0.0  # along her segment
            closest = np.inf
            for q in range(count):
                u = 1.0 if q == count - 1 and count > 1 else q * du  # numpy.linspace(0, 1, count)
                tu = walked * u
                d = point_rect_distance(centres[j, 0] + tu * velocities[j, 0], centres[j, 1] + tu * velocities[j, 1], rows[k, 0], rows[k, 1],
                                  cos_h[k], sin_h[k], rows[k, 2], rows[k, 3])
                closest = min(closest, d)
            spacing = speed[j] * walked / max(count - 1, 1)
            best = min(best, closest - 0.5 * spacing - radius[j] - (0.0 if t < delay[j] else growth[j] * t))
    return min(best, best_far)


@numba.njit(cache=True)
def strip_slack(row, cos_h, sin_h, points, half_spacing, strip_radius):
    """Least gap [m] between the footprint ``row`` (5,) (heading cosine ``cos_h``, sine
    ``sin_h``) and the crossings' strips: per strip c, the least distance to its sample points
    ``points[c]`` (S, 2), less ``half_spacing[c]`` and ``strip_radius[c]`` [m]."""
    best = np.inf
    for c in range(points.shape[0]):
        closest = np.inf
        for q in range(points.shape[1]):
            closest = min(closest, point_rect_distance(points[c, q, 0], points[c, q, 1], row[0], row[1], cos_h, sin_h, row[2], row[3]))
        best = min(best, closest - half_spacing[c] - strip_radius[c])
    return best
