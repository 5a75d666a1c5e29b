"""A controlled car's way along its SUMO route through a city network: the car lanes it takes
edge to edge, the junctions' internal lanes between them, and the curvature-continuous path,
speed caps, stop lines and lateral band along it.

Frames and units: SUMO's network frame [m] (x right, y up); arc lengths along a polyline [m];
headings [rad] from the x axis, positive to the left. Car-lane indices count the lanes of an edge
open to ``network.VEHICLE_CLASS`` from the right (``network.car_lanes``). The network must be
read with its internal lanes (``sumolib.net.readNet(path, withInternal=True)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from aac_sumo.experiments.lane_geometry import (
    CURVE_DECEL,
    SAMPLE_STEP,
    SMOOTH_PAD,
    centring_shift,
    offset_polyline,
    smoothstep,
)
from aac_sumo.geometry import along
from aac_sumo.network import VEHICLE_CLASS, car_lanes
from aac_sumo.references import curve_speeds, smooth_path

#: The smoothing spline keeps within about this of the lanes' shapes [m] (``smooth_path``'s
#: tolerance). It leaves SUMO's polylines of internal lanes (netconvert's five points a turn, corners
#: of up to 0.5 rad) by at most 0.16 m on 90-degree turns of 10 m radius, 0.23 m on 4 m ones, and
#: wanders up to 0.06 m off straight lanes; at 0.03 its curvature jumps at their corners.
SMOOTH_TOLERANCE = 0.04
#: Stop lines and junction borders are looked for this far either side of where the lanes'
#: bookkeeping puts them on the path [m] (a route may cross itself at a junction it passes twice).
PROJECTION_WINDOW = 5.0
#: A path moves over to its curb clearance (``route_path``'s ``curb``) along this much arc length
#: [m]: a quintic smoothstep of 0.4 m over 30 m turns at most 0.0026 /m, 0.5 m/s^2 at 14 m/s.
CURB_RAMP = 30.0


@dataclass(frozen=True)
class Leg:
    """One edge of a route: the car lane it is entered on (``arrive``) and left from (``leave``;
    another lane: a lane change on this edge), the internal lanes ``via`` from there to the next
    edge (empty on the last edge), the traffic light ``tls`` and link index ``link`` of that
    connection (``''`` and -1 without), and the node ``junction`` at the edge's end."""

    edge: str
    arrive: int
    leave: int
    via: tuple[str, ...]
    tls: str
    link: int
    junction: str


def _links(here, there) -> dict[tuple[int, int], object]:
    """The connections from edge ``here`` to edge ``there``, by (car lane, car lane) index."""
    src, dst = car_lanes(here), car_lanes(there)
    return {(src.index(c.getFromLane()), dst.index(c.getToLane())): c for c in here.getConnections(there)
            if c.getFromLane() in src and c.getToLane() in dst}


def internal_lanes(net, conn) -> tuple[str, ...]:
    """The internal lanes of ``conn`` in driving order: its via lane and those it leads on through
    to ``conn``'s target lane (SUMO splits a turn that waits inside the junction in two)."""
    chain, lane_id = [], conn.getViaLaneID()
    while lane_id:
        chain.append(lane_id)
        lane_id = next((c.getViaLaneID() for c in net.getLane(lane_id).getOutgoing() if c.getToLane() == conn.getToLane()), "")
    return tuple(chain)


