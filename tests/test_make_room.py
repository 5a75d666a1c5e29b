"""Make room (coordination/make_room.py): who leads, who is in the leader's way, and where the
robots in its way go. Geometry in the world frame [m]; states are rear-axle (x, y, heading, v)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo.coordination.make_room import LEAD_PROGRESS, ROOM_EXTRA, MakeRoom

CORRIDOR = 1.0


def _fleet(points, headings=None):
    points = np.asarray(points, dtype=float)
    states = np.zeros((len(points), 4))
    states[:, :2] = points
    states[:, 2] = 0.0 if headings is None else headings
    return states


def test_a_parked_robot_far_ahead_on_the_leaders_way_is_left_where_it_is():
    """The leader stands at the origin with its goal 10 m east. A robot 1 m ahead is in its way;
    one parked 8 m ahead, near the leader's goal, is not (it was pushed off its own goal)."""
    room = MakeRoom(3, stall_periods=10, lead_periods=80, corridor=CORRIDOR)
    states = _fleet([[0.0, 0.0], [1.0, 0.2], [8.0, -0.1]])
    targets = room.room_targets(states, states[:, :2], np.array([10.0, 0.0]), leader=0)
    assert set(targets) == {1}


def test_near_its_goal_the_leader_clears_the_goal_and_a_corridor_beyond_it():
    room = MakeRoom(3, stall_periods=10, lead_periods=80, corridor=CORRIDOR)
    states = _fleet([[0.0, 0.0], [1.2, 0.0], [1.5 + 0.9, 0.3]])
    targets = room.room_targets(states, states[:, :2], np.array([1.5, 0.0]), leader=0)
    assert set(targets) == {1, 2}


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(-6, 6), st.floats(-6, 6)), min_size=2, max_size=12),
       st.floats(-8, 8), st.floats(-8, 8))
def test_every_blocker_is_ahead_within_reach_and_its_target_is_out_of_the_corridor(points, gx, gy):
    """Blockers lie ahead of the leader, within the corridor and the lead's reach; each target is
    ROOM_EXTRA out of the corridor and the corridor's width further along the leader's way."""
    states = _fleet(points)
    goal = np.array([gx, gy])
    room = MakeRoom(len(points), stall_periods=10, lead_periods=80, corridor=CORRIDOR)
    targets = room.room_targets(states, states[:, :2], goal, leader=0)
    seg = goal - states[0, :2]
    length = float(np.hypot(*seg))
    if length < 1e-9:
        assert targets == {}
        return
    u = seg / length
    n = np.array([-u[1], u[0]])
    reach = min(length, LEAD_PROGRESS + CORRIDOR) + CORRIDOR
    for j, target in targets.items():
        rel = states[j, :2] - states[0, :2]
        assert j != 0 and 0.0 < rel @ u < reach and abs(rel @ n) < CORRIDOR
        moved = target - states[0, :2]
        assert abs(moved @ n) >= CORRIDOR + ROOM_EXTRA - 1e-9
        assert np.isclose(moved @ u - rel @ u, CORRIDOR)


def test_the_stalled_robot_that_led_least_recently_leads_until_it_has_made_progress():
    """Robots 0 and 1 stand from the start; 0 leads first (ties: the lower index), and its lead
    ends after LEAD_PROGRESS [m] of progress; then 1, which has never led, leads."""
    goals = np.array([[10.0, 0.0], [0.0, 10.0]])
    states = _fleet([[0.0, 0.0], [0.0, 5.0]])
    centres = states[:, :2]
    active = np.array([True, True])
    room = MakeRoom(2, stall_periods=3, lead_periods=100, corridor=CORRIDOR)
    for period in range(3):
        room.update(states, centres, goals, active, period)
    assert room.leader == 0
    states[0, 0] = LEAD_PROGRESS + 0.1  # made its progress, and stands again
    room.update(states, states[:, :2], goals, active, 3)
    assert room.leader == 1
