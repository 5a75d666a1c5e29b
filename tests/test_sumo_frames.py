"""The one SUMO frame conversion: front bumper + navigational degrees <-> rear axle + radians CCW."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aac_sumo.network import sumo_binary
from aac_sumo.sim.sumo_frames import (
    body_from_sumo, collision_cover, heading_from_sumo, lane_change_sweep, lane_direction, signalled_sweep, state_from_sumo, sumo_from_state,
    velocity_from_sumo,
)

coords = st.floats(-1e4, 1e4, allow_nan=False)
dims = st.tuples(st.floats(0.3, 20.0), st.floats(0.0, 1.0)).map(lambda t: (t[0], t[0] * t[1]))  # length, wheelbase <= length


@given(coords, coords, st.floats(-math.pi, math.pi), st.floats(-30, 30), dims)
def test_state_round_trips_through_sumo(x, y, heading, v, dim):
    length, wheelbase = dim
    back = state_from_sumo(*sumo_from_state([x, y, heading, v], length, wheelbase), v, length, wheelbase)
    assert back[:2] == pytest.approx([x, y], abs=1e-6)
    assert math.cos(back[2] - heading) == pytest.approx(1.0, abs=1e-9)
    assert back[3] == v


@given(coords, coords, st.floats(0.0, 359.999), dims)
def test_sumo_pose_round_trips_through_state(x, y, angle, dim):
    length, wheelbase = dim
    sx, sy, sangle = sumo_from_state(state_from_sumo(x, y, angle, 0.0, length, wheelbase), length, wheelbase)
    assert (sx, sy) == pytest.approx((x, y), abs=1e-6)
    assert math.cos(math.radians(sangle - angle)) == pytest.approx(1.0, abs=1e-9)
    assert 0.0 <= sangle < 360.0


@pytest.mark.parametrize("heading, angle, ahead", [
    (0.0, 90.0, (1, 0)),             # east
    (math.pi / 2, 0.0, (0, 1)),      # north
    (math.pi, 270.0, (-1, 0)),       # west
    (-math.pi / 2, 180.0, (0, -1)),  # south
])
def test_front_bumper_lies_half_length_plus_half_wheelbase_ahead(heading, angle, ahead):
    x, y, a = sumo_from_state([10.0, 20.0, heading, 5.0], 4.0, 2.6)
    assert (x, y) == pytest.approx(np.array([10.0, 20.0]) + 3.3 * np.array(ahead))
    assert a == pytest.approx(angle)


def _inside(points, centre, heading, length, width, tol=1e-6):
    c, s = math.cos(heading), math.sin(heading)
    rel = np.asarray(points) - centre
    along, across = rel @ np.array([c, s]), rel @ np.array([-s, c])
    return np.all(np.abs(along) <= 0.5 * length + tol) and np.all(np.abs(across) <= 0.5 * width + tol)


@given(coords, coords, st.floats(0.0, 359.9), st.floats(-40.0, 40.0), st.floats(0.5, 20.0), st.floats(0.3, 3.0), st.floats(-4.0, 4.0))
def test_collision_cover_holds_the_body_and_sumos_box_and_no_more(x, y, lane_angle, turn, length, width, sweep):
    """The cover of a vehicle at ``turn`` degrees to its lane holds its body (the rectangle
    behind its front along its heading) and SUMO's collision box (the rectangle behind its front
    along the lane), now and ``sweep`` across the lane, each of its four sides touches one of
    them, and on its lane without a sweep it is the body."""
    angle = (lane_angle + turn) % 360.0
    centre, heading, cover_length, cover_width = collision_cover(x, y, angle, lane_angle, length, width, sweep)
    corners = []
    lane = heading_from_sumo(lane_angle)
    for direction, shift in ((heading_from_sumo(angle), 0.0), (lane, 0.0), (lane, sweep)):
        ahead, left = np.array([math.cos(direction), math.sin(direction)]), np.array([-math.sin(direction), math.cos(direction)])
        front = np.array([x, y]) + shift * np.array([-math.sin(lane), math.cos(lane)])
        corners += [front - back * ahead + side * 0.5 * width * left for back in (0.0, length) for side in (-1, 1)]
    assert _inside(corners, centre, heading, cover_length, cover_width)
    c, s = math.cos(heading), math.sin(heading)
    rel = np.array(corners) - centre
    assert np.max(np.abs(rel @ np.array([c, s]))) == pytest.approx(0.5 * cover_length, abs=1e-6)
    assert np.max(np.abs(rel @ np.array([-s, c]))) == pytest.approx(0.5 * cover_width, abs=1e-6)
    if turn == 0.0 and sweep == 0.0:
        body, body_heading = body_from_sumo(x, y, angle, length)
        assert centre == pytest.approx(body, abs=1e-6) and (cover_length, cover_width) == pytest.approx((length, width))
        assert math.cos(heading - body_heading) == pytest.approx(1.0)


def test_a_car_pulling_out_at_24_degrees_is_covered_in_both_lanes():
    """A 4.5 m car pulling out to the right at 24 degrees to its lane (front at y = -7.4 m):
    SUMO counts it from y = -8.3 to -6.5 m, its body reaches up to y = -4.75 m; the cover spans
    both, 3.55 m across, and 4.5 m plus the front corner's 0.37 m along."""
    centre, heading, length, width = collision_cover(1200.0, -7.4, 114.0, 90.0, 4.5, 1.8)
    assert heading == pytest.approx(0.0, abs=1e-12)
    assert centre[1] - 0.5 * width == pytest.approx(-8.3)
    assert centre[1] + 0.5 * width == pytest.approx(-7.4 + 4.5 * math.sin(math.radians(24)) + 0.9 * math.cos(math.radians(24)))
    assert length == pytest.approx(4.5 + 0.9 * math.sin(math.radians(24)))


