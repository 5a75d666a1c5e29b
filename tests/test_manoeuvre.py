"""Manoeuvres, the last resort of committed-plan AAC: primitives start and end at rest within
the robot's limits, a found manoeuvre keeps the margin from every obstacle at every period of
its rollout with the simulator's own Euler step and ends within the goal's radius, a walled-in
goal has none, and a random crossing that deadlocked completes with them."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.coordination.manoeuvre import INCHING, SPARE, ManoeuvrePlanner, speed_profile
from aac_sumo.geometry import rect_clearance_rows
from aac_sumo.kernels.motion import footprint_rows, rollouts
from aac_sumo.runs import runner

DT, WHEELBASE, LENGTH, WIDTH, OFFSET = 0.1, 0.45, 0.6, 0.4, 0.3
LIMITS = np.array([0.6, 3.0, 2.0])  # steer_max [rad], a_lat_max [m/s^2], steer_rate_max [rad/s]
MARGIN = 0.05


def planner(v_min: float = -1.5) -> ManoeuvrePlanner:
    return ManoeuvrePlanner(WHEELBASE, LIMITS, v_min, 1.5, -2.0, 1.0, LENGTH, WIDTH, OFFSET, DT)


def course(state: np.ndarray, inputs: np.ndarray, v_min: float = -1.5) -> np.ndarray:
    """Rear-axle states (K+1, 4) of ``inputs`` from ``state``, as the simulator steps them."""
    return rollouts(state[None], inputs[None], DT, np.array([WHEELBASE]), np.array([v_min]), np.array([1.5]))[0]


def least_clearance(states: np.ndarray, obstacles: np.ndarray) -> float:
    rows = footprint_rows(states[None], np.array([OFFSET]), np.array([LENGTH]), np.array([WIDTH]))[0]
    return min(float(rect_clearance_rows(np.repeat(row[None], len(obstacles), axis=0), obstacles).min()) for row in rows)


@pytest.mark.parametrize("length", [0.3, 0.9, 2.0])
def test_a_speed_profile_goes_from_rest_to_rest_within_its_bounds(length):
    accels = speed_profile(length, 0.4, 1.0, 1.0, DT)
    speeds = np.concatenate([[0.0], np.cumsum(accels * DT)])
    assert speeds[-1] == pytest.approx(0.0, abs=1e-12) and np.all(speeds >= -1e-12) and speeds.max() <= 0.4 + 1e-12
    assert np.all(np.abs(accels) <= 1.0 + 1e-12)
    # Euler moves each period at the speed it starts with; the cruise is rounded to whole periods
    assert abs(np.sum(speeds[:-1]) * DT - length) <= 0.5 * 0.4 * DT + 1e-9


def test_primitives_turn_the_wheels_at_the_steering_rate_before_they_move():
    rows, lengths, costs = planner().primitives(0.0)
    for inputs in rows:
        steer = np.concatenate([[0.0], inputs[:, 1]])
        assert np.all(np.abs(np.diff(steer)) <= LIMITS[2] * DT + 1e-12)
        speeds = np.cumsum(inputs[:, 0] * DT)
        moving = np.flatnonzero(np.abs(speeds) > 1e-12)
        assert np.all(np.diff(steer[1:][moving[0]:]) == 0.0)  # one arc: the wheels stand still while it drives
    assert np.all(costs >= lengths * DT - 1e-12)


@pytest.mark.parametrize("v, accels, driven", [(0.25, [-1.0, -1.0, -0.5], 0.045), (-0.15, [1.0, 0.5], 0.02), (0.0, [], 0.0)])
def test_a_rocking_robot_brakes_to_rest_at_the_primitives_deceleration(v, accels, driven):
    """From 0.25 m/s at 1 m/s^2 and dt = 0.1 s: -1, -1, then -0.5 to end exactly at rest, having
    driven 0.025 + 0.015 + 0.005 m (Euler: each period at the speed it starts with); the wheels
    stay where they are, and the rest state is where the simulator's rollout ends."""
    state = np.array([1.0, -2.0, 0.3, v])
    inputs, rest = planner().to_rest(state, 0.2)
    assert np.allclose(inputs[:, 0], accels) and np.all(inputs[:, 1] == 0.2)
    states = course(state, inputs)
    assert np.allclose(states[-1], rest) and rest[3] == 0.0
    assert DT * np.abs(states[:-1, 3]).sum() == pytest.approx(driven)


