"""Compiled loop of the proximity decision (:mod:`aac_sumo.coordination.proximity`): the sampled
trees grown from each robot of a close pair.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def grow_trees(starts, samples, blockers, blocker_radius, foreign, step):
    """Grow one sampling tree per row of ``starts`` (R, 2) [m] towards its ``samples`` (R, K, 2)
    in order: each sample's nearest node (first on ties) steps at most ``step`` [m] towards it.
    A new node's collision cost sums ``(1 - d / r)^2`` over the ``blockers`` (M, 2) it is
    closer to than their ``blocker_radius`` (M,), counting only those ``foreign`` (R, M) to
    the tree; its path cost adds its parent's. Returns nodes (R, K+1, 2) and path costs
    (R, K+1), the root first."""
    r_count, k_count = samples.shape[0], samples.shape[1]
    nodes = np.empty((r_count, k_count + 1, 2))
    path_cost = np.zeros((r_count, k_count + 1))
    near_blockers = np.empty(blockers.shape[0], dtype=np.int64)
    for r in range(r_count):
        nodes[r, 0, 0], nodes[r, 0, 1] = starts[r, 0], starts[r, 1]
        # every node lies between the root and a sample, so in their box: a blocker farther from
        # the box than its radius adds 0 to every node's cost, and is left out of the sums
        x_lo, x_hi = min(starts[r, 0], samples[r, :, 0].min()), max(starts[r, 0], samples[r, :, 0].max())
        y_lo, y_hi = min(starts[r, 1], samples[r, :, 1].min()), max(starts[r, 1], samples[r, :, 1].max())
        count = 0
        for b in range(blockers.shape[0]):
            gap = math.hypot(max(x_lo - blockers[b, 0], blockers[b, 0] - x_hi, 0.0), max(y_lo - blockers[b, 1], blockers[b, 1] - y_hi, 0.0))
            if foreign[r, b] and gap < blocker_radius[b] + 1e-9:
                near_blockers[count] = b
                count += 1
        for it in range(k_count):
            sx, sy = samples[r, it, 0], samples[r, it, 1]
            near, best = 0, np.inf
            for j in range(it + 1):
                dx, dy = sx - nodes[r, j, 0], sy - nodes[r, j, 1]
                d2 = dx * dx + dy * dy
                if d2 < best:
                    near, best = j, d2
            qx, qy = nodes[r, near, 0], nodes[r, near, 1]
            dx, dy = sx - qx, sy - qy
            length = math.hypot(dx, dy)
            scale = step / max(length, 1e-12) if length > step else 1.0
            nx, ny = qx + scale * dx, qy + scale * dy
            cost = 0.0
            for e in range(count):
                b = near_blockers[e]
                closeness = max(1.0 - math.hypot(nx - blockers[b, 0], ny - blockers[b, 1]) / blocker_radius[b], 0.0)
                cost += closeness * closeness
            nodes[r, it + 1, 0], nodes[r, it + 1, 1] = nx, ny
            path_cost[r, it + 1] = path_cost[r, near] + cost
    return nodes, path_cost