@given(st.floats(4.0, 60.0), st.floats(0.0, 1.0), st.floats(2.0, 12.0), st.sampled_from([-1.0, 1.0]), st.floats(0.0, 359.9))
def test_a_car_following_a_curved_lane_is_covered_by_its_body(radius, where, length, turn, start_deg):
    """A car on a lane that turns a quarter circle of ``radius`` (left or right), front and back
    on its centre-line, at the angle SUMO gives it (the chord from back to front): the lane's
    direction under it is that chord, so its cover is its body, however tight the turn. The
    tangent at its front would have widened the cover by about length^2 / (2 radius)."""
    start = math.radians(start_deg)
    phi = start + turn * np.linspace(0.0, 0.5 * math.pi, 60)  # the lane's heading along it
    centre = -turn * radius * np.array([-math.sin(start), math.cos(start)])  # the circle's centre, the lane starting at 0
    shape = centre + turn * radius * np.c_[-np.sin(phi), np.cos(phi)]
    arc = np.r_[0.0, np.cumsum(np.hypot(*np.diff(shape, axis=0).T))]
    pos = length + where * (arc[-1] - length) if arc[-1] > length else arc[-1]
    front = np.interp(pos, arc, shape[:, 0]), np.interp(pos, arc, shape[:, 1])
    back = np.interp(pos - length, arc, shape[:, 0]), np.interp(pos - length, arc, shape[:, 1])
    if pos - length < 0.0:
        return
    angle = (90.0 - math.degrees(math.atan2(front[1] - back[1], front[0] - back[0]))) % 360.0
    tangent = (90.0 - math.degrees(np.interp(pos, arc, np.unwrap(phi)))) % 360.0
    _, _, cover_length, cover_width = collision_cover(*front, angle, lane_direction(shape, arc, pos, length, tangent), length, 1.8)
    assert (cover_length, cover_width) == pytest.approx((length, 1.8), abs=1e-6)
    _, _, _, tangent_width = collision_cover(*front, angle, tangent, length, 1.8)
    assert tangent_width > 1.8 + 0.25 * length**2 / radius * 0.5  # what the tangent made of it


def test_a_straight_lane_keeps_sumos_tangent():
    """Under a car on a straight stretch the lane's direction is SUMO's tangent, unchanged to the last bit."""
    shape = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0]])
    arc = np.array([0.0, 100.0, 150.0])
    assert lane_direction(shape, arc, 50.0, 5.0, 89.99999999999999) == 89.99999999999999
    assert lane_direction(shape, arc, 102.0, 5.0, 0.0) == pytest.approx(90.0 - math.degrees(math.atan2(2.0, 3.0)))


def test_a_sumo_velocity_is_the_speed_along_the_lane_plus_the_lateral_speed_across_it():
    """SUMO moves a car changing lanes across its lane at its lateral speed (positive to the
    left), whatever its heading: on a lane heading east (90 degrees) at 19.9 m/s, 1.75 m/s to the
    right is (19.9, -1.75) m/s; on a lane heading north, to the left is towards -x."""
    assert velocity_from_sumo(19.9, -1.75, 90.0) == pytest.approx([19.9, -1.75])
    assert velocity_from_sumo(10.0, 1.0, 0.0) == pytest.approx([-1.0, 10.0])


