"""Detours of committed-plan AAC: the grid planner keeps clear of what stands, goes round a
parked robot, its compiled distance field and shortcut are the numpy definitions, and a random
crossing that deadlocked without detours completes with them."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.cli.app import main
from aac_sumo.coordination.detour import LOOKAHEAD, SAMPLES, Detours, plan_detour
from aac_sumo.geometry import rect_distances
from aac_sumo.kernels.detours import band_costs, distance_field, rects_within, shortcut
from aac_sumo.references import PathReference

HARD, CLEARANCE, CELL = 0.25, 0.5, 0.1


def polyline_distance(waypoints: np.ndarray, rects: np.ndarray) -> float:
    """Smallest distance [m] from the polyline ``waypoints`` to ``rects``, sampled every 5 mm."""
    pieces = [a + np.linspace(0.0, 1.0, max(2, int(np.hypot(*(b - a)) / 0.005)))[:, None] * (b - a)
              for a, b in zip(waypoints[:-1], waypoints[1:])]
    return float(rect_distances(np.vstack(pieces), rects).min())


def test_rect_distances_is_the_exact_distance():
    rect = np.array([[1.0, 2.0, 2.0, 1.0, np.pi / 2]])  # 2 m along y, 1 m along x
    points = np.array([[1.0, 2.0], [2.0, 2.0], [1.0, 4.0], [2.5, 4.0]])
    np.testing.assert_allclose(rect_distances(points, rect), [0.0, 0.5, 1.0, np.hypot(1.0, 1.0)])


def numpy_field(lo, cell, rows, cols, rects, reach):
    """:func:`distance_field` by its definition: rect_distances of every cell centre, over the
    rectangles whose window (enclosing disc grown by ``reach``, whole cells) holds it."""
    xs, ys = lo[0] + cell * np.arange(cols), lo[1] + cell * np.arange(rows)
    dist = np.full((rows, cols), np.inf)
    for rect in rects:
        r = 0.5 * np.hypot(rect[2], rect[3]) + reach
        c0, r0 = np.floor((rect[:2] - r - lo) / cell).astype(int).clip(0)
        c1, r1 = np.ceil((rect[:2] + r - lo) / cell).astype(int) + 1
        if c0 >= cols or r0 >= rows or c1 <= 0 or r1 <= 0:
            continue
        gx, gy = np.meshgrid(xs[c0:c1], ys[r0:r1])
        near = rect_distances(np.column_stack([gx.ravel(), gy.ravel()]), rect[None]).reshape(gx.shape)
        dist[r0:r1, c0:c1] = np.minimum(dist[r0:r1, c0:c1], near)
    return dist


def numpy_shortcut(path, kept, rects, hard, cell):
    """:func:`shortcut` by its definition (the Python loop it replaced), as point indices."""
    out, i, last = [0], 0, len(path) - 1
    while i < last:
        j = i + 1
        while j < last:
            need = max(float(kept[i:j + 2].min()), hard) - 0.5 * cell
            a, b = path[i], path[j + 1]
            t = np.linspace(0.0, 1.0, max(2, int(np.ceil(SAMPLES * np.hypot(*(b - a)) / cell)) + 1))
            if rect_distances(a + t[:, None] * (b - a), rects).min() < need:
                break
            j += 1
        out.append(j)
        i = j
    return out


def random_rects(rng, m):
    return np.column_stack([rng.uniform(-3, 3, (m, 2)), rng.uniform(0.2, 1.2, (m, 2)), rng.uniform(-np.pi, np.pi, m)])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(0, 6))
def test_distance_field_is_rect_distances_in_each_window(seed, m):
    rng = np.random.default_rng(seed)
    rects, lo, cell = random_rects(rng, m), rng.uniform(-4, -2, 2), rng.uniform(0.05, 0.3)
    rows, cols = rng.integers(1, 60, 2)
    field = distance_field(lo, cell, rows, cols, rects, 0.5)
    np.testing.assert_array_equal(field, numpy_field(lo, cell, rows, cols, rects, 0.5))


def test_band_costs_rise_from_one_at_the_clearance_to_the_penalty_at_the_hard_distance():
    dist = np.array([[np.inf, 2.0, CLEARANCE, 0.5 * (HARD + CLEARANCE)], [HARD, 0.9 * HARD, 0.0, 1e-12]])
    expected = np.array([[1.0, 1.0, 1.0, 1.0 + 0.5 * 20.0], [21.0, np.inf, np.inf, np.inf]])
    np.testing.assert_allclose(band_costs(dist, HARD, CLEARANCE, 20.0), expected, rtol=1e-12)
    dist = np.random.default_rng(0).uniform(0.0, 1.0, (7, 9))  # the numpy definition, bit for bit
    numpy_cost = 1.0 + 20.0 * np.clip((CLEARANCE - dist) / (CLEARANCE - HARD), 0.0, 1.0)
    numpy_cost[dist < HARD] = np.inf
    np.testing.assert_array_equal(band_costs(dist, HARD, CLEARANCE, 20.0), numpy_cost)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(0, 6), k=st.integers(2, 40))
def test_compiled_shortcut_keeps_the_corners_of_the_python_loop(seed, m, k):
    rng = np.random.default_rng(seed)
    rects = random_rects(rng, m)
    path = np.cumsum(rng.uniform(-0.3, 0.3, (k, 2)), axis=0) + rng.uniform(-4, 4, 2)  # a random walk
    kept = np.minimum(rect_distances(path, rects), CLEARANCE)
    assert list(shortcut(path, kept, rects, HARD, CELL, SAMPLES)) == numpy_shortcut(path, kept, rects, HARD, CELL)


def test_detour_goes_round_a_parked_robot_with_its_clearance():
    parked = np.array([[0.0, 0.05, 0.6, 0.4, 1.2]])  # a robot standing across the straight line
    start, goal = np.array([-3.0, 0.0]), np.array([3.0, 0.0])
    assert polyline_distance(np.array([start, goal]), parked) == 0.0
    path = plan_detour(start, goal, parked, HARD, CLEARANCE, CELL)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal)
    assert polyline_distance(path, parked) >= CLEARANCE - CELL
    assert len(path) <= 5  # corners only, not grid cells
    assert np.sum(np.hypot(*np.diff(path, axis=0).T)) < 6.0 + 1.0  # round it, not far away


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 8))
def test_detour_keeps_the_hard_distance_from_debris(seed, m):
    rng = np.random.default_rng(seed)
    debris = np.column_stack([rng.uniform(-2.5, 2.5, (m, 2)), rng.uniform(0.4, 1.2, (m, 2)), rng.uniform(0, np.pi, m)])
    start, goal = np.array([-4.5, rng.uniform(-1, 1)]), np.array([4.5, rng.uniform(-1, 1)])
    path = plan_detour(start, goal, debris, HARD, CLEARANCE, CELL)
    if path is None:
        return  # walled in (debris may merge into a wall): nothing to keep clear
    np.testing.assert_allclose(path[[0, -1]], [start, goal])
    # every grid cell on the way kept HARD; its corners are at most half a cell's diagonal off
    assert polyline_distance(path, debris) >= HARD - CELL


def test_no_detour_to_a_walled_in_goal():
    wall = np.array([[0.0, 1.0, 2.0, 0.2, 0.0], [0.0, -1.0, 2.0, 0.2, 0.0], [1.0, 0.0, 0.2, 2.0, 0.0], [-1.0, 0.0, 0.2, 2.0, 0.0]])
    assert plan_detour([-4.0, 0.0], [0.0, 0.0], wall, HARD, CLEARANCE, CELL) is None


def test_detours_only_where_a_standing_robot_is_in_the_way():
    tasks = [PathReference([[-3.0, 0.0], [3.0, 0.0]], 1.0, approach=0.6),   # runs through robot 1's spot
             PathReference([[-4.0, 4.0], [0.0, 0.0]], 1.0, approach=0.6),   # parked at its goal
             PathReference([[-3.0, -3.0], [3.0, -3.0]], 1.0, approach=0.6)]  # far from it
    detours = Detours(tasks, stall_periods=10, check_periods=10, hard=HARD, clearance=CLEARANCE, cell=CELL)
    states = np.array([[-3.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.8, 0.0], [-3.0, -3.0, 0.0, 1.0]])
    footprints = np.column_stack([states[:, :2], np.full(3, 0.6), np.full(3, 0.4), states[:, 2]])
    done = np.array([False, True, False])
    detours.update(states, footprints, done, done, np.zeros((0, 5)), period=0)
    assert detours.routes[1] is None and detours.routes[2] is None
    route = detours.path(0)
    assert route is not tasks[0]
    np.testing.assert_allclose(route.points[-1], tasks[0].points[-1])
    assert polyline_distance(route.points, footprints[[1]]) >= CLEARANCE - CELL
    assert route.speed == tasks[0].speed and route.approach == tasks[0].approach


def test_a_robot_plans_round_what_stands_within_the_lookahead_on_its_way_and_not_beyond():
    """A parked robot on a long way is gone round once it lies within ``LOOKAHEAD`` of the rest of
    the way, not while it lies farther on (it is likely to have moved by then)."""
    for start, detoured in ((-LOOKAHEAD - 5.0, False), (-LOOKAHEAD + 5.0, True)):
        tasks = [PathReference([[start, 0.0], [10.0, 0.0]], 1.0, approach=0.6),  # runs through robot 1's spot at x = 0
                 PathReference([[-4.0, 4.0], [0.0, 0.0]], 1.0, approach=0.6)]    # parked at its goal
        detours = Detours(tasks, stall_periods=10, check_periods=10, hard=HARD, clearance=CLEARANCE, cell=CELL)
        states = np.array([[start, 0.0, 0.0, 1.0], [0.0, 0.0, 0.8, 0.0]])
        footprints = np.column_stack([states[:, :2], np.full(2, 0.6), np.full(2, 0.4), states[:, 2]])
        done = np.array([False, True])
        detours.update(states, footprints, done, done, np.zeros((0, 5)), period=0)
        assert (detours.routes[0] is not None) == detoured


def test_detour_needs_committed_plans(capsys):
    argv = ["run", "random_crossing", "--set", "aac.commit=false", "--set", "aac.authorities=1", "--set", "aac.detour=true"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "aac.detour" in err[0]


@pytest.mark.slow
def test_random_crossing_that_deadlocked_completes_with_detours():
    """Seed 8 ended in a deadlock at 43.9 s without detours (commit ed6d6fa)."""
    scenario = config.load("random_crossing", ["scenario.seed=8"])
    assert scenario["aac.detour"]
    metrics = runner.run(scenario).metrics
    assert metrics["completed"] and metrics["collisions"] == 0
    assert metrics["min_clearance_m"] >= scenario["aac.commit_margin"] - 1e-9


def test_near_its_goal_a_detour_goes_straight_there():
    """A detour's last corner close to the goal is a hook a car cannot follow: within FINAL of
    the goal, with the straight way free, the robot goes straight."""
    tasks = [PathReference([[-3.0, 0.0], [3.0, 0.0]], 1.0, approach=0.6)]
    detours = Detours(tasks, stall_periods=10, check_periods=10, hard=HARD, clearance=CLEARANCE, cell=CELL)
    detours.routes[0] = detours.route(0, np.array([[-3.0, 0.0], [2.6, -0.6], [3.0, 0.0]]))
    state = np.array([[2.0, -0.5, 0.0, 0.8]])
    footprint = np.column_stack([state[:, :2], [0.6], [0.4], state[:, 2]])
    detours.update(state, footprint, np.zeros(1, dtype=bool), np.zeros(1, dtype=bool), np.zeros((0, 5)), period=1)
    np.testing.assert_allclose(detours.path(0).points, [state[0, :2], [3.0, 0.0]])
    # a standing footprint on the straight way keeps the detour
    detours.routes[0], detours.final[0] = detours.route(0, np.array([[-3.0, 0.0], [2.6, -0.6], [3.0, 0.0]])), False
    debris = np.array([[2.5, -0.25, 0.3, 0.3, 0.0]])
    detours.next_check[0] = 100
    detours.update(state, footprint, np.zeros(1, dtype=bool), np.zeros(1, dtype=bool), debris, period=2)
    assert len(detours.path(0).points) == 3


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(0, 40), k=st.integers(1, 300), along_path=st.booleans())
def test_rects_within_is_rect_distances_below_the_reach(seed, m, k, along_path):
    """Scattered points, and samples every few centimetres along a winding way (as a reference's
    are), where the kernel skips the samples that a rectangle's distance rules out."""
    rng = np.random.default_rng(seed)
    if along_path:
        turns = np.cumsum(rng.normal(0, 0.3, k))
        points = np.cumsum(rng.uniform(0.0, 0.1, k)[:, None] * np.column_stack([np.cos(turns), np.sin(turns)]), axis=0) - 2.0
    else:
        points = rng.uniform(-4, 4, (k, 2))
    rects = random_rects(rng, m)
    expected = [rect_distances(points, rect[None]).min() < CLEARANCE for rect in rects]
    np.testing.assert_array_equal(rects_within(points, rects, CLEARANCE), np.array(expected, dtype=bool))


