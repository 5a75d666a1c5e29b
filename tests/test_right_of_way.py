"""Right of way at junctions (aac_sumo.experiments.right_of_way) on junctions the wheel's netconvert
builds: which links yield to which, when a yield line holds a car, and what counts as a violation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aac_sumo import network
from aac_sumo.experiments.junction_routes import route_legs, route_path
from aac_sumo.experiments.right_of_way import FOE_ACCEL, FOE_SPEED_FACTOR, RightOfWay, clear_time, may_hold, travel_time, yield_lines


def build(folder, node_type: str, major_lanes: int = 1):
    """Node C at the origin of type ``node_type`` (turn radius 8 m), arms N, E, S, W 100 m out;
    the W-E road is the major one (priority 2 against 1). Edges are named by their nodes: NC
    leads from N into C."""
    folder.mkdir()
    arms = {"N": (0, 100), "E": (100, 0), "S": (0, -100), "W": (-100, 0)}
    nodes = [f'<node id="C" x="0" y="0" type="{node_type}" radius="8"/>'] + [f'<node id="{n}" x="{x}" y="{y}"/>' for n, (x, y) in arms.items()]
    edges = [f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="{major_lanes if n in "WE" else 1}" speed="13.9" priority="{2 if n in "WE" else 1}"/>'
             for n in arms for a, b in ((n, "C"), ("C", n))]
    (folder / "net.nod.xml").write_text("<nodes>" + "".join(nodes) + "</nodes>")
    (folder / "net.edg.xml").write_text("<edges>" + "".join(edges) + "</edges>")
    return network.read(network.build(folder)[0], "sumo.net", "test", withInternal=True)


@pytest.fixture(scope="module")
def priority(tmp_path_factory):
    return build(tmp_path_factory.mktemp("row") / "priority", "priority")


@pytest.fixture(scope="module")
def unregulated(tmp_path_factory):
    return build(tmp_path_factory.mktemp("row") / "unregulated", "unregulated")


def lines(net, edges):
    path = route_path(net, route_legs(net, edges, 0), 5.0, 2.0, 10.0, 30.0)
    return yield_lines(net, path), path


def test_a_minor_road_yields_to_the_major_road_and_the_major_road_to_no_one(priority):
    ((y, s),), path = lines(priority, ["SC", "CN"])  # straight across the major road
    assert y.state in "m" and y.counts and not y.tls
    assert {foe.approach for foe in y.foes} == {"WC_0", "EC_0"}  # both ways along the major road
    assert all(foe.inside for foe in y.foes)  # each with its internal lanes
    assert s == pytest.approx(path.junctions[0].s_in)
    assert y.s_out > y.s_in and 0.0 < y.speed <= 13.9
    assert lines(priority, ["WC", "CE"])[0] == []  # straight along the major road: nothing to yield to


def test_a_junction_may_hold_a_car_where_its_link_has_foes_it_yields_to(priority, unregulated):
    """The major road's straight link holds no one; the minor road's, and the major road's left
    turn (across the oncoming lane), may; at an unregulated junction every link may."""
    assert not may_hold(priority, "WC", "CE") and not may_hold(priority, "WC", "CS")  # straight on, right turn
    assert may_hold(priority, "SC", "CN") and may_hold(priority, "WC", "CN")
    assert all(may_hold(unregulated, a, b) for a, b in (("WC", "CE"), ("SC", "CN"), ("WC", "CS")))


def test_a_left_turn_from_the_major_road_yields_to_the_oncoming_major_road(priority):
    ((y, _),), _ = lines(priority, ["WC", "CN"])
    assert "EC_0" in {foe.approach for foe in y.foes}
    assert "SC_0" not in {foe.approach for foe in y.foes}


def test_at_an_unregulated_junction_a_car_yields_to_every_crossing_way_and_counts_no_violation(unregulated):
    ((y, _),), _ = lines(unregulated, ["SC", "CN"])
    assert not y.counts
    assert {"WC_0", "EC_0"} <= {foe.approach for foe in y.foes}
    (straight,) = unregulated.getEdge("NC").getConnections(unregulated.getEdge("CS"))
    (left,) = unregulated.getEdge("NC").getConnections(unregulated.getEdge("CE"))
    ways = {foe.inside[0] for foe in y.foes}
    assert left.getViaLaneID() in ways  # the oncoming left turn crosses it
    assert straight.getViaLaneID() not in ways  # the oncoming straight way neither crosses nor joins it


@given(st.floats(0.0, 200.0), st.floats(0.0, 20.0), st.floats(0.5, 4.0), st.floats(1.0, 20.0))
def test_travel_time_is_the_kinematics_of_speeding_up_then_cruising(distance, speed, accel, top):
    t = travel_time(distance, speed, accel, top)
    if speed >= top:
        assert t == pytest.approx(distance / max(speed, 1e-9))
        return
    t_up = (top - speed) / accel
    covered = speed * min(t, t_up) + 0.5 * accel * min(t, t_up) ** 2 + top * max(t - t_up, 0.0)
    assert covered == pytest.approx(distance, abs=1e-6)
    assert travel_time(distance + 1.0, speed, accel, top) > t  # further takes longer


@given(st.floats(0.0, 50.0), st.floats(1.0, 30.0), st.floats(0.0, 20.0), st.floats(0.5, 4.0), st.floats(1.0, 20.0))
def test_a_car_goes_through_a_junction_no_faster_than_its_cap(to_line, through, speed, accel, top):
    """Below the cap: speeding up over the whole distance. Above it: its own speed to the line, then
    the cap, so it never takes less than the junction at the cap."""
    t = clear_time(to_line, through, speed, accel, top)
    if speed <= top:
        assert t == travel_time(to_line + through, speed, accel, top)
    else:
        assert t == pytest.approx(to_line / speed + through / top)
    assert t >= through / top - 1e-9


def test_a_car_faster_than_its_junctions_cap_is_held_for_a_foe_it_would_meet_at_the_cap(priority):
    """A car at 12 m/s 20 m before the line of a left turn capped below that: at its own speed it
    would clear before a foe arriving in ``gap``, at the cap it would not, so the line holds."""
    ((y, _),), _ = lines(priority, ["SC", "CW"])
    foe = next(f for f in y.foes if f.approach == "WC_0")
    speed, length = 12.0, 4.0
    assert y.speed < speed
    through = (y.s_out - y.s_in) + length
    at_cap, at_own = clear_time(20.0, through, speed, 1.5, y.speed), (20.0 + through) / speed
    arrive = 0.5 * (at_cap + at_own) + 1.0  # between the two, after the 1 s gap
    room = FOE_SPEED_FACTOR * foe.speed * arrive
    vehicles = {foe.approach: [("bg.0", foe.length - room, FOE_SPEED_FACTOR * foe.speed)]}
    boxes = RightOfWay(gap=1.0, accel=1.5).boxes(0.0, approach(y, 20.0), {}, vehicles, ["aac.0"], np.array([speed]),
                                                 np.array([9.0]), np.array([length]))
    assert len(boxes) == 1


def approach(y, d):
    return {0: [(y, d)]}


def test_a_yield_line_holds_a_car_while_a_foe_could_arrive_before_it_has_left_and_only_then(priority):
    ((y, _),), _ = lines(priority, ["SC", "CN"])
    foe = next(f for f in y.foes if f.approach == "WC_0")
    speeds, comfort, lengths = np.array([0.0]), np.array([2.0]), np.array([4.0])
    car_clears = travel_time(2.0 + (y.s_out - y.s_in) + 4.0, 0.0, 1.5, y.speed)  # from standing 2 m before the line
    for gap_s, holds in ((car_clears - 1.0, True), (car_clears + 2.0, False)):
        room = FOE_SPEED_FACTOR * foe.speed * gap_s  # a foe at top speed arriving gap_s from now
        vehicles = {foe.approach: [("bg.0", foe.length - room, FOE_SPEED_FACTOR * foe.speed)]}
        row = RightOfWay(gap=1.0, accel=1.5)
        boxes = row.boxes(0.0, approach(y, 2.0), {}, vehicles, ["aac.0"], speeds, comfort, lengths)
        assert len(boxes) == int(holds), gap_s
        if holds:
            assert boxes[0].kind == "signal" and np.hypot(*(boxes[0].centre - y.line.point)) == pytest.approx(0.5)
    inside = {foe.inside[0]: [("bg.0", 1.0, 5.0)]}
    assert len(RightOfWay(1.0, 1.5).boxes(0.0, approach(y, 2.0), {}, inside, ["aac.0"], speeds, comfort, lengths)) == 1
    standing = {foe.approach: [("bg.0", foe.length - 1.0, 0.0)]}  # a standing foe at its line may set off
    assert len(RightOfWay(1.0, 1.5).boxes(0.0, approach(y, 2.0), {}, standing, ["aac.0"], speeds, comfort, lengths)) == 1
    far = {foe.approach: [("bg.0", 0.0, 0.0)]}  # standing at its lane's far end: too far to come
    assert RightOfWay(1.0, 1.5).boxes(0.0, approach(y, 2.0), {}, far, ["aac.0"], speeds, comfort, lengths) == []


def test_a_car_that_cannot_stop_comfortably_when_the_line_starts_to_hold_goes_on(priority):
    ((y, _),), _ = lines(priority, ["SC", "CN"])
    foe = next(f for f in y.foes if f.approach == "WC_0")
    row = RightOfWay(1.0, 1.5)
    near = {foe.approach: [("bg.0", foe.length - 5.0, 10.0)]}
    assert row.boxes(0.0, approach(y, 10.0), {}, near, ["aac.0"], np.array([10.0]), np.array([2.0]), np.array([4.0])) == []


def run_through(y, foe_pos, foe_speed, dt=0.1, speed=10.0):
    """A car driving through ``y``'s junction at ``speed`` from 20 m before the line, a foe on the
    major road at ``foe_pos`` going ``foe_speed``: the violations counted."""
    row = RightOfWay(1.0, 1.5)
    foe = next(f for f in y.foes if f.approach == "WC_0")
    d, t = 20.0, 0.0
    while d > -(y.s_out - y.s_in + 4.0 + 2.0):
        pos = foe_pos + foe_speed * t
        vehicles = {foe.approach: [("bg.0", pos, foe_speed)]} if pos < foe.length else {}
        row.count(t, 0, y, d, {}, vehicles, "aac.0", 4.0)
        d, t = d - speed * dt, t + dt
    return row.violations


def test_entering_before_a_foe_with_priority_that_arrives_while_the_car_is_inside_is_a_violation(priority):
    ((y, _),), _ = lines(priority, ["SC", "CN"])
    length = next(f for f in y.foes if f.approach == "WC_0").length
    entry = 2.0  # the car crosses its line 2 s in, and leaves the junction about 2.6 s later
    assert run_through(y, length - 10.0 * (entry + 0.5), 10.0) == 1  # the foe arrives 0.5 s after the car entered
    assert run_through(y, length - 10.0 * (entry + 6.0), 10.0) == 0  # 6 s after: the car is long gone
    assert run_through(y, length - 1.0, 0.0) == 0  # a foe standing at its line does not arrive
    assert math.isfinite(FOE_ACCEL)


def test_at_an_unregulated_junction_the_line_holds_for_a_crossing_foe(unregulated):
    ((y, _),), _ = lines(unregulated, ["SC", "CN"])
    foe = next(f for f in y.foes if f.approach == "WC_0")
    vehicles = {foe.approach: [("bg.0", foe.length - 20.0, 13.9)]}
    boxes = RightOfWay(1.0, 1.5).boxes(0.0, approach(y, 2.0), {}, vehicles, ["aac.0"], np.array([0.0]), np.array([2.0]),
                                                   np.array([4.0]))
    assert len(boxes) == 1


def lane_position(net, lane: str, d: float) -> float:
    """The SUMO lane position of a front ``d`` [m] before ``lane``'s end."""
    return net.getLane(lane).getLength() - d


