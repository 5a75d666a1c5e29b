"""Traffic lights as stop lines (aac_sumo.experiments.signals): when a line holds traffic, who is let
through at yellow, and what counts as running a red light."""

import numpy as np
import pytest
from hypothesis import given, strategies as st

from aac_sumo.experiments.signals import BOX_LENGTH, BOX_WIDTH, YELLOW_SPARE, Line, Signals, YellowRule
from aac_sumo.geometry import OrientedRect, point_rect_signed_distance

LINE = Line("J1", 2, "e_in_0", np.array([100.0, 0.0]), 0.0)
COMFORT = np.array([3.0, 3.0])
LENGTHS = np.array([4.0, 4.0])


def boxes(signals, state, distances, speeds):
    """One period: the light J1 shows ``state`` on link 2; car k's front is ``distances[k]`` [m] before the line."""
    approach = {k: [(LINE, d)] for k, d in enumerate(distances)}
    return signals.boxes({"J1": "rr" + state + "r"}, approach, np.asarray(speeds, dtype=float), COMFORT, LENGTHS)


def test_a_green_line_holds_nothing_and_a_red_one_stands_just_beyond_the_line():
    s = Signals()
    assert boxes(s, "G", [50.0], [10.0]) == []
    (box,) = boxes(s, "r", [50.0], [10.0])
    assert box.kind == "signal" and np.all(box.velocity == 0.0)
    assert (box.length, box.width) == (BOX_LENGTH, BOX_WIDTH)
    assert box.centre == pytest.approx([100.0 + 0.5 * BOX_LENGTH, 0.0])  # its back edge on the line
    rect = OrientedRect(*box.footprint())
    assert point_rect_signed_distance(np.array([[99.99, 0.0]]), rect)[0] > 0.0  # nothing of it before the line


def test_at_yellow_a_car_that_can_stop_comfortably_is_held_and_one_that_cannot_goes_on():
    s = Signals()
    boxes(s, "G", [40.0, 60.0], [14.0, 14.0])
    # 14 m/s stops in 14^2 / (2 * 3) = 32.7 m: car 0 at 30 m cannot, car 1 at 50 m can
    assert boxes(s, "y", [30.0, 50.0], [14.0, 14.0]) == []  # car 0 is let through: no box in its way
    assert boxes(s, "y", [10.0, 36.0], [14.0, 14.0]) == []
    # car 0's front has passed the line, but its body is still over the box's place
    assert boxes(s, "y", [-2.0, 24.0], [14.0, 12.0]) == []
    (box,) = boxes(s, "y", [-(LENGTHS[0] + BOX_LENGTH) - 0.1, 20.0], [14.0, 9.0])  # it has cleared it: the box holds car 1
    assert box.name == "signal J1 2 e_in_0"
    assert s.violations == 0


def test_crossing_at_red_is_a_violation_and_at_yellow_only_for_a_car_the_line_held():
    s = Signals()
    boxes(s, "y", [5.0], [14.0])
    boxes(s, "y", [-1.0], [14.0])  # crossed at yellow
    assert s.violations == 0
    s = Signals()
    boxes(s, "r", [5.0], [14.0])
    boxes(s, "r", [-1.0], [14.0])  # crossed at red
    assert s.violations == 1
    boxes(s, "r", [-3.0], [14.0])  # counted once
    assert s.violations == 1
    s = Signals()
    boxes(s, "y", [40.0], [14.0])  # it can stop: the line holds it
    boxes(s, "y", [1.0], [14.0])
    boxes(s, "y", [-1.0], [14.0])  # crossed at yellow all the same
    assert s.violations == 1


def test_the_cars_let_through_are_chosen_afresh_each_time_the_line_leaves_green():
    s = Signals()
    boxes(s, "y", [10.0], [14.0])  # let through
    assert boxes(s, "r", [5.0], [14.0]) == []
    boxes(s, "G", [200.0], [14.0])  # green again, the car comes round again from far
    assert len(boxes(s, "y", [150.0], [14.0])) == 1  # it can stop now: held


@given(d=st.floats(0.0, 200.0), v=st.floats(0.0, 20.0), comfort=st.floats(0.5, 6.0))
def test_a_car_is_held_at_yellow_exactly_when_it_can_stop_before_the_line_at_its_comfort_deceleration(d, v, comfort):
    s = Signals()
    held = s.boxes({"J1": "rry"}, {0: [(LINE, d)]}, np.array([v]), np.array([comfort]), np.array([4.0]))
    assert bool(held) == (v * v <= 2.0 * comfort * d)


