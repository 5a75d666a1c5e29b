"""AAC and LFC coordinators: close pairs, swept hull regions, proximity decision, round robin,
priority order, safety stops, and the fairness metric."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pandas as pd
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

from aac_sumo.barriers import FcbfParams, barrier_value
from aac_sumo.coordination.anticipation import Anticipation
from aac_sumo.coordination.aac import AacCoordinator, AacParams
from aac_sumo.coordination.base import straight_behind
from aac_sumo.coordination.lfc import LfcCoordinator, LfcParams
from aac_sumo.coordination.tracking import track
from aac_sumo.coordination.proximity import ProximityParams, close_pairs, proximity_decision
from aac_sumo.coordination.regions import Fleet
from aac_sumo.coordination.safety import BRAKING_TIE, STRIP_OVERSHOOT, SafetyCheck, WalkerSpeeds
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.kernels.safety import STANDING_GAP
from aac_sumo.kernels.geometry import swept_hull_ellipses
from aac_sumo.geometry import containing_ellipse, convex_hull, ellipse_signed_distance, rect_corners
from aac_sumo.metrics import authority_jain
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.mpc.plan import Plan
from aac_sumo.references import PathReference
from aac_sumo.sim.sumo_frames import body_from_sumo, collision_cover, lane_change_sweep, velocity_from_sumo
from aac_sumo.world import Obstacle, RobotSpec, WorldState

DT = 0.1
LIMITS = VehicleLimits(a_min=-2.0, a_max=1.0, steer_max=0.6, v_min=0.0, v_max=1.5)
coord = st.floats(-20.0, 20.0, allow_nan=False)


def robot(i: int) -> RobotSpec:
    return RobotSpec(f"robot{i}", 0.6, 0.4, BicycleModel(0.45, LIMITS))


def planner(horizon: int = 5) -> MpcPlanner:
    return MpcPlanner(MpcConfig(horizon=horizon, dt=DT, slots=4, d_safe=0.1, fcbf=FcbfParams(v0=0.5), q_heading=0.5))


def straight_tasks(states: np.ndarray, goals: np.ndarray) -> list[PathReference]:
    return [PathReference([s[:2], g], 1.0) for s, g in zip(states, goals)]


# --- close pairs -------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(points=st.lists(st.tuples(coord, coord), min_size=0, max_size=25), distance=st.floats(0.1, 15.0))
def test_close_pairs_match_brute_force(points, distance):
    pts = np.array(points, dtype=float).reshape(-1, 2)
    brute = {(i, j) for i, j in itertools.combinations(range(len(pts)), 2) if np.hypot(*(pts[i] - pts[j])) < distance}
    found = close_pairs(pts, distance)
    assert {tuple(p) for p in found.tolist()} == brute
    assert len(found) == len(brute)  # no duplicates
    assert np.all(found[:, 0] < found[:, 1]) if len(found) else True


# --- swept convex-hull regions ----------------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(
    x=coord, y=coord, heading=st.floats(-np.pi, np.pi), speed=st.floats(0.0, 1.5),
    accel=st.floats(-2.0, 1.0), steer=st.floats(-0.6, 0.6), barrier=st.sampled_from(["fcbf", "cbf"]),
)
def test_hull_region_contains_current_and_next_footprints(x, y, heading, speed, accel, steer, barrier):
    """Stage 0 of a robot's region contains the convex hull of its footprints now and after one
    period of its input: every hull vertex is inside the ellipse (exact signed distance <= 0)."""
    fleet = Fleet([robot(0)])
    idx = np.array([0])
    inputs = np.tile([accel, steer], (1, 3, 1))
    traj = fleet.rollout(idx, np.array([[x, y, heading, speed]]), inputs, DT)
    region = fleet.swept_regions(idx, traj, 1, barrier, FcbfParams(v0=0.5))[0].ellipses
    corners = rect_corners(fleet.footprints(idx, traj[:, :2]))[0].reshape(-1, 2)
    hull = convex_hull(corners)
    cx, cy, a, b, phi = region[0]
    assert np.all(ellipse_signed_distance(hull, cx, cy, a, b, phi) <= 1e-9)
    assert np.all(barrier_value(hull[:, 0], hull[:, 1], cx, cy, np.cos(phi), np.sin(phi), a**-2, b**-2) <= 1e-9)


@settings(max_examples=60, deadline=None)
@given(points=st.lists(st.tuples(coord, coord), min_size=3, max_size=12), theta=st.floats(-np.pi, np.pi))
def test_containing_ellipse_contains_every_point_and_is_tight(points, theta):
    pts = np.array(points)
    cx, cy, a, b, phi = containing_ellipse(pts, theta)
    q = barrier_value(pts[:, 0], pts[:, 1], cx, cy, np.cos(phi), np.sin(phi), a**-2, b**-2) + 1.0
    assert np.all(q <= 1.0)
    spread = np.ptp(pts @ np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]]), axis=0)
    if np.all(spread > 1e-6):
        assert q.max() == pytest.approx(1.0, rel=1e-6)  # scaled until the farthest point is on it



@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 12), stages=st.integers(1, 12))
def test_compiled_swept_hull_ellipses_are_the_numpy_definition_bit_for_bit(seed, m, stages):
    """The compiled ellipse round the footprints at stages k and k+1 is containing_ellipse of
    their eight rect_corners, the same numbers."""
    rng = np.random.default_rng(seed)
    rows = np.concatenate([rng.uniform(-10, 10, (m, stages + 1, 2)), rng.uniform(0.1, 5.0, (m, stages + 1, 2)),
                           rng.uniform(-7, 7, (m, stages + 1, 1))], axis=2)
    theta = rng.uniform(-7, 7, (m, stages))
    corners = rect_corners(rows)
    expected = containing_ellipse(np.concatenate([corners[:, :-1], corners[:, 1:]], axis=2), theta)
    np.testing.assert_array_equal(swept_hull_ellipses(rows, theta), expected)

# --- proximity decision -----------------------------------------------------------------------

PROX = ProximityParams(iterations=40, alpha=1.0, beta=3.0, step=0.3, sample_radius=3.0, collision_radius=1.0)


def boxed_in_case():
    """Two robots queue for the same way north: robot 0 in front has open ground ahead; robot 1,
    1 m behind it, has robot 0 in front and debris on both sides."""
    starts = np.array([[0.0, 0.0], [0.0, -1.0]])
    goals = np.array([[0.0, 5.0], [0.0, 4.0]])
    blockers = np.vstack([starts, [[-1.0, -1.0], [1.0, -1.0]]])
    radius = np.array([1.0, 1.0, 1.2, 1.2])
    owner = np.array([0, 1, -1, -1])
    return starts, goals, blockers, radius, owner


def test_proximity_decision_picks_the_unobstructed_robot():
    for seed in range(5):
        result = proximity_decision(*boxed_in_case(), PROX, np.random.default_rng(seed))
        assert result.winner == 0
        assert result.progress[0] > result.progress[1] + 0.5


def test_proximity_decision_is_deterministic_for_a_seed():
    a = proximity_decision(*boxed_in_case(), PROX, np.random.default_rng(7))
    b = proximity_decision(*boxed_in_case(), PROX, np.random.default_rng(7))
    c = proximity_decision(*boxed_in_case(), PROX, np.random.default_rng(8))
    np.testing.assert_array_equal(a.scores, b.scores)
    np.testing.assert_array_equal(a.best_nodes, b.best_nodes)
    assert not np.array_equal(a.best_nodes, c.best_nodes)


def test_tree_steps_never_exceed_the_step_length_from_the_start():
    result = proximity_decision(*boxed_in_case(), PROX, np.random.default_rng(0))
    starts = boxed_in_case()[0]
    assert np.all(np.hypot(*(result.best_nodes - starts).T) <= PROX.iterations * PROX.step + 1e-9)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 100_000), step=st.floats(0.1, 3.0))
def test_compiled_trees_grow_as_the_nearest_node_rule_says(seed, step):
    """Each new node steps at most ``step`` from the tree node nearest its sample (the first on
    ties) towards the sample, and its path cost is its parent's plus ``(1 - d / r)^2`` summed
    over the blockers foreign to its tree that are within their radius: the rule written out
    with numpy, one iteration at a time."""
    from aac_sumo.kernels.proximity import grow_trees

    rng = np.random.default_rng(seed)
    r_count, k, m = 3, 25, 7
    starts, samples = rng.uniform(-5, 5, (r_count, 2)), rng.uniform(-8, 8, (r_count, k, 2))
    samples[:, 3] = samples[:, 2]  # a repeated sample: ties between nodes
    blockers, radius = rng.uniform(-5, 5, (m, 2)), rng.uniform(0.5, 3.0, m)
    foreign = rng.random((r_count, m)) < 0.7
    nodes, cost = grow_trees(starts, samples, blockers, radius, foreign, step)

    rows = np.arange(r_count)
    want, want_cost = np.empty_like(nodes), np.zeros_like(cost)
    want[:, 0] = starts
    for it in range(k):
        rel = samples[:, it, None, :] - want[:, : it + 1]
        near = np.argmin(np.einsum("rkc,rkc->rk", rel, rel), axis=1)
        towards = samples[:, it] - want[rows, near]
        length = np.hypot(*towards.T)
        new = want[rows, near] + np.where(length > step, step / np.maximum(length, 1e-12), 1.0)[:, None] * towards
        gap = np.hypot(*(new[:, None, :] - blockers[None]).transpose(2, 0, 1))
        want[:, it + 1] = new
        want_cost[:, it + 1] = want_cost[rows, near] + (np.clip(1.0 - gap / radius, 0.0, None) ** 2 * foreign).sum(axis=1)
    np.testing.assert_allclose(nodes, want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cost, want_cost, rtol=1e-12, atol=1e-12)



@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 100_000))
def test_blockers_out_of_every_trees_reach_change_no_cost_to_the_bit(seed):
    """A blocker farther than its radius from every point a tree can grow to adds nothing: the
    trees and their costs are those grown without it, exactly."""
    from aac_sumo.kernels.proximity import grow_trees

    rng = np.random.default_rng(seed)
    starts, samples = rng.uniform(-5, 5, (3, 2)), rng.uniform(-8, 8, (3, 25, 2))
    blockers, radius = rng.uniform(-5, 5, (7, 2)), rng.uniform(0.5, 3.0, 7)
    far = np.column_stack([rng.uniform(12, 40, 20) * rng.choice([-1, 1], 20), rng.uniform(-40, 40, 20)])
    foreign = rng.random((3, 27)) < 0.7
    near = grow_trees(starts, samples, blockers, radius, foreign[:, :7], 0.7)
    both = grow_trees(starts, samples, np.vstack([blockers, far]), np.r_[radius, np.full(20, 3.0)], foreign, 0.7)
    np.testing.assert_array_equal(near[0], both[0])
    np.testing.assert_array_equal(near[1], both[1])

# --- AAC: round robin, candidates, safety stop ------------------------------------------------


def far_apart_world(n: int = 4) -> tuple[WorldState, list[PathReference]]:
    states = np.array([[0.0, 6.0 * i, 0.0, 0.5] for i in range(n)])
    goals = np.array([[30.0, 6.0 * i] for i in range(n)])
    return WorldState(0.0, states, [robot(i) for i in range(n)]), straight_tasks(states, goals)


def step_world(world: WorldState, inputs: np.ndarray) -> WorldState:
    states = np.array([r.model.step(s, u, DT) for r, s, u in zip(world.robots, world.states, inputs)])
    return WorldState(world.t + DT, states, world.robots, world.obstacles)


def test_round_robin_gives_every_unfinished_robot_authority_in_turn():
    world, tasks = far_apart_world(4)
    finished = lambda w: np.array([False, False, True, False])  # robot 2 has arrived
    for commit in (False, True):
        aac = AacCoordinator(planner(), tasks, finished=finished, params=AacParams(close_distance=2.0, commit=commit))
        holders, state = [], world
        for _ in range(6):
            decision = aac.decide(state)
            holders.append([i for i, r in enumerate(decision.robots) if r.authority])
            assert all(r.reason == "round_robin" for r in decision.robots if r.authority)
            # without commitments it brakes at once; with them it brakes on its stopping tail, then holds
            assert decision.robots[2].mode in (("tail", "hold") if commit else ("hold",))
            assert decision.inputs[2, 0] <= 0.0 and not decision.robots[2].authority
            state = step_world(state, decision.inputs)
        assert holders == [[0], [1], [3], [0], [1], [3]]


def test_close_pair_candidates_get_scores_and_one_wins():
    states = np.array([[0.0, 0.0, 0.0, 0.5], [0.0, 1.0, -np.pi / 2, 0.5], [0.0, 20.0, 0.0, 0.5]])
    goals = np.array([[5.0, 0.0], [0.0, -4.0], [30.0, 20.0]])
    world = WorldState(0.0, states, [robot(i) for i in range(3)])
    aac = AacCoordinator(planner(), straight_tasks(states, goals), params=AacParams(close_distance=1.5, proximity=PROX))
    decision = aac.decide(world)
    holders = [i for i, r in enumerate(decision.robots) if r.authority]
    assert holders == [0] and decision.robots[0].reason == "proximity"
    assert decision.robots[0].score is not None and decision.robots[1].score is not None
    assert decision.robots[2].score is None  # not in a close pair
    assert decision.notes["authority"] == "robot0"


@pytest.mark.parametrize("length,to_goal,extra,shift", [
    (16.0, 8.0, 0.0, 2.5), (16.0, 5.625, 0.0, 1.25), (16.0, 3.75, 0.0, 0.0),  # a long path: whole from 3, gone at 1.5 shifts from the goal
    (16.0, 7.875, 1.0, 1.75),                                                 # a grown shift (3.5 m) fades out over 10.5 to 5.25 m
    (8.0, 6.0, 0.0, 2.5), (8.0, 4.0, 0.0, 1.25), (8.0, 3.0, 0.0, 0.0),        # a short path: whole from 5/8, gone at 3/8 of its length
    (8.0, 5.6, 1.0, 1.75),                                                    # and a grown shift over 7 to 4.2 m
])
def test_keep_right_fades_out_before_the_goal_in_shifts_shrunk_on_short_paths(length, to_goal, extra, shift):
    """With another robot 2 m ahead, a robot's reference moves keep_right (2.5 m, plus what it
    grew in a jam) to the right, fading out linearly as its goal nears: between 3 and 1.5 shifts
    before it; on a path too short for keep_right's fade to begin and end by 5/8 and 3/8 of the
    path before the goal, the distances shrink in proportion (an 8 m path: 5 and 3 m with
    keep_right alone, so the shift is 1.25 m at the path's middle, where a circle swap's crowd
    meets)."""
    states = np.array([[0.0, 0.0, 0.0, 0.0], [length - to_goal + 2.0, 0.0, np.pi, 0.0]])
    tasks = straight_tasks(np.array([[0.0, 0.0, 0.0, 0.0], [30.0, 0.0, np.pi, 0.0]]), np.array([[length, 0.0], [-30.0, 0.0]]))
    aac = AacCoordinator(planner(), tasks, params=AacParams(keep_right=2.5))
    aac.extra_shift[0] = extra
    states[0, 0] = length - to_goal
    world = WorldState(0.0, states, [robot(i) for i in range(2)])
    assert aac.keep_right_shift(world, 0) == pytest.approx(shift)
    reference = aac.reference(world, 0)
    assert reference[:, 1] == pytest.approx(np.full(len(reference), -shift))


@pytest.mark.parametrize("enabled", [True, False])
def test_safety_stop_brakes_a_robot_heading_into_another(enabled):
    """Robot 2 drives at 1 m/s on its tracking law toward robot 1, which stands 0.3 m ahead
    (bumper to bumper): one more period at speed plus 0.25 m of braking would hit it. Robot 0,
    far away, holds authority. With the safety stop, robot 2 brakes and it is counted."""
    states = np.array([[0.0, 20.0, 0.0, 0.0], [0.9, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    goals = np.array([[10.0, 20.0], [10.0, 0.5], [10.0, 0.0]])
    world = WorldState(0.0, states, [robot(i) for i in range(3)])
    aac = AacCoordinator(planner(), straight_tasks(states, goals), params=AacParams(close_distance=0.5, safety_stop=enabled, safety_margin=0.05, commit=False))
    decision = aac.decide(world)
    assert decision.robots[0].authority
    if enabled:
        assert decision.robots[2].mode == "safety_stop"
        assert decision.notes["safety_stops"] == sum(r.mode == "safety_stop" for r in decision.robots)
        assert decision.inputs[2, 0] == pytest.approx(LIMITS.a_min)
    else:
        assert decision.robots[2].mode == "tracking" and decision.notes["safety_stops"] == 0
        assert decision.inputs[2, 0] > LIMITS.a_min


AXES = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])  # the four axis-aligned headings, as unit vectors


def box_gap(a, b) -> float:
    """Signed clearance [m] of two axis-aligned boxes ``(cx, cy, half_x, half_y)``, in closed
    form: the Euclidean gap when apart, minus the smaller penetration when they overlap."""
    gx, gy = abs(a[0] - b[0]) - a[2] - b[2], abs(a[1] - b[1]) - a[3] - b[3]
    return max(gx, gy) if gx < 0.0 and gy < 0.0 else float(np.hypot(max(gx, 0.0), max(gy, 0.0)))


def straight_course(v0: float, first: float, stages: int, comfort: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance [m] covered (stages+1,) and speed of a robot driving straight on the model's Euler
    steps: ``first`` [m/s^2] for one period (None: braking already), then braking at ``comfort``
    [m/s^2] but never below standstill, its speed kept in [0, v_max]."""
    s, v = np.zeros(stages + 1), np.zeros(stages + 1)
    v[0] = v0
    for k in range(stages):
        a = first if (k == 0 and first is not None) else min(max(-v[k] / DT, -comfort), LIMITS.a_max)
        s[k + 1], v[k + 1] = s[k] + v[k] * DT, min(max(v[k] + a * DT, LIMITS.v_min), LIMITS.v_max)
    return s, v


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 100_000), margin=st.floats(0.0, 1.0))
def test_safety_check_flags_exactly_what_its_definition_says(seed, margin):
    """An independent oracle of the check, on robots that drive along the axes (headings 0, 90,
    180, 270 degrees, braking straight on), so that every course is closed-form 1-D kinematics
    and every footprint an axis-aligned box: robot i must brake when, at some stage k >= 1 of its
    course (its input once, then braking at its comfort deceleration), its gap to some target is
    below ``margin`` and below, by more than ``BRAKING_TIE``, both its gap now and the gap
    braking at once would leave at stage k. Targets: every other robot on its course and braking
    at once, a cone that counts only within ``STANDING_GAP``, a cart moving at constant velocity,
    and a standing walker whose box grows by the pedestrian margin plus her reach times the time,
    counting only until robot i's course stands. Stages run until the fastest robot could have
    stopped, plus two."""
    rng = np.random.default_rng(seed)
    n, comfort = 4, -LIMITS.a_min
    robots = [robot(i) for i in range(n)]
    axis = rng.integers(0, 4, n)
    states = np.column_stack([rng.uniform(-2.5, 2.5, (n, 2)), axis * np.pi / 2, rng.uniform(0, LIMITS.v_max, n)])
    accel = rng.uniform(LIMITS.a_min, LIMITS.a_max, n)
    cart_velocity = rng.uniform(-1, 1, 2)
    obstacles = [Obstacle("cone", "cone", rng.uniform(-2, 2, 2), np.zeros(2), 0.0, 0.3, 0.3),
                 Obstacle("walker", "pedestrian", rng.uniform(-2, 2, 2), np.zeros(2), 0.0, 0.3, 0.5),
                 Obstacle("cart", "scripted", rng.uniform(-2, 2, 2), cart_velocity, 0.0, 0.8, 0.5)]
    config = MpcConfig(dt=DT, pedestrian_reach=1.0, pedestrian_margin=0.2)
    check = SafetyCheck(WorldState(0.0, states, robots, obstacles), Fleet(robots), config, states[:, 2], np.zeros(n))
    got = check.unsafe(np.arange(n), np.column_stack([accel, np.zeros(n)]), margin)

    stages = int(np.ceil(states[:, 3].max() / comfort / DT)) + 2
    k = np.arange(stages + 1)

    def boxes(i, first):  # robot i's footprint boxes (stages+1, 4) along its course
        s, _ = straight_course(states[i, 3], first, stages, comfort)
        centre = states[i, :2] + np.outer(s + robots[i].centre_offset, AXES[axis[i]])
        half = np.abs(AXES[axis[i]]) * robots[i].length / 2 + np.abs(AXES[axis[i]][::-1]) * robots[i].width / 2
        return np.column_stack([centre, np.tile(half, (stages + 1, 1))])

    course = [boxes(i, accel[i]) for i in range(n)]
    braking = [boxes(i, None) for i in range(n)]
    cone, walker, cart = (np.tile([*o.centre, o.length / 2, o.width / 2], (stages + 1, 1)) for o in obstacles)
    walker[:, 2:] += (config.pedestrian_margin + config.pedestrian_reach * DT * k)[:, None]
    cart[:, :2] += DT * k[:, None] * cart_velocity
    expected = np.zeros(n, dtype=bool)
    for i in range(n):
        moved = [s for s in range(1, stages + 1) if np.any(course[i][s, :2] != course[i][s - 1, :2])]
        targets = [(t, margin, stages) for j in range(n) if j != i for t in (course[j], braking[j])]
        targets += [(cone, min(margin, STANDING_GAP), stages), (cart, margin, stages), (walker, margin, moved[-1] if moved else 0)]
        for target, within, last in targets:
            now = box_gap(course[i][0], target[0])
            for s in range(1, last + 1):
                later = box_gap(course[i][s], target[s])
                if later < within and later < now - BRAKING_TIE and later < box_gap(braking[i][s], target[s]) - BRAKING_TIE:
                    expected[i] = True
    event(f"flagged {int(expected.sum())} of {n}")
    np.testing.assert_array_equal(got, expected)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 100_000), margin=st.floats(0.0, 1.0))
