"""Compiled loops of footprint geometry: the clearance between oriented rectangles (the loop form of
:func:`aac_sumo.geometry.rect_clearance_rows`) and the ellipses round swept hulls (:mod:`aac_sumo.barriers`).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _vertex_gap(ax, ay, al, aw, ah, bx, by, bl, bw, bh):
    """Least distance [m] from the corners of rectangle a to rectangle b (0 for a corner inside b)."""
    ca, sa, cb, sb = math.cos(ah), math.sin(ah), math.cos(bh), math.sin(bh)
    best = np.inf
    for su, sv in ((1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0)):
        du, dv = 0.5 * al * su, 0.5 * aw * sv
        dx, dy = ax + ca * du - sa * dv - bx, ay + sa * du + ca * dv - by
        qu = max(abs(cb * dx + sb * dy) - 0.5 * bl, 0.0)
        qv = max(abs(-sb * dx + cb * dy) - 0.5 * bw, 0.0)
        best = min(best, math.hypot(qu, qv))
    return best


@numba.njit(cache=True)
def rect_clearance(a, b):
    """Signed clearance [m] between rectangle rows ``a`` and ``b`` ``[cx, cy, length, width,
    heading]``, as :func:`aac_sumo.geometry.rect_clearance_rows`: the exact gap when apart,
    minus the penetration depth along the best separating axis when they overlap."""
    ax, ay, al, aw, ah = a[0], a[1], a[2], a[3], a[4]
    bx, by, bl, bw, bh = b[0], b[1], b[2], b[3], b[4]
    dx, dy = bx - ax, by - ay
    la, wa, lb, wb = 0.5 * al, 0.5 * aw, 0.5 * bl, 0.5 * bw
    cd, sd = abs(math.cos(bh - ah)), abs(math.sin(bh - ah))
    ca, sa, cb, sb = math.cos(ah), math.sin(ah), math.cos(bh), math.sin(bh)
    overlap = min(la + lb * cd + wb * sd - abs(dx * ca + dy * sa),
                  wa + lb * sd + wb * cd - abs(-dx * sa + dy * ca),
                  lb + la * cd + wa * sd - abs(dx * cb + dy * sb),
                  wb + la * sd + wa * cd - abs(-dx * sb + dy * cb))
    if overlap > 0.0:
        return -overlap
    return min(_vertex_gap(ax, ay, al, aw, ah, bx, by, bl, bw, bh), _vertex_gap(bx, by, bl, bw, bh, ax, ay, al, aw, ah))


@numba.njit(cache=True)
def point_rect_distance(px, py, cx, cy, c, s, length, width):
    """Signed distance [m] from the point ``(px, py)`` to the rectangle centred at ``(cx, cy)``
    with heading cosine ``c`` and sine ``s`` and sides ``length`` x ``width``, negative inside
    (the loop form of :func:`aac_sumo.geometry.point_rect_signed_distance`)."""
    dx, dy = px - cx, py - cy
    qu = abs(c * dx + s * dy) - 0.5 * length
    qv = abs(-s * dx + c * dy) - 0.5 * width
    return math.hypot(max(qu, 0.0), max(qv, 0.0)) + min(max(qu, qv), 0.0)


@numba.njit(cache=True)
def pairwise_clearance(a, b):
    """Clearance matrix (n, m) [m] of :func:`rect_clearance` between rectangle rows ``a`` (n, 5)
    and ``b`` (m, 5)."""
    out = np.empty((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            out[i, j] = rect_clearance(a[i], b[j])
    return out


@numba.njit(cache=True)
def paired_clearance(a, b):
    """Clearances (p,) [m] of :func:`rect_clearance` between rows ``a[k]`` and ``b[k]`` (p, 5)."""
    out = np.empty(a.shape[0])
    for k in range(a.shape[0]):
        out[k] = rect_clearance(a[k], b[k])
    return out


@numba.njit(cache=True)
def swept_hull_ellipses(rows, theta):
    """Ellipses ``[cx, cy, a, b, theta]`` (m, K, 5) containing, per stage k, the corners of the
    footprints ``rows`` (m, K+1, 5) at k and k+1, oriented by ``theta`` (m, K) [rad]: in the
    frame rotated by theta, centred on the corners' bounding box with its aspect ratio and
    scaled until the farthest corner lies on it. The same numbers, operation for operation, as
    :func:`aac_sumo.geometry.containing_ellipse` of :func:`aac_sumo.geometry.rect_corners` of
    both stages."""
    m, stages = theta.shape
    out = np.empty((m, stages, 5))
    px, py = np.empty(8), np.empty(8)
    su = (1.0, 1.0, -1.0, -1.0)  # the corner signs of rect_corners
    sv = (-1.0, 1.0, 1.0, -1.0)
    for j in range(m):
        for k in range(stages):
            for half in range(2):
                r = rows[j, k + half]
                c, s = math.cos(r[4]), math.sin(r[4])
                for q in range(4):
                    du = 0.5 * r[2] * su[q]
                    dv = 0.5 * r[3] * sv[q]
                    px[4 * half + q] = r[0] + c * du - s * dv
                    py[4 * half + q] = r[1] + s * du + c * dv
            ct, st = math.cos(theta[j, k]), math.sin(theta[j, k])
            u_lo, u_hi, v_lo, v_hi = np.inf, -np.inf, np.inf, -np.inf
            for p in range(8):
                u = ct * px[p] + st * py[p]
                v = -st * px[p] + ct * py[p]
                u_lo, u_hi, v_lo, v_hi = min(u_lo, u), max(u_hi, u), min(v_lo, v), max(v_hi, v)
            uc, vc = 0.5 * (u_lo + u_hi), 0.5 * (v_lo + v_hi)
            hu = max(0.5 * (u_hi - u_lo), 1e-6)
            hv = max(0.5 * (v_hi - v_lo), 1e-6)
            scale = 0.0
            for p in range(8):
                u = ct * px[p] + st * py[p]
                v = -st * px[p] + ct * py[p]
                scale = max(scale, math.sqrt(((u - uc) / hu) ** 2 + ((v - vc) / hv) ** 2))
            scale = max(scale, 1.0) * (1.0 + 1e-9)
            out[j, k, 0] = ct * uc - st * vc
            out[j, k, 1] = st * uc + ct * vc
            out[j, k, 2] = scale * hu
            out[j, k, 3] = scale * hv
            out[j, k, 4] = theta[j, k]
    return out
