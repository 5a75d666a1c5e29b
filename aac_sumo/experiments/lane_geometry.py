"""Lane geometry of SUMO roads for car references: points along lane centre lines, smooth
blends from one lane onto another, lane edges, and curvature-continuous references.

Frames and units: SUMO's network frame [m]; arc lengths along a polyline [m]."""

from __future__ import annotations

import numpy as np

from aac_sumo import network
from aac_sumo.geometry import along
from aac_sumo.references import PathReference, curve_speeds, smooth_path

SAMPLE_STEP = 1.0  # reference path resolution along the road [m]
SMOOTH_SPACING = 1.0  # point spacing of the smoothed reference paths [m]
CURVE_DECEL = 1.5  # a reference slows down for a curve at most this hard [m/s^2]
ROAD_MARGIN = 0.1  # the rear axle keeps half a car width plus this from the road edges [m]
MIN_LANES = 2  # a lane change needs a second lane [lanes]
BAND_SETTLE = 10.0  # beyond the end of its lane change a vehicle's band narrows to its target lane over this [m]
SMOOTH_PAD = 20.0  # a reference's spline is fitted with this much of its straight run-on, so that it meets it without a kink [m]


def smoothstep(x) -> np.ndarray:
    """Quintic 0 -> 1 on [0, 1] with zero first and second derivatives at both ends."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def blend(line_a: np.ndarray, line_b: np.ndarray, s_from: float, s_begin: float, length: float) -> np.ndarray:
    """Points (M, 2) [m] from arc length ``s_from`` of polyline ``line_a`` to its end, moving onto
    ``line_b`` (at the same fraction of its length) between arc lengths ``s_begin`` and
    ``s_begin + length`` of ``line_a`` with a quintic smoothstep."""
    la, lb = (float(np.hypot(*np.diff(line, axis=0).T).sum()) for line in (line_a, line_b))
    sa = np.r_[np.arange(s_from, la, SAMPLE_STEP), la]
    pa, _ = along(line_a, sa)
    pb, _ = along(line_b, sa * lb / la)
    w = smoothstep((sa - s_begin) / length)[:, None]
    return (1.0 - w) * pa + w * pb


def smooth_reference(waypoints: np.ndarray, speed: float, a_lat: float, beyond: float = 0.0) -> PathReference:
    """The reference along a curvature-continuous version of ``waypoints`` (M, 2) [m]
    (:func:`~aac_sumo.references.smooth_path`) at ``speed`` [m/s], slower where its curvature
    would need more than ``a_lat`` [m/s^2] of lateral acceleration. With ``beyond`` [m] it runs
    on straight for that far along the waypoints' last direction (the road's, at its end): the
    spline's own end direction, which a path beyond its end follows, was up to 0.02 rad off
    (its free end), and two cars driving on in neighbouring lanes closed in 1 m across in 60 m.
    The spline is then fitted with ``SMOOTH_PAD`` metres of that straight line, and meets it
    without a kink; likewise with ``SMOOTH_PAD`` metres of straight lead-in before the start,
    which is then dropped: with a free start, the reference's heading where the cars start was
    up to 0.16 rad off the car's (the curved sidewalk road of ``tests/test_driving.py``)."""
    pts = np.asarray(waypoints, dtype=float)
    if beyond <= 0.0:
        points, curvature = smooth_path(pts, SMOOTH_SPACING)
        return PathReference(points, speed, stop_at_end=False, limits=curve_speeds(curvature, SMOOTH_SPACING, speed, a_lat, CURVE_DECEL))
    direction = (pts[-1] - pts[-2]) / np.hypot(*(pts[-1] - pts[-2]))
    first = (pts[1] - pts[0]) / np.hypot(*(pts[1] - pts[0]))
    length = float(np.hypot(*np.diff(pts, axis=0).T).sum())
    pad = np.arange(SAMPLE_STEP, SMOOTH_PAD + 1e-9, SAMPLE_STEP)
    lead_in = pts[0] - pad[::-1, None] * first  # so that the spline's start is no free end either
    points, curvature = smooth_path(np.vstack([lead_in, pts, pts[-1] + pad[:, None] * direction]), SMOOTH_SPACING)
    arc = np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))] - pad[-1]
    keep = (arc >= 0.0) & (arc < length)
    tail = np.arange(SMOOTH_SPACING, beyond + 1e-9, SMOOTH_SPACING)
    points = np.vstack([points[keep], points[keep][-1] + tail[:, None] * direction])
    curvature = np.r_[curvature[keep], np.zeros(len(tail))]
    return PathReference(points, speed, stop_at_end=False, limits=curve_speeds(curvature, SMOOTH_SPACING, speed, a_lat, CURVE_DECEL))