def test_safe_inputs_are_the_gentlest_braking_that_passes_the_check(seed, margin):
    """The compiled stop equals its definition in rounds: robots that pass keep their inputs;
    a flagged robot coasts, then brakes with a third and two thirds of its strongest braking
    (never harder than it meant to), each time checked again with the others' new inputs
    (once it passes it keeps that input), and brakes fully if it never passes; a robot that
    must stop before a walker's path brakes at least as hard as that needs."""
    rng = np.random.default_rng(seed)
    n = 6
    robots = [robot(i) for i in range(n)]
    states = np.column_stack([rng.uniform(-3, 3, (n, 2)), rng.uniform(-np.pi, np.pi, n), rng.uniform(0, LIMITS.v_max, n)])
    obstacles = [Obstacle("walker", "pedestrian", rng.uniform(-2, 2, 2), rng.uniform(-1, 1, 2), 0.0, 0.3, 0.5)]
    check = SafetyCheck(WorldState(0.0, states, robots, obstacles), Fleet(robots), MpcConfig(dt=DT, pedestrian_reach=1.0),
                        rng.uniform(-np.pi, np.pi, n), np.zeros(n))
    inputs = np.column_stack([rng.uniform(LIMITS.a_min, LIMITS.a_max, n), rng.uniform(-0.6, 0.6, n)])
    checked = np.sort(rng.choice(n, size=int(rng.integers(1, n + 1)), replace=False))
    got = check.safe_inputs(checked, inputs, margin)

    steer = check.braking_steer(states)
    expected = inputs.copy()
    flagged = check.unsafe(checked, expected, margin)
    for share in (0.0, 1 / 3, 2 / 3):
        if not flagged.any():
            break
        for i in checked[flagged]:
            expected[i] = [min(inputs[i, 0], share * LIMITS.a_min), steer[i]]
        flagged &= check.unsafe(checked, expected, margin)
    for i in checked[flagged]:
        expected[i] = [LIMITS.braking_input(states[i, 3], DT)[0], steer[i]]
    stops = check.walker_stops(checked, inputs)
    for i in np.flatnonzero(np.isfinite(stops)):
        brake = LIMITS.braking_input(states[i, 3], DT, stops[i])[0]
        if brake < expected[i, 0]:
            expected[i] = [brake, steer[i]]
    np.testing.assert_array_equal(got, expected)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 100_000), stages=st.integers(1, 6))
