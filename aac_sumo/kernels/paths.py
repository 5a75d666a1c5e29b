"""Compiled loops of path projection and offsets: the nearest point of a polyline, the headings and
poses along it, and a lateral band's signed offsets (:mod:`aac_sumo.references`, :mod:`aac_sumo.geometry`).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def path_headings(cum, seg_heading, s0, count, spacing):
    """Headings (count,) [rad] of a path (cumulative arc lengths ``cum`` (M,), segment headings
    (M-1,)) at arc lengths ``s0 + spacing * k`` [m], as :meth:`aac_sumo.references.PathReference.pose_at`
    gives them, unwrapped as ``numpy.unwrap`` does."""
    out = np.empty(count)
    last = seg_heading.shape[0] - 1
    correction, raw = 0.0, 0.0
    for k in range(count):
        j = min(max(np.searchsorted(cum, s0 + spacing * k, side="right") - 1, 0), last)
        h = seg_heading[j]
        if k:
            d = h - raw
            dd = (d + math.pi) % (2.0 * math.pi) - math.pi
            if dd == -math.pi and d > 0.0:
                dd = math.pi
            if abs(d) >= math.pi:
                correction += dd - d
        raw = h
        out[k] = h + correction
    return out


@numba.njit(cache=True)
def _closest_in(points, seg_len, t_max, px, py, first, last, best_i, best_t, best_d):
    """:func:`closest_on_polyline` over segments ``first..last-1``, starting from the best so far."""
    for i in range(first, last):
        ax, ay = points[i, 0], points[i, 1]
        dx, dy = points[i + 1, 0] - ax, points[i + 1, 1] - ay
        t = min(max(((px - ax) * dx + (py - ay) * dy) / seg_len[i] ** 2, 0.0), t_max[i])
        d = math.hypot(ax + t * dx - px, ay + t * dy - py)
        if d < best_d or (d == best_d and i < best_i):
            best_i, best_t, best_d = i, t, d
    return best_i, best_t, best_d


@numba.njit(cache=True)
def closest_on_polyline(points, seg_len, t_max, px, py, chunk_centre, chunk_radius, chunk):
    """The segment ``i`` of polyline ``points`` (M, 2) [m] (segment lengths ``seg_len`` (M-1,))
    closest to the point ``(px, py)`` (the first on ties), the fraction ``t`` of it, clipped
    into ``[0, t_max[i]]``, at which the closest point lies, and the distance [m] to it.

    Segments come in chunks of ``chunk``, chunk ``c`` within ``chunk_radius[c]`` of
    ``chunk_centre[c]`` (:func:`polyline_chunks`): the chunk with the nearest bound is scanned
    first, then every other whose bound is within the best distance found, with the same answer
    as a scan of every segment (ties go to the lowest index whatever the order). The last
    segment, which may carry on past the end (``t_max`` above 1), is always scanned. Nothing is
    allocated: the continuations and stopping courses project once a period of their courses."""
    n = seg_len.shape[0]
    best_i, best_t, best_d = _closest_in(points, seg_len, t_max, px, py, n - 1, n, 0, 0.0, np.inf)
    nearest, nearest_bound = -1, np.inf
    for c in range(chunk_radius.shape[0]):
        bound = max(math.hypot(chunk_centre[c, 0] - px, chunk_centre[c, 1] - py) - chunk_radius[c], 0.0)
        if bound < nearest_bound:
            nearest, nearest_bound = c, bound
    if nearest >= 0 and nearest_bound <= best_d:
        best_i, best_t, best_d = _closest_in(points, seg_len, t_max, px, py, nearest * chunk, min((nearest + 1) * chunk, n), best_i, best_t,
                                             best_d)
    for c in range(chunk_radius.shape[0]):
        if c != nearest and max(math.hypot(chunk_centre[c, 0] - px, chunk_centre[c, 1] - py) - chunk_radius[c], 0.0) <= best_d:
            best_i, best_t, best_d = _closest_in(points, seg_len, t_max, px, py, c * chunk, min((c + 1) * chunk, n), best_i, best_t, best_d)
    return best_i, best_t, best_d


@numba.njit(cache=True)
def project_points(points, seg_len, cum, t_max, queries, chunk_centre, chunk_radius, chunk):
    """Arc lengths (K,) [m] along polyline ``points`` (cumulative lengths ``cum``) of the
    closest points to ``queries`` (K, 2), and the distances (K,) [m] to them
    (:func:`closest_on_polyline` each)."""
    s = np.empty(queries.shape[0])
    d = np.empty(queries.shape[0])
    for k in range(queries.shape[0]):
        i, t, d[k] = closest_on_polyline(points, seg_len, t_max, queries[k, 0], queries[k, 1], chunk_centre, chunk_radius, chunk)
        s[k] = cum[i] + t * seg_len[i]
    return s, d


def polyline_chunks(points: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres (C, 2) and radii (C,) [m] of circles holding the segments of ``points`` (M, 2),
    ``chunk`` segments each (the last chunk may be shorter): the bounds of :func:`closest_on_polyline`."""
    n = len(points) - 1
    starts = np.arange(0, n, chunk)
    centres, radii = np.empty((len(starts), 2)), np.empty(len(starts))
    for row, start in enumerate(starts):
        part = points[start:min(start + chunk, n) + 1]
        centres[row] = 0.5 * (part.min(axis=0) + part.max(axis=0))
        radii[row] = np.hypot(part[:, 0] - centres[row, 0], part[:, 1] - centres[row, 1]).max()
    return centres, radii


