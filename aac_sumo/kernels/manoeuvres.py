"""Compiled search of a manoeuvre (:mod:`aac_sumo.coordination.manoeuvre`): hybrid A* over motion
primitives of the kinematic bicycle, each rolled out with the simulator's Euler step and held
clear of oriented rectangles (:func:`~aac_sumo.kernels.geometry.rect_clearance`).
"""

from __future__ import annotations

import heapq
import math

import numba
import numpy as np

from aac_sumo.kernels.geometry import rect_clearance
from aac_sumo.kernels.motion import _bicycle_step


#: Side [m] of the buckets that sort the obstacles for the clearance checks, and how far [m]
#: beyond the search's box they reach (a footprint beyond them checks every obstacle).
BUCKET = 0.5
BUCKET_PAD = 2.0


@numba.njit(cache=True, nogil=True)
def _buckets(obstacles, radii, grow, lo, size, nx, ny):
    """The obstacles by bucket (side ``size`` [m], the grid's corner ``lo`` (2,), ``nx`` by
    ``ny``): each is in every bucket that the square round its circumcircle grown by ``grow``
    [m] touches (clamped into the grid), and in a last bucket (index ``nx * ny``) that holds
    them all, for footprints beyond the grid. Returns the buckets' first entries
    (nx * ny + 2,) and the obstacle indices, bucket after bucket."""
    cells = nx * ny
    first = np.zeros(cells + 2, dtype=np.int64)
    fill = first[:-1].copy()
    items = np.empty(0, dtype=np.int64)
    for phase in range(2):
        for o in range(obstacles.shape[0]):
            if cells > 0:
                r = radii[o] + grow
                x0 = min(max(int(math.floor((obstacles[o, 0] - r - lo[0]) / size)), 0), nx - 1)
                x1 = min(max(int(math.floor((obstacles[o, 0] + r - lo[0]) / size)), 0), nx - 1)
                y0 = min(max(int(math.floor((obstacles[o, 1] - r - lo[1]) / size)), 0), ny - 1)
                y1 = min(max(int(math.floor((obstacles[o, 1] + r - lo[1]) / size)), 0), ny - 1)
                for i in range(x0, x1 + 1):
                    for j in range(y0, y1 + 1):
                        _put(phase, first, fill, items, i * ny + j, o)
            _put(phase, first, fill, items, cells, o)
        if phase == 0:
            first = np.cumsum(first)
            fill = first[:-1].copy()
            items = np.empty(first[-1], dtype=np.int64)
    return first, items


@numba.njit(cache=True, nogil=True)
def _put(phase, first, fill, items, bucket, o):
    """Count obstacle ``o`` in ``bucket`` (phase 0), or file it there (phase 1)."""
    if phase == 0:
        first[bucket + 1] += 1
    else:
        items[fill[bucket]] = o
        fill[bucket] += 1


@numba.njit(cache=True, nogil=True)
def _primitive(state, inputs, steps, obstacles, radii, body, dt, wheelbase, v_min, v_max, offset, length, width, floor, cap,
               first, items, glo, size, nx, ny):
    """Rear-axle state (4,) after ``steps`` of ``inputs`` (K, 2) from ``state``, and the least
    clearance [m] of the footprints on the way to ``obstacles`` (m, 5) (circumradii ``radii``;
    ``body`` the footprint's), and at its end, each at most ``cap``; the first is -inf as soon
    as a state comes closer than ``floor``. Only the obstacles of the footprint centre's bucket
    (:func:`_buckets`, grown by ``body + cap``) can come closer than ``cap``: the others are
    not looked at (beyond the buckets' grid, the last bucket holds them all)."""
    x, y, h, v = state[0], state[1], state[2], state[3]
    row = np.empty(5)
    row[2], row[3] = length, width
    least, last = cap, cap
    for k in range(steps + 1):
        if k > 0:
            x, y, h, v = _bicycle_step(x, y, h, v, inputs[k - 1, 0], inputs[k - 1, 1], dt, wheelbase, v_min, v_max)
        row[0], row[1], row[4] = x + offset * math.cos(h), y + offset * math.sin(h), h
        ix, iy = int(math.floor((row[0] - glo[0]) / size)), int(math.floor((row[1] - glo[1]) / size))
        c = ix * ny + iy if 0 <= ix < nx and 0 <= iy < ny else nx * ny
        here = cap
        for o in items[first[c]:first[c + 1]]:
            bound = math.hypot(row[0] - obstacles[o, 0], row[1] - obstacles[o, 1]) - body - radii[o]
            if bound >= here:
                continue
            here = min(here, rect_clearance(row, obstacles[o]))
        least = min(least, here)
        if least < floor:
            return np.array([x, y, h, v]), -np.inf, here
        last = here
    return np.array([x, y, h, v]), least, last