def test_fleet_footprints_are_the_worlds_footprints_at_every_stage(seed, stages):
    """The compiled footprint rows of robots along trajectories are, stage by stage, what the
    world reports for robots at those states (centre ahead of the rear axle, size, heading)."""
    rng = np.random.default_rng(seed)
    n = 4
    robots = [RobotSpec(f"r{i}", rng.uniform(0.5, 5), rng.uniform(0.3, 2), BicycleModel(rng.uniform(0.2, 0.4), LIMITS)) for i in range(n)]
    traj = np.concatenate([rng.uniform(-9, 9, (n, stages, 2)), rng.uniform(-7, 7, (n, stages, 1)), rng.uniform(0, 5, (n, stages, 1))], axis=2)
    idx = rng.permutation(n)
    rows = Fleet(robots).footprints(idx, traj)
    for k in range(stages):
        world = WorldState(0.0, traj[:, k], [robots[i] for i in idx])
        np.testing.assert_array_equal(rows[:, k], world.robot_footprints())


def test_safety_stop_keeps_a_car_from_creeping_into_a_crossing_walker():
    """A car (4 m x 1.8 m) stands 0.48 m from a walker who crosses in front of it, inside her
    grown region (margin 1 m, reach 1.5 m/s), as in a 15-car LFC run that collided. Late in
    any course her region swallows the car whatever it does; driving on is still closer than
    standing at the earlier stages, so it is flagged, and standing still is not. (Comparing
    only the two courses' closest approaches let the car creep into her.)"""
    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0)
    car = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, limits))
    walker = Obstacle("walker", "pedestrian", np.array([4.04, 0.43]), np.array([0.0, -1.16]), -np.pi / 2, 0.3, 0.5)
    far = np.array([0.0, 100.0, 0.0, 10.0])  # a car at 10 m/s far away: the courses last 1.9 s
    world = WorldState(0.0, np.array([[0.0, 0.0, 0.0, 0.0], far]), [car, car], [walker])
    check = SafetyCheck(world, Fleet([car, car]), MpcConfig(dt=DT, pedestrian_reach=1.5, pedestrian_margin=1.0), np.zeros(2), np.zeros(2))
    assert check.unsafe(np.array([0]), np.array([[3.0, 0.0], [0.0, 0.0]]), 0.3).tolist() == [True]
    assert check.unsafe(np.array([0]), np.array([[0.0, 0.0], [0.0, 0.0]]), 0.3).tolist() == [False]