@numba.njit(cache=True)
def polyline_offsets(points, polyline):
    """Signed distance [m] (K,) of each of ``points`` (K, 2) to ``polyline`` (M, 2), M >= 2, its
    end segments carried on straight: positive to the left of its direction of travel, on the
    side of the nearest segment (the first on ties), as :func:`aac_sumo.geometry.polyline_offset`."""
    out = np.empty(points.shape[0])
    last = polyline.shape[0] - 2
    for k in range(points.shape[0]):
        px, py = points[k, 0], points[k, 1]
        best, best_i = np.inf, 0
        for i in range(last + 1):
            ax, ay = polyline[i, 0], polyline[i, 1]
            dx, dy = polyline[i + 1, 0] - ax, polyline[i + 1, 1] - ay
            length2 = dx * dx + dy * dy
            t = ((px - ax) * dx + (py - ay) * dy) / length2 if length2 >= 1e-18 else 0.0  # under 1 nm: a point, not carried on
            if i > 0:
                t = max(t, 0.0)
            if i < last:
                t = min(t, 1.0)
            gx, gy = px - (ax + t * dx), py - (ay + t * dy)
            dist = math.sqrt(gx * gx + gy * gy)
            if dist < best:
                best, best_i = dist, i
        ax, ay = polyline[best_i, 0], polyline[best_i, 1]
        dx, dy = polyline[best_i + 1, 0] - ax, polyline[best_i + 1, 1] - ay
        out[k] = -best if dx * (py - ay) - dy * (px - ax) < 0.0 else best
    return out


@numba.njit(cache=True)
def path_poses(points, cum, seg_len, seg_dir, seg_heading, stop_at_end, s):
    """Rows ``[x, y, heading]`` (K, 3) of the polyline ``points`` (M, 2) at the arc lengths ``s``
    (K,) [m]: on the segment each lies on (the first or the last beyond the ends; ``cum`` (M,)
    cumulative arc lengths, ``seg_len``, ``seg_dir`` (M-1, 2) and ``seg_heading`` per segment),
    clamped to it when ``stop_at_end``, else carried on straight past the ends."""
    out = np.empty((s.shape[0], 3))
    last = seg_len.shape[0] - 1
    for k in range(s.shape[0]):
        i = min(max(np.searchsorted(cum, s[k], side="right") - 1, 0), last)
        local = s[k] - cum[i]
        if stop_at_end:
            local = min(max(local, 0.0), seg_len[i])
        out[k, 0] = points[i, 0] + local * seg_dir[i, 0]
        out[k, 1] = points[i, 1] + local * seg_dir[i, 1]
        out[k, 2] = seg_heading[i]
    return out


@numba.njit(cache=True)
def paths_at(states, points, seg_len, cum, seg_dir, seg_heading, t_max, chunk_centre, chunk_radius, path_rows, seg_rows, chunk_rows,
             chunk, stop_at_end, approach, length):
    """Where each robot's rear axle (``states`` (n, 4)) projects on its own path, for many paths
    stored end to end (path k: ``points[path_rows[k]:path_rows[k + 1]]`` with its segments'
    arrays from ``seg_rows[k]`` and its projection chunks from ``chunk_rows[k]``, as
    :meth:`~aac_sumo.references.PathReference.arrays` gives each): the arc length (n,) [m] and
    the pose ``[x, y, heading]`` (n, 3) there, as ``PathReference.project`` and ``pose_at``
    give them, and whether the robot is surely on its path rather than approaching its goal
    (``PathReference.horizon``'s rule, with a nanometre to spare; False: decide it there)."""
    n = states.shape[0]
    s = np.empty(n)
    pose = np.empty((n, 3))
    on_path = np.zeros(n, dtype=np.bool_)
    for k in range(n):
        p0, p1, q0, q1 = path_rows[k], path_rows[k + 1], seg_rows[k], seg_rows[k + 1]
        pts, lengths, arcs = points[p0:p1], seg_len[q0:q1], cum[p0:p1]
        i, t, off = closest_on_polyline(pts, lengths, t_max[q0:q1], states[k, 0], states[k, 1], chunk_centre[chunk_rows[k]:chunk_rows[k + 1]],
                                        chunk_radius[chunk_rows[k]:chunk_rows[k + 1]], chunk[k])
        s[k] = arcs[i] + t * lengths[i]
        pose[k] = path_poses(pts, arcs, lengths, seg_dir[q0:q1], seg_heading[q0:q1], stop_at_end[k], s[k:k + 1])[0]
        gx, gy = pts[p1 - p0 - 1, 0] - states[k, 0], pts[p1 - p0 - 1, 1] - states[k, 1]
        dist = math.hypot(gx, gy)
        on_path[k] = not stop_at_end[k] or approach[k] <= 0.0 or (dist > approach[k] + 1e-9 and length[k] - s[k] > off + 1e-9)
    return s, pose, on_path
