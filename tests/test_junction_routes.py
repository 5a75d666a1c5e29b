"""A car's way through city junctions (aac_sumo.experiments.junction_routes), on networks real
netconvert builds: a plus-shaped crossing with a traffic light, arms 100 m long (the west arm
with 2 lanes each way, the others with 1), and a 2x1 grid of priority junctions."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
import sumo
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import network
from aac_sumo.experiments.junction_routes import CURB_RAMP, RoutePath, curb_shift, route_legs, route_path
from aac_sumo.experiments.lane_geometry import CURVE_DECEL, centring_shift
from aac_sumo.geometry import along

A_LAT = 2.0  # [m/s^2]
CHANGE_START, CHANGE_LENGTH = 10.0, 30.0  # [m]
WIDTH = 3.2  # netconvert's default lane width [m]


def build(folder, nodes: dict[str, tuple[float, float, str]], edges: list[tuple[str, str, str, int]], extra: str = ""):
    """The network netconvert builds from ``nodes`` (id: x, y, extra attributes) and ``edges``
    (id, from, to, lanes; 13.9 m/s; ``extra`` attributes on each): its file."""
    folder.mkdir()
    (folder / "net.nod.xml").write_text(
        "<nodes>" + "".join(f'<node id="{n}" x="{x}" y="{y}" {extra}/>' for n, (x, y, extra) in nodes.items()) + "</nodes>")
    (folder / "net.edg.xml").write_text(
        "<edges>" + "".join(f'<edge id="{e}" from="{a}" to="{b}" numLanes="{k}" speed="13.9" {extra}/>' for e, a, b, k in edges) + "</edges>")
    return network.build(folder)[0]


def read(path):
    return network.read(path, "sumo.net", "test", withInternal=True)


def plus_network(folder, extra: str = ""):
    """Node C at the origin with a traffic light (turn radius 10 m); arms N, E, S, W 100 m out.
    Edges are named by their nodes: NC leads from N into C, CW from C out to W."""
    arms = {"N": (0, 100), "E": (100, 0), "S": (0, -100), "W": (-100, 0)}
    nodes = {"C": (0, 0, 'type="traffic_light" radius="10"')} | {n: (x, y, "") for n, (x, y) in arms.items()}
    edges = [e for n in arms for e in ((f"{n}C", n, "C", 1 + (n == "W")), (f"C{n}", "C", n, 1 + (n == "W")))]
    return build(folder, nodes, edges, extra)


@pytest.fixture(scope="module")
def plus_file(tmp_path_factory):
    return plus_network(tmp_path_factory.mktemp("plus") / "plus")


@pytest.fixture(scope="module")
def plus(plus_file):
    return read(plus_file)


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """Six priority nodes 100 m apart, a0 a1 a2 along y = 0 and b0 b1 b2 along y = 100 (turn
    radius 10 m), and one-lane streets both ways along every grid line."""
    nodes = {f"{r}{c}": (100 * c, 100 * (r == "b"), 'radius="10"') for r in "ab" for c in range(3)}
    lines = [("a0", "a1"), ("a1", "a2"), ("b0", "b1"), ("b1", "b2"), ("a0", "b0"), ("a1", "b1"), ("a2", "b2")]
    return read(build(tmp_path_factory.mktemp("grid") / "grid", nodes, [(f"{u}{v}", u, v, 1) for a, b in lines for u, v in ((a, b), (b, a))]))


def shape(lane) -> np.ndarray:
    return np.asarray(lane.getShape(), dtype=float)


def lane_of(net, edge: str, index: int):
    return network.car_lanes(net.getEdge(edge))[index]


def followed(net, path: RoutePath) -> list[np.ndarray]:
    """The shapes of every lane the path follows: its edges' arrive and leave lanes, and the
    internal lanes between them."""
    lanes = [lane_of(net, leg.edge, k) for leg in path.legs for k in {leg.arrive, leg.leave}]
    return [shape(lane) for lane in lanes] + [shape(net.getLane(v)) for leg in path.legs for v in leg.via]


def distance(points: np.ndarray, polylines: list[np.ndarray]) -> np.ndarray:
    """Distance [m] of each of ``points`` (M, 2) to the nearest of ``polylines``."""
    best = np.full(len(points), np.inf)
    for line in polylines:
        for a, b in pairwise(line):
            t = np.clip((points - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
            best = np.minimum(best, np.hypot(*(a + t[:, None] * (b - a) - points).T))
    return best


def headings(points: np.ndarray) -> np.ndarray:
    """Unwrapped headings [rad] of the segments of ``points``."""
    seg = np.diff(points, axis=0)
    return np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))


def assert_smooth(points: np.ndarray) -> None:
    """No kink: the heading turns by under 0.15 rad from one segment (about 1 m) to the next
    (SUMO's polylines turn by up to 0.5 rad at a corner of an internal lane); no jump in the
    curvature: that turn changes by under 0.05 rad from one segment to the next (half of a
    straight run's into a 10 m arc)."""
    turn = np.diff(headings(points))
    assert np.abs(turn).max() < 0.15 and np.abs(np.diff(turn)).max() < 0.05


def arc(points: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]


def crossings(points: np.ndarray, point: np.ndarray, heading: float) -> np.ndarray:
    """Arc lengths [m] where polyline ``points`` crosses the line through ``point`` across
    ``heading``, going along ``heading``."""
    ahead = (points - point) @ np.array([np.cos(heading), np.sin(heading)])
    k = np.flatnonzero((ahead[:-1] < 0.0) & (ahead[1:] >= 0.0))
    s = arc(points)
    return s[k] + (s[k + 1] - s[k]) * -ahead[k] / (ahead[k + 1] - ahead[k])


def path(net, edges: list[str], lane: int = 0, s0: float = 5.0, **changes) -> RoutePath:
    options = {"change_start": CHANGE_START, "change_length": CHANGE_LENGTH} | changes
    return route_path(net, route_legs(net, edges, lane), s0, A_LAT, **options)


# --- legs: lanes edge to edge ------------------------------------------------------------------


def test_a_right_turn_is_one_leg_per_edge_through_the_connections_internal_lane_under_its_light(plus):
    legs = route_legs(plus, ["NC", "CW"], 0)
    (conn,) = plus.getEdge("NC").getConnections(plus.getEdge("CW"))
    assert [(leg.edge, leg.arrive, leg.leave, leg.junction) for leg in legs] == [("NC", 0, 0, "C"), ("CW", 0, 0, "W")]
    assert legs[0].via == (conn.getViaLaneID(),)
    assert (legs[0].tls, legs[0].link) == (conn.getTLSID(), conn.getTLLinkIndex()) and legs[0].tls == "C"
    assert (legs[1].via, legs[1].tls, legs[1].link) == ((), "", -1)


def test_a_left_turn_leads_through_both_internal_lanes_sumo_splits_it_into(plus):
    """SUMO stops a left turn that yields to oncoming traffic inside the junction: its via lane
    leads on through a second internal lane, which reaches the next edge."""
    (leg, _) = route_legs(plus, ["NC", "CE"], 0)
    (conn,) = plus.getEdge("NC").getConnections(plus.getEdge("CE"))
    first, second = (plus.getLane(v) for v in leg.via)
    assert first.getID() == conn.getViaLaneID() and first.getEdge().getFunction() == second.getEdge().getFunction() == "internal"
    assert [c.getViaLaneID() for c in first.getOutgoing()] == [second.getID()]
    assert np.allclose(shape(first)[-1], shape(second)[0]) and np.allclose(shape(second)[-1], shape(lane_of(plus, "CE", 0))[0])


@pytest.mark.parametrize("edges, lane, lanes", [
    (["WC", "CN"], 0, [(0, 1), (0, 0)]),  # only lane 1 of the two-lane arm turns left: one change
    (["WC", "CE"], 0, [(0, 0), (0, 0)]),  # straight on from lane 0: no change
    (["WC", "CE"], 1, [(1, 0), (0, 0)]),  # lane 1 turns left only: over to lane 0 for straight on
    (["EC", "CW"], 0, [(0, 0), (0, 0)]),  # onto either lane of CW: the rightmost
    (["SC", "CW"], 0, [(0, 0), (1, 1)]),  # a left turn onto the left lane of CW
    (["EC", "CW", "WC", "CN"], 0, [(0, 0), (1, 1), (1, 1), (0, 0)]),  # the U-turn at W leaves CW_1: enter CW there
])
def test_legs_cross_the_fewest_lanes_ties_to_the_right(plus, edges, lane, lanes):
    assert [(leg.arrive, leg.leave) for leg in route_legs(plus, edges, lane)] == lanes


def test_edges_that_do_not_connect_are_a_one_line_value_error_naming_both(plus):
    with pytest.raises(ValueError, match="NC does not connect to edge SC") as err:
        route_legs(plus, ["NC", "SC"], 0)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="WC has no car lane 2"):
        route_legs(plus, ["WC", "CE"], 2)
    with pytest.raises(ValueError, match="unknown edge XY"):
        route_legs(plus, ["WC", "XY"], 0)


def test_a_network_read_without_its_internal_lanes_is_a_value_error(plus_file):
    with pytest.raises(ValueError, match="withInternal=True"):
        route_legs(network.read(plus_file, "sumo.net", "test"), ["NC", "CW"], 0)


# --- the path through the junction ---------------------------------------------------------------


@pytest.mark.parametrize("edges, turn", [(["NC", "CW"], -90.0), (["NC", "CE"], 90.0), (["NC", "CS"], 0.0),
                                         (["EC", "CS"], 90.0), (["EC", "CW"], 0.0), (["SC", "CW"], 90.0)])
def test_a_turn_follows_the_lanes_smoothly_and_slows_for_the_internal_lanes_radius(plus, edges, turn):
    """The path starts at s0 on its lane, ends at the last lane's end, turns by the junction's
    angle (left positive), keeps within 0.3 m of the lanes' and internal lanes' shapes (their
    polylines; the spline rounds their corners), is smooth (``assert_smooth``), and its speed
    cap in the junction is at most the internal lanes' limit and sqrt(a_lat R) for their mean
    radius R (their length over their turn: the curve is tighter somewhere)."""
    p = path(plus, edges)
    first, last = lane_of(plus, edges[0], p.legs[0].arrive), lane_of(plus, edges[-1], p.legs[-1].arrive)
    assert np.hypot(*(p.points[0] - along(shape(first), 5.0)[0][0])) < 0.05
    assert np.hypot(*(p.points[-1] - shape(last)[-1])) < 0.05
    h = headings(p.points)
    assert np.degrees(h[-1] - h[0]) == pytest.approx(turn, abs=0.5)
    assert distance(p.points, followed(plus, p)).max() < 0.3
    assert_smooth(p.points)
    internal = [shape(plus.getLane(v)) for v in p.legs[0].via]
    cap = p.limits[(arc(p.points) >= p.junctions[0].s_in) & (arc(p.points) <= p.junctions[0].s_out)].min()
    if turn:
        radius = sum(arc(line)[-1] for line in internal) / np.radians(abs(turn))
        assert cap <= np.sqrt(A_LAT * radius) + 0.1
    assert cap <= min(plus.getLane(v).getSpeed() for v in p.legs[0].via) + 1e-9


def test_speed_caps_are_the_lanes_limits_on_straights_and_fall_at_most_at_curve_decel(plus):
    p = path(plus, ["NC", "CW"])
    s = arc(p.points)
    assert p.limits[s < 20.0] == pytest.approx(13.9)  # far from the junction: the lane's limit
    decel = (p.limits[:-1] ** 2 - p.limits[1:] ** 2) / (2.0 * np.diff(s))
    assert decel.max() <= CURVE_DECEL * 1.02  # caps come every metre of the spline's parameter, within 2 % of its arc length


def test_a_left_turn_from_the_two_lane_arm_changes_lanes_within_the_edge(plus):
    """WC runs east along y = -4.8 (lane 0) and y = -1.6 (lane 1) from x = -100 to -13.2: the
    change leaves lane 0 no earlier than change_start past s0 and reaches lane 1 change_start
    before the edge's end."""
    p = path(plus, ["WC", "CN"], 0, s0=5.0)
    assert [(leg.arrive, leg.leave) for leg in p.legs] == [(0, 1), (0, 0)]
    x, y = p.points[p.points[:, 0] < -13.2].T
    assert x[y > -4.8 + 0.1][0] >= -100.0 + 5.0 + CHANGE_START
    assert x[y > -1.6 - 0.1][0] <= -13.2 - CHANGE_START
    assert np.all(y[x >= x[y > -4.8 + 0.1][0]] > -4.8 + 0.1)  # one way across


def test_a_straight_route_keeps_its_lane(plus):
    p = path(plus, ["WC", "CE"], 0)
    assert [(leg.arrive, leg.leave) for leg in p.legs] == [(0, 0), (0, 0)]
    assert np.abs(p.points[p.points[:, 0] < -20.0, 1] + 4.8).max() < 0.1


def test_a_change_too_long_for_the_edge_is_shortened_to_fit_and_one_less_than_half_is_an_error(plus):
    """WC is 86.8 m long: from s0 = 0, a change may run from 10 m to 76.8 m (66.8 m). A start
    beyond the lane's end is an error too."""
    p = path(plus, ["WC", "CN"], 0, s0=0.0, change_length=100.0)
    x, y = p.points[p.points[:, 0] < -13.2].T
    assert x[y > -1.6 - 0.1][0] <= -13.2 - CHANGE_START
    with pytest.raises(ValueError, match="edge WC is too short"):
        path(plus, ["WC", "CN"], 0, s0=0.0, change_length=140.0)
    with pytest.raises(ValueError, match="does not lie on lane WC_0"):
        path(plus, ["WC", "CE"], 0, s0=90.0)


def test_the_band_is_the_lane_and_both_lanes_while_changing(plus):
    """From s0 = 0 on WC (x = -100 ..- 13.2) the change runs from x = -90 to -60: the band runs
    along y = -6.4 .. -3.2 (lane 0) before it, -6.4 .. 0 (both lanes) during it, -3.2 .. 0 (lane
    1) after it; in the junction it is the internal lanes' width."""
    p = path(plus, ["WC", "CN"], 0, s0=0.0)
    x = p.points[:, 0]
    for where, lo, hi in ((x < -91.0, -6.4, -3.2), ((x > -89.0) & (x < -61.0), -6.4, 0.0), ((x > -59.0) & (x < -13.2), -3.2, 0.0)):
        assert p.band_right[where, 1] == pytest.approx(lo, abs=1e-6)
        assert p.band_left[where, 1] == pytest.approx(hi, abs=1e-6)
    span = p.junctions[0]
    s = arc(p.points)
    inside = (s > span.s_in + 1.0) & (s < span.s_out - 1.0)
    assert np.hypot(*(p.band_left - p.band_right)[inside].T) == pytest.approx(WIDTH, abs=0.02)


@pytest.mark.parametrize("edges", [["NC", "CE"], ["WC", "CN"], ["EC", "CS"], ["NC", "CE", "EC", "CN"]])
def test_stop_lines_lie_where_the_path_crosses_the_incoming_lanes_end(plus, edges):
    """One stop line for each pass through the light at C, in order (NC CE EC CN passes it twice,
    U-turning at E), where the path crosses the incoming lane's end; the junction's span begins
    there and is about as long as its internal lanes."""
    p = path(plus, edges)
    passes = [(leg, after, span) for leg, after, span in zip(p.legs, p.legs[1:], p.junctions) if span.junction == "C"]
    assert len(p.stops) == len(passes) and [stop.s for stop in p.stops] == sorted(stop.s for stop in p.stops)
    for stop, (leg, after, span) in zip(p.stops, passes):
        lane = lane_of(plus, leg.edge, leg.leave)
        conn = next(c for c in plus.getEdge(leg.edge).getConnections(plus.getEdge(after.edge)) if c.getFromLane() == lane)
        assert (stop.tls, stop.link, stop.lane, stop.width) == (conn.getTLSID(), conn.getTLLinkIndex(), lane.getID(), WIDTH)
        assert np.allclose(stop.point, shape(lane)[-1])
        (x0, y0), (x1, y1) = shape(lane)[-2:]
        assert stop.heading == pytest.approx(np.arctan2(y1 - y0, x1 - x0))
        assert np.abs(crossings(p.points, stop.point, stop.heading) - stop.s).min() < 0.2
        assert span.s_in == stop.s
        assert span.s_out - span.s_in == pytest.approx(sum(plus.getLane(v).getLength() for v in leg.via), abs=1.0)


def test_two_turns_through_priority_junctions(grid):
    """a0 -> a1 east, left at a1 onto a1 -> b1 north, right at b1 onto b1 -> b2 east: no lights,
    two junctions, headings 0, 90 and 0 degrees in turn, every point on the lanes."""
    p = path(grid, ["a0a1", "a1b1", "b1b2"])
    assert p.stops == [] and [(leg.tls, leg.link) for leg in p.legs] == [("", -1)] * 3
    assert [j.junction for j in p.junctions] == ["a1", "b1"]
    s, h = arc(p.points), headings(p.points)
    (a1, b1) = p.junctions
    assert np.degrees(h[s[:-1] < a1.s_in - 5.0]) == pytest.approx(0.0, abs=1.0)  # the spline wanders a little on straights
    between = (s[:-1] > a1.s_out + 5.0) & (s[:-1] < b1.s_in - 5.0)
    assert np.degrees(h[between]) == pytest.approx(90.0, abs=1.0)
    assert np.degrees(h[-1]) == pytest.approx(0.0, abs=0.5)
    assert distance(p.points, followed(grid, p)).max() < 0.3
    assert_smooth(p.points)


@settings(max_examples=25, deadline=None)
@given(data=st.data(), s0=st.floats(0.0, 20.0))
def test_the_path_starts_at_s0_on_the_start_lane(plus, data, s0):
    edges = data.draw(st.sampled_from([["WC", "CE"], ["WC", "CN"], ["WC", "CS"], ["NC", "CE"], ["EC", "CW"]]))
    lane = data.draw(st.integers(0, len(network.car_lanes(plus.getEdge(edges[0]))) - 1))
    p = route_path(plus, route_legs(plus, edges, lane), s0, A_LAT, CHANGE_START, CHANGE_LENGTH)
    assert np.hypot(*(p.points[0] - along(shape(lane_of(plus, edges[0], lane)), s0)[0][0])) < 0.1


def test_a_junction_whose_internal_lane_has_no_length_is_passed_as_the_lanes_meet():
    """The wheel's grid6 network (built by an old netconvert) joins 1/0tobottom1 and gneE29 at node
    bottom1 through an internal lane of zero length: the path runs on from one lane onto the next."""
    net = read(Path(sumo.__file__).parent / "tools" / "game" / "grid6" / "grid6.net.xml")
    (conn,) = net.getEdge("1/0tobottom1").getConnections(net.getEdge("gneE29"))
    assert np.ptp(shape(net.getLane(conn.getViaLaneID())), axis=0).max() == 0.0
    route = path(net, ["1/0tobottom1", "gneE29"])
    followed_lanes = [shape(lane_of(net, "1/0tobottom1", 0)), shape(lane_of(net, "gneE29", 0))]
    assert distance(route.points, followed_lanes).max() < 0.5
    assert_smooth(route.points)
    (span,) = [j for j in route.junctions if j.junction == "bottom1"]
    assert span.s_out - span.s_in < 1.0


# --- turns that keep the body in its lane ------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(radius=st.floats(3.0, 500.0), front=st.floats(1.0, 5.0), half=st.floats(0.2, 1.2), left=st.booleans())
def test_the_centring_shift_centres_the_band_a_turning_body_sweeps_on_the_curve(radius, front, half, left):
    """A rear axle on the circle of radius R - |shift| sweeps from its inner rear corner to its
    outer front corner a band whose middle is the curve of radius R; the shift points to the
    curve's centre (the curvature's sign)."""
    shift = centring_shift((1.0 if left else -1.0) / radius, front, half)
    assert np.sign(shift) == (1.0 if left else -1.0)
    u = radius - abs(shift)
    inner, outer = u - half, np.hypot(u + half, front)
    assert 0.5 * (inner + outer) == pytest.approx(radius, rel=1e-12)


def body_corners(points: np.ndarray, front: float, rear: float, half: float) -> np.ndarray:
    """Every corner (4 M, 2) of a body whose rear axle is at each of ``points`` (M, 2), headed along the path."""
    seg = np.gradient(points, axis=0)
    h = np.arctan2(seg[:, 1], seg[:, 0])
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    out = [points + np.hstack([c * a - s * b, s * a + c * b]) for a in (front, -rear) for b in (half, -half)]
    return np.vstack(out)


@pytest.mark.parametrize("edges", [["NC", "CW"], ["NC", "CE"]])
def test_a_car_whose_path_keeps_inside_a_turn_sweeps_a_band_nearer_its_lanes(plus, edges):
    """A 4.5 m car (wheelbase 2.6 m) on a right and a left turn of the plus crossing: with the
    centring shift its body's farthest corner comes nearer the centre lines of the lanes it
    follows, by most of the shift, and the path stays on the lanes away from the turn."""
    length, wheelbase, width = 4.5, 2.6, 1.8
    front, rear = 0.5 * (length + wheelbase), 0.5 * (length - wheelbase)
    plain = path(plus, edges)
    kept = path(plus, edges, front=front, half_width=0.5 * width)
    lanes = followed(plus, plain)
    turning = np.abs(plain.curvature) > 0.05  # the same stretch of both paths (point k lies beside point k)
    reach = [distance(body_corners(p.points[turning], front, rear, 0.5 * width), lanes).max() for p in (plain, kept)]
    largest = np.abs(centring_shift(plain.curvature, front, 0.5 * width)).max()
    assert 0.2 < largest < 0.5
    assert reach[1] < reach[0] - 0.5 * largest
    straight = np.abs(plain.curvature) < 1e-4
    assert np.abs(kept.points[straight] - plain.points[straight]).max() < 1e-3


# --- the curb clearance before a junction ---------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(a=st.floats(80.0, 300.0), inside=st.floats(4.0, 40.0), h=st.floats(0.05, 1.0), length=st.floats(0.0, 60.0))
def test_the_curb_shift_holds_its_clearance_before_the_junction_and_ramps_smoothly_either_side(a, inside, h, length):
    """Full shift ``h`` on the last ``length`` before the junction's entry ``a``, none a ramp
    before that or beyond the junction's exit, never more than ``h``, and a slope no steeper
    than the quintic smoothstep's (15/8 h over the ramp, or over the junction on the way back)."""
    b = a + inside
    s = np.linspace(0.0, b + 50.0, 20001)
    shift = curb_shift(s, [(a, b, h)], length)
    assert shift.min() >= 0.0 and shift.max() <= h + 1e-12
    assert np.allclose(shift[(s >= a - length) & (s <= a)], h)
    assert np.all(shift[(s <= a - length - CURB_RAMP) | (s >= b)] < 1e-9)
    slope = np.abs(np.diff(shift) / np.diff(s))
    assert slope.max() <= 15.0 / 8.0 * h / min(CURB_RAMP, inside) * 1.001


@pytest.fixture(scope="module")
def plus_walks(tmp_path_factory):
    """The plus crossing with a 2 m sidewalk on the right of every edge."""
    return read(plus_network(tmp_path_factory.mktemp("plus_walks") / "plus_walks", 'sidewalkWidth="2.0"'))


def test_a_car_beside_a_sidewalk_keeps_its_curb_clearance_on_the_last_stretch_before_the_junction(plus_walks):
    """A 1.8 m wide car going straight through the plus crossing with a sidewalk beside its lanes:
    with ``curb = (1.1, 40)`` its right side keeps 1.1 m from its lane's right edge on the last
    40 m before the junction (its path 0.4 m left of the 3.2 m lane's centre), keeps to the
    centre line further back and beyond the junction, stays inside its lane all along, and turns
    no sharper than the ramp's curvature (0.4 x 5.77 / 30^2 m^-1) on the straight."""
    half = 0.9
    plain = path(plus_walks, ["NC", "CS"], half_width=half)
    kept = path(plus_walks, ["NC", "CS"], half_width=half, curb=(1.1, 40.0))
    s_in = plain.junctions[0].s_in
    s = arc(kept.points)
    near = (s > s_in - 40.0) & (s < s_in - 0.5)
    incoming = [shape(lane_of(plus_walks, "NC", 0))]
    offset = distance(kept.points, incoming)
    right = distance(kept.points, [shape(lane_of(plus_walks, "NC", 0)) + [-WIDTH / 2, 0.0]])  # the lane runs south at x = -1.6
    assert np.allclose(offset[near], 0.4, atol=0.02)
    assert np.all(right[near] - half > 1.1 - 0.02)
    far = s < s_in - 40.0 - CURB_RAMP
    assert np.abs(kept.points[far] - plain.points[far]).max() < 1e-6
    beyond = s > plain.junctions[0].s_out + 1.0
    assert np.allclose(kept.points[beyond], plain.points[beyond], atol=0.02)
    assert np.all(kept.points[:, 0] + half < 0.0) and np.all(kept.points[:, 0] - half > -WIDTH)  # its body inside the southbound lane
    assert np.abs(kept.curvature[s < s_in]).max() < 0.4 * 5.78 / CURB_RAMP**2 + 1e-3


def test_without_a_sidewalk_the_curb_clearance_changes_nothing(plus):
    plain = path(plus, ["NC", "CW"], half_width=0.9)
    kept = path(plus, ["NC", "CW"], half_width=0.9, curb=(1.1, 40.0))
    assert np.array_equal(plain.points, kept.points) and np.array_equal(plain.curvature, kept.curvature)