def test_a_car_stopped_within_the_margin_of_a_cone_may_creep_away_but_not_into_it():
    """A car (4 m x 1.8 m) stands pointing 35 degrees to the right of its lane, its front 0.25 m
    from a cone, as in a 15-car AAC run that deadlocked there: it does not reverse, so it can
    only leave forwards, turning left and coming a little closer to the cone first. A cone
    cannot come at it, so it counts only within ``STANDING_GAP``: creeping away passes the check within the
    0.3 m margin, and the same car at 3 m/s, which cannot stop short of the cone, is flagged."""
    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0)
    car = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, limits))
    heading = -0.615
    ahead = np.array([np.cos(heading), np.sin(heading)])
    nose = (car.centre_offset + 2.0) * ahead  # the middle of the front bumper, from the rear axle
    cone = Obstacle("cone", "cone", nose + (0.25 + 0.2) * ahead, np.zeros(2), heading, 0.4, 0.4)
    for speed, flagged in ((0.0, False), (3.0, True)):
        world = WorldState(0.0, np.array([[0.0, 0.0, heading, speed]]), [car], [cone])
        check = SafetyCheck(world, Fleet([car]), MpcConfig(dt=DT), np.zeros(1), np.zeros(1))
        assert check.unsafe(np.array([0]), np.array([[3.0 if speed == 0.0 else 0.0, 0.33]]), 0.3).tolist() == [flagged]


def test_the_safety_stop_halts_a_car_short_of_a_cone_not_in_contact():
    """A car at 4.8 m/s on a cone's lane, 3 m from it, in the safety stop on every period
    (stress run 443 at 1157803 stopped 0.9 mm from a cone, which SUMO, measuring along the lane,
    counted as a collision): it brakes, harder than comfort at the end, and stands at least
    ``STANDING_GAP`` short of the cone, never in contact."""
    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0, a_comfort=3.0)
    car = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, limits))
    nose = car.centre_offset + 2.0
    cone = Obstacle("cone", "cone", np.array([nose + 3.0 + 0.2, 0.0]), np.zeros(2), 0.0, 0.4, 0.4)
    state, config = np.array([0.0, 0.0, 0.0, 4.8]), MpcConfig(dt=DT)
    for _ in range(60):
        world = WorldState(0.0, state[None, :], [car], [cone])
        check = SafetyCheck(world, Fleet([car]), config, np.zeros(1), np.zeros(1))
        accel, steer = check.safe_inputs(np.array([0]), np.array([[0.0, 0.0]]), 0.3)[0]
        state = car.model.step(state, np.array([accel, steer]), DT)
    gap = cone.centre[0] - 0.2 - (state[0] + nose)
    assert state[3] == 0.0 and STANDING_GAP - 1e-9 <= gap < 0.3


def test_a_car_closing_from_behind_is_a_follower_not_a_reason_to_brake():
    """Which uncontrolled vehicles a robot at 16 m/s leaves to keep their distance: a car 30 m
    behind in its lane at 18 m/s, and ones 60 m and 12 m behind in the next lane; not a car
    ahead, one behind driving the other way, or a walker. On
    the work-zone highway, a car 71 m behind in the lane a robot moved into, predicted at
    constant velocity over a 7 s stopping course, made the robot brake at 6 m/s^2."""
    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0)
    car = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, limits))
    state = np.array([[0.0, 0.0, 0.0, 16.0]])
    config = MpcConfig(dt=DT)
    assert not SafetyCheck(WorldState(0.0, state, [car], [Obstacle("bg", "scripted", np.array([-30.0, 0.3]), np.array([18.0, 0.0]),
                                                                   0.0, 4.5, 1.8)]), Fleet([car]), config, np.zeros(1), np.zeros(1)).ignored.any()
    cases = [(Obstacle("behind", "scripted", np.array([-30.0, 0.3]), np.array([18.0, 0.0]), 0.0, 4.5, 1.8), True),
             (Obstacle("room", "scripted", np.array([-60.0, 3.5]), np.array([18.0, 0.0]), 0.0, 4.5, 1.8), True),
             (Obstacle("close", "scripted", np.array([-12.0, 3.5]), np.array([20.0, 0.0]), 0.0, 4.5, 1.8), True),
             (Obstacle("ahead", "scripted", np.array([30.0, 0.0]), np.array([10.0, 0.0]), 0.0, 4.5, 1.8), False),
             (Obstacle("oncoming", "scripted", np.array([-70.0, 0.0]), np.array([-18.0, 0.0]), np.pi, 4.5, 1.8), False),
             (Obstacle("walker", "pedestrian", np.array([-10.0, 0.0]), np.array([1.0, 0.0]), 0.0, 0.3, 0.5), False)]
    for other, follows in cases:
        check = SafetyCheck(WorldState(0.0, state, [car], [other]), Fleet([car]), config, np.zeros(1), np.zeros(1), followers=True)
        assert check.ignored[0, 2] == follows, other.name


# --- LFC --------------------------------------------------------------------------------------


class RecordingPlanner(MpcPlanner):
    """The real planner, remembering the order of its calls and the regions it was given."""

    def __init__(self, config):
        super().__init__(config)
        self.calls = []

    def plan(self, robot, state, reference, u_prev, obstacles, previous=None, corridor=None):
        self.calls.append((robot.name, {getattr(o, "name", None): o for o in obstacles}))
        return super().plan(robot, state, reference, u_prev, obstacles, previous, corridor)


def test_lfc_plans_in_index_order_around_the_plans_made_before():
    states = np.array([[0.0, 0.0, 0.0, 1.0], [2.0, -1.5, np.pi / 2, 1.0], [4.0, 1.5, -np.pi / 2, 1.0]])
    goals = np.array([[8.0, 0.0], [2.0, 4.0], [4.0, -4.0]])
    world = WorldState(0.0, states, [robot(i) for i in range(3)])
    pl = RecordingPlanner(planner().config)
    lfc = LfcCoordinator(pl, straight_tasks(states, goals))
    decision = lfc.decide(world)
    assert [name for name, _ in pl.calls] == ["robot0", "robot1", "robot2"]
    assert all(r.authority and r.reason == "priority" for r in decision.robots)
    fleet = Fleet(world.robots)
    for i, (_, seen) in enumerate(pl.calls):
        for j in range(i):  # leaders: their plan of this period, swept
            plan = lfc.plans[j].states
            traj = np.vstack([plan, fleet.rollout(np.array([j]), plan[None, -1], np.zeros((1, 1, 2)), DT)[0, -1:]])
            expected = fleet.swept_regions(np.array([j]), traj[None], 5, "fcbf", FcbfParams(v0=0.5))[0].ellipses
            np.testing.assert_allclose(seen[f"robot{j}"].ellipses, expected)
        for j in range(i + 1, 3):  # followers: their current motion
            cv = fleet.rollout(np.array([j]), states[[j]], np.zeros((1, 6, 2)), DT)
            expected = fleet.swept_regions(np.array([j]), cv, 5, "fcbf", FcbfParams(v0=0.5))[0].ellipses
            np.testing.assert_allclose(seen[f"robot{j}"].ellipses, expected)


def hemmed_in_world() -> tuple[WorldState, list[PathReference]]:
    """Robot 0 stands 0.12 m beside a cone, well inside its MPC region (the solve must fail),
    with an open lane ahead; robot 1 is far away."""
    states = np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 30.0, 0.0, 0.5]])
    goals = np.array([[10.0, 0.0], [10.0, 30.0]])
    cone = Obstacle("cone", "cone", np.array([0.225, 0.42]), np.zeros(2), 0.0, 0.2, 0.2)
    return WorldState(0.0, states, [robot(i) for i in range(2)], [cone]), straight_tasks(states, goals)


@pytest.mark.parametrize("fallback", ["brake", "tracking"])
def test_a_robot_whose_solve_fails_brakes_or_tracks(fallback):
    """Both coordinators: a failed solve is counted as such; with the braking fallback the robot
    stays put, with the tracking fallback it applies the tracking law, which the safety stop
    passes here (driving along the cone does not bring the footprints closer)."""
    world, tasks = hemmed_in_world()
    lfc = LfcCoordinator(planner(), tasks, params=LfcParams(safety_stop=True, safety_margin=0.05, fallback=fallback, lookahead=1.0))
    aac = AacCoordinator(planner(), tasks, params=AacParams(close_distance=0.5, safety_stop=True, safety_margin=0.05, fallback=fallback, commit=False))
    for decision in (lfc.decide(world), aac.decide(world)):
        assert decision.robots[0].authority and decision.robots[0].status in ("infeasible", "failed")
        if fallback == "brake":
            assert decision.robots[0].mode == "mpc" and decision.inputs[0, 0] == 0.0
        else:
            assert decision.robots[0].mode == "tracking"
            np.testing.assert_allclose(decision.inputs[0], track(world.robots[0], world.states[0], tasks[0], 1.0, 1.0, 0.0, DT))
            assert decision.inputs[0, 0] > 0.0


def test_the_tracking_fallback_needs_the_safety_stop():
    with pytest.raises(ValueError):
        LfcParams(safety_stop=False, fallback="tracking")
    with pytest.raises(ValueError):
        AacParams(safety_stop=False, fallback="tracking")


@settings(max_examples=60, deadline=None)
@given(angle=st.floats(-np.pi, np.pi), shift=st.tuples(coord, coord))
def test_straight_behind_is_the_same_in_every_frame(angle, shift):
    """Robot 0 drives along +x; behind it in its lane (1), beside it (2), ahead (3), behind in
    the next lane (4), just touching its rear bumper (5). Only 1 is straight behind, however
    the scene is rotated and moved."""
    local = np.array([[0.0, 0.0], [-1.0, 0.1], [0.0, 0.5], [1.0, 0.0], [-1.0, 0.5], [-0.55, 0.0]])
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    states = np.column_stack([local @ rot.T + np.array(shift), np.full(6, angle), np.zeros(6)])
    world = WorldState(0.0, states, [robot(i) for i in range(6)])
    assert straight_behind(world, Fleet(world.robots), 0, np.arange(1, 6)).tolist() == [True, False, False, False, False]