def test_with_a_yellow_rule_a_car_that_would_brake_beyond_its_gentle_deceleration_goes_on_if_it_passes_before_red():
    """At 13.89 m/s a car stops at 2 m/s^2 in 48.2 m, and with one period's travel and 1 m to
    spare it needs 50.6 m. 48 m before a line that turns yellow it could stop at its comfort
    deceleration (3 m/s^2: 32.2 m), so without the rule it is held and must brake beyond 2 m/s^2;
    with it, it goes on: it reaches the line in 3.46 s, within the 4 s yellow (less 0.5 s). With a
    3 s yellow it is held. A car 52 m before the line stops gently: held either way."""
    rule = YellowRule(2.0, 1.0, 0.1, {"J1": 4.0})
    assert boxes(Signals(), "y", [48.0, 52.0], [13.89, 13.89]) != []
    s = Signals(rule)
    assert boxes(s, "y", [48.0], [13.89]) == []  # let through
    assert len(boxes(Signals(rule), "y", [52.0], [13.89])) == 1  # can stop gently
    short = Signals(YellowRule(2.0, 1.0, 0.1, {"J1": 3.0}))
    assert len(boxes(short, "y", [48.0], [13.89])) == 1
    assert len(boxes(Signals(rule), "r", [48.0], [13.89])) == 1  # straight to red: the comfort rule alone


@given(d=st.floats(0.0, 200.0), v=st.floats(0.1, 20.0), yellow=st.floats(0.0, 6.0))
def test_a_car_the_yellow_rule_lets_through_reaches_the_line_before_the_yellow_ends(d, v, yellow):
    rule = YellowRule(2.0, 1.0, 0.1, {"J1": yellow})
    s = Signals(rule)
    held = s.boxes({"J1": "rry"}, {0: [(LINE, d)]}, np.array([v]), np.array([3.0]), np.array([4.0]))
    if not held and v * v <= 2.0 * 3.0 * d:  # let through by the gentle rule alone
        assert d / v < yellow - YELLOW_SPARE
        assert v * v > 2.0 * 2.0 * (d - 0.1 * v - 1.0)


def test_the_links_of_one_lane_share_its_line_no_box_comes_down_on_a_car_of_another_link():
    """Lane e_in_0 has two links at one line, 1 (right turn) and 2 (straight). Car 0 turns right
    and has just crossed the line when both turn yellow; car 1, going straight, is far enough
    back to stop. The boxes wait until car 0 has cleared the line, then hold car 1."""
    right = Line("J1", 1, "e_in_0", LINE.point, 0.0)
    s = Signals()

    def period(state, d0, d1):
        approach = {0: [(right, d0)], 1: [(LINE, d1)]}
        return s.boxes({"J1": "r" + state + state + "r"}, approach, np.array([2.0, 10.0]), COMFORT, LENGTHS)

    assert period("G", 0.1, 40.0) == []
    assert period("y", -0.3, 38.0) == []  # car 0 is over the line: neither box comes down on it
    held = period("y", -(LENGTHS[0] + BOX_LENGTH) - 0.1, 30.0)
    assert {b.name for b in held} == {"signal J1 1 e_in_0", "signal J1 2 e_in_0"}
    assert s.violations == 0


GRID6 = [(42.0, "GGrrGGrr"), (3.0, "yyrryyrr"), (42.0, "rrGGrrGG"), (3.0, "rryyrryy")]  # grid6's junction 2/0


def test_green_left_is_the_time_until_each_link_leaves_green_round_the_cycle():
    from aac_sumo.experiments.signals import green_left

    assert green_left(GRID6, 0, 10.0) == [10.0, 10.0, 0.0, 0.0, 10.0, 10.0, 0.0, 0.0]
    assert green_left(GRID6, 2, 41.9) == [0.0, 0.0, 41.9, 41.9, 0.0, 0.0, 41.9, 41.9]
    two = [(10.0, "Gr"), (5.0, "gr"), (4.0, "yr"), (12.0, "rG"), (4.0, "ry")]  # green with and without priority: green all the same
    assert green_left(two, 0, 3.0) == [8.0, 0.0]
    assert green_left([(30.0, "GO"), (30.0, "rO")], 1, 5.0) == [0.0, np.inf]  # off (no signal) all round the cycle
    assert green_left(GRID6, 4, 1.0) is None  # a phase the program does not have