def route_legs(net, edges: list[str], start_lane: int) -> list[Leg]:
    """The legs along edge ids ``edges``, entered on car lane ``start_lane`` of the first: lanes that
    follow the network's connections with the fewest lanes crossed in total (dynamic programming
    over the edges; ties go to the rightmost lanes, leave lane first). ``ValueError`` (one line)
    for an unknown edge, a start lane the first edge has no car lane for, or an edge that does not
    connect to the next for ``VEHICLE_CLASS``."""
    unknown = [eid for eid in edges if not net.hasEdge(eid)]
    if unknown or not edges:
        raise ValueError(f"unknown edge {unknown[0]}" if unknown else "a route needs at least one edge")
    route = [net.getEdge(eid) for eid in edges]
    if not 0 <= start_lane < len(car_lanes(route[0])):
        raise ValueError(f"edge {edges[0]} has no car lane {start_lane} ({len(car_lanes(route[0]))} lanes open to {VEHICLE_CLASS})")
    links = [_links(a, b) for a, b in pairwise(route)]
    for (a, b), found in zip(pairwise(edges), links):
        if not found:
            raise ValueError(f"edge {a} does not connect to edge {b} for {VEHICLE_CLASS}")
    if any(c.getViaLaneID() for found in links for c in found.values()) and not net.hasInternal:
        raise ValueError("the network was read without its internal lanes (readNet(..., withInternal=True))")
    cost = [0] * len(car_lanes(route[-1]))  # lanes crossed from arriving on car lane k of the edge on
    picks = []  # per edge but the last, per arrive lane: (leave lane, next edge's arrive lane)
    for found, edge in zip(links[::-1], route[-2::-1]):
        best = [min((abs(leave - a) + cost[b], leave, b) for leave, b in found) for a in range(len(car_lanes(edge)))]
        cost = [c for c, _, _ in best]
        picks.insert(0, [(leave, b) for _, leave, b in best])
    legs, arrive = [], start_lane
    for edge, found, pick in zip(route, links, picks):
        leave, after = pick[arrive]
        conn = found[(leave, after)]
        legs.append(Leg(edge.getID(), arrive, leave, internal_lanes(net, conn), conn.getTLSID(), conn.getTLLinkIndex(), edge.getToNode().getID()))
        arrive = after
    return legs + [Leg(edges[-1], arrive, arrive, (), "", -1, route[-1].getToNode().getID())]


@dataclass(frozen=True)
class StopLine:
    """Where a traffic light's connection begins: the incoming lane's end ``point`` (2,) [m], its
    ``heading`` [rad] and ``width`` [m] there, arc length ``s`` [m] along ``RoutePath.points``
    (the point's projection), the light ``tls``, its ``link`` index and the incoming ``lane`` id."""

    point: np.ndarray
    heading: float
    s: float
    width: float
    tls: str
    link: int
    lane: str


@dataclass(frozen=True)
class JunctionSpan:
    """The stretch of ``RoutePath.points`` inside node ``junction``: arc lengths [m] from where the
    path leaves its incoming lane (``s_in``, the first internal lane's start) to where it joins the
    next edge's lane (``s_out``, the last internal lane's end)."""

    junction: str
    s_in: float
    s_out: float


@dataclass(frozen=True)
class RoutePath:
    """A route's centre line ``points`` (M, 2) [m], curvature-continuous, about ``SAMPLE_STEP``
    apart; speed caps ``limits`` (M,) [m/s] (lane speed limits and curve speeds); the ``legs``; the
    traffic lights' ``stops`` and the ``junctions`` in driving order; and the right and left edges
    ``band_right``, ``band_left`` (M, 2) [m] of the lane(s) the car is in beside each point: the
    lanes' shapes (internal lanes' too) offset by half their widths, both lanes while it changes;
    and the ``curvature`` (M,) [1/m] at each point."""

    points: np.ndarray
    limits: np.ndarray
    legs: list[Leg]
    stops: list[StopLine]
    junctions: list[JunctionSpan]
    band_right: np.ndarray
    band_left: np.ndarray
    curvature: np.ndarray


def _shape(lane) -> np.ndarray:
    return np.asarray(lane.getShape(), dtype=float)[:, :2]


def _arc(line: np.ndarray) -> np.ndarray:
    """Cumulative arc lengths (M,) [m] of polyline ``line`` (M, 2)."""
    return np.r_[0.0, np.cumsum(np.hypot(*np.diff(line, axis=0).T))]


def _stations(line: np.ndarray, s_from: float) -> np.ndarray:
    """Arc lengths [m] along ``line`` from ``s_from`` to its end: every ``SAMPLE_STEP`` and at each
    vertex (the shape's corners kept)."""
    arc = _arc(line)
    s = np.unique(np.r_[np.arange(s_from, arc[-1], SAMPLE_STEP), arc[(arc > s_from) & (arc < arc[-1])], arc[-1]])
    return s[np.r_[True, np.diff(s) > 1e-6]]  # no sliver segments: their direction is noise