def smooth_road(rd: network.Road) -> network.Road:
    """``rd`` with every lane's centre line curvature-continuous (:func:`~aac_sumo.references.smooth_path`
    of the line sampled every ``SAMPLE_STEP`` metres, so that long straight edges stay straight;
    points every ``SMOOTH_SPACING`` metres): blends of its lines are then curvature-continuous too."""
    lanes = []
    for line in rd.lanes:
        length = float(np.hypot(*np.diff(line, axis=0).T).sum())
        lanes.append(smooth_path(along(line, np.r_[np.arange(0.0, length, SAMPLE_STEP), length])[0], SMOOTH_SPACING)[0])
    return network.Road(rd.edges, lanes, rd.widths)


def lane_reference(points: np.ndarray, speed: float, a_lat: float, caps=None) -> PathReference:
    """The reference along ``points`` (M, 2) [m], a path already curvature-continuous and
    sampled about ``SAMPLE_STEP`` apart (blends of :func:`smooth_road`'s lines), at ``speed``
    [m/s], slower where its curvature would need more than ``a_lat`` [m/s^2] of lateral
    acceleration, and at most ``caps`` (M,) [m/s] when given."""
    seg = np.diff(points, axis=0)
    seg_len = np.hypot(*seg.T)
    keep = np.r_[True, seg_len > 1e-9]
    points = points[keep]
    caps = None if caps is None else np.asarray(caps, dtype=float)[keep]
    seg = np.diff(points, axis=0)
    seg_len, heading = np.hypot(*seg.T), np.arctan2(seg[:, 1], seg[:, 0])
    turn = np.angle(np.exp(1j * np.diff(heading))) / (0.5 * (seg_len[1:] + seg_len[:-1]))
    curvature = np.r_[turn[:1], turn, turn[-1:]] if len(turn) else np.zeros(len(points))
    limits = curve_speeds(curvature, float(np.mean(seg_len)), speed, a_lat, CURVE_DECEL)
    if caps is not None:
        limits = np.minimum(limits, caps)
    return PathReference(points, speed, stop_at_end=False, limits=limits)


def centring_shift(curvature, front: float, half_width: float) -> np.ndarray:
    """How far [m] a car's rear axle keeps inside a curve of signed ``curvature`` (...,) [1/m]
    (positive: turning left; the result has its sign) for the band its body sweeps to be centred
    on the curve: a car whose rear axle runs on a circle of radius u sweeps from its inner rear
    corner, u - w/2, to its outer front corner, sqrt((u + w/2)^2 + f^2), with ``front`` = f [m] from
    the rear axle to the front bumper and ``half_width`` = w/2 [m]. Their mean is R for
    u = R - f^2 / (4 (R + w/2)): the shift is f^2 |k| / (4 (1 + |k| w/2)) (0.39 m on a 7 m turn for
    f = 3.5 m, w = 1.8 m; 6 mm on a 500 m curve). On the curve itself (u = R) that band lies
    off-centre towards the outside: the front corner swings wide into the next lane."""
    k = np.asarray(curvature, dtype=float)
    return front**2 * k / (4.0 * (1.0 + np.abs(k) * half_width))


def offset_polyline(line: np.ndarray, offset) -> np.ndarray:
    """``line`` (M, 2) shifted ``offset`` [m] (a number, or one per vertex (M,)) to its left
    (negative: right), vertex by vertex along the mean of the adjacent segments' normals."""
    seg = np.diff(line, axis=0)
    seg = seg / np.maximum(np.hypot(*seg.T), 1e-12)[:, None]
    normal = np.column_stack([-seg[:, 1], seg[:, 0]])
    vertex = np.vstack([normal[:1], normal[:-1] + normal[1:], normal[-1:]])
    vertex /= np.maximum(np.hypot(*vertex.T), 1e-12)[:, None]
    return line + np.asarray(offset, dtype=float)[..., None] * vertex


def lane_edges(rd: network.Road, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """The right edge of lane ``lo`` and the left edge of lane ``hi`` (polylines [m]): their
    centre lines shifted out by half their width (SUMO numbers lanes from the right)."""
    return offset_polyline(rd.lanes[lo], -0.5 * rd.widths[lo]), offset_polyline(rd.lanes[hi], 0.5 * rd.widths[hi])
