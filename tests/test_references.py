"""Reference paths: projection, horizon windows, and what happens at and beyond the path's end."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from aac_sumo.references import PathReference


def test_projection_of_a_point_beside_the_path():
    path = PathReference([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]], 1.0)
    s, d = path.project([4.0, -2.0])
    assert (s, d) == (4.0, 2.0)


def test_a_stopping_path_clamps_the_projection_to_its_end():
    path = PathReference([[0.0, 0.0], [10.0, 0.0]], 2.0)
    s, d = path.project([15.0, 1.0])
    assert s == 10.0 and np.isclose(d, np.hypot(5.0, 1.0))


def test_a_path_that_goes_on_projects_beyond_its_end_and_leads_forwards():
    """A car that drove past the end of its (non-stopping) path still has its reference ahead of
    it along the last segment's direction, never behind it (it would turn round)."""
    path = PathReference([[0.0, 0.0], [10.0, 0.0]], 2.0, stop_at_end=False)
    s, d = path.project([25.0, 1.0])
    assert s == 25.0 and d == 1.0
    ref = path.horizon(np.array([25.0, 1.0, 0.0, 2.0]), 5, 0.5)
    np.testing.assert_allclose(ref[:, 0], 25.0 + np.arange(6))
    np.testing.assert_allclose(ref[:, 1], 0.0)
    np.testing.assert_allclose(ref[:, 3], 2.0)


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 100_000), stop=st.booleans())
def test_projection_is_the_closest_point_of_the_path(seed, stop):
    """The projection's distance is the least distance from the point to any segment (the last
    one extended forwards when the path goes on), and the path point at its arc length lies at
    that distance from the point."""
    rng = np.random.default_rng(seed)
    path = PathReference(np.cumsum(rng.uniform(-3, 3, (int(rng.integers(2, 30)), 2)), axis=0), 1.0, stop_at_end=stop)
    point = rng.uniform(-20, 20, 2)
    s, d = path.project(point)
    a, b = path.points[:-1], path.points[1:]
    t = np.einsum("ij,ij->i", point - a, b - a) / np.einsum("ij,ij->i", b - a, b - a)
    t = np.clip(t, 0.0, np.r_[np.ones(len(t) - 1), 1.0 if stop else np.inf])
    assert d == pytest.approx(np.hypot(*(a + t[:, None] * (b - a) - point).T).min(), abs=1e-9)
    assert np.hypot(*(path.pose_at(s)[0, :2] - point)) == pytest.approx(d, abs=1e-9)


def test_heading_at_is_the_horizons_first_heading_up_to_full_turns():
    """The heading where a point projects is the horizon's first heading, which is only unwrapped
    to lie near the robot's heading."""
    path = PathReference([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 12.0]], 2.0)
    for x, y, heading in [(3.0, 1.0, 0.0), (12.0, 4.0, 7.0), (5.0, 13.0, -3.0), (10.0, 0.0, 1.0)]:
        first = path.horizon(np.array([x, y, heading, 1.0]), 0, 0.1)[0, 2]
        assert np.cos(path.heading_at([x, y]) - first) == pytest.approx(1.0)


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 100_000), stop=st.booleans(), at_vertex=st.booleans())
def test_heading_at_is_the_heading_of_the_pose_where_the_point_projects(seed, stop, at_vertex):
    """heading_at agrees with pose_at at the projection's arc length everywhere, at a vertex too
    (the later segment's heading)."""
    rng = np.random.default_rng(seed)
    path = PathReference(np.cumsum(rng.uniform(-3, 3, (int(rng.integers(2, 30)), 2)), axis=0), 1.0, stop_at_end=stop)
    point = path.points[rng.integers(len(path.points))] if at_vertex else rng.uniform(-20, 20, 2)
    assert path.heading_at(point) == path.pose_at(path.project(point)[0])[0, 2]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), stop=st.booleans(), points=st.integers(2, 3000))