@pytest.mark.parametrize("ignore", [False, True])
def test_the_authority_may_leave_its_follower_to_the_safety_stop(ignore):
    """With ignore_followers, AAC's authority plans without the region of the robot straight
    behind it; the robot beside it is still avoided."""
    states = np.array([[0.0, 0.0, 0.0, 1.0], [-1.0, 0.0, 0.0, 1.0], [0.0, 0.6, 0.0, 1.0]])
    goals = np.array([[10.0, 0.0], [10.0, 0.0], [10.0, 0.6]])
    world = WorldState(0.0, states, [robot(i) for i in range(3)])
    pl = RecordingPlanner(planner().config)
    aac = AacCoordinator(pl, straight_tasks(states, goals), params=AacParams(close_distance=0.1, safety_stop=True, ignore_followers=ignore, commit=False))
    aac.decide(world)
    (name, seen), = pl.calls
    assert name == "robot0" and "robot2" in seen
    assert ("robot1" in seen) is not ignore
    with pytest.raises(ValueError):
        AacParams(safety_stop=False, ignore_followers=True)


# --- fairness metric --------------------------------------------------------------------------


def test_authority_jain_is_one_for_pure_round_robin():
    world, tasks = far_apart_world(4)
    aac = AacCoordinator(planner(), tasks, params=AacParams(close_distance=2.0))
    rows = []
    for _ in range(12):
        decision = aac.decide(world)
        rows += [dict(t=world.t, robot=r.name, authority=d.authority, arrived=False) for r, d in zip(world.robots, decision.robots)]
        world = step_world(world, decision.inputs)
    assert authority_jain(pd.DataFrame(rows)) == pytest.approx(1.0)


def test_authority_jain_counts_only_unfinished_robots():
    """Robot b arrives after two periods; from then on a alone is due all authority."""
    rows = [dict(t=0, robot="a", authority=True, arrived=False), dict(t=0, robot="b", authority=False, arrived=False),
            dict(t=1, robot="a", authority=False, arrived=False), dict(t=1, robot="b", authority=True, arrived=False),
            dict(t=2, robot="a", authority=True, arrived=False), dict(t=2, robot="b", authority=False, arrived=True),
            dict(t=3, robot="a", authority=True, arrived=False), dict(t=3, robot="b", authority=False, arrived=True)]
    assert authority_jain(pd.DataFrame(rows)) == pytest.approx(1.0)
    rows[1]["authority"], rows[3]["authority"] = False, False  # b never got its turns
    rows[2]["authority"] = True
    assert authority_jain(pd.DataFrame(rows)) < 0.6


HIGHWAY_LIMITS = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
HIGHWAY_CAR = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, HIGHWAY_LIMITS))
WALKERS = MpcConfig(dt=DT, pedestrian_reach=1.5, pedestrian_margin=1.0)


def drive_past_walker(front: float, north: float, speed: float = 16.0, walk: float = 1.3, seconds: float = 12.0, accel: float = 0.0,
                      config: MpcConfig = WALKERS):
    """A car (4 m x 1.8 m, a_comfort 3, a_min -6 m/s^2) in a lane along y = -1.75 m heading
    east at ``speed``, its front ``front`` metres before x = 0 [m], meant to drive on (input
    ``accel`` [m/s^2] every period, up to 16 m/s), through the safety stop (the planner's
    ``config``); a walker (0.3 m x 0.5 m) crossing at x = 0 from
    ``north`` [m] south at ``walk`` [m/s], as in the highway's seed 4. Returns the car's states
    (K+1, 4), the applied accelerations (K,) and the walker's centres (K+1, 2)."""
    state = np.array([-front - HIGHWAY_CAR.centre_offset - 2.0, -1.75, 0.0, speed])
    walker, steer = np.array([0.0, north]), 0.0
    states, accels, walkers = [state], [], [walker]
    for k in range(int(round(seconds / DT))):
        person = Obstacle("p3", "pedestrian", walker, np.array([0.0, -walk]), -np.pi / 2, 0.3, 0.5)
        world = WorldState(k * DT, state[None, :], [HIGHWAY_CAR], [person])
        wanted = np.array([[min(accel, (16.0 - state[3]) / DT), 0.0]])
        u = SafetyCheck(world, Fleet([HIGHWAY_CAR]), config, np.zeros(1), np.array([steer])).safe_inputs(np.array([0]), wanted, 0.3)[0]
        steer = u[1]
        state = HIGHWAY_CAR.model.step(state, u, DT)
        walker = walker + DT * np.array([0.0, -walk])
        states.append(state), accels.append(u[0]), walkers.append(walker)
    return np.array(states), np.array(accels), np.array(walkers)


def test_a_car_stops_before_a_walker_who_sets_off_next_to_the_road_with_the_margin_braking_just_as_hard_as_needed():
    """The highway's seed 4: a walker sets off next to the road (her centre at y = 4.25 m, 6 m
    north of the car's lane centre) as a car at 16 m/s is 40 m before her path. Under the
    check's assumption (she may start towards it at 1.5 m/s) the car cannot pass, and it can stop
    before her path with the 1 m margin at v^2 / (2 (D - v dt / 2 - 6 dt^2 / 8)) = 3.38 m/s^2,
    D = 40 - 0.29 - 1 m (half her diagonal, the margin; the rest is the model's Euler steps): an
    emergency beyond its comfort 3 m/s^2, below its strongest 6. It brakes exactly so from the
    first period to standstill, along its lane (it never swerves), and stands with its front just
    outside her strip; before, the check braked it at 3 m/s^2, then 6, and it stood 0.4 m from
    her path."""
    states, accels, _ = drive_past_walker(40.0, 4.25)
    edge = -0.5 * np.hypot(0.3, 0.5) - 1.0  # her strip: half her diagonal and the margin
    need = 16.0**2 / (2.0 * (40.0 + edge - 0.5 * 16.0 * DT - 6.0 * DT**2 / 8))  # the model's Euler steps
    braking = accels[states[:-1, 3] > 1e-9]
    assert need == pytest.approx(3.38, abs=0.005)
    np.testing.assert_allclose(braking[:-1], -need, atol=1e-9)  # the last period only brakes what is left
    assert -braking[-1] <= need
    front = states[-1, 0] + HIGHWAY_CAR.centre_offset + 2.0
    assert states[-1, 3] == 0.0 and edge - 0.05 <= front <= edge
    assert np.ptp(states[:, 1]) == 0.0 and np.ptp(states[:, 2]) == 0.0


def test_a_walker_stop_comes_as_late_as_comfort_allows_and_ends_once_she_is_gone():
    """The same walker 80 m ahead of the car: it drives on until braking at its comfort
    deceleration (3 m/s^2) is just enough to stop before her path, then brakes at what it needs
    (no emergency), and drives on as soon as she has crossed its lane and its margin, walking
    away (she is not taken to turn back). A walker 20 m north, who cannot come within the
    margin of its lane before it has passed, does not stop it at all."""
    states, accels, walkers = drive_past_walker(80.0, 4.0)
    braking = np.flatnonzero(accels < 0.0)
    assert braking.size and -accels.min() <= HIGHWAY_LIMITS.a_comfort + 1e-9
    assert -accels[braking[0]] == pytest.approx(3.0, abs=0.1)  # it waited as long as its comfort braking allowed
    assert accels[braking[-1] + 1:].max(initial=0.0) == 0.0 and states[-1, 3] > 0.0  # then on its way again
    clear = -1.75 - 0.9 - 0.15 - 1.0  # her centre where she is beyond its lane and the margin (her half extent across: 0.15 m)
    assert walkers[braking[-1] + 1, 1] < clear <= walkers[braking[-1], 1] + 1e-9  # as soon as she was, not later
    assert states[:, 3].min() > 0.0  # it did not need to stand
    states, accels, _ = drive_past_walker(40.0, 20.0)
    assert np.all(accels == 0.0)


def test_with_a_comfort_envelope_a_walker_stop_starts_early_enough_to_brake_calmly():
    """The walker 80 m ahead again, with the planner's comfort envelope at 2 m/s^2
    (``controller.comfort_accel``, as in the lane change): the car starts braking as soon as
    braking at 2 m/s^2 is just enough, not at its 3 m/s^2 comfort deceleration, and stops no
    harder than that (the aggressive-driving threshold); 40 m ahead, too late for that, it
    still brakes just as hard as it needs (3.38 m/s^2)."""
    calm = MpcConfig(dt=DT, pedestrian_reach=1.5, pedestrian_margin=1.0, comfort_accel=2.0)
    states, accels, _ = drive_past_walker(80.0, 4.0, config=calm)
    braking = np.flatnonzero(accels < 0.0)
    assert braking.size and -accels.min() <= 2.0
    assert -accels[braking[0]] == pytest.approx(2.0, abs=0.1)
    _, late, _ = drive_past_walker(40.0, 4.25, config=calm)
    assert -late.min() == pytest.approx(3.38, abs=0.005)