def test_with_a_preview_a_line_holds_before_its_yellow_for_the_cars_that_would_not_pass_before_it_ends():
    """3 s before a 3 s yellow a car at 13.89 m/s 60 m before the line reaches it in 4.3 s, within
    the 5.5 s the yellow (less 0.5 s) leaves: it goes on, and no box stands in its way. One 80 m
    before it needs 5.8 s: the line holds it now, while it can stop at 1.2 m/s^2, not at the
    yellow, when it would be 38 m before the line and need 2.5 m/s^2."""
    rule = YellowRule(2.0, 1.0, 0.1, {"J1": 3.0}, preview=3.0, accel=1.5)

    def early(distances, speeds, left, tops=None):
        s = Signals(rule)
        approach = {k: [(LINE, d)] for k, d in enumerate(distances)}
        n = len(distances)
        return s, s.boxes({"J1": "rrGr"}, approach, np.asarray(speeds, dtype=float), np.full(n, 3.0), np.full(n, 4.0),
                          {"J1": [0.0, 0.0, left, 0.0]}, None if tops is None else np.asarray(tops, dtype=float))

    assert early([60.0], [13.89], 3.0)[1] == []
    s, held = early([80.0], [13.89], 3.0)
    assert len(held) == 1 and s.violations == 0
    assert early([80.0], [13.89], 3.1)[1] == []  # further from the yellow than the preview: green as ever
    assert len(early([60.0], [13.89], 3.0, tops=[5.0])[1]) == 1  # one that must slow to 5 m/s for its turn at the line: 6.2 s
    assert early([30.0], [4.0], 3.0, tops=[13.89])[1] == []  # one setting off from a queue speeds up: 30 m in 4.2 s


def test_a_car_the_preview_lets_through_is_held_again_once_it_would_no_longer_pass_before_the_yellow_ends():
    """The cars let through are chosen afresh each period while the light is green: one that
    falls behind (a slow car ahead of it) and can still stop comfortably gets the box; at the
    yellow the choice of its last green period stands."""
    s = Signals(YellowRule(2.0, 1.0, 0.1, {"J1": 3.0}, preview=3.0, accel=1.5))

    def period(state, d, v, left):
        return s.boxes({"J1": "rr" + state + "r"}, {0: [(LINE, d)]}, np.array([v]), np.array([3.0]), np.array([4.0]),
                       {"J1": [0.0, 0.0, left, 0.0]})

    assert period("G", 60.0, 13.89, 3.0) == []
    assert period("G", 55.0, 13.89, 2.5) == []
    assert len(period("G", 45.0, 5.0, 1.5)) == 1  # it slowed: 45 m from 5 m/s takes 5.1 s, the yellow ends in 4 s
    assert len(period("y", 30.0, 3.0, 0.0)) == 1  # held at yellow too
    s = Signals(YellowRule(2.0, 1.0, 0.1, {"J1": 3.0}, preview=3.0, accel=1.5))
    assert period("G", 40.0, 13.89, 1.0) == []
    assert period("y", 26.0, 13.89, 0.0) == []  # let through in the preview: it goes on at yellow
    assert period("y", -1.0, 13.89, 0.0) == [] and s.violations == 0


@given(d=st.one_of(st.just(0.0), st.floats(1e-6, 200.0)), v=st.floats(0.0, 20.0), top=st.floats(0.5, 20.0))
def test_a_car_reaches_the_line_at_an_average_speed_between_its_own_and_its_paths_speed_there(d, v, top):
    """:func:`arrival_time`: speeding up (v < top) it is :func:`travel_time`; slowing to its path's
    speed at the line, its average speed lies between that speed and its own (at the line, or
    from a micrometre on: 5e-324 m divided by a speed underflows to a time of 0)."""
    from aac_sumo.experiments.signals import arrival_time, travel_time

    t = arrival_time(d, v, 1.5, top)
    if v <= top:
        assert t == travel_time(d, v, 1.5, top)
    elif d > 0.0:
        assert top * (1 - 1e-9) <= d / t <= v * (1 + 1e-9)