def test_a_stalled_robot_replans_only_when_the_standing_set_near_its_detour_changes():
    """Robot 0 stands on a detour round parked robot 1: a further stall re-plans nothing while
    the footprints near its way stay; a robot that comes to stand on its way makes it re-plan."""
    tasks = [PathReference([[-3.0, 0.0], [3.0, 0.0]], 1.0, approach=0.6),
             PathReference([[-4.0, 4.0], [0.0, 0.0]], 1.0, approach=0.6),   # parked at its goal, on robot 0's way
             PathReference([[4.0, 3.0], [1.5, 3.0]], 1.0, approach=0.6)]    # far from it, for now
    detours = Detours(tasks, stall_periods=10, check_periods=10, hard=HARD, clearance=CLEARANCE, cell=CELL)
    states = np.array([[-3.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.8, 0.0], [4.0, 3.0, np.pi, 0.0]])
    done = np.array([False, True, False])

    def run(periods, first):
        footprints = np.column_stack([states[:, :2], np.full(3, 0.6), np.full(3, 0.4), states[:, 2]])
        for period in range(first, first + periods):
            detours.update(states, footprints, done, done, np.zeros((0, 5)), period)

    run(1, 0)
    assert detours.planned == 1
    run(30, 1)  # robot 0 stalls three times, robot 2 stands far off: nothing new near the detour
    assert detours.planned == 2  # and robot 2's own, at its first stall only
    first = detours.path(0)
    states[2, :2] = first.pose_at(np.array([1.0]))[0, :2]  # robot 2 now stands on robot 0's detour
    run(30, 31)
    assert detours.path(0) is not first
    assert polyline_distance(detours.path(0).points, np.array([[*states[2, :2], 0.6, 0.4, np.pi]])) >= HARD - CELL


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), workers=st.integers(2, 4))
def test_detours_planned_on_threads_are_those_planned_one_by_one(seed, workers):
    """A period's detours are planned round what stood at its start, so threads change nothing."""
    rng = np.random.default_rng(seed)
    parked = rng.uniform(-2.0, 2.0, (4, 2))
    tasks = [PathReference([[-4.0, y], [4.0, -y]], 1.0, approach=0.6) for y in np.linspace(-2.0, 2.0, 6)]
    tasks += [PathReference([p + 3.0, p], 1.0, approach=0.6) for p in parked]
    states = np.array([[*t.points[0], 0.0, 0.0] for t in tasks[:6]] + [[*p, 0.0, 0.0] for p in parked])
    footprints = np.column_stack([states[:, :2], np.full(len(states), 0.6), np.full(len(states), 0.4), states[:, 2]])
    done = np.arange(len(states)) >= 6
    debris = random_rects(rng, 3)
    plans = []
    for count in (1, workers):
        detours = Detours(tasks, stall_periods=10, check_periods=10, hard=HARD, clearance=CLEARANCE, cell=CELL, workers=count)
        detours.update(states, footprints, done, done, debris, period=0)
        plans.append([None if r is None else r.points for r in detours.routes])
    assert sum(p is not None for p in plans[0]) >= 1
    for one, many in zip(*plans):
        assert (one is None) == (many is None)
        if one is not None:
            np.testing.assert_array_equal(one, many)


def test_one_and_two_workers_drive_the_random_crossing_alike(monkeypatch):
    """controller.workers changes how fast a period is decided, not what is decided."""
    import aac_sumo.coordination.detour as detour

    calls = []
    plan = detour.plan_detour
    monkeypatch.setattr(detour, "plan_detour", lambda *args: calls.append(1) or plan(*args))
    runs = [runner.run(config.load("random_crossing", ["scenario.duration=10", f"controller.workers={w}"])) for w in (1, 2)]
    assert len(calls) >= 20  # both runs planned detours
    first, second = (r.trajectories for r in runs)
    assert first.equals(second)
