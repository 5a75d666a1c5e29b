"""Planar geometry: exact ellipse and oriented-rectangle distances.

World frame: x right, y up, lengths in m, angles in rad counter-clockwise from +x. All signed
distances are negative inside. The ellipse distance follows D. Eberly, "Distance from a Point to an
Ellipse, an Ellipsoid, or a Hyperellipsoid" (robust bisection on the monotone root function).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.kernels.geometry import pairwise_clearance
from aac_sumo.kernels.paths import polyline_offsets

# Bisection cap: enough halvings to shrink any positive double interval to adjacent floats
# (Eberly's digits - min_exponent); the loop stops as soon as every interval has collapsed.
_MAX_BISECTIONS = 1100


def along(polyline, s, extend: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Points (K, 2) [m] at arc lengths ``s`` (K,) [m] along ``polyline`` (M, 2) [m], and the
    headings (K,) [rad] of the segments they lie on (at a vertex, the one that begins there). Arc
    lengths outside the polyline are clamped to its ends, or with ``extend`` continue straight
    along its first and last segments. Repeated points are skipped; a polyline of one point
    stands there."""
    pts = np.asarray(polyline, dtype=float)
    s = np.atleast_1d(np.asarray(s, dtype=float))
    seg = np.diff(pts, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    keep = length > 1e-9
    starts, seg, length = pts[:-1][keep], seg[keep], length[keep]
    if len(length) == 0:
        return np.repeat(pts[:1], len(s), axis=0), np.zeros(len(s))
    arc = np.r_[0.0, np.cumsum(length)]
    if not extend:
        s = np.clip(s, 0.0, arc[-1])
    k = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(length) - 1)
    return starts[k] + ((s - arc[k]) / length[k])[:, None] * seg[k], np.arctan2(seg[k, 1], seg[k, 0])


def wrap_angle(angle) -> np.ndarray:
    """``angle`` [rad] wrapped into [-pi, pi] (the same direction within one turn)."""
    return np.angle(np.exp(1j * np.asarray(angle, dtype=float)))


@dataclass(frozen=True)
class Ellipse:
    """Ellipse centred at (cx, cy) [m]; semi-axis ``a`` along local x' (rotated by ``theta`` [rad]
    from world +x), ``b`` along local y'. ``a`` may be smaller than ``b``."""

    cx: float
    cy: float
    a: float
    b: float
    theta: float


@dataclass(frozen=True)
class OrientedRect:
    """Rectangle centred at (cx, cy) [m], ``length`` along ``heading`` [rad], ``width`` across."""

    cx: float
    cy: float
    length: float
    width: float
    heading: float

    def corners(self) -> np.ndarray:
        """World-frame corners (4, 2), counter-clockwise, starting at front-right."""
        return rect_corners(self.as_row())

    def as_row(self) -> np.ndarray:
        """Row ``[cx, cy, length, width, heading]`` as used by :func:`pairwise_rect_clearance`."""
        return np.array([self.cx, self.cy, self.length, self.width, self.heading], dtype=float)


# --------------------------------------------------------------------------------------------
# Ellipse
# --------------------------------------------------------------------------------------------



def _bisect_root(r0, q, z0, z1, g):
    """Root t > 0 of F(t) = (r0 z0/(t+q))^2 + (z1/t)^2 - 1 by bisection, vectorised (1-D).

    Eberly's GetRoot with his s shifted to t = s + 1 so that roots near s = -1 (points near the
    centre of near-circles) keep full relative precision. Requires r0 = q + 1 >= 1, z0 > 0,
    z1 > 0. F is strictly decreasing for t > 0 with F(z1) >= 0; the root lies in [z1, 1] inside
    (g < 0) and in [z1, |(r0 z0, z1)|] outside.
    """
    n0 = r0 * z0
    t0 = z1.copy()
    t1 = np.where(g < 0.0, 1.0, np.hypot(n0, z1))
    t = 0.5 * (t0 + t1)
    active = np.flatnonzero((t != t0) & (t != t1))
    for _ in range(_MAX_BISECTIONS):
        if active.size == 0:
            break
        lo, hi = t0[active], t1[active]
        mid = 0.5 * (lo + hi)
        t[active] = mid
        fval = (n0[active] / (mid + q[active])) ** 2 + (z1[active] / mid) ** 2 - 1.0
        lo = np.where(fval >= 0.0, mid, lo)
        hi = np.where(fval <= 0.0, mid, hi)
        t0[active], t1[active] = lo, hi
        nxt = 0.5 * (lo + hi)
        active = active[(nxt != lo) & (nxt != hi)]
    return t