def test_a_walker_who_has_crossed_and_walks_away_lets_a_car_go_on_every_reading():
    """The lane change's seed 4 at N = 10, at 26.7 s: veh11 at 1.4 m/s, its front 0.6 m before
    the strip of a walker who has just crossed its lane southwards, 2.8 m beyond it, at 0.97 to
    1.14 m/s step by step (SUMO). She walks away beyond the margin: she is not taken to turn
    back, so the car is let go on every reading, whatever her speeds of late
    (:class:`WalkerSpeeds`; when she could turn back at 1.5 m/s, the decision flipped from one
    reading to the next, and the car that was let go had to stop at 2.9 m/s^2)."""
    readings = [1.139, 1.064, 0.991, 1.104, 0.972, 0.992, 1.145]
    car = np.array([[233.53, -4.752, 0.0, 1.405]])
    calm = MpcConfig(dt=DT, pedestrian_reach=1.5, pedestrian_margin=1.0, comfort_accel=2.0)
    speeds = WalkerSpeeds()
    wanted = np.array([[1.5, 0.0]])
    for k, v in enumerate(readings):
        walker = Obstacle("p0", "pedestrian", np.array([238.76, -8.09 - 0.105 * k]), np.array([0.0, -v]), -np.pi / 2, 0.3, 0.5)
        world = WorldState(26.1 + k * DT, car, [HIGHWAY_CAR], [walker])
        bounds = speeds.update(world)
        for known in (None, bounds):
            check = SafetyCheck(world, Fleet([HIGHWAY_CAR]), calm, np.zeros(1), np.zeros(1), walker_speeds=known)
            assert not np.isfinite(check.walker_paths()[2][0, 0])  # not held before her path
            assert check.safe_inputs(np.array([0]), wanted, 0.3)[0, 0] == 1.5  # let go
    assert bounds["p0"] == (0.972, 1.145)


def test_a_cars_reference_stops_where_the_safety_stop_holds_it_before_a_walkers_path():
    """The lane change's seed 0 at N = 15, at 22.9 s: veh14 stands 0.37 m before the path of a
    walker who crossed its lane and walks away, still within the 1 m margin of it; the safety
    stop holds it before her path. (Its anticipated reference once ignored such a walker and its
    tracking law set off: its next solve braked at 2.8 m/s^2.) Held before her path
    (``hold_before_strips``), its reference creeps up to there and no further, and the law
    barely moves it."""
    config = MpcConfig(dt=DT, pedestrian_reach=1.5, pedestrian_margin=1.0, comfort_accel=2.0, comfort_lat=2.0)
    task = PathReference([[0.0, -4.85], [500.0, -4.85]], 10.0, stop_at_end=False)
    lfc = LfcCoordinator(MpcPlanner(config), [task], params=LfcParams(safety_stop=True, fallback="tracking", lookahead=10.0))
    lfc.anticipation, lfc.fleet = Anticipation(pedestrian_reach=1.5, pedestrian_margin=1.0), Fleet([HIGHWAY_CAR])
    walker = Obstacle("p0", "pedestrian", np.array([238.76, -6.72]), np.array([0.0, -1.06]), -np.pi / 2, 0.3, 0.5)
    world = WorldState(22.9, np.array([[233.80, -4.85, 0.0, 0.0]]), [HIGHWAY_CAR], [walker])
    safety = lfc.safety_check(world)
    room = safety.walker_paths()[2][0, 0]
    assert room == pytest.approx(0.37, abs=0.01)
    lfc.hold_before_strips(safety)
    ref = lfc.reference(world, 0)
    assert ref[-1, 0] - ref[0, 0] <= room + STRIP_OVERSHOOT and ref[-1, 3] < 0.1  # (the stages ramp in steps)
    assert lfc.tracking_speed(world, 0, 1.0) < 0.1


def test_a_stored_plan_brakes_at_least_as_the_anticipation_says():
    """AAC with stored plans (``commit = false``): a car at 1.7 m/s whose stored plan brakes at
    1 m/s^2, 2.4 m behind a standing car (within the 2 m standstill gap plus what the comfortable
    rate needs), brakes as its tracking law would (1.5 m/s^2, the anticipation's rate); at 7 m/s
    (70 % of its cruise speed) with the road ahead clear it keeps to its plan, which accelerates
    more gently than the law would."""
    config = MpcConfig(dt=DT, comfort_accel=2.0, comfort_lat=2.0)
    task = PathReference([[0.0, 0.0], [500.0, 0.0]], 10.0, stop_at_end=False)
    aac = AacCoordinator(MpcPlanner(config), [task], params=AacParams(commit=False, safety_stop=True, fallback="tracking",
                                                                      lookahead=10.0))
    aac.anticipation, aac.fleet = Anticipation(), Fleet([HIGHWAY_CAR])
    front = HIGHWAY_CAR.centre_offset + 0.5 * HIGHWAY_CAR.length
    ahead = Obstacle("veh7", "scripted", np.array([front + 2.4 + 2.0, 0.0]), np.zeros(2), 0.0, 4.0, 1.8)
    for obstacles, speed, plan_accel, wanted in [([ahead], 1.7, -1.0, -1.5), ([], 7.0, 0.5, 0.5)]:
        aac.plans[0] = Plan(np.zeros((6, 4)), np.tile([plan_accel, 0.0], (5, 1)), "solved", 0.0, "fatrop")
        aac.used[0] = 1
        state = np.array([[0.0, 0.0, 0.0, speed]])
        inputs, mode = aac.intended_inputs(WorldState(0.0, state, [HIGHWAY_CAR], obstacles), 0, False, 7)
        assert mode == "plan" and inputs[0, 0] == pytest.approx(wanted) and np.all(inputs[1:4, 0] == plan_accel)


@pytest.mark.parametrize("leader_speed, sets_off", [(0.0, False), (3.0, True)])
def test_a_car_in_a_stopped_queue_sets_off_with_its_leader_without_waiting_for_its_turn(leader_speed, sets_off):
    """AAC with stored plans: a car standing at its standstill gap (2 m) behind its leader holds a
    plan made while the leader stood (stand still). When the leader has set off at 3 m/s, the
    car (below 60 % of its cruise speed) drops that plan and its tracking law drives it off at
    once, at no more than the planner's comfort acceleration, as a queue of SUMO's drivers sets
    off together; while the leader still stands, it keeps standing on its plan."""
    config = MpcConfig(dt=DT, comfort_accel=2.0, comfort_lat=2.0)
    task = PathReference([[0.0, 0.0], [500.0, 0.0]], 10.0, stop_at_end=False)
    aac = AacCoordinator(MpcPlanner(config), [task], params=AacParams(commit=False, safety_stop=True, fallback="tracking",
                                                                      lookahead=10.0))
    aac.anticipation, aac.fleet = Anticipation(accel=2.0), Fleet([HIGHWAY_CAR])
    front = HIGHWAY_CAR.centre_offset + 0.5 * HIGHWAY_CAR.length
    leader = Obstacle("veh7", "scripted", np.array([front + 2.0 + 2.0, 0.0]), np.array([leader_speed, 0.0]), 0.0, 4.0, 1.8)
    aac.plans[0] = Plan(np.zeros((6, 4)), np.zeros((5, 2)), "solved", 0.0, "fatrop")
    aac.used[0] = 1
    world = WorldState(0.0, np.zeros((1, 4)), [HIGHWAY_CAR], [leader])
    inputs, mode = aac.intended_inputs(world, 0, False, 7)
    if sets_off:
        assert mode == "tracking" and 0.0 < inputs[0, 0] <= 2.0 + 1e-9
        assert aac.used[0] == len(aac.plans[0].inputs)  # the outrun plan is gone until its next turn
    else:
        assert mode == "plan" and inputs[0, 0] <= 0.0