@dataclass
class _Piece:
    """Points (K, 2) [m] of one lane's stretch of the route, its speed limit [m/s], and the band's
    right and left edges (K, 2) [m] beside them."""

    points: np.ndarray
    speed: float
    right: np.ndarray
    left: np.ndarray


def _edges(points: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """The right and left edges of a lane of ``width`` [m] along centre line ``points`` (K, 2)."""
    return offset_polyline(points, -0.5 * width), offset_polyline(points, 0.5 * width)


def _drawn(net, leg: Leg) -> list:
    """The internal lanes of ``leg``'s connection that have a length (an old network may hold
    zero-length ones, where the shapes meet anyway)."""
    return [lane for lane in map(net.getLane, leg.via) if _arc(_shape(lane))[-1] > 1e-6]


def _lane_piece(lane, s_from: float = 0.0) -> _Piece:
    line = _shape(lane)
    points = along(line, _stations(line, s_from))[0]
    return _Piece(points, lane.getSpeed(), *_edges(points, lane.getWidth()))


def _change_piece(edge_id: str, lane_a, lane_b, s_from: float, crossed: int, change_start: float, change_length: float) -> _Piece:
    """Lane ``lane_a`` from ``s_from`` to its end, moving onto ``lane_b`` (at the same fraction of
    its length) with a quintic smoothstep from ``change_start`` after ``s_from``, ``change_length``
    per lane crossed, cut short to end ``change_start`` before the edge's end. Its band is lane
    ``lane_a``, both lanes while the change is under way, then lane ``lane_b``."""
    line_a, line_b = _shape(lane_a), _shape(lane_b)
    la, lb = _arc(line_a)[-1], _arc(line_b)[-1]
    begin, length = s_from + change_start, change_length * crossed
    room = la - change_start - begin
    if room < 0.5 * length:
        raise ValueError(f"edge {edge_id} is too short for a change of {crossed} lane(s): {max(room, 0.0):.1f} m between "
                         f"{begin:.1f} m and {la - change_start:.1f} m, {0.5 * length:.1f} m needed")
    length = min(length, room)
    s = _stations(line_a, s_from)
    pa, pb = along(line_a, s)[0], along(line_b, s * lb / la)[0]
    w = smoothstep((s - begin) / length)[:, None]
    a_edges, b_edges = _edges(pa, lane_a.getWidth()), _edges(pb, lane_b.getWidth())
    rightmost, leftmost = (a_edges, b_edges) if lane_b.getIndex() > lane_a.getIndex() else (b_edges, a_edges)
    before, after = (s < begin)[:, None], (s > begin + length)[:, None]
    right = np.where(before, a_edges[0], np.where(after, b_edges[0], rightmost[0]))
    left = np.where(before, a_edges[1], np.where(after, b_edges[1], leftmost[1]))
    return _Piece((1.0 - w) * pa + w * pb, min(lane_a.getSpeed(), lane_b.getSpeed()), right, left)


def _project(points: np.ndarray, arc: np.ndarray, point: np.ndarray, near: float) -> float:
    """Arc length [m] of ``point``'s closest point on polyline ``points`` (arc lengths ``arc``),
    looked for within ``PROJECTION_WINDOW`` of arc length ``near``."""
    seg = np.flatnonzero((arc[1:] >= near - PROJECTION_WINDOW) & (arc[:-1] <= near + PROJECTION_WINDOW))
    a, d = points[seg], points[seg + 1] - points[seg]
    t = np.clip(np.einsum("ij,ij->i", point - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0.0, 1.0)
    k = int(np.argmin(np.hypot(*(a + t[:, None] * d - point).T)))
    return float(arc[seg[k]] + t[k] * (arc[seg[k] + 1] - arc[seg[k]]))


def _smooth(line: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The curvature-continuous path (N + 1, 2) [m] along polyline ``line`` (points at most
    ``SAMPLE_STEP`` apart), its curvature (N + 1,) [1/m], and its spacing [m], the N-th part of
    ``line``'s length: ``smooth_path`` of ``line`` fitted with ``SMOOTH_PAD`` of straight lead-in and
    run-on (a spline's free ends wander: 0.03 m and 1 degree off a straight lane 80 m before a
    turn), which are then dropped. The spline's parameter is the arc length along ``line``: point
    k lies next to ``line``'s point k steps along it."""
    length = _arc(line)[-1]
    n = int(np.ceil(length / SAMPLE_STEP))
    step = length / n
    pad = np.arange(1, int(np.ceil(SMOOTH_PAD / step)) + 1)[:, None] * step
    first, last = ((b - a) / np.hypot(*(b - a)) for a, b in ((line[0], line[1]), (line[-2], line[-1])))
    points, curvature = smooth_path(np.vstack([line[0] - pad[::-1] * first, line, line[-1] + pad * last]), step, SMOOTH_TOLERANCE)
    return points[len(pad): len(pad) + n + 1], curvature[len(pad): len(pad) + n + 1], step


def _beside_walkway(net, leg: Leg) -> float:
    """The width [m] of the car lane ``leg`` leaves its edge on, if a lane open only to
    pedestrians (a sidewalk) runs on its right; 0 otherwise."""
    edge = net.getEdge(leg.edge)
    lane = car_lanes(edge)[leg.leave]
    i = lane.getIndex()
    walkway = i > 0 and edge.getLane(i - 1).allows("pedestrian") and not edge.getLane(i - 1).allows(VEHICLE_CLASS)
    return lane.getWidth() if walkway else 0.0


def curb_shift(s: np.ndarray, spans: list[tuple[float, float, float]], length: float) -> np.ndarray:
    """Leftward shift [m] at arc lengths ``s`` (N,) [m] of a path that keeps over by ``h`` [m] on
    the last ``length`` [m] before each junction span ``(a, b, h)`` (arc lengths [m] where it
    enters and leaves the junction): a smoothstep up over ``CURB_RAMP`` before that stretch and
    back down across the junction; the largest where two overlap."""
    shift = np.zeros_like(s)
    for a, b, h in spans:
        up = smoothstep((s - (a - length - CURB_RAMP)) / CURB_RAMP)
        down = 1.0 - smoothstep((s - a) / max(b - a, 1e-6))
        shift = np.maximum(shift, h * np.minimum(up, down))
    return shift


def route_path(net, legs: list[Leg], s0: float, a_lat: float, change_start: float, change_length: float,
               front: float = 0.0, half_width: float = 0.0, curb: tuple[float, float] = (0.0, 0.0)) -> RoutePath:
    """The path along ``legs`` from arc length ``s0`` [m] of the first leg's arrive lane (along its
    shape: SUMO's lane positions run along ``getLength()``, which may differ) to the end of the last
    edge's lane, through the junctions' internal lanes: ``smooth_path`` of the lanes' shapes sampled
    every ``SAMPLE_STEP`` and at their vertices. A leg's lane change is a quintic smoothstep from
    its arrive lane onto its leave lane, beginning ``change_start`` [m] after the edge's start (after
    ``s0`` on the first edge), ``change_length`` [m] per lane crossed, cut short to end
    ``change_start`` before the edge's end. ``limits`` caps the speed at each lane's limit and at
    ``a_lat`` [m/s^2] of lateral acceleration, lowered ahead of each cap at ``CURVE_DECEL``.
    ``ValueError`` where ``s0`` does not lie on the first lane, or a change would be cut to less
    than half its length. With a car's ``front`` (rear axle to front bumper) and ``half_width`` [m],
    the path keeps :func:`~aac_sumo.experiments.lane_geometry.centring_shift` inside each curve, so
    that the body of a car whose rear axle follows it sweeps a band centred on the lanes (its
    curvature and curve speeds are the shifted path's)."""
    first = car_lanes(net.getEdge(legs[0].edge))[legs[0].arrive]
    if not 0.0 <= s0 < _arc(_shape(first))[-1]:
        raise ValueError(f"s0 = {s0:.1f} m does not lie on lane {first.getID()} ({_arc(_shape(first))[-1]:.1f} m long)")
    pieces, marks = [], []  # marks: per junction, the index in pieces of its incoming edge's piece
    for i, leg in enumerate(legs):
        lanes = car_lanes(net.getEdge(leg.edge))
        s_from = s0 if i == 0 else 0.0
        if leg.arrive == leg.leave:
            pieces.append(_lane_piece(lanes[leg.arrive], s_from))
        else:
            pieces.append(_change_piece(leg.edge, lanes[leg.arrive], lanes[leg.leave], s_from, abs(leg.leave - leg.arrive),
                                        change_start, change_length))
        if i + 1 < len(legs):
            marks.append(len(pieces) - 1)
            pieces += [_lane_piece(lane) for lane in _drawn(net, leg)]
    raw = np.vstack([p.points for p in pieces])
    raw_arc = _arc(raw)
    ends = np.cumsum([len(p.points) for p in pieces]) - 1  # index in raw of each piece's last point
    borders = [(ends[k], ends[k + len(_drawn(net, leg))] + 1) for leg, k in zip(legs, marks)]  # per junction: raw indices in and out
    keep = np.r_[True, np.diff(raw_arc) > 1e-6]  # junction gaps: the shapes meet, drop the duplicates
    line, arc = raw[keep], raw_arc[keep]
    speed = np.concatenate([np.full(len(p.points), p.speed) for p in pieces])[keep]
    right, left = (np.vstack([getattr(p, side) for p in pieces])[keep] for side in ("right", "left"))

    points, curvature, step = _smooth(line)
    s_raw = np.arange(len(points)) * step  # point k is the spline at the shapes' arc length k * step
    shift = np.zeros(len(points))
    if front > 0.0:
        shift = centring_shift(curvature, front, half_width)
        curvature = curvature / np.maximum(1.0 - np.abs(curvature * shift), 0.5)  # a circle of radius R - |shift| (at most twice as tight)
    clearance, curb_length = curb
    if clearance > 0.0 and half_width > 0.0:
        spans = [(raw_arc[into], raw_arc[out], max(clearance - (0.5 * width - half_width), 0.0))
                 for leg, (into, out) in zip(legs, borders) if (width := _beside_walkway(net, leg)) > 0.0]
        over = curb_shift(s_raw, spans, curb_length)
        shift = shift + over
        curvature = curvature + np.gradient(np.gradient(over, step), step)  # a lateral offset's second derivative bends a straight path
    if shift.any():
        points = offset_polyline(points, shift)
    i = np.clip(np.searchsorted(arc, s_raw, side="right") - 1, 0, len(arc) - 2)
    t = np.clip((s_raw - arc[i]) / (arc[i + 1] - arc[i]), 0.0, 1.0)
    caps = np.minimum(speed[i], speed[i + 1])  # a gap's bridge or a shared point: the lower limit
    path_arc = _arc(points)
    limits = curve_speeds(curvature, path_arc[-1] / (len(points) - 1), caps, a_lat, CURVE_DECEL)  # a speed per point: it broadcasts
    band_right, band_left = (edge[i] + t[:, None] * (edge[i + 1] - edge[i]) for edge in (right, left))

    def s_of(raw_index: int) -> float:
        """Arc length along the path of raw point ``raw_index``, projected near where the bookkeeping puts it."""
        return _project(points, path_arc, raw[raw_index], float(np.interp(raw_arc[raw_index], s_raw, path_arc)))

    stops, junctions = [], []
    for leg, (into, out) in zip(legs, borders):
        s_in = s_of(into)  # the incoming lane's end
        junctions.append(JunctionSpan(leg.junction, s_in, s_of(out)))  # the next edge's lane's start
        if leg.tls:
            lane = car_lanes(net.getEdge(leg.edge))[leg.leave]
            (x0, y0), (x1, y1) = _shape(lane)[-2:]
            stops.append(StopLine(np.array([x1, y1]), float(np.arctan2(y1 - y0, x1 - x0)), s_in, lane.getWidth(), leg.tls, leg.link,
                                  lane.getID()))
    return RoutePath(points, limits, legs, stops, junctions, band_right, band_left, curvature)