def _first_quadrant_closest(e0, e1, y0, y1):
    """Closest ellipse point (x0, x1) and unsigned distance for e0 >= e1 > 0, y0, y1 >= 0 (1-D)."""
    # Coordinates below 1e-100 of the axis are snapped onto it (an error of at most that much):
    # subnormal values leave the bisection without relative precision.
    y0 = np.where(y0 < 1e-100 * e0, 0.0, y0)
    y1 = np.where(y1 < 1e-100 * e1, 0.0, y1)
    x0 = np.empty_like(y0)
    x1 = np.empty_like(y0)
    z0 = y0 / e0
    z1 = y1 / e1
    g = z0 * z0 + z1 * z1 - 1.0

    # Generic: strictly inside the quadrant and off the boundary -> bisection.
    gen = (y0 > 0.0) & (y1 > 0.0) & (g != 0.0)
    if gen.any():
        e0g, e1g = e0[gen], e1[gen]
        q = (e0g - e1g) * (e0g + e1g) / (e1g * e1g)
        r0 = q + 1.0
        t = _bisect_root(r0, q, z0[gen], z1[gen], g[gen])
        x0[gen] = r0 * y0[gen] / (t + q)
        x1[gen] = y1[gen] / t

    on_boundary = (y0 > 0.0) & (y1 > 0.0) & (g == 0.0)
    x0[on_boundary], x1[on_boundary] = y0[on_boundary], y1[on_boundary]

    # On the minor axis: the minor vertex is nearest.
    minor = (y0 == 0.0) & (y1 > 0.0)
    x0[minor], x1[minor] = 0.0, e1[minor]

    # On the major axis: off-axis foot inside the evolute (y0 < (e0^2-e1^2)/e0), else the vertex.
    major = y1 == 0.0
    numer0 = e0 * y0
    denom0 = (e0 - e1) * (e0 + e1)
    evolute = major & (numer0 < denom0)
    xde0 = numer0[evolute] / denom0[evolute]
    x0[evolute] = e0[evolute] * xde0
    x1[evolute] = e1[evolute] * np.sqrt((1.0 - xde0) * (1.0 + xde0))
    vertex = major & ~evolute
    x0[vertex], x1[vertex] = e0[vertex], 0.0

    return x0, x1, np.hypot(x0 - y0, x1 - y1), g


def _ellipse_solve(points, cx, cy, a, b, theta):
    """Signed distance (...) and world closest point (..., 2), broadcasting points and params."""
    points = np.asarray(points, dtype=float)
    px, py, cx, cy, a, b, theta = np.broadcast_arrays(
        points[..., 0], points[..., 1], *(np.asarray(v, dtype=float) for v in (cx, cy, a, b, theta))
    )
    shape = px.shape
    px, py, cx, cy, a, b, theta = (v.ravel() for v in (px, py, cx, cy, a, b, theta))
    c, s = np.cos(theta), np.sin(theta)
    dx, dy = px - cx, py - cy
    u = c * dx + s * dy  # local x'
    v = -s * dx + c * dy  # local y'

    # Put the major axis first so that e0 >= e1.
    swap = a < b
    e0, e1 = np.where(swap, b, a), np.where(swap, a, b)
    q0, q1 = np.where(swap, v, u), np.where(swap, u, v)
    x0, x1, dist, g = _first_quadrant_closest(e0, e1, np.abs(q0), np.abs(q1))
    x0 = np.copysign(x0, q0)
    x1 = np.copysign(x1, q1)
    lu, lv = np.where(swap, x1, x0), np.where(swap, x0, x1)

    signed = np.where(g < 0.0, -dist, dist).reshape(shape)
    closest = np.stack([cx + c * lu - s * lv, cy + s * lu + c * lv], axis=-1).reshape(*shape, 2)
    return signed, closest


def ellipse_signed_distance(points, cx, cy, a, b, theta) -> np.ndarray:
    """Exact Euclidean signed distance [m] from world ``points`` (..., 2) to an ellipse boundary.

    Negative inside. Ellipse parameters (centre [m], semi-axes ``a`` along local x' and ``b``
    along local y' [m], rotation ``theta`` [rad]) may be arrays broadcasting with
    ``points[..., 0]``.
    Returns an array of the broadcast shape (0-d for a single point).
    """
    return _ellipse_solve(points, cx, cy, a, b, theta)[0]