@pytest.mark.parametrize("lateral_speed, position, sweep", [
    (0.0, 0.4, 0.0),      # no change under way
    (-1.75, 0.0, 0.0),    # at the centre: the step that ends a change (a change's first step has moved already)
    (-1.75, -0.175, -3.325),  # just begun to the right: almost a whole lane
    (-1.75, -1.2, -2.3),  # on its way, still on the old lane
    (-1.75, 1.5, -1.5),   # past halfway: SUMO has it on the new lane, 1.5 m left of its centre
    (1.75, -0.5, 0.5),    # to the left, on the new lane
])
def test_a_lane_change_sweeps_the_front_to_the_centre_of_the_lane_it_moves_into(lateral_speed, position, sweep):
    assert lane_change_sweep(lateral_speed, position, 3.5) == pytest.approx(sweep)


@pytest.mark.parametrize("signals, position, right, left, sweep", [
    (2, 0.0, 1, 1, 3.5),     # left blinker: to the centre of the lane on its left
    (1, 0.0, 1, 1, -3.5),    # right blinker
    (1, 0.3, 1, 0, -3.8),    # 0.3 m left of its lane's centre
    (2, 0.0, 1, 0, 0.0),     # no lane on its left (the blinker of a turn ahead)
    (3, 0.0, 1, 1, 0.0),     # hazard lights: no change
    (8, 0.0, 1, 1, 0.0),     # brake lights alone
])
def test_a_blinker_sweeps_the_car_to_the_centre_of_the_next_lane_on_its_side(signals, position, right, left, sweep):
    assert signalled_sweep(signals, position, 3.5, right, left) == pytest.approx(sweep)


def test_sumo_drivers_change_lanes_only_to_the_side_their_blinker_showed():
    """Real libsumo, the bundled highway with SUMO's continuous lane changes (2 s): a car that
    had a blinker on the step before its lane change began (one that waited for a gap) moves to
    that side, so :func:`signalled_sweep` points where such a car goes once a gap opens."""
    libsumo = pytest.importorskip("libsumo")
    config = Path(__file__).resolve().parents[1] / "sumo_networks" / "highway_work_zone" / "highway_work_zone.sumocfg"
    libsumo.start([sumo_binary("sumo"), "-c", str(config), "--lanechange.duration", "2", "--no-warnings", "--no-step-log"])
    try:
        before, signalled = {}, []
        while libsumo.simulation.getTime() < 120.0:
            libsumo.simulationStep()
            now = {vid: (libsumo.vehicle.getLateralSpeed(vid), libsumo.vehicle.getSignals(vid)) for vid in libsumo.vehicle.getIDList()}
            for vid, (lateral, _) in now.items():
                lateral_before, signals = before.get(vid, (1.0, 0))
                if lateral != 0.0 and lateral_before == 0.0 and signals & 3 in (1, 2):  # one blinker (both: hazard lights)
                    signalled.append(signalled_sweep(signals, 0.0, 3.5, 1, 1) * lateral)
            before = now
    finally:
        libsumo.close()
    assert signalled and all(product > 0.0 for product in signalled)


def test_sumo_reports_a_lane_change_at_the_lane_centre_only_at_its_last_step():
    """Real libsumo, the bundled highway with SUMO's continuous lane changes (2 s): a car whose
    lateral speed is set while it sits on its lane's centre has its lateral speed gone the next
    step (the change ended there), and no change starts at the centre, so
    :func:`lane_change_sweep` reads the centre as the end."""
    libsumo = pytest.importorskip("libsumo")
    config = Path(__file__).resolve().parents[1] / "sumo_networks" / "highway_work_zone" / "highway_work_zone.sumocfg"
    libsumo.start([sumo_binary("sumo"), "-c", str(config), "--lanechange.duration", "2", "--no-warnings", "--no-step-log"])
    try:
        before, ends, firsts = {}, 0, []
        while libsumo.simulation.getTime() < 60.0:
            libsumo.simulationStep()
            now = {vid: (libsumo.vehicle.getLateralSpeed(vid), libsumo.vehicle.getLateralLanePosition(vid))
                   for vid in libsumo.vehicle.getIDList()}
            for vid, (lateral, position) in before.items():
                if lateral != 0.0 and position == 0.0 and vid in now:
                    assert now[vid][0] == 0.0
                    ends += 1
            firsts += [position for vid, (lateral, position) in now.items() if lateral != 0.0 and before.get(vid, (0.0, 0.0))[0] == 0.0]
            before = now
    finally:
        libsumo.close()
    assert ends > 0 and firsts and all(p != 0.0 for p in firsts)