@pytest.mark.parametrize("north, waits", [(4.0, True), (8.7, False)])
def test_a_car_standing_at_the_edge_of_a_walkers_path_goes_first_only_when_it_clears_her_path_in_time(north, waits):
    """The lane change's seed 3 at N = 15, at 13.5 s: veh14 has braked to stand with its front
    2 cm before the strip of a walker who comes south across the road from y = ``north`` (its
    lane along y = -1.75 m) at 1.1 m/s, and its tracking law sets off at 1.5 m/s^2. Standing, it
    counts on setting off at half its strongest acceleration (1.5 m/s^2): its rear leaves her
    strip 3.0 s later. From y = 8.7 m she needs 5.6 s to come within the margin of its lane at
    1.5 m/s (she may go faster than she walks): it goes first, and has left her strip before she
    comes near. From y = 4 m she needs 2.5 s: it stays out of her strip until she has crossed its
    lane, and she passes with the 1 m margin (once, a car that set off stopped again inside her
    strip and stood 0.51 m from her as she passed). Either way she never comes within the margin
    of its footprint."""
    half = 0.5 * np.hypot(0.3, 0.5) + 1.0  # half her strip: her diagonal, plus the margin
    states, accels, walkers = drive_past_walker(half + 0.02, north, speed=0.0, walk=1.1, seconds=20.0, accel=1.5)
    front = states[:, 0] + HIGHWAY_CAR.centre_offset + 2.0
    rear = front - HIGHWAY_CAR.length
    # her footprint (0.5 m wide along the road) against the car's, whenever she is within the margin of its lane
    beside = np.abs(walkers[:, 1] + 1.75) < 0.9 + 0.15 + 1.0
    assert beside.any()
    behind_her = walkers[beside, 0] - 0.25 - front[beside] >= 1.0
    past_her = rear[beside] - (walkers[beside, 0] + 0.25) >= 1.0
    assert np.all(behind_her if waits else past_her)
    if waits:
        assert np.all(front[walkers[:, 1] > -1.75] < -half)  # it stays out of her strip until she has crossed its lane
    assert states[-1, 3] > 0.0  # and then goes


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 100_000))
@example(seed=675)  # a robot at 0.02 m/s answers a walker with 1.2e-6 m/s^2: 180,000 periods to stand
@example(seed=672)  # a robot at 15 m/s that even its strongest braking stops 1 cm inside her strip
def test_braking_as_a_walker_stop_says_stands_before_her_strip_and_she_is_left_out_of_the_check(seed):
    """On random worlds (cars at random headings and speeds, walkers at random velocities, some
    standing): a robot answers a walker only when she walks, her strip lies ahead of it, and it
    cannot pass her (driving on, its rear leaves her strip no sooner than she could come within
    the margin of its path at her speed towards it plus the reach); braking from now at the
    deceleration it answers her with, at most its strongest braking, it comes to stand with its
    footprint outside her strip unless even that braking is too late; exactly those walkers are
    left out of its check."""
    rng = np.random.default_rng(seed)
    n, m = 4, 3
    robots = [HIGHWAY_CAR] * n
    states = np.column_stack([rng.uniform(-30, 30, (n, 2)), rng.uniform(-np.pi, np.pi, n), rng.uniform(0, 16, n)])
    velocities = rng.uniform(-1.6, 1.6, (m, 2)) * (np.arange(m) > 0)[:, None]  # walker 0 stands
    walkers = [Obstacle(f"w{j}", "pedestrian", rng.uniform(-20, 20, 2), velocities[j], float(np.arctan2(*velocities[j][::-1])), 0.3, 0.5)
               for j in range(m)]  # each heads where she walks
    world = WorldState(0.0, states, robots, walkers)
    check = SafetyCheck(world, Fleet(robots), WALKERS, states[:, 2], np.zeros(n))
    index, need, enter, passing = check.walker_paths()
    assert index.tolist() == [j for j in range(m) if np.hypot(*walkers[j].velocity) > 0.1]
    np.testing.assert_array_equal(check.ignored[:, 2 * n:][:, index], np.isfinite(enter) | passing)
    assert not np.any((need > 0.0) & passing)
    assert not check.ignored[:, 2 * n:][:, [j for j in range(m) if j not in index]].any()
    for i, col in zip(*np.nonzero(need)):
        w = walkers[index[col]]
        course = np.arctan2(w.velocity[1], w.velocity[0])
        across = np.array([-np.sin(course), np.cos(course)])
        half = 0.5 * np.hypot(0.3, 0.5) + 1.0  # half her diagonal, plus the margin
        assert need[i, col] <= 6.0
        # braking at need with straight wheels, Euler steps: speeds v0 - k a dt for the K = ceil(v0 / (a dt)) steps that
        # move (the last one then stops it), travelling dt times their sum along its heading (closed form: a robot that
        # barely moves needs only a tiny deceleration, and hundreds of thousands of steps)
        v0, a = states[i, 3], need[i, col]
        steps = np.ceil(v0 / (a * DT) - 1e-12)
        travel = DT * (steps * v0 - a * DT * steps * (steps - 1) / 2.0)
        end = states[i] + [travel * np.cos(states[i, 2]), travel * np.sin(states[i, 2]), 0.0, -v0]
        state = states[i].copy()
        for _ in range(int(min(steps, 2000))):  # the closed form is the model's course (checked where it is short)
            state = HIGHWAY_CAR.model.step(state, [HIGHWAY_LIMITS.braking_input(state[3], DT, a)[0], 0.0], DT)
        if steps <= 2000:
            assert abs(state[3]) < 1e-9 and np.allclose(state[:2], end[:2], atol=1e-6)
        # a straight course: every corner's side of her strip changes linearly, so its ends bound it
        sides = np.array([(rect_corners(WorldState(0.0, s[None, :], [HIGHWAY_CAR]).robot_footprints())[0] - w.centre) @ across
                          for s in (states[i], end)])
        if a < 6.0 - 1e-9:  # at its strongest braking (6 m/s^2) it may be too late: it brakes as hard as it can
            assert np.all(sides.min(axis=1) > half - 1e-6) or np.all(sides.max(axis=1) < -half + 1e-6)  # never in her strip


#: Seed 1 of the highway at 218.4-219.4 s: SUMO's bg.16 (4.5 m x 1.8 m) pulls out of the
#: leftmost lane (y = -1.75 m) to the right: its front [m], SUMO's angle [deg] and its speed
#: along the lane [m/s], every 0.1 s; its front moves 1.75 m/s across (a lane per 2 s).
PULL_OUT = np.array([
    [1489.187, -1.893, 91.8, 0.43], [1489.247, -2.054, 93.8, 0.61], [1489.321, -2.227, 96.0, 0.73], [1489.410, -2.402, 98.1, 0.90],
    [1489.519, -2.577, 100.1, 1.09], [1489.644, -2.752, 102.0, 1.26], [1489.782, -2.927, 103.8, 1.37], [1489.938, -3.102, 105.5, 1.56],
    [1490.115, -3.277, 107.1, 1.78], [1490.303, -3.452, 108.5, 1.88], [1490.509, -3.627, 109.8, 2.06]])


@pytest.mark.parametrize("seen", ["cover", "body"])
def test_a_car_keeps_clear_of_a_sumo_car_pulling_out_in_front_of_it_as_sumo_counts_it(seen):
    """The highway's seed 1, replayed: our car (4 m x 1.8 m) comes up the next lane (y = -5.25 m)
    at 4.95 m/s, braking gently (-1.34 m/s^2) for the queue ahead, 2.3 m behind the box SUMO's
    collision check gives the car pulling out (behind its front, at its front's lateral
    position). Seen as the SUMO adapter shows it (its collision cover: that box from where it is
    to the centre of the lane it moves into, moving along the lane), the safety stop brakes ours
    in time (an emergency, 6 m/s^2): their SUMO boxes stay 0.47 m apart. Seen as its body moving
    along its heading (a few degrees while it crawls), as before, ours drove into that box:
    SUMO's side collision."""
    state, worst = np.array([1479.127, -5.2467, 0.0, 4.95]), np.inf
    for k in range(30):
        x, y, angle, speed = PULL_OUT[min(k, len(PULL_OUT) - 1)]
        if k >= len(PULL_OUT):  # on as it went: faster, further across, to the next lane's centre
            x, y, speed = x + 0.21 * (k - len(PULL_OUT) + 1), max(y - 0.175 * (k - len(PULL_OUT) + 1), -5.25), speed + 0.15 * (k - len(PULL_OUT) + 1)
        lateral = -1.75 if y > -5.25 else 0.0
        if seen == "cover":  # SUMO has it on the new lane from halfway across
            sweep = lane_change_sweep(lateral, y + 1.75 if y > -3.5 else y + 5.25, 3.5)
            centre, heading, length, width = collision_cover(x, y, angle, 90.0, 4.5, 1.8, sweep)
            velocity = velocity_from_sumo(speed, 0.0, 90.0)
        else:
            (centre, heading), length, width = body_from_sumo(x, y, angle, 4.5), 4.5, 1.8
            velocity = speed * np.array([np.cos(heading), np.sin(heading)])
        front = state[0] + HIGHWAY_CAR.centre_offset + 2.0
        along = (x - 4.5) - front  # SUMO's boxes along the lane now: theirs behind its front, ours behind ours
        across = (y - 0.9) - (state[1] + 0.9)
        worst = min(worst, max(along, across))
        world = WorldState(0.1 * k, state[None, :], [HIGHWAY_CAR], [Obstacle("bg.16", "scripted", centre, velocity, heading, length, width)])
        check = SafetyCheck(world, Fleet([HIGHWAY_CAR]), WALKERS, np.zeros(1), np.zeros(1))
        state = HIGHWAY_CAR.model.step(state, check.safe_inputs(np.array([0]), np.array([[-1.34, 0.0]]), 0.3)[0], DT)
    if seen == "cover":
        assert worst > 0.4
    else:
        assert worst < -1.0