@numba.njit(cache=True, nogil=True)
def lattice_search(start, start_room, goal, tolerance, prims, steps, costs, wheels_after, obstacles, radii, body, margin, spare,
                   lo, hi, cell, headings, max_expansions, weight, speed, dt, wheelbase, v_min, v_max, offset, length, width):
    """Hybrid A* from rear-axle ``start`` (4,) at rest (wheel set ``W - 1``) to a rest within
    ``tolerance`` of ``goal`` (2,). ``prims`` (W, P, K, 2) are the primitives' inputs from each
    wheel set, ``steps`` (W, P) their lengths, ``costs`` (W, P) their costs [s] and
    ``wheels_after`` (P,) the wheel set each leaves. Every state keeps at least ``margin`` +
    ``spare`` from the ``obstacles`` (or, from a state closer than that, as much as it keeps);
    ends stay in the box ``lo``-``hi`` (2,); the closed set is a lattice of ``cell`` [m] and
    ``headings`` bins; the heuristic is ``weight`` times the time at ``speed`` to the goal.
    Returns the (wheel set, primitive) pairs (J, 2) from start to goal, empty when none is found
    within ``max_expansions``."""
    nx = int(math.ceil((hi[0] - lo[0]) / cell)) + 1
    ny = int(math.ceil((hi[1] - lo[1]) / cell)) + 1
    best = np.full(nx * ny * headings, np.inf)
    cap = max_expansions * prims.shape[1] + 1
    states = np.empty((cap, 4))
    room = np.empty(cap)
    wheel = np.empty(cap, dtype=np.int64)
    parent = np.empty(cap, dtype=np.int64)
    prim = np.empty(cap, dtype=np.int64)
    states[0], room[0], wheel[0], parent[0], prim[0] = start, start_room, prims.shape[0] - 1, -1, -1
    count = 1
    key = _key(start, lo, cell, ny, headings)
    best[key] = 0.0
    heap = [(weight * math.hypot(goal[0] - start[0], goal[1] - start[1]) / speed, 0.0, 0)]
    expansions = 0
    found = -1
    reach = margin + 2.0 * spare  # the clearance cap of every check
    glo = lo - BUCKET_PAD
    gnx = int(math.ceil((hi[0] - lo[0] + 2.0 * BUCKET_PAD) / BUCKET)) + 1
    gny = int(math.ceil((hi[1] - lo[1] + 2.0 * BUCKET_PAD) / BUCKET)) + 1
    first, items = _buckets(obstacles, radii, body + reach, glo, BUCKET, gnx, gny)
    while len(heap) and expansions < max_expansions:
        _, g, k = heapq.heappop(heap)
        if math.hypot(states[k, 0] - goal[0], states[k, 1] - goal[1]) <= tolerance:
            found = k
            break
        if g > best[_key(states[k], lo, cell, ny, headings)]:
            continue
        expansions += 1
        w = wheel[k]
        floor = max(margin, min(margin + spare, room[k]))
        for p in range(prims.shape[1]):
            end, least, last = _primitive(states[k], prims[w, p], steps[w, p], obstacles, radii, body, dt, wheelbase, v_min, v_max,
                                          offset, length, width, floor, reach, first, items, glo, BUCKET, gnx, gny)
            if least < floor or end[0] < lo[0] or end[0] > hi[0] or end[1] < lo[1] or end[1] > hi[1]:
                continue
            end[3] = 0.0
            cost = g + costs[w, p]
            key = _key(end, lo, cell, ny, headings)
            if cost >= best[key]:
                continue
            best[key] = cost
            states[count], room[count], wheel[count], parent[count], prim[count] = end, last, wheels_after[p], k, p
            heapq.heappush(heap, (cost + weight * math.hypot(goal[0] - end[0], goal[1] - end[1]) / speed, cost, count))
            count += 1
    if found < 0:
        return np.empty((0, 2), dtype=np.int64)
    chain = []
    k = found
    while parent[k] >= 0:
        chain.append((wheel[parent[k]], prim[k]))
        k = parent[k]
    out = np.empty((len(chain), 2), dtype=np.int64)
    for j in range(len(chain)):
        out[j, 0], out[j, 1] = chain[len(chain) - 1 - j]
    return out


@numba.njit(cache=True, nogil=True)
def _key(state, lo, cell, ny, headings):
    """The closed set's lattice index of a rear-axle state."""
    ix = int(round((state[0] - lo[0]) / cell))
    iy = int(round((state[1] - lo[1]) / cell))
    ih = int(round(state[2] / (2.0 * math.pi / headings))) % headings
    return (ix * ny + iy) * headings + ih