def test_a_robot_between_parked_neighbours_manoeuvres_to_its_goal():
    """The 24-robot circle swap's seed 3 (r = 4 m): the last robot stood 1.2 m short of its goal,
    its MPC infeasible for the ellipses round its neighbours, which the rectangles leave room."""
    state = np.array([-0.475, -3.5466, 6.1527, 0.0])
    goal = np.array([0.733, -3.761])
    parked = np.array([[-0.038, -4.343, 0.6, 0.4, 3.800], [2.139, -3.564, 0.6, 0.4, 4.827],
                       [-0.929, -3.889, 0.6, 0.4, 5.060], [2.911, -2.929, 0.6, 0.4, 5.423]])
    inputs = planner().plan(state, 0.0, goal, 0.25, parked, MARGIN)
    assert inputs is not None
    states = course(state, inputs)
    assert np.hypot(*(states[-1, :2] - goal)) <= 0.25 and states[-1, 3] == pytest.approx(0.0, abs=1e-9)
    assert least_clearance(states, parked) >= MARGIN + SPARE - 1e-9


def test_a_smoothed_manoeuvre_drives_the_same_legs_without_the_stops():
    """Legs of one direction run into each other: the course ends near where the searched legs
    end, sooner, never standing between them, its wheels within the steering rate."""
    p = planner()
    legs = [(1, 0.0), (0, p.steers[-1]), (1, 0.0)]  # 0.9 m straight, a 0.3 m full-left arc, 0.9 m straight
    state = np.zeros(4)
    searched, smoothed = p.stop_and_go(legs, 0.0), p.smooth(legs, 0.0, 1.0)
    a, b = course(state, searched), course(state, smoothed)
    assert len(smoothed) < len(searched)
    assert np.hypot(*(a[-1, :2] - b[-1, :2])) < 0.2 and abs(b[-1, 3]) < 1e-9
    assert np.all(np.abs(b[1:-1, 3]) > 0.0)  # it stands only at the ends
    steer = np.concatenate([[0.0], smoothed[:, 1]])
    assert np.all(np.abs(np.diff(steer)) <= LIMITS[2] * DT + 1e-12) and np.all(np.abs(steer) <= LIMITS[0] + 1e-12)


def test_a_robot_boxed_in_with_a_few_centimetres_to_spare_inches_where_no_longer_arc_fits():
    """Parked footprints 0.3 m ahead of and behind the robot's, and 0.07 m along both its sides: its
    goal lies 0.17 m ahead. No primitive of LENGTHS (0.28 m of driving and more) fits in the box, so the lattice of
    LENGTHS finds no way; the inching lattice (INCHING) drives its shortest primitive there."""
    state = np.array([0.0, 0.0, 0.0, 0.0])
    front, back = OFFSET + 0.5 * LENGTH + 0.3, OFFSET - 0.5 * LENGTH - 0.3  # the gaps' far sides [m], rear-axle frame
    box = np.array([[front + 0.3, 0.0, 0.6, 1.2, 0.0], [back - 0.3, 0.0, 0.6, 1.2, 0.0],
                    [OFFSET, 0.42, 2.0, 0.3, 0.0], [OFFSET, -0.42, 2.0, 0.3, 0.0]])
    goal = np.array([0.17, 0.0])
    assert planner().plan(state, 0.0, goal, 0.05, box, MARGIN) is None
    inching = ManoeuvrePlanner(WHEELBASE, LIMITS, -1.5, 1.5, -2.0, 1.0, LENGTH, WIDTH, OFFSET, DT, INCHING)
    inputs = inching.plan(state, 0.0, goal, 0.05, box, MARGIN)
    assert inputs is not None
    states = course(state, inputs)
    assert np.hypot(*(states[-1, :2] - goal)) <= 0.05 and states[-1, 3] == pytest.approx(0.0, abs=1e-9)
    assert least_clearance(states, box) >= MARGIN + SPARE - 1e-9


def test_no_manoeuvre_to_a_walled_in_goal():
    wall = np.array([[1.0, 1.0, 2.0, 0.2, 0.0], [1.0, -1.0, 2.0, 0.2, 0.0], [2.0, 0.0, 0.2, 2.0, 0.0], [0.0, 0.0, 0.2, 2.0, 0.0]])
    assert planner().plan(np.array([-2.0, 0.0, 0.0, 0.0]), 0.0, np.array([1.0, 0.0]), 0.2, wall, MARGIN) is None


def test_a_robot_that_cannot_reverse_only_drives_forwards():
    """A goal straight behind: without reverse it turns round on forward arcs."""
    state = np.array([0.0, 0.0, 0.0, 0.0])
    inputs = planner(v_min=0.0).plan(state, 0.0, np.array([-1.0, 0.0]), 0.25, np.zeros((0, 5)), MARGIN)
    assert inputs is not None
    assert np.all(course(state, inputs, v_min=0.0)[:, 3] >= 0.0)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 8))