def ellipse_closest_point(points, cx, cy, a, b, theta) -> np.ndarray:
    """Nearest point on the ellipse boundary (..., 2), world frame; arguments as
    :func:`ellipse_signed_distance`."""
    return _ellipse_solve(points, cx, cy, a, b, theta)[1]


# --------------------------------------------------------------------------------------------
# Oriented rectangles
# --------------------------------------------------------------------------------------------

# Corner signs (along, across) in counter-clockwise order: front-right, front-left, rear-left,
# rear-right.
_CORNER_SIGNS = np.array([[1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0]])


def rect_corners(rects: np.ndarray) -> np.ndarray:
    """Corners (..., 4, 2) of rectangle rows (..., 5) ``[cx, cy, length, width, heading]``."""
    c, s = np.cos(rects[..., 4:5]), np.sin(rects[..., 4:5])
    du = 0.5 * rects[..., 2:3] * _CORNER_SIGNS[:, 0]
    dv = 0.5 * rects[..., 3:4] * _CORNER_SIGNS[:, 1]
    return np.stack(
        [rects[..., 0:1] + c * du - s * dv, rects[..., 1:2] + s * du + c * dv], axis=-1
    )


def _vertex_gap(ka, rb):
    """Min distance from the corners ``ka`` (..., 4, 2) to rectangles ``rb`` (..., 5).

    Zero for corners inside ``rb``; for corners outside it equals the minimum distance to the
    edges of ``rb``.
    """
    c, s = np.cos(rb[..., 4:5]), np.sin(rb[..., 4:5])
    dx, dy = ka[..., 0] - rb[..., 0:1], ka[..., 1] - rb[..., 1:2]
    qu = np.maximum(np.abs(c * dx + s * dy) - 0.5 * rb[..., 2:3], 0.0)
    qv = np.maximum(np.abs(-s * dx + c * dy) - 0.5 * rb[..., 3:4], 0.0)
    return np.hypot(qu, qv).min(axis=-1)


def _clearance(ra: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """Signed clearance between rectangle rows ``ra`` and ``rb`` (..., 5), broadcasting."""
    ra, rb = np.broadcast_arrays(ra, rb)
    dx, dy = rb[..., 0] - ra[..., 0], rb[..., 1] - ra[..., 1]
    ha, hb = ra[..., 4], rb[..., 4]
    la, wa, lb, wb = 0.5 * ra[..., 2], 0.5 * ra[..., 3], 0.5 * rb[..., 2], 0.5 * rb[..., 3]
    cd, sd = np.abs(np.cos(hb - ha)), np.abs(np.sin(hb - ha))
    ca, sa, cb, sb = np.cos(ha), np.sin(ha), np.cos(hb), np.sin(hb)
    # Overlap of the projections on the 4 SAT axes: half-extent sum minus centre offset.
    overlap = np.stack(
        [
            la + lb * cd + wb * sd - np.abs(dx * ca + dy * sa),
            wa + lb * sd + wb * cd - np.abs(-dx * sa + dy * ca),
            lb + la * cd + wa * sd - np.abs(dx * cb + dy * sb),
            wb + la * sd + wa * cd - np.abs(-dx * sb + dy * cb),
        ]
    ).min(axis=0)
    # Separated convex polygons: the closest pair always involves a vertex of one of them.
    gap = np.minimum(_vertex_gap(rect_corners(ra), rb), _vertex_gap(rect_corners(rb), ra))
    return np.where(overlap > 0.0, -overlap, gap)


def rect_clearance(a: OrientedRect, b: OrientedRect) -> float:
    """Signed clearance [m] between two oriented rectangles.

    Separated or touching: exact Euclidean gap (min over vertex-to-edge distances, >= 0).
    Overlapping: minus the penetration depth, i.e. the smallest translation along one of the 4
    SAT axes (edge normals) that separates them.
    """
    return float(_clearance(a.as_row(), b.as_row()))


def rect_clearance_rows(rects_a, rects_b) -> np.ndarray:
    """Clearance [m] between rectangle rows ``[cx, cy, length, width, heading]`` (..., 5),
    broadcasting the leading axes; each entry equals :func:`rect_clearance` of its pair."""
    return _clearance(np.asarray(rects_a, dtype=float), np.asarray(rects_b, dtype=float))


def pairwise_rect_clearance(rects_a, rects_b) -> np.ndarray:
    """Clearance matrix (n, m) [m] between rows (n, 5) and (m, 5) of
    ``[cx, cy, length, width, heading]``; entry (i, j) equals ``rect_clearance(a_i, b_j)``
    (compiled: :func:`~aac_sumo.kernels.geometry.pairwise_clearance`)."""
    return pairwise_clearance(np.asarray(rects_a, dtype=float).reshape(-1, 5), np.asarray(rects_b, dtype=float).reshape(-1, 5))


def point_rect_signed_distance(points, rect: OrientedRect) -> np.ndarray:
    """Exact signed distance [m] from world ``points`` (..., 2) to the boundary of ``rect``,
    negative inside. Returns shape ``points.shape[:-1]``."""
    points = np.asarray(points, dtype=float)
    c, s = np.cos(rect.heading), np.sin(rect.heading)
    dx, dy = points[..., 0] - rect.cx, points[..., 1] - rect.cy
    qu = np.abs(c * dx + s * dy) - 0.5 * rect.length
    qv = np.abs(-s * dx + c * dy) - 0.5 * rect.width
    outside = np.hypot(np.maximum(qu, 0.0), np.maximum(qv, 0.0))
    inside = np.minimum(np.maximum(qu, qv), 0.0)
    return outside + inside


def rect_distances(points: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """Distance [m] from each of ``points`` (k, 2) to the nearest of the rectangles ``rects``
    (m, 5) ``[cx, cy, length, width, heading]`` (0 inside; inf without rectangles)."""
    if len(rects) == 0:
        return np.full(len(points), np.inf)
    c, s = np.cos(rects[:, 4]), np.sin(rects[:, 4])
    dx, dy = points[:, None, 0] - rects[None, :, 0], points[:, None, 1] - rects[None, :, 1]
    qx = np.abs(c * dx + s * dy) - 0.5 * rects[:, 2]
    qy = np.abs(-s * dx + c * dy) - 0.5 * rects[:, 3]
    return np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0)).min(axis=1)