def test_projection_finds_the_closest_point_of_every_segment(seed, stop, points):
    """The projection's pruned search (bounding circles of segment chunks, 16 segments each or
    the square root of their count) gives the answer of a
    plain scan of every segment, on wiggly paths that come back near themselves, for points
    near, far, before and beyond them (past the end of a path that does not stop)."""
    rng = np.random.default_rng(seed)
    turns = np.cumsum(rng.normal(0, 0.6, points))
    path = PathReference(np.cumsum(rng.uniform(0.05, 3.0, points)[:, None] * np.column_stack([np.cos(turns), np.sin(turns)]), axis=0),
                         5.0, stop_at_end=stop)
    span = np.ptp(path.points, axis=0).max() + 10.0
    for p in np.vstack([path.points[rng.integers(0, len(path.points), 20)] + rng.normal(0, 1.0, (20, 2)),
                        path.points.mean(axis=0) + rng.uniform(-span, span, (20, 2))]):
        a, b = path.points[:-1], path.points[1:]
        t = np.clip(np.einsum("ij,ij->i", p - a, b - a) / path.seg_len**2, 0.0, path._t_max)
        d = np.hypot(*(a + t[:, None] * (b - a) - p).T)
        i = int(np.argmin(d))  # the first on ties
        s, dist = path.project(p)
        assert dist == pytest.approx(d[i], abs=1e-12)
        assert s == pytest.approx(path.s[i] + t[i] * path.seg_len[i], abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(steps=st.lists(st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)), min_size=1, max_size=40),
       point=st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0)), count=st.integers(1, 100),
       spacing=st.floats(0.1, 3.0), stops=st.booleans())
def test_the_headings_ahead_are_the_paths_poses_unwrapped(steps, point, count, spacing, stops):
    """``headings_ahead`` (compiled: kernels.path_headings) gives exactly numpy.unwrap of the
    headings ``pose_at`` gives every ``spacing`` metres from where the point projects, on any
    polyline, with its turns beyond pi."""
    points = np.cumsum(np.vstack([[0.0, 0.0], steps]), axis=0)
    assume(np.any(np.hypot(*np.diff(points, axis=0).T) > 1e-6))
    path = PathReference(points, 10.0, stop_at_end=stops)
    s0 = path.project(np.array(point))[0]
    expected = np.unwrap(path.pose_at(s0 + spacing * np.arange(count))[:, 2])
    np.testing.assert_array_equal(path.headings_ahead(np.array(point), count, spacing), expected)


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-2.0, 12.0), y=st.floats(-3.0, 3.0), heading=st.floats(-np.pi, np.pi), speed=st.floats(-1.0, 1.0),
       turn_radius=st.sampled_from([0.0, 0.66]), approach=st.sampled_from([0.0, 1.0, 3.0]))
def test_heading_free_says_what_the_horizon_does(x, y, heading, speed, turn_radius, approach):
    """heading_free is the horizon's free (NaN) heading, near the goal or beside the path's end,
    and not while backing off from a goal inside a turning circle."""
    path = PathReference(np.column_stack([np.linspace(0.0, 10.0, 21), np.zeros(21)]), 1.0, 0.5, approach=approach,
                         turn_radius=turn_radius, arrive=0.1)
    state = np.array([x, y, heading, speed])
    assert path.heading_free(state) == bool(np.isnan(path.horizon(state, 0, 0.1)[0, 2]))


