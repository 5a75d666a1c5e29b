"""Specification tests for aac_sumo.geometry (ellipse and oriented-rectangle distances)."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from aac_sumo.geometry import (
    Ellipse,
    OrientedRect,
    ellipse_closest_point,
    ellipse_signed_distance,
    pairwise_rect_clearance,
    point_rect_signed_distance,
    rect_clearance,
    rect_clearance_rows,
    wrap_angle,
)

SIGMA = np.linspace(0.0, 2.0 * np.pi, 200_000, endpoint=False)
COS_S, SIN_S = np.cos(SIGMA), np.sin(SIGMA)

semi = st.floats(0.05, 20.0)
angle = st.floats(-2 * np.pi, 2 * np.pi)
coord = st.floats(-50.0, 50.0)
unit = st.floats(-2.5, 2.5)


def rot(phi):
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


def local(p, cx, cy, theta):
    """World point -> ellipse-local (x', y')."""
    return rot(-theta) @ (np.asarray(p, dtype=float) - [cx, cy])


def world(q, cx, cy, theta):
    return rot(theta) @ np.asarray(q, dtype=float) + [cx, cy]


def brute_distance(p, cx, cy, a, b, theta):
    """Unsigned distance to the boundary by dense sampling of sigma plus local refinement of
    every sampled local minimum; also returns the raw sampled minimum (an upper bound)."""
    u, v = local(p, cx, cy, theta)
    d2 = (a * COS_S - u) ** 2 + (b * SIN_S - v) ** 2
    sampled = np.sqrt(d2.min())
    minima = np.flatnonzero((d2 <= np.roll(d2, 1)) & (d2 <= np.roll(d2, -1)))
    minima = minima[np.argsort(d2[minima])[:8]]
    h = SIGMA[1]
    best = sampled
    for i in minima:  # optimise the offset from the sample so Brent's relative tolerance is tiny
        res = minimize_scalar(
            lambda ds, s=SIGMA[i]: (a * np.cos(s + ds) - u) ** 2 + (b * np.sin(s + ds) - v) ** 2,
            bounds=(-2 * h, 2 * h),
            method="bounded",
            options={"xatol": 1e-14},
        )
        best = min(best, np.sqrt(res.fun))
    return best, sampled


# ---------------------------------------------------------------------------------------------
# Ellipse: brute force and sign
# ---------------------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(cx=coord, cy=coord, a=semi, b=semi, theta=angle, ku=unit, kv=unit)
def test_ellipse_distance_matches_dense_boundary_sampling(cx, cy, a, b, theta, ku, kv):
    scale = max(a, b)
    p = world([ku * scale, kv * scale], cx, cy, theta)
    d = float(ellipse_signed_distance(p, cx, cy, a, b, theta))
    refined, sampled = brute_distance(p, cx, cy, a, b, theta)
    tol = 1e-9 * (scale + 50.0)
    assert abs(d) <= sampled + tol  # never farther than an actual boundary point
    assert abs(d) == pytest.approx(refined, abs=tol)
    u, v = local(p, cx, cy, theta)
    g = (u / a) ** 2 + (v / b) ** 2
    if abs(g - 1.0) > 1e-9:
        assert (d < 0) == (g < 1.0)


@settings(max_examples=60, deadline=None)
@given(cx=coord, cy=coord, a=semi, b=semi, theta=angle, ku=unit, kv=unit)
def test_closest_point_lies_on_ellipse_at_the_distance(cx, cy, a, b, theta, ku, kv):
    scale = max(a, b)
    p = world([ku * scale, kv * scale], cx, cy, theta)
    d = ellipse_signed_distance(p, cx, cy, a, b, theta)
    q = ellipse_closest_point(p, cx, cy, a, b, theta)
    qu, qv = local(q, cx, cy, theta)
    assert (qu / a) ** 2 + (qv / b) ** 2 == pytest.approx(1.0, abs=1e-9)
    assert np.linalg.norm(q - p) == pytest.approx(abs(d), abs=1e-9 * (scale + 50.0))


@settings(max_examples=40, deadline=None)
@given(cx=coord, cy=coord, a=semi, b=semi, theta=angle, phi=angle, ku=unit, kv=unit)
def test_rotation_invariance(cx, cy, a, b, theta, phi, ku, kv):
    scale = max(a, b)
    p = world([ku * scale, kv * scale], cx, cy, theta)
    p_rot = rot(phi) @ (p - [cx, cy]) + [cx, cy]
    d = ellipse_signed_distance(p, cx, cy, a, b, theta)
    d_rot = ellipse_signed_distance(p_rot, cx, cy, a, b, theta + phi)
    assert d_rot == pytest.approx(d, abs=1e-9 * (scale + 50.0))


def test_vectorised_and_broadcast_over_parameters():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-10, 10, size=(7, 3, 2))
    a = rng.uniform(0.1, 5, size=3)
    b = rng.uniform(0.1, 5, size=3)
    theta = rng.uniform(-3, 3, size=3)
    d = ellipse_signed_distance(pts, 1.0, -2.0, a, b, theta)
    assert d.shape == (7, 3)
    for i in range(7):
        for j in range(3):
            assert d[i, j] == ellipse_signed_distance(pts[i, j], 1.0, -2.0, a[j], b[j], theta[j])
    assert ellipse_closest_point(pts, 1.0, -2.0, a, b, theta).shape == (7, 3, 2)
    assert ellipse_signed_distance(np.array([3.0, 0.0]), 0, 0, 1, 1, 0).shape == ()


def test_ellipse_dataclass_fields():
    e = Ellipse(cx=1.0, cy=2.0, a=3.0, b=0.5, theta=0.2)
    d = ellipse_signed_distance([1.0, 2.0], e.cx, e.cy, e.a, e.b, e.theta)
    assert d == pytest.approx(-0.5)


# ---------------------------------------------------------------------------------------------
# Ellipse: closed forms and edge cases
# ---------------------------------------------------------------------------------------------

ELLIPSES = [(3.0, 2.0), (2.0, 3.0), (20.0, 0.05), (0.05, 20.0), (10.0, 0.01), (1.0, 1.0)]


@pytest.mark.parametrize("a,b", ELLIPSES)
@pytest.mark.parametrize("theta", [0.0, 0.7, -2.9])
def test_points_on_axes_outside(a, b, theta):
    cx, cy = 1.5, -4.0
    for k in [1.0 + 1e-9, 1.3, 7.0]:
        for sgn in (1.0, -1.0):
            px = world([sgn * k * a, 0.0], cx, cy, theta)
            py = world([0.0, sgn * k * b], cx, cy, theta)
            d_x = ellipse_signed_distance(px, cx, cy, a, b, theta)
            d_y = ellipse_signed_distance(py, cx, cy, a, b, theta)
            assert d_x == pytest.approx((k - 1) * a, rel=1e-9, abs=1e-12)
            assert d_y == pytest.approx((k - 1) * b, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("a,b", ELLIPSES)
@pytest.mark.parametrize("theta", [0.0, 1.1])
def test_centre(a, b, theta):
    assert ellipse_signed_distance([2.0, 3.0], 2.0, 3.0, a, b, theta) == pytest.approx(-min(a, b))


@pytest.mark.parametrize("a,b", [(3.0, 2.0), (2.0, 3.0), (10.0, 0.01), (20.0, 0.05)])
def test_interior_axes_including_evolute(a, b):
    """Inside, on the minor axis the minor vertex is nearest; on the major axis inside the evolute
    (|x| < (a^2-b^2)/a) the nearest point is off the axis, beyond it the major vertex."""
    e0, e1 = max(a, b), min(a, b)
    along_major = np.array([1.0, 0.0]) if a >= b else np.array([0.0, 1.0])
    along_minor = along_major[::-1]
    for t in [0.0, 0.3, 0.9, 0.999]:
        d = ellipse_signed_distance(t * e1 * along_minor, 0, 0, a, b, 0.0)
        assert d == pytest.approx(-(1 - t) * e1, rel=1e-12)
    c = (e0**2 - e1**2) / e0
    for x in [0.1 * c, 0.5 * c, 0.999 * c]:
        xi = e0 * x / (e0**2 - e1**2)
        expected = -np.hypot(e0 * xi - x, e1 * np.sqrt(1 - xi**2))
        d = ellipse_signed_distance(x * along_major, 0, 0, a, b, 0.0)
        assert d == pytest.approx(expected, rel=1e-12)
    for x in [1.0001 * c, 0.5 * (c + e0)]:
        if x < e0:
            d = ellipse_signed_distance(x * along_major, 0, 0, a, b, 0.0)
            assert d == pytest.approx(-(e0 - x), rel=1e-9)


@pytest.mark.parametrize("a,b", [(10.0, 0.01), (0.01, 10.0), (20.0, 0.05)])
def test_very_elongated_against_brute_force(a, b):
    rng = np.random.default_rng(1)
    s = max(a, b)
    pts = np.column_stack([rng.uniform(-1.2, 1.2, 40) * a, rng.uniform(-1.2, 1.2, 40) * b])
    pts = np.vstack([pts, rng.uniform(-1.5, 1.5, (20, 2)) * s])
    d = ellipse_signed_distance(pts, 0.0, 0.0, a, b, 0.0)
    assert np.all(np.isfinite(d))
    for p, dp in zip(pts, d):
        refined, sampled = brute_distance(p, 0.0, 0.0, a, b, 0.0)
        assert abs(dp) == pytest.approx(refined, abs=1e-9 * s)


def test_circle_exact():
    rng = np.random.default_rng(2)
    pts = rng.uniform(-10, 10, (1000, 2))
    pts[0] = [0.5, -1.0]  # the centre
    r = np.hypot(pts[:, 0] - 0.5, pts[:, 1] + 1.0)
    d = ellipse_signed_distance(pts, 0.5, -1.0, 3.0, 3.0, 0.4)
    np.testing.assert_allclose(d, r - 3.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("b", [1e-2, 1.0, 7.0])
def test_near_circle(b):
    a = b * (1 + 1e-12)
    rng = np.random.default_rng(3)
    pts = rng.uniform(-3 * b, 3 * b, (1000, 2))
    pts = np.vstack([pts, [[0.0, 0.0], [1e-14, 0.0], [0.5 * b, 0.0], [0.0, 0.5 * b], [2 * b, 0.0]]])
    d = ellipse_signed_distance(pts, 0.0, 0.0, a, b, 0.3)
    assert np.all(np.isfinite(d))
    np.testing.assert_allclose(d, np.hypot(pts[:, 0], pts[:, 1]) - b, rtol=0, atol=1e-10 * b)


@pytest.mark.parametrize("a,b", ELLIPSES)
def test_points_on_boundary(a, b):
    cx, cy, theta = -3.0, 8.0, 0.9
    sig = np.linspace(0, 2 * np.pi, 37)
    q = np.column_stack([a * np.cos(sig), b * np.sin(sig)])
    pts = q @ rot(theta).T + [cx, cy]
    d = ellipse_signed_distance(pts, cx, cy, a, b, theta)
    np.testing.assert_allclose(d, 0.0, atol=1e-12 * (max(a, b) + 10.0))


# ---------------------------------------------------------------------------------------------
# Oriented rectangles
# ---------------------------------------------------------------------------------------------


def test_corners_counter_clockwise():
    r = OrientedRect(1.0, -2.0, 4.0, 1.5, 0.8)
    k = r.corners()
    assert k.shape == (4, 2)
    x, y = k[:, 0], k[:, 1]
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert area == pytest.approx(4.0 * 1.5)
    np.testing.assert_allclose(k.mean(axis=0), [1.0, -2.0])
    edges = np.linalg.norm(np.roll(k, -1, axis=0) - k, axis=1)
    np.testing.assert_allclose(sorted(edges), [1.5, 1.5, 4.0, 4.0])
    front = 0.5 * (k[0] + k[1])  # first two corners are the front edge
    np.testing.assert_allclose(front, [1.0 + 2.0 * np.cos(0.8), -2.0 + 2.0 * np.sin(0.8)])


def test_point_rect_signed_distance_closed_form():
    r = OrientedRect(1.0, 2.0, 4.0, 2.0, np.pi / 2)  # extends 2 m along y, 1 m along x
    pts = np.array(
        [
            [1.0, 2.0],  # centre
            [1.0, 7.0],  # 3 m past the front face
            [4.0, 2.0],  # 2 m beside the side face
            [5.0, 8.0],  # diagonal from corner (2, 4): (3, 4)
            [1.5, 2.0],  # inside, 0.5 m from the side
            [1.0, 0.5],  # inside, 0.5 m from the rear
            [2.0, 3.0],  # on the boundary
        ]
    )
    d = point_rect_signed_distance(pts, r)
    np.testing.assert_allclose(d, [-1.0, 3.0, 2.0, 5.0, -0.5, -0.5, 0.0], atol=1e-12)
    assert point_rect_signed_distance(pts.reshape(7, 1, 2), r).shape == (7, 1)


def seg_dist(p, s0, s1):
    d = s1 - s0
    t = np.clip(np.dot(p - s0, d) / np.dot(d, d), 0.0, 1.0)
    return np.linalg.norm(p - s0 - t * d)


def oracle_clearance(ra: OrientedRect, rb: OrientedRect) -> float:
    """Independent loop implementation: SAT with corner projections, vertex-to-edge gap."""
    ka, kb = ra.corners(), rb.corners()
    axes = [np.array([np.cos(h), np.sin(h)]) for h in (ra.heading, rb.heading)]
    axes += [np.array([-u[1], u[0]]) for u in axes]
    overlaps = []
    for u in axes:
        pa, pb = ka @ u, kb @ u
        overlaps.append(min(pa.max() - pb.min(), pb.max() - pa.min()))
    if min(overlaps) > 0:
        return -min(overlaps)
    pairs = [(p, kb) for p in ka] + [(p, ka) for p in kb]
    return min(seg_dist(p, k[i], k[(i + 1) % 4]) for p, k in pairs for i in range(4))


def test_rect_separated_axis_aligned():
    a = OrientedRect(0.0, 0.0, 4.0, 2.0, 0.0)
    b = OrientedRect(7.0, 0.5, 2.0, 2.0, 0.0)
    assert rect_clearance(a, b) == pytest.approx(4.0)
    assert rect_clearance(a, OrientedRect(0.3, -6.0, 2.0, 2.0, np.pi)) == pytest.approx(4.0)


def test_rect_corner_to_corner_diagonal():
    a = OrientedRect(0.0, 0.0, 2.0, 2.0, 0.0)
    b = OrientedRect(5.0, 6.0, 2.0, 2.0, 0.0)  # corners (1, 1) and (4, 5)
    assert rect_clearance(a, b) == pytest.approx(5.0)


def test_rect_vertex_to_face_rotated():
    a = OrientedRect(0.0, 0.0, 2.0, 2.0, 0.0)
    b = OrientedRect(1.5 + np.sqrt(2.0), 0.0, 2.0, 2.0, np.pi / 4)  # diamond tip at x = 1.5
    assert rect_clearance(a, b) == pytest.approx(0.5)


def test_rect_touching():
    a = OrientedRect(0.0, 0.0, 4.0, 2.0, 0.0)
    assert rect_clearance(a, OrientedRect(3.0, 0.7, 2.0, 2.0, 0.0)) == pytest.approx(0.0, abs=1e-12)
    assert rect_clearance(a, OrientedRect(3.0, 2.0, 2.0, 2.0, 0.0)) == pytest.approx(0.0, abs=1e-12)


def test_rect_overlapping_axis_aligned():
    a = OrientedRect(0.0, 0.0, 4.0, 2.0, 0.0)  # x in [-2, 2], y in [-1, 1]
    b = OrientedRect(2.5, 0.5, 2.0, 2.0, 0.0)  # x in [1.5, 3.5], y in [-0.5, 1.5]
    assert rect_clearance(a, b) == pytest.approx(-0.5)
    c = OrientedRect(0.0, 0.2, 1.0, 1.0, 0.0)  # inside a: push out along y by 1 + 0.5 - 0.2
    assert rect_clearance(a, c) == pytest.approx(-1.3)


@pytest.mark.parametrize("heading", [0.0, 0.4, np.pi / 2, 3.0])
def test_rect_against_itself(heading):
    r = OrientedRect(3.0, -1.0, 4.5, 1.8, heading)
    assert rect_clearance(r, r) == pytest.approx(-1.8)


rect = st.builds(
    OrientedRect,
    cx=st.floats(-6.0, 6.0),
    cy=st.floats(-6.0, 6.0),
    length=st.floats(0.2, 6.0),
    width=st.floats(0.2, 3.0),
    heading=angle,
)


def row(r: OrientedRect):
    return [r.cx, r.cy, r.length, r.width, r.heading]


@settings(max_examples=150, deadline=None)
@given(a=rect, b=rect)
def test_rect_clearance_symmetric_and_matches_oracle(a, b):
    c = rect_clearance(a, b)
    assert c == pytest.approx(rect_clearance(b, a), abs=1e-12)
    assert c == pytest.approx(oracle_clearance(a, b), abs=1e-9)
    if c > 0:  # gap is a lower bound on every corner's distance to the other rectangle
        assert point_rect_signed_distance(a.corners(), b).min() >= c - 1e-9
        assert point_rect_signed_distance(b.corners(), a).min() >= c - 1e-9


@settings(max_examples=40, deadline=None)
@given(ra=st.lists(rect, min_size=1, max_size=6), rb=st.lists(rect, min_size=1, max_size=6))
def test_pairwise_matches_rect_clearance(ra, rb):
    m = pairwise_rect_clearance(np.array([row(r) for r in ra]), np.array([row(r) for r in rb]))
    assert m.shape == (len(ra), len(rb))
    expected = np.array([[rect_clearance(x, y) for y in rb] for x in ra])
    np.testing.assert_allclose(m, expected, rtol=0, atol=1e-12)


def test_pairwise_self_diagonal_negative():
    rng = np.random.default_rng(4)
    rows = np.column_stack(
        [rng.uniform(-20, 20, (50, 2)), rng.uniform(1, 5, (50, 2)), rng.uniform(-3, 3, 50)]
    )
    m = pairwise_rect_clearance(rows, rows)
    assert m.shape == (50, 50)
    np.testing.assert_allclose(np.diag(m), -np.minimum(rows[:, 2], rows[:, 3]))
    np.testing.assert_allclose(m, m.T, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(points=st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20)), min_size=1, max_size=6),
       line=st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20)), min_size=2, max_size=6))
def test_polyline_offset_matches_dense_sampling(points, line):
    """|offset| is the distance to the polyline with its end segments carried on straight."""
    from aac_sumo.geometry import polyline_offset

    pts, poly = np.array(points), np.array(line)

    def carried(a, b, back, ahead):  # the segment, extended 200 m where asked (the points lie within 60 m)
        d = b - a
        n = np.hypot(*d)
        if n < 1e-9:
            return a, b
        unit = d / n
        return a - 200.0 * back * unit, b + 200.0 * ahead * unit

    last = len(poly) - 2
    segments = [carried(a, b, i == 0, i == last) for i, (a, b) in enumerate(zip(poly[:-1], poly[1:]))]
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    dense = np.vstack([a + t * (b - a) for a, b in segments])
    brute = np.hypot(*(pts[:, None, :] - dense[None]).transpose(2, 0, 1)).min(axis=1)
    got = np.abs(polyline_offset(pts, poly))
    assert np.all(got <= brute + 1e-9)
    seg = max(np.hypot(*(b - a)) for a, b in segments)
    assert np.all(brute - got <= seg / 20000 + 1e-9)


def test_polyline_offset_sign_is_left_positive():
    from aac_sumo.geometry import polyline_offset

    line = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])  # east, then north
    np.testing.assert_allclose(polyline_offset([[5.0, 2.0], [5.0, -3.0], [12.0, 5.0], [8.0, 5.0]], line), [2.0, -3.0, -2.0, 2.0])
    # beyond the ends the end segments go on: 30 m past the end, 1 m right of the line's extension
    np.testing.assert_allclose(polyline_offset([[11.0, 40.0], [-20.0, -1.0]], line), [-1.0, -1.0])


@given(angle=st.floats(-1e3, 1e3, allow_nan=False))
def test_wrap_angle_lands_in_one_turn_and_keeps_the_direction(angle):
    wrapped = float(wrap_angle(angle))
    assert -np.pi <= wrapped <= np.pi
    assert np.cos(wrapped) == pytest.approx(np.cos(angle), abs=1e-9)
    assert np.sin(wrapped) == pytest.approx(np.sin(angle), abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(a=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(0.1, 5), st.floats(0.1, 3), st.floats(-7, 7)),
       b=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(0.1, 5), st.floats(0.1, 3), st.floats(-7, 7)))
def test_compiled_rect_clearance_equals_the_numpy_one(a, b):
    """The safety stop's compiled clearance is the geometry module's, apart or overlapping."""
    from aac_sumo.kernels.geometry import rect_clearance as compiled_clearance

    a, b = np.array(a), np.array(b)
    assert compiled_clearance(a, b) == pytest.approx(float(rect_clearance_rows(a, b)), abs=1e-12)


@settings(max_examples=80, deadline=None)
@given(line=st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20)), min_size=2, max_size=6),
       frac=st.floats(-0.5, 1.5))
@example(line=[(0.0, 1.0), (0.0, 0.0), (0.0, 1.0)], frac=0.5)  # on the vertex where the line turns back
def test_along_walks_the_arc_length(line, frac):
    """A point at arc length s lies s along the polyline (its end segments carried on straight
    with ``extend``, clamped to its ends without), with the heading of the segment it lies on (at
    a vertex, the one that begins there)."""
    from aac_sumo.geometry import along

    poly = np.array(line)
    seg = np.diff(poly, axis=0)
    keep = np.hypot(*seg.T) > 1e-9
    if not keep.any():
        return
    starts, seg = poly[:-1][keep], seg[keep]
    lengths = np.hypot(*seg.T)
    begins = np.r_[0.0, np.cumsum(lengths)[:-1]]
    total = lengths.sum()
    s = frac * total
    for extend in (False, True):
        (point,), (heading,) = along(poly, s, extend=extend)
        walk = s if extend else min(max(s, 0.0), total)
        k = int(np.clip(np.searchsorted(begins, walk, side="right") - 1, 0, len(lengths) - 1))
        np.testing.assert_allclose(point, starts[k] + (walk - begins[k]) / lengths[k] * seg[k], atol=1e-9 * max(1.0, total))
        assert heading == pytest.approx(np.arctan2(seg[k, 1], seg[k, 0]))


def test_along_closed_form():
    from aac_sumo.geometry import along

    line = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [10.0, 10.0]])  # east, a repeated point, then north
    points, headings = along(line, [-2.0, 4.0, 15.0, 23.0])
    np.testing.assert_allclose(points, [[0.0, 0.0], [4.0, 0.0], [10.0, 5.0], [10.0, 10.0]])
    np.testing.assert_allclose(headings, [0.0, 0.0, np.pi / 2, np.pi / 2])
    points, _ = along(line, [-2.0, 23.0], extend=True)
    np.testing.assert_allclose(points, [[-2.0, 0.0], [10.0, 13.0]])
    np.testing.assert_allclose(along(np.array([[3.0, 4.0]]), [0.0, 5.0])[0], [[3.0, 4.0], [3.0, 4.0]])