def convex_hull(points) -> np.ndarray:
    """Vertices (H, 2) of the convex hull of ``points`` (K, 2) [m], counter-clockwise (scipy/Qhull)."""
    from scipy.spatial import ConvexHull

    pts = np.asarray(points, dtype=float)
    return pts[ConvexHull(pts).vertices]


def containing_ellipse(points, theta) -> np.ndarray:
    """Ellipses ``[cx, cy, a, b, theta]`` (..., 5) that contain each point set (..., K, 2) [m].

    In the frame rotated by ``theta`` (...,) [rad] the ellipse is centred on the points'
    bounding box, with the box's aspect ratio, and scaled until the farthest point lies on it, so
    every point satisfies ``(x'/a)^2 + (y'/b)^2 <= 1``. An ellipse is convex, so it contains the
    points' convex hull too; the scale is at most sqrt(2) (the box corners).
    """
    pts = np.asarray(points, dtype=float)
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    u = c * pts[..., 0] + s * pts[..., 1]
    v = -s * pts[..., 0] + c * pts[..., 1]
    u_lo, u_hi, v_lo, v_hi = u.min(-1), u.max(-1), v.min(-1), v.max(-1)
    uc, vc = 0.5 * (u_lo + u_hi), 0.5 * (v_lo + v_hi)
    hu = np.maximum(0.5 * (u_hi - u_lo), 1e-6)  # a micron: thinner ellipses lose containment to round-off
    hv = np.maximum(0.5 * (v_hi - v_lo), 1e-6)
    scale = np.sqrt(((u - uc[..., None]) / hu[..., None]) ** 2 + ((v - vc[..., None]) / hv[..., None]) ** 2).max(-1)
    scale = np.maximum(scale, 1.0) * (1.0 + 1e-9)
    cx = np.cos(theta) * uc - np.sin(theta) * vc
    cy = np.sin(theta) * uc + np.cos(theta) * vc
    return np.stack([cx, cy, scale * hu, scale * hv, theta], axis=-1)


def polyline_offset(points, polyline) -> np.ndarray:
    """Signed distance [m] from each of ``points`` (K, 2) to the polyline (M, 2), M >= 2, whose
    first and last segments go on straight beyond its ends: positive to the left of its
    direction of travel, negative to the right (side of the nearest segment). Compiled
    (:func:`~aac_sumo.kernels.paths.polyline_offsets`)."""
    return polyline_offsets(np.asarray(points, dtype=float).reshape(-1, 2), np.asarray(polyline, dtype=float))