@pytest.mark.parametrize("course, answered", [(-0.151, False), (np.pi / 2, True)])
def test_a_walker_turning_onto_the_footpath_along_the_road_is_no_reason_to_stop(course, answered):
    """The highway's seed 0 at 177.4 s: a walker who has crossed the road turns east onto the
    footpath 6 m to the right of a car's lane, walking 8.7 degrees away from the road, as the
    car comes at 16 m/s 95 m behind her. Her path's line crosses the car's lane 39 m behind her,
    where she came from, not where she goes: the car does not stop for it (it braked at its
    comfort 3 m/s^2 for 1.5 s). Walking back north across the road from there, she is answered."""
    state = np.array([[1400.99, -8.9647, 0.0, 15.99]])
    walker = Obstacle("p3", "pedestrian", np.array([1499.5, -15.0]), 1.12 * np.array([np.cos(course), np.sin(course)]), course, 0.3, 0.5)
    check = SafetyCheck(WorldState(177.4, state, [HIGHWAY_CAR], [walker]), Fleet([HIGHWAY_CAR]), WALKERS, np.zeros(1), np.zeros(1))
    _, need, _, _ = check.walker_paths()
    assert bool(need[0, 0] > 0.0) == answered
    if not answered:
        assert np.isnan(check.walker_stops(np.array([0]), np.zeros((1, 2)))[0])


@pytest.mark.parametrize("braking_heading, answered", [(0.0123, False), (-0.1816, True)])
def test_a_car_changing_lanes_towards_the_footpath_does_not_stop_for_a_walker_on_it(braking_heading, answered):
    """The highway's seed 0 at 194.5 s: a car at 7.3 m/s changes lanes to the right, 10 degrees
    off its lane (heading 0.0123 rad here), 5 m to the left of a walker on the footpath walking
    along the lane. The safety stop's course brakes turning towards the lane's heading, along
    which the car never meets her path: no stop (it braked at 3.3 m/s^2 along the line of its
    heading at that moment, which does cross the footpath 9 m ahead)."""
    state = np.array([[1527.146, -10.736, -0.1816, 7.32]])
    walker = Obstacle("p3", "pedestrian", np.array([1519.04, -15.366]), 1.265 * np.array([np.cos(0.0123), np.sin(0.0123)]), 0.0123, 0.3, 0.5)
    check = SafetyCheck(WorldState(194.5, state, [HIGHWAY_CAR], [walker]), Fleet([HIGHWAY_CAR]), WALKERS, np.array([braking_heading]), np.zeros(1))
    assert bool(check.walker_paths()[1][0, 0] > 0.0) == answered


def test_a_car_too_late_to_stop_before_a_walker_passes_her_when_it_clears_her_path_before_she_comes():
    """The highway's seed 1 at 202.5 s: a car at 5.4 m/s has its front 0.55 m from the path of a
    walker who comes north from the footpath (1.08 m/s, 5.4 m from its lane); it can no longer
    stop before her path, and it leaves her strip in 1.4 s, before she could come within the
    margin of its lane even starting towards it at her reach (1.7 s): it passes her rather than
    brake (the check alone braked it at 3 m/s^2, and it stood on the crossing with her passing
    0.92 m behind it). The seed-4 walker with the car 12 m before her path at 16 m/s: too late
    to stop, and she is 2.8 s from its lane at her speed: it passes her."""
    state = np.array([[1494.4586, -11.1598, -0.1264, 5.4265]])
    walker = Obstacle("p4", "pedestrian", np.array([1499.68, -17.7714]), np.array([0.0, 1.0838]), np.pi / 2, 0.3, 0.5)
    check = SafetyCheck(WorldState(202.5, state, [HIGHWAY_CAR], [walker]), Fleet([HIGHWAY_CAR]), WALKERS, np.zeros(1), np.zeros(1))
    _, need, _, passing = check.walker_paths()
    assert need[0, 0] == 0.0 and passing[0, 0] and check.ignored[0, 2]
    assert check.safe_inputs(np.array([0]), np.zeros((1, 2)), 0.3)[0, 0] == 0.0
    states, accels, _ = drive_past_walker(12.0, 4.0)
    assert np.all(accels == 0.0)


def _arc_headings(radius: float, count: int) -> np.ndarray:
    """Headings every metre along a left-turning arc of ``radius`` [m] that starts heading east."""
    return np.arange(count) / radius


def test_the_safety_stops_braking_course_follows_a_curved_lane():
    """A car at 10 m/s on a 150 m arc (the curved sidewalk road): braking along the path's
    headings ahead, its course stays within 0.1 m of the arc; holding the heading where it is, it
    ran off along the tangent by about 1 m (and braked for the cones of the lane beside it)."""
    radius = 150.0
    state = np.array([[0.0, -radius, 0.0, 10.0]])  # on the circle about the origin, heading east (counter-clockwise)
    world = WorldState(0.0, state, [HIGHWAY_CAR], [])
    for table, worst in ((_arc_headings(radius, 60)[None, :], 0.1), (np.zeros(1), None)):
        check = SafetyCheck(world, Fleet([HIGHWAY_CAR]), WALKERS, table, np.zeros(1))
        course = check.stopping_course(None, 40, -check.fleet.comfort)[0]
        off = np.abs(np.hypot(course[:, 0], course[:, 1]) - radius).max()
        assert off < worst if worst else off > 0.8


def test_a_walker_walking_along_a_curved_sidewalk_beside_the_lane_is_no_crossing():
    """The curved sidewalk road at 0 s: a walker walks along the sidewalk 2.6 m outside a car's
    lane on a 150 m arc, 20 m ahead of the car at 10 m/s. With its path unbent she walks beside
    its course and it does not stop before her "path" (on the tangent her line crossed the
    car's course ahead, and it braked at 3.4 m/s^2); a walker crossing the road is still answered."""
    radius = 150.0
    state = np.array([[0.0, -radius, 0.0, 10.0]])
    at = 20.0 / radius  # her angle along the arc
    out = radius + 2.6
    for course, answered in ((at, False), (at + np.pi / 2, True)):
        walker = Obstacle("w0", "pedestrian", out * np.array([np.sin(at), -np.cos(at)]),
                          1.3 * np.array([np.cos(course), np.sin(course)]), course, 0.3, 0.5)
        check = SafetyCheck(WorldState(0.0, state, [HIGHWAY_CAR], [walker]), Fleet([HIGHWAY_CAR]), WALKERS,
                            _arc_headings(radius, 60)[None, :], np.zeros(1))
        assert bool(check.walker_paths()[1][0, 0] > 0.0) == answered


@pytest.mark.parametrize("walkway, stays", [((80.0, 260.0), True), ((20.0, 320.0), False), (None, False)])
def test_a_walker_far_along_her_sidewalk_stays_on_it_and_a_car_drives_past_her(walkway, stays):
    """The curved sidewalk road at 0 s, the walker 2.6 m outside the car's lane walking along the
    sidewalk 20 m ahead. Were she free to step out at 1.5 m/s, braking at once would end inside her
    growing region, so the car must brake now (it braked at 3 m/s^2 from 10 to 2 m/s). On a
    walkway of her own whose ends she cannot reach within ``walkway_time`` (10 s at 1.3 + 1.5
    m/s: 28 m) she stays on it, keeps her margin only, and the car cruises on."""
    radius, at = 150.0, 20.0 / 150.0
    state = np.array([[0.0, -radius, 0.0, 10.0]])
    walker = Obstacle("w0", "pedestrian", (radius + 2.6) * np.array([np.sin(at), -np.cos(at)]),
                      1.3 * np.array([np.cos(at), np.sin(at)]), at, 0.3, 0.5, walkway=walkway)
    assert walker.step_out_speed(1.5, 10.0) == (0.0 if stays else 1.5)
    check = SafetyCheck(WorldState(0.0, state, [HIGHWAY_CAR], [walker]), Fleet([HIGHWAY_CAR]),
                        dataclasses.replace(WALKERS, walkway_time=10.0), _arc_headings(radius, 60)[None, :], np.zeros(1))
    cruise = np.array([[0.0, np.arctan(2.6 / radius)]])  # holding the arc at its speed
    assert check.unsafe(np.array([0]), cruise, 0.0).tolist() == [not stays]


@pytest.mark.parametrize("leader_speed, held", [(7.0, False), (0.0, True)])
def test_a_car_behind_a_car_that_drives_on_is_not_held_for_a_walker_it_clears_in_time(leader_speed, held):
    """Two cars in a lane along +x at 7 m/s and 18 m apart (rear axles at 0 and 18 m); a walker
    14 m beside the lane walks towards it at 1.2 m/s on a path across it at x = 40 m. Driving on,
    the rear car's rear leaves her strip (her footprint's diagonal plus the 1 m margin either
    side) 6.0 s from now, before she could come within the margin of its lane at her 1.5 m/s
    reach (8.0 s): the car ahead, driving on at 7 m/s, stops before her strip if it must, and
    does not hold the rear car. A car standing 18 m ahead would leave it no room to clear her
    strip: then it stops before her path."""
    states = np.array([[0.0, 0.0, 0.0, 7.0], [18.0, 0.0, 0.0, leader_speed]])
    walker = Obstacle("p0", "pedestrian", np.array([40.0, 14.0]), np.array([0.0, -1.2]), -np.pi / 2, 0.3, 0.5)
    world = WorldState(0.0, states, [HIGHWAY_CAR, HIGHWAY_CAR], [walker])
    check = SafetyCheck(world, Fleet([HIGHWAY_CAR, HIGHWAY_CAR]), WALKERS, np.zeros(2), np.zeros(2))
    _, need, enter, _ = check.walker_paths()
    assert bool(need[0, 0] > 0.0) == held and bool(np.isfinite(enter[0, 0])) == held