@settings(max_examples=300, deadline=None)
@given(along=st.floats(-0.6, 0.6), across=st.floats(-0.4, 0.4), heading=st.floats(-0.2, 0.2))
def test_a_goal_the_tightest_turn_reaches_is_approached_and_one_deep_in_a_turning_circle_is_backed_off_from(along, across, heading):
    """A reversing robot (turning radius R = 0.66 m, arrival 0.3 m) standing near the goal of a
    path that stops: where the tightest turn on or back passes within 0.8 * 0.3 m of the goal
    (the goal lies at least R - 0.24 m from both turning centres), its reference is the approach
    (heading free), not the back-off (circle swap, 8 robots: robots that stopped 0.2 m past their
    goals backed off a metre and came round, 2-3 s a run); a goal deeper inside a turning circle
    is backed off from at half the cruise speed."""
    radius = 0.66
    path = PathReference(np.array([[-10.0, 0.0], [0.0, 0.0]]), 1.0, 0.5, approach=0.9, turn_radius=radius, arrive=0.3)
    c, s = np.cos(heading), np.sin(heading)
    rear = -along * np.array([c, s]) - across * np.array([-s, c])  # the goal lies `along` ahead, `across` to the left
    assume(np.hypot(along, across) > 0.3)
    state = np.array([rear[0], rear[1], heading, 0.0])
    gap = min(np.hypot(along, across - radius), np.hypot(along, across + radius))  # goal to the turning centres
    ref = path.horizon(state, 3, 0.1)
    if gap >= radius - 0.8 * 0.3:
        assert path.heading_free(state) and np.isnan(ref[0, 2])
    else:
        assert not path.heading_free(state) and abs(ref[0, 3]) == 0.5


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(2, 12), stop=st.booleans())
def test_pose_at_is_the_segment_interpolation_clamped_on_a_stopping_path(seed, m, stop):
    """The compiled poses equal their numpy definition bit for bit: the segment each arc length
    lies on (the first or last beyond the ends), clamped to it on a path that stops, carried on
    straight past its ends on one that does not."""
    rng = np.random.default_rng(seed)
    path = PathReference(np.cumsum(rng.uniform(-2, 2, (m, 2)), axis=0), 1.0, stop_at_end=stop)
    s = rng.uniform(-2.0, path.length + 2.0, 30)
    i = np.clip(np.searchsorted(path.s, s, side="right") - 1, 0, len(path.seg_len) - 1)
    local = s - path.s[i]
    if stop:
        local = np.minimum(np.maximum(local, 0.0), path.seg_len[i])
    heading = path.seg_heading[i]
    xy = path.points[i] + local[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    np.testing.assert_array_equal(path.pose_at(s), np.column_stack([xy, heading]))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), robots=st.integers(1, 40))
def test_reference_points_are_each_horizons_first_row_to_the_bit(seed, robots):
    """``reference_points`` (the runner's reference of every robot, its speeds and headings
    computed for all at once) gives row for row what ``horizon(state, 0, dt)[0]`` gives: on
    paths that stop or go on, with speed limits, near goals (the approach and the back-off, with
    their free headings) and on the paths themselves, with headings many turns off."""
    from aac_sumo.references import PathSet, reference_points

    rng = np.random.default_rng(seed)
    tasks, states = [], []
    for _ in range(robots):
        points = np.cumsum(rng.uniform(-3, 3, (int(rng.integers(2, 12)), 2)), axis=0)
        limits = rng.uniform(0.5, 2.0, len(points)) if rng.random() < 0.2 else None
        tasks.append(PathReference(points, rng.uniform(0.5, 3.0), rng.uniform(0.5, 2.0), stop_at_end=bool(rng.random() < 0.7),
                                   approach=float(rng.choice([0.0, 1.0])), turn_radius=float(rng.choice([0.0, 0.66])), arrive=0.2,
                                   limits=limits))
        near = tasks[-1].points[int(rng.integers(len(tasks[-1].points)))]
        states.append([*(near + rng.normal(0, 1.5, 2)), rng.uniform(-20, 20), rng.uniform(-1, 2)])
    states = np.array(states)
    expected = np.array([task.horizon(state, 0, 0.1)[0] for task, state in zip(tasks, states)])
    np.testing.assert_array_equal(reference_points(tasks, states, 0.1), expected)
    np.testing.assert_array_equal(reference_points(tasks, states, 0.1, PathSet(tasks)), expected)  # the arrays kept
    stale = PathSet(tasks[::-1])  # built for other tasks: not used
    assert stale.holds(tasks[::-1]) and (robots == 1 or not stale.holds(tasks))
    np.testing.assert_array_equal(reference_points(tasks, states, 0.1, stale), expected)