@pytest.mark.parametrize("d_south, d_west, goes", [(2.0, 2.0, "aac.0"), (6.0, 2.0, "aac.1"), (2.0, 6.0, "aac.0")])
def test_two_controlled_cars_that_must_yield_to_each_other_settle_it_by_who_reaches_the_line_first(unregulated, d_south, d_west,
                                                                                                    goes):
    """At an unregulated junction each of two crossing cars yields to the other; standing at their
    lines, each alone would wait for the other for ever. The one nearer its line (by name when
    level) goes, the other waits for it, and the cars behind it wait too."""
    (south, _), (west, _) = lines(unregulated, ["SC", "CN"])[0][0], lines(unregulated, ["WC", "CE"])[0][0]
    assert any(f.approach == "WC_0" for f in south.foes) and any(f.approach == "SC_0" for f in west.foes)
    vehicles = {"SC_0": [("aac.0", lane_position(unregulated, "SC_0", d_south), 0.0)],
                "WC_0": [("aac.1", lane_position(unregulated, "WC_0", d_west), 0.0), ("bg.0", 10.0, 0.0)]}
    row = RightOfWay(1.0, 1.5)
    boxes = row.boxes(0.0, {0: [(south, d_south)], 1: [(west, d_west)]}, {}, vehicles, ["aac.0", "aac.1"], np.zeros(2),
                      np.full(2, 2.0), np.full(2, 4.0), np.full(2, 6.0))
    held = {box.name.split()[-1] for box in boxes}
    assert held == {"WC_0" if goes == "aac.0" else "SC_0"}


def test_a_controlled_car_that_can_no_longer_stop_is_not_taken_to_give_way(unregulated):
    (south, _), (west, _) = lines(unregulated, ["SC", "CN"])[0][0], lines(unregulated, ["WC", "CE"])[0][0]
    vehicles = {"SC_0": [("aac.0", lane_position(unregulated, "SC_0", 2.0), 0.0)],
                "WC_0": [("aac.1", lane_position(unregulated, "WC_0", 8.0), 12.0)]}  # 12 m/s, 8 m out: 9 m/s^2 to stop
    row = RightOfWay(1.0, 1.5)
    boxes = row.boxes(0.0, {0: [(south, 2.0)], 1: [(west, 8.0)]}, {}, vehicles, ["aac.0", "aac.1"], np.array([0.0, 12.0]),
                      np.full(2, 2.0), np.full(2, 4.0), np.full(2, 6.0))
    assert {box.name.split()[-1] for box in boxes} == {"SC_0"}  # the standing car waits for the one that must go on