def test_a_manoeuvre_keeps_the_margin_at_every_period_and_ends_at_its_goal(seed, m):
    rng = np.random.default_rng(seed)
    state = np.array([-2.0, rng.uniform(-0.5, 0.5), rng.uniform(-np.pi, np.pi), 0.0])
    goal = np.array([2.0, rng.uniform(-1.0, 1.0)])
    obstacles = np.column_stack([rng.uniform(-1.5, 1.5, (m, 2)) * [1.0, 1.5], rng.uniform(0.3, 0.8, (m, 2)), rng.uniform(0, np.pi, m)])
    # obstacles never cover start or goal: a robot stands clear where it starts, and its goal is free
    keep = np.array([least_clearance(state[None], o[None]) > MARGIN + SPARE for o in obstacles])
    obstacles = obstacles[keep & (np.hypot(*(obstacles[:, :2] - goal).T) > 0.9)]
    inputs = planner().plan(state, 0.0, goal, 0.25, obstacles, MARGIN)
    if inputs is None:
        return  # walled in, or beyond the search's budget
    states = course(state, inputs)
    assert np.hypot(*(states[-1, :2] - goal)) <= 0.25
    if len(obstacles):
        assert least_clearance(states, obstacles) >= MARGIN + SPARE - 1e-9


@pytest.mark.slow
def test_the_random_crossing_that_deadlocked_completes_with_manoeuvres():
    """Seed 27 (20 robots) ended in a deadlock at 53.1 s without manoeuvres (commit 5c3b9e6):
    three robots stood a few centimetres from each other and from debris, their solves leaving
    them where they stood."""
    scenario = config.load("random_crossing", ["scenario.seed=27"])
    assert scenario["aac.manoeuvre"]
    result = runner.run(scenario)
    assert result.metrics["completed"] and result.metrics["collisions"] == 0
    assert result.metrics["min_clearance_m"] >= scenario["aac.commit_margin"] - 1e-9
    assert (result.steps["mode"] == "manoeuvre").any()


@pytest.mark.slow
def test_a_dense_crossing_whose_last_robot_rocked_completes():
    """20 robots at 16.7 per 100 m^2, seed 7: the last robot rocked on the spot beside a robot that
    kept making room for it and coming back, so that the jam rule never held (a deadlock at
    36.2 s); neighbours that get no nearer their goals now leave the jam as it is. (On the machine
    of 2026-12-07 the same run needs no manoeuvre: single runs differ between machines.)"""
    scenario = config.load("random_crossing", ["scenario.seed=7", "random_crossing.density=16.7"])
    result = runner.run(scenario)
    assert result.metrics["completed"] and result.metrics["collisions"] == 0


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 60))
def test_the_buckets_give_every_primitive_the_clearances_of_all_obstacles(seed, m):
    """A primitive's least and last clearance and its end are the same whether it looks only at
    its footprint's bucket of obstacles (kernels/manoeuvres.py) or at every obstacle."""
    from aac_sumo.kernels.manoeuvres import BUCKET, _buckets, _primitive

    rng = np.random.default_rng(seed)
    obstacles = np.column_stack([rng.uniform(-3, 3, (m, 2)), rng.uniform(0.2, 1.5, (m, 2)), rng.uniform(-np.pi, np.pi, m)])
    radii = 0.5 * np.hypot(obstacles[:, 2], obstacles[:, 3])
    body, cap, floor = float(np.hypot(0.5 * LENGTH, 0.5 * WIDTH)), MARGIN + 2 * SPARE, -np.inf
    glo = np.array([-2.0, -2.0])
    first, items = _buckets(obstacles, radii, body + cap, glo, BUCKET, 8, 8)  # a grid smaller than the area: both paths run
    rows, lengths, _ = planner().primitives(float(rng.uniform(-0.6, 0.6)))
    state = np.array([*rng.uniform(-2.5, 2.5, 2), rng.uniform(-np.pi, np.pi), 0.0])
    for inputs, k in zip(rows, lengths):
        args = (state, inputs, int(k), obstacles, radii, body, DT, WHEELBASE, -1.5, 1.5, OFFSET, LENGTH, WIDTH, floor, cap)
        bucketed = _primitive(*args, first, items, glo, BUCKET, 8, 8)
        everyone = _primitive(*args, *_buckets(obstacles, radii, body + cap, glo, BUCKET, 0, 0), glo, BUCKET, 0, 0)
        assert np.array_equal(bucketed[0], everyone[0]) and bucketed[1] == everyone[1] and bucketed[2] == everyone[2]
