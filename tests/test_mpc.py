"""Specification tests for the MPC-FCBF planner (aac_sumo.mpc).

What a user of :class:`MpcPlanner` may rely on:

* on an empty road it tracks its reference;
* every plan reported ``solved`` keeps every ego disc at least ``radius + d_safe`` (exact Euclidean
  distance) outside every obstacle's safety ellipse at every stage, for F-CBF and plain CBF;
* when no admissible plan exists it says so (status not ``solved``, solver ``fallback``) and
  brakes along its heading without reversing;
* warm starts and the solver choice do not change a well-posed solution.
"""

import dataclasses
import os
import subprocess
import sys
from functools import lru_cache

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, note, settings
from hypothesis import strategies as st

from aac_sumo.barriers import barrier_value, inactive_slot, safety_ellipses
from aac_sumo.dynamics import BicycleModel, VehicleLimits, bicycle_step
from aac_sumo.geometry import ellipse_signed_distance
from aac_sumo.mpc import codegen, problem
from aac_sumo.mpc.plan import STATUSES, Plan
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner, ego_discs
from aac_sumo.prediction import predict_obstacle
from aac_sumo.world import Obstacle, RobotSpec

HORIZON, DT, SLOTS = 10, 0.1, 2
LIMITS = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.6, v_min=0.0, v_max=12.0)
ROBOT = RobotSpec("ego", length=1.0, width=0.6, model=BicycleModel(wheelbase=0.8, limits=LIMITS))
DIST_TOL = 1e-6  # exact-distance tolerance on solved plans [m]


@lru_cache(maxsize=None)
def planner(barrier="fcbf", gamma=0.3, discs=1, solver="fatrop", retry=True, band=False) -> MpcPlanner:
    """Planners share compiled problems through get_problem's per-process cache."""
    cfg = MpcConfig(horizon=HORIZON, dt=DT, solver=solver, barrier=barrier, gamma=gamma, slots=SLOTS, discs=discs,
                    retry_with_ipopt=retry, band=band)
    return MpcPlanner(cfg)


def straight_reference(x_start, speed, t0=0.0, y=0.0):
    """Reference along y = const at constant ``speed``: stage k at time t0 + k dt."""
    k = np.arange(HORIZON + 1)
    return np.column_stack([x_start + speed * (t0 + k * DT), np.full(HORIZON + 1, y), np.zeros(HORIZON + 1), np.full(HORIZON + 1, speed)])


def disc_centres(states, offsets):
    """Disc centres (N+1, discs, 2) of rear-axle states (N+1, 4)."""
    direction = np.stack([np.cos(states[:, 2]), np.sin(states[:, 2])], axis=-1)
    return states[:, None, :2] + offsets[None, :, None] * direction[:, None, :]


def clearance_margins(states, obstacles, cfg: MpcConfig):
    """Exact signed distance from every ego disc centre to every obstacle's safety ellipse at the
    same stage, minus the required clearance radius + d_safe. Shape (obstacles, N+1, discs)."""
    offsets, radius = ego_discs(ROBOT, cfg.discs)
    centres = disc_centres(states, offsets)
    out = []
    for ob in obstacles:
        ell = safety_ellipses(predict_obstacle(ob, len(states) - 1, cfg.dt), cfg.barrier, cfg.fcbf)
        sd = ellipse_signed_distance(centres, *(ell[:, i, None] for i in range(5)))
        out.append(sd - radius - cfg.d_safe)
    return np.array(out)


def moved(obstacles, dt):
    """Obstacles after dt at constant velocity (what the constant-velocity prediction assumes)."""
    return [
        Obstacle(o.name, o.kind, o.centre + o.velocity * dt, o.velocity, o.heading, o.length, o.width) for o in obstacles
    ]


def assert_model_trajectory(plan: Plan, state):
    """A plan is a trajectory of the bicycle model from ``state`` within the robot's limits."""
    assert plan.states.shape == (HORIZON + 1, 4) and plan.inputs.shape == (HORIZON, 2)
    np.testing.assert_allclose(plan.states[0], state, atol=1e-9)
    predicted = bicycle_step(plan.states[:-1], plan.inputs, DT, ROBOT.model.wheelbase)
    np.testing.assert_allclose(plan.states[1:], predicted, atol=1e-6)
    assert np.all(plan.inputs[:, 0] >= LIMITS.a_min - 1e-6) and np.all(plan.inputs[:, 0] <= LIMITS.a_max + 1e-6)
    assert np.all(np.abs(plan.inputs[:, 1]) <= LIMITS.steer_max + 1e-6)
    assert np.all(plan.states[:, 3] >= LIMITS.v_min - 1e-6) and np.all(plan.states[:, 3] <= LIMITS.v_max + 1e-6)


def cone(x, y, heading=0.0):
    return Obstacle("cone", "static", np.array([x, y]), np.zeros(2), heading, 0.8, 0.5)


def walker(x, y, vx, vy):
    return Obstacle("ped", "pedestrian", np.array([x, y]), np.array([vx, vy]), float(np.arctan2(vy, vx)), 0.6, 0.6)


# --------------------------------------------------------------------------------------------
# Geometry of the ego discs and slot filling (no solves)
# --------------------------------------------------------------------------------------------


@given(discs=st.integers(1, 5), length=st.floats(0.3, 6.0), width=st.floats(0.2, 3.0), wheelbase=st.floats(0.1, 4.0))
@settings(max_examples=40)
def test_ego_discs_cover_the_footprint(discs, length, width, wheelbase):
    """Every point of the footprint rectangle (centred wheelbase/2 ahead of the rear axle) lies in
    at least one disc, so keeping the disc centres clear keeps the body clear."""
    robot = RobotSpec("r", length, width, BicycleModel(wheelbase, LIMITS))
    offsets, radius = ego_discs(robot, discs)
    assert offsets.shape == (discs,)
    along = robot.centre_offset + np.linspace(-0.5 * length, 0.5 * length, 61)
    across = np.linspace(-0.5 * width, 0.5 * width, 21)
    gx, gy = np.meshgrid(along, across)
    dist = np.hypot(gx[..., None] - offsets, gy[..., None]).min(axis=-1)
    assert dist.max() <= radius * (1 + 1e-12)


def test_nearest_obstacles_fill_the_slots():
    """With more obstacles than slots the nearest ones are planned around; unused slots are off."""
    pl = planner()
    state = np.array([0.0, 0.0, 0.0, 3.0])
    far, near, mid = cone(40.0, 0.0), cone(3.0, 1.0), cone(8.0, -1.0)
    params = pl.obstacle_parameters(ROBOT, state, [far, near, mid])
    assert params.shape == (HORIZON + 1, SLOTS, 7)
    used = {tuple(params[0, s, :2]) for s in range(SLOTS)}
    assert used == {(3.0, 1.0), (8.0, -1.0)}
    assert np.all(params[..., 6] == 1.0)
    one = pl.obstacle_parameters(ROBOT, state, [near])
    assert np.all(one[:, 0, 6] == 1.0) and np.all(one[:, 1, 6] == 0.0)


obstacle_strategy = st.builds(
    lambda kind, x, y, vx, vy, heading, accel, length: Obstacle(f"{kind}{x}", kind, np.array([x, y]), np.array([vx, vy]), heading,
                                                                length, 0.6 * length, accel=accel),
    st.sampled_from(["vehicle", "pedestrian", "cone"]), st.floats(-30, 30), st.floats(-30, 30), st.floats(-12, 12),
    st.floats(-12, 12), st.floats(-np.pi, np.pi), st.floats(-6, 2), st.floats(0.3, 5.0))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(obstacle_strategy, min_size=0, max_size=14), st.sampled_from(["cbf", "fcbf"]),
       st.sampled_from(["constant_velocity", "constant_acceleration"]), st.floats(0.0, 1.5), st.floats(0.0, 1.0))
def test_nearest_regions_equal_a_full_scan(obstacles, barrier, prediction, margin, reach):
    """Ranking on stage 0 alone and predicting only the nearest gives, bit for bit, the regions of
    predicting every obstacle, growing the walkers' and keeping the ``slots`` nearest."""
    cfg = MpcConfig(horizon=HORIZON, dt=DT, barrier=barrier, slots=4, prediction=prediction, pedestrian_margin=margin,
                    pedestrian_reach=reach, solver="ipopt", codegen=False)  # ipopt, not compiled to C: built once, in a second
    pl = MpcPlanner(cfg)
    state = np.array([0.5, -1.0, 0.3, 4.0])
    got, _, _ = pl.nearest_regions(state, obstacles)
    if not obstacles:
        assert got.shape[1] == 0
        return
    full = np.stack([safety_ellipses(predict_obstacle(o, HORIZON, DT, prediction), barrier, cfg.fcbf) for o in obstacles])
    walker = np.array([o.kind == "pedestrian" for o in obstacles])
    full[walker, :, 2:4] += margin + reach * DT * np.arange(HORIZON + 1)[:, None]
    gaps = np.hypot(full[:, 0, 0] - state[0], full[:, 0, 1] - state[1]) - np.maximum(full[:, 0, 2], full[:, 0, 3])
    keep = np.argsort(gaps, kind="stable")[: cfg.slots] if len(obstacles) > cfg.slots else np.arange(len(obstacles))
    np.testing.assert_array_equal(got, full[keep].transpose(1, 0, 2))


def test_plan_shifted_warm_start():
    states = np.arange(3 * 4, dtype=float).reshape(3, 4)
    inputs = np.arange(2 * 2, dtype=float).reshape(2, 2) + 100
    plan = Plan(states, inputs, "solved", 0.0, "fatrop")
    new_state = np.array([-1.0, -2.0, -3.0, -4.0])
    s, u = plan.shifted(new_state)
    np.testing.assert_array_equal(s, [new_state, states[2], states[2]])
    np.testing.assert_array_equal(u, [inputs[1], inputs[1]])
    np.testing.assert_array_equal(plan.states, np.arange(12.0).reshape(3, 4))  # not mutated


# --------------------------------------------------------------------------------------------
# Tracking
# --------------------------------------------------------------------------------------------


def test_tracks_straight_reference_from_lateral_offset():
    """Closed loop on an empty road: start 1 m beside a 3 m/s straight reference, slower than it;
    after 6 s the robot is on the line at the reference speed, every solve succeeded."""
    pl = planner()
    state = np.array([0.0, 1.0, 0.0, 2.0])
    u_prev, previous, statuses = np.zeros(2), None, []
    for i in range(60):
        plan = pl.plan(ROBOT, state, straight_reference(0.0, 3.0, t0=i * DT), u_prev, [], previous)
        statuses.append(plan.status)
        assert_model_trajectory(plan, state)
        u_prev = plan.inputs[0]
        state = ROBOT.model.step(state, u_prev, DT)
        previous = plan
    assert statuses == ["solved"] * 60
    assert abs(state[1]) < 0.1
    assert abs(state[3] - 3.0) < 0.2
    assert abs(state[2]) < 0.05
    assert abs(state[0] - 3.0 * 60 * DT) < 0.5


# --------------------------------------------------------------------------------------------
# Safety of solved plans
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("barrier", ["fcbf", "cbf"])
@given(
    cone_xy=st.tuples(st.floats(2.0, 9.0), st.floats(-1.5, 1.5)),
    walker_xy=st.tuples(st.floats(3.0, 12.0), st.floats(-5.0, 5.0)),
    walker_v=st.tuples(st.floats(-2.0, 2.0), st.floats(-2.0, 2.0)),
    speed=st.floats(1.0, 6.0),
    gamma=st.sampled_from([0.3, 1.0]),
)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
def test_solved_plans_never_enter_safety_ellipses(barrier, cone_xy, walker_xy, walker_v, speed, gamma):
    """From a safe start (discs outside every region now and at stage 1, whose rear-axle
    position the start fixes), a solved plan keeps every ego disc centre at exact distance
    >= radius + d_safe from each obstacle's safety ellipse at every later stage."""
    pl = planner(barrier=barrier, gamma=gamma)
    state = np.array([0.0, 0.0, 0.0, speed])
    obstacles = [cone(*cone_xy, heading=0.4), walker(*walker_xy, *walker_v)]
    # safe start: the algebraic barrier (which the MPC propagates) is non-negative now
    params = pl.obstacle_parameters(ROBOT, state, obstacles)
    offsets, _ = ego_discs(ROBOT, pl.config.discs)
    centres = disc_centres(state[None], offsets)[0]
    h0 = [barrier_value(c[0], c[1], *params[0, s, :6]) for s in range(SLOTS) for c in centres]
    state1 = ROBOT.model.step(state, np.zeros(2), DT)
    centres1 = disc_centres(state1[None], offsets)[0]
    h1 = [barrier_value(c[0], c[1], *params[1, s, :6]) for s in range(SLOTS) for c in centres1]
    assume(min(h0) >= 0.0 and min(h1) >= 0.0)
    plan = pl.plan(ROBOT, state, straight_reference(0.0, speed), np.zeros(2), obstacles)
    note(f"status={plan.status} solver={plan.solver}")
    event(f"{plan.status} ({plan.solver})")
    assert plan.status in STATUSES
    if plan.status == "solved":
        assert_model_trajectory(plan, state)
        assert clearance_margins(plan.states, obstacles, pl.config)[:, 2:].min() >= -DIST_TOL
    else:
        assert plan.solver == "fallback"


@pytest.mark.parametrize("gamma", [0.3, 1.0])
@pytest.mark.parametrize("barrier", ["fcbf", "cbf"])
def test_closed_loop_passes_obstacles_without_entering_safety_ellipses(barrier, gamma):
    """A cone just beside the lane and a pedestrian crossing it: 5 s of closed loop with two ego
    discs. Every solved plan is safe at every stage, the executed trajectory is safe, and the
    robot gets past both obstacles back onto its lane."""
    pl = planner(barrier=barrier, gamma=gamma, discs=2)
    cfg = pl.config
    state = np.array([0.0, 0.0, 0.0, 3.0])
    obstacles = [cone(5.0, 0.1), walker(9.0, -2.5, 0.0, 1.0)]
    u_prev, previous = np.zeros(2), None
    solved, executed_margin, active = 0, np.inf, False
    for _ in range(50):
        plan = pl.plan(ROBOT, state, straight_reference(state[0], 3.0), u_prev, obstacles, previous)
        if plan.status == "solved":
            solved += 1
            margins = clearance_margins(plan.states, obstacles, cfg)
            assert margins.min() >= -DIST_TOL, f"solved plan enters a safety ellipse by {-margins.min():.3g} m"
            active |= margins.min() < 0.1
        u_prev = plan.inputs[0]
        state = ROBOT.model.step(state, u_prev, DT)
        obstacles = moved(obstacles, DT)
        previous = plan
        executed_margin = min(executed_margin, clearance_margins(state[None], obstacles, cfg).min())
    assert solved == 50
    assert executed_margin >= -DIST_TOL
    assert active, "the obstacles never constrained the plan; the scenario tests nothing"
    assert state[0] > 12.0 and abs(state[1]) < 0.2


# --------------------------------------------------------------------------------------------
# Infeasibility contract
# --------------------------------------------------------------------------------------------


def test_impossible_start_is_reported_and_brakes():
    """10 m/s straight at a wall-like static obstacle 2.6 m ahead: the first barrier condition
    h(x1) >= (1 - gamma) h(x0) fails for every admissible input (x1's position does not depend on
    u0), so no plan exists. The planner must say so and brake along its heading."""
    pl = planner(barrier="fcbf", gamma=0.3, discs=1)
    cfg = pl.config
    state = np.array([0.0, 0.0, 0.0, 10.0])
    obstacles = [Obstacle("wall", "static", np.array([2.6, 0.0]), np.zeros(2), 0.0, 1.0, 1.0)]

    # Precondition, checked rather than assumed: infeasible whatever u0.
    params = pl.obstacle_parameters(ROBOT, state, obstacles)[:, 0, :]
    offsets, _ = ego_discs(ROBOT, cfg.discs)
    grid = np.stack(np.meshgrid(np.linspace(LIMITS.a_min, LIMITS.a_max, 7), np.linspace(-LIMITS.steer_max, LIMITS.steer_max, 61)), -1).reshape(-1, 2)
    x1 = bicycle_step(np.tile(state, (len(grid), 1)), grid, DT, ROBOT.model.wheelbase)
    assert np.ptp(x1[:, :2], axis=0).max() == 0.0
    c0 = disc_centres(state[None], offsets)[0, 0]
    c1 = disc_centres(x1, offsets)[:, 0]
    h0 = barrier_value(c0[0], c0[1], *params[0, :6])
    h1 = barrier_value(c1[:, 0], c1[:, 1], *params[1, :6])
    assert h0 > 0.0
    assert h1.max() < (1 - cfg.gamma) * h0

    plan = pl.plan(ROBOT, state, straight_reference(0.0, 10.0), np.zeros(2), obstacles)
    assert plan.status in ("infeasible", "failed")
    assert plan.solver == "fallback"
    np.testing.assert_array_equal(plan.states[0], state)
    assert plan.inputs[0, 0] < 0.0
    assert np.all(plan.inputs[:, 1] == 0.0)
    speeds = plan.states[:, 3]
    assert np.all(np.diff(speeds) <= 0.0) and np.all(speeds >= 0.0)
    assert np.all(plan.states[:, 1] == 0.0) and np.all(plan.states[:, 2] == 0.0)  # along its heading
    np.testing.assert_allclose(speeds, np.maximum(10.0 + LIMITS.a_min * DT * np.arange(HORIZON + 1), 0.0), atol=1e-12)


def test_fallback_from_slow_start_never_reverses():
    """Fallback braking from 0.5 m/s stops and stays stopped (v_min = 0)."""
    pl = planner(barrier="cbf", gamma=0.3, discs=1)
    state = np.array([0.0, 0.0, 0.0, 0.5])
    # The ego's disc already overlaps the box, which comes at it at 5 m/s: the ego cannot back
    # away (v_min = 0), so not even "no deeper than now" can hold.
    obstacles = [Obstacle("box", "pedestrian", np.array([0.9, 0.0]), np.array([-5.0, 0.0]), np.pi, 1.0, 1.0)]
    plan = pl.plan(ROBOT, state, straight_reference(0.0, 0.5), np.zeros(2), obstacles)
    assert plan.status != "solved"
    assert plan.solver == "fallback"
    assert plan.inputs[0, 0] == pytest.approx(-5.0)  # (0 - 0.5) / 0.1, inside a_min
    assert np.all(plan.inputs[1:, 0] == 0.0)
    assert np.all(plan.states[1:, 3] == 0.0)
    assert np.all(np.diff(plan.states[:, 0]) >= 0.0)


@given(heading=st.floats(-1.0, 1.0), speed=st.floats(0.5, 12.0))
@settings(max_examples=40, deadline=None)
def test_fallback_brakes_turning_towards_the_reference_heading(heading, speed):
    """The fallback brakes at full strength, never reverses, and turns the heading towards the
    reference's (a straight lane along +x) without overshooting it: a car brakes in its lane."""
    pl = planner(barrier="fcbf", gamma=0.3, discs=1)
    state = np.array([0.0, 0.0, heading, speed])
    states, inputs = pl.fallback(ROBOT, state, straight_reference(0.0, speed), np.zeros(2))
    speeds = states[:, 3]
    np.testing.assert_allclose(speeds, np.maximum(speed + LIMITS.a_min * DT * np.arange(HORIZON + 1), 0.0), atol=1e-12)
    assert np.all(np.abs(inputs[:, 1]) <= LIMITS.steer_max)
    errors = np.abs(states[:, 2])
    assert np.all(np.diff(errors) <= 1e-12)  # the heading error never grows
    assert np.all(np.sign(states[:, 2]) * np.sign(heading) >= 0.0)  # and never changes side
    if abs(heading) > 1e-6 and speed > 2.0:
        assert errors[-1] < abs(heading)


@given(heading=st.floats(-3.0, 3.0), speed=st.floats(0.0, 5.0))
@settings(max_examples=30, deadline=None)
def test_a_free_reference_heading_makes_the_fallback_brake_straight_on(heading, speed):
    """Near a goal the reference leaves the heading free (NaN): the fallback then brakes along
    the robot's heading, with finite inputs (a NaN steering stopped a CBF-QP run at t = 15.5 s)."""
    pl = planner(barrier="fcbf", gamma=0.3, discs=1)
    reference = straight_reference(0.0, speed)
    reference[:, 2] = np.nan
    states, inputs = pl.fallback(ROBOT, np.array([1.0, 2.0, heading, speed]), reference, np.zeros(2))
    assert np.all(np.isfinite(inputs)) and np.all(inputs[:, 1] == 0.0)
    np.testing.assert_allclose(states[:, 2], heading)


# --------------------------------------------------------------------------------------------
# Warm start and solver agreement
# --------------------------------------------------------------------------------------------

WELL_POSED = dict(state=np.array([0.0, 0.0, 0.0, 3.0]), obstacles=[cone(2.5, 1.0)])


def test_obstacle_binds_in_well_posed_case():
    """The cone beside the lane changes the plan (so agreement tests below are not trivial)."""
    pl = planner()
    ref = straight_reference(0.0, 3.0)
    free = pl.plan(ROBOT, WELL_POSED["state"], ref, np.zeros(2), [])
    bound = pl.plan(ROBOT, WELL_POSED["state"], ref, np.zeros(2), WELL_POSED["obstacles"])
    assert free.status == bound.status == "solved"
    assert np.abs(bound.states - free.states).max() > 0.05
    assert bound.inputs[0, 1] < -0.01  # steers away (to the right) from the cone on the left



def _captured_solve(monkeypatch):
    """The arguments of the fatrop solve behind one well-posed plan, and that problem."""
    seen = []
    solve = problem.MpcProblem.solve

    def capture(self, *args):
        seen.append((self, [np.array(a, copy=True) for a in args]))
        return solve(self, *args)

    monkeypatch.setattr(problem.MpcProblem, "solve", capture)
    plan = planner(retry=False).plan(ROBOT, WELL_POSED["state"], straight_reference(0.0, 3.0), np.zeros(2), WELL_POSED["obstacles"])
    monkeypatch.undo()
    assert plan.status == "solved" and len(seen) == 1
    return seen[0]


def test_a_solve_through_the_bound_arrays_equals_a_call_by_keywords(monkeypatch):
    """MpcProblem.solve evaluates the solver on arrays bound to it once (casadi's FunctionBuffer);
    the plan is the one a call by keywords returns, to the bit."""
    prob, (params, w0, lbx, ubx) = _captured_solve(monkeypatch)
    outcome = prob.solve(params, w0, lbx, ubx)
    by_keywords = np.asarray(prob.solver(x0=w0, p=params, lbx=lbx, ubx=ubx, lbg=prob._lbg, ubg=prob._ubg)["x"]).ravel()
    states, inputs = prob.unpack(by_keywords)
    assert outcome.status == "solved"
    assert np.array_equal(outcome.states, states) and np.array_equal(outcome.inputs, inputs)


@pytest.mark.parametrize("where", [0, 1, 2])
def test_a_nan_in_a_problem_fails_that_solve_alone(monkeypatch, where):
    """A NaN among the parameters, the guess or the bounds fails the solve at once, and the next
    well-posed solve is solved as before (handed to fatrop, one such solve made every later one
    fail at its first iteration)."""
    prob, args = _captured_solve(monkeypatch)
    before = prob.solve(*args)
    broken = [a.copy() for a in args]
    broken[where][3] = np.nan
    failed = prob.solve(*broken)
    after = prob.solve(*args)
    assert failed.status == "failed" and "NaN" in failed.detail
    assert after.status == "solved" and np.array_equal(after.states, before.states)

def test_warm_start_reproduces_first_input():
    """Solving the same problem again, warm-started from the previous plan, returns the same
    first input."""
    pl = planner()
    ref = straight_reference(0.0, 3.0)
    first = pl.plan(ROBOT, WELL_POSED["state"], ref, np.zeros(2), WELL_POSED["obstacles"])
    second = pl.plan(ROBOT, WELL_POSED["state"], ref, np.zeros(2), WELL_POSED["obstacles"], previous=first)
    assert first.status == second.status == "solved"
    np.testing.assert_allclose(second.inputs[0], first.inputs[0], atol=1e-4)
    np.testing.assert_allclose(second.states, first.states, atol=1e-3)


def test_a_warm_start_the_solver_cannot_use_is_retried_cold():
    """A previous plan that fatrop cannot start from (500 m away: it stops after a few
    iterations) costs the robot nothing: the same solver is retried from the zero-input
    rollout and solves, without any ipopt retry, to the plan a cold start gives."""
    pl = planner(retry=False)
    ref = straight_reference(0.0, 3.0)
    cold = pl.plan(ROBOT, WELL_POSED["state"], ref, np.zeros(2), WELL_POSED["obstacles"])
    broken = Plan(cold.states + np.array([500.0, 500.0, 0.0, 0.0]), cold.inputs, "solved", 0.0, "fatrop")
    retried = pl.plan(ROBOT, WELL_POSED["state"], ref, np.zeros(2), WELL_POSED["obstacles"], previous=broken)
    assert (retried.status, retried.solver) == ("solved", "fatrop")
    np.testing.assert_allclose(retried.inputs, cold.inputs, atol=1e-6)


def test_without_warm_start_the_previous_plan_is_ignored():
    """With ``warm_start`` off, a solve given a previous plan is the cold solve, iteration for
    iteration; with it on, the same previous plan changes the iterations."""
    base = planner(retry=False)
    cold_planner = MpcPlanner(dataclasses.replace(base.config, warm_start=False))
    ref = straight_reference(0.0, 3.0)
    args = (ROBOT, WELL_POSED["state"], ref, np.zeros(2), WELL_POSED["obstacles"])
    cold = cold_planner.plan(*args)
    previous = Plan(cold.states + 0.3, cold.inputs, "solved", 0.0, "fatrop")
    ignored = cold_planner.plan(*args, previous=previous)
    warm = base.plan(*args, previous=previous)
    assert (ignored.iterations, ignored.status) == (cold.iterations, "solved")
    np.testing.assert_array_equal(ignored.inputs, cold.inputs)
    assert warm.iterations != cold.iterations


@pytest.mark.parametrize("obstacles", [[], WELL_POSED["obstacles"]], ids=["empty", "cone"])
def test_fatrop_and_ipopt_agree(obstacles):
    """The structure-exploiting fast path and ipopt find the same optimum of a well-posed problem."""
    state = np.array([0.0, 0.5, 0.1, 2.5]) if not obstacles else WELL_POSED["state"]
    ref = straight_reference(0.0, 3.0)
    fast = planner(solver="fatrop", retry=False).plan(ROBOT, state, ref, np.zeros(2), obstacles)
    slow = planner(solver="ipopt").plan(ROBOT, state, ref, np.zeros(2), obstacles)
    assert (fast.status, fast.solver) == ("solved", "fatrop")
    assert (slow.status, slow.solver) == ("solved", "ipopt")
    np.testing.assert_allclose(fast.inputs[0], slow.inputs[0], atol=1e-3)
    np.testing.assert_allclose(fast.states, slow.states, atol=1e-3)


def test_fatrop_converges_with_a_heavy_input_change_cost():
    """The input-change cost couples consecutive inputs; carried in the stage state it stays a
    stage cost, so fatrop converges (it does not stop at its iteration cap with a merely
    feasible iterate) and finds ipopt's optimum, starting from a steering input of 0.2 rad."""
    plans = {}
    for solver in ("fatrop", "ipopt"):
        cfg = MpcConfig(horizon=HORIZON, dt=DT, solver=solver, slots=SLOTS, s_accel=1.0, s_steer=10.0, retry_with_ipopt=False)
        plans[solver] = MpcPlanner(cfg).plan(ROBOT, np.array([0.0, 0.5, 0.1, 2.5]), straight_reference(0.0, 3.0), np.array([0.5, 0.2]), [])
    fast, slow = plans["fatrop"], plans["ipopt"]
    assert (fast.status, fast.solver, fast.detail) == ("solved", "fatrop", "0")
    assert fast.iterations < 30
    np.testing.assert_allclose(fast.inputs, slow.inputs, atol=1e-3)


def test_plans_stay_inside_a_lateral_band():
    """A reference 3 m to the left of a road whose edges are 2 m either side: the plan follows
    it only as far as the band allows (rear axle 0.5 m inside the left edge)."""
    from aac_sumo.references import LateralBand

    pl = planner(barrier="fcbf", gamma=0.3, band=True)
    band = LateralBand(right=[[-10.0, -2.0], [100.0, -2.0]], left=[[-10.0, 2.0], [100.0, 2.0]], margin=0.5)
    state = np.array([0.0, 0.0, 0.0, 3.0])
    reference = straight_reference(0.0, 3.0, y=3.0)
    rows = band.limits(reference)
    np.testing.assert_allclose(rows[:, 2:], np.tile([-1.5, 1.5], (HORIZON, 1)))
    free = pl.plan(ROBOT, state, reference, np.zeros(2), [])
    banded = pl.plan(ROBOT, state, reference, np.zeros(2), [], corridor=band)
    assert free.status == banded.status == "solved"
    assert free.states[:, 1].max() > 1.6  # without the band it heads for the reference
    assert banded.states[:, 1].max() <= 1.5 + 1e-6


def test_a_band_the_robot_is_already_outside_of_holds_it_where_it_is():
    """Starting 1 m beyond the band's left limit, the plan may not drift further out than the
    band's give."""
    from aac_sumo.mpc.planner import BAND_GIVE
    from aac_sumo.references import LateralBand

    pl = planner(barrier="fcbf", gamma=0.3, band=True)
    band = LateralBand(right=[[-10.0, -2.0], [100.0, -2.0]], left=[[-10.0, 2.0], [100.0, 2.0]], margin=0.5)
    state = np.array([0.0, 2.5, 0.0, 3.0])
    with pytest.raises(ValueError):
        planner(barrier="fcbf", gamma=0.3).plan(ROBOT, state, straight_reference(0.0, 3.0), np.zeros(2), [], corridor=band)
    plan = pl.plan(ROBOT, state, straight_reference(0.0, 3.0, y=4.0), np.zeros(2), [], corridor=band)
    assert plan.status == "solved"
    assert plan.states[:, 1].max() <= 2.5 + BAND_GIVE + 1e-6


def test_a_robot_pointing_out_of_its_band_may_turn_back_in():
    """A robot standing on its band's left edge, heading 0.9 rad out of it, gets the room it
    needs to turn back in at full lock (R (1 - cos e)), so it drives off instead of standing
    for ever (it does not reverse), and it does not go further out than that room."""
    from aac_sumo.mpc.planner import BAND_GIVE
    from aac_sumo.references import LateralBand

    pl = planner(barrier="fcbf", gamma=0.3, band=True)
    band = LateralBand(right=[[-10.0, -2.0], [100.0, -2.0]], left=[[-10.0, 2.0], [100.0, 2.0]], margin=0.5)
    state = np.array([0.0, 1.5, 0.9, 0.0])
    plan = pl.plan(ROBOT, state, straight_reference(0.0, 3.0), np.zeros(2), [], corridor=band)
    room = ROBOT.model.wheelbase / np.tan(LIMITS.steer_max) * (1.0 - np.cos(0.9))
    assert (plan.status, plan.solver) == ("solved", "fatrop")
    assert plan.states[-1, 0] > 0.1
    assert plan.states[:, 1].max() <= 1.5 + BAND_GIVE + room + 1e-6


def test_a_standing_robot_on_its_band_edge_can_plan():
    """A robot standing exactly on its band's edge, heading slightly outwards, still gets a solved
    plan (without the band's give, the feasible set has no interior and the solvers fail)."""
    from aac_sumo.references import LateralBand

    pl = planner(barrier="fcbf", gamma=0.3, band=True)
    band = LateralBand(right=[[-10.0, -2.0], [100.0, -2.0]], left=[[-10.0, 2.0], [100.0, 2.0]], margin=0.5)
    state = np.array([0.0, 1.5, 0.01, 0.0])
    plan = pl.plan(ROBOT, state, straight_reference(0.0, 3.0), np.zeros(2), [], corridor=band)
    assert (plan.status, plan.solver) == ("solved", "fatrop")
    assert plan.states[-1, 0] > 0.1  # it drives off


TINY = dict(horizon=3, slots=1, discs=1, solver="fatrop", dt=DT)  # a problem that compiles in about a second


def tiny_solve(prob: problem.MpcProblem) -> problem.SolveOutcome:
    """One cold solve of a ``TINY`` problem: a robot at 1 m/s, 0.1 m beside a reference at 1 m/s, no obstacle."""
    params = prob.parameters(wheelbase=0.8, gamma=0.3, disc_offsets=[0.4], weights=np.ones(12),
                             x_ref=np.column_stack([np.arange(4.0), np.zeros((4, 2)), np.ones(4)]),
                             obstacles=inactive_slot(3)[:, None, :], band=np.zeros(0), limits=np.full(2, problem.NO_LIMIT),
                             terminal=np.zeros(0), stop_decel=np.zeros(0))
    x0 = np.array([0.0, 0.1, 0.0, 1.0])
    lbx, ubx = prob.bounds(x0, np.zeros(2), [-np.inf, -np.inf, -np.inf, 0.0], [np.inf, np.inf, np.inf, 5.0], [-3.0, -0.5], [3.0, 0.5])
    return prob.solve(params, prob.pack(np.tile(x0, (4, 1)), np.zeros((3, 2)), np.zeros(2)), lbx, ubx)


def test_a_compiled_problem_is_reused_without_building_it_again(tmp_path, monkeypatch):
    """With ``codegen`` the problem's functions are compiled once into a library keyed by the
    shape, casadi's version and the problem's source; a second build of the same shape loads
    that library without building the symbolic problem, and solves to the same plan. Another
    shape gets another library."""
    monkeypatch.setenv("AAC_SUMO_CACHE", str(tmp_path))
    shape = problem.ProblemShape(**TINY, codegen=True)
    first = problem.MpcProblem(shape)
    assert problem.library_path(shape).exists()
    monkeypatch.setattr(problem.MpcProblem, "_symbolic", lambda self: pytest.fail("built the problem again"))
    again = problem.MpcProblem(shape)
    a, b = tiny_solve(first), tiny_solve(again)
    assert a.status == b.status == "solved"
    np.testing.assert_allclose(a.inputs, b.inputs, atol=1e-9)
    assert problem.library_path(shape) != problem.library_path(dataclasses.replace(shape, horizon=4))


def test_the_compiled_problem_solves_as_the_interpreted_one_bit_for_bit(tmp_path, monkeypatch):
    """Compiling the problem's functions to C (at ``codegen.CFLAGS``) changes how fast they
    evaluate, never what they give: the same solve ends at the same iterate, bit for bit, after
    as many iterations."""
    monkeypatch.setenv("AAC_SUMO_CACHE", str(tmp_path))
    compiled, interpreted = (tiny_solve(problem.MpcProblem(problem.ProblemShape(**TINY, codegen=c))) for c in (True, False))
    assert compiled.status == interpreted.status == "solved"
    np.testing.assert_array_equal(compiled.states, interpreted.states)
    np.testing.assert_array_equal(compiled.inputs, interpreted.inputs)
    assert compiled.iterations == interpreted.iterations


def test_two_processes_compiling_one_library_at_once_leave_a_whole_one(tmp_path, monkeypatch):
    """Two processes compiling the same library at the same time (two sweep workers on an empty
    cache) each rename a finished file over it: the library left loads and solves, and neither
    leaves a temporary file behind."""
    monkeypatch.setenv("AAC_SUMO_CACHE", str(tmp_path))
    compile_one = ("from aac_sumo.mpc import codegen, problem as p\n"
                   f"shape = p.ProblemShape(**{TINY!r}, codegen=True)\n"
                   "interpreted = p.MpcProblem(p.ProblemShape(**{**shape.__dict__, 'codegen': False}))\n"
                   "codegen.compile_library(interpreted.solver, p.library_path(shape))\n")
    workers = [subprocess.Popen([sys.executable, "-c", compile_one], env=os.environ) for _ in range(2)]
    assert [w.wait(timeout=300) for w in workers] == [0, 0]
    shape = problem.ProblemShape(**TINY, codegen=True)
    assert list(tmp_path.iterdir()) == [problem.library_path(shape)]
    assert tiny_solve(problem.MpcProblem(shape)).status == "solved"


def test_a_failed_compile_leaves_the_cache_as_it_was(tmp_path, monkeypatch):
    """A compile that fails (here gcc rejects a flag) raises, and leaves neither a library nor a
    temporary file in the cache: the next run compiles afresh."""
    monkeypatch.setenv("AAC_SUMO_CACHE", str(tmp_path))
    monkeypatch.setattr(codegen, "CFLAGS", ("-fno-such-option",))
    with pytest.raises(subprocess.CalledProcessError):
        problem.MpcProblem(problem.ProblemShape(**TINY, codegen=True))
    assert list(tmp_path.iterdir()) == []


def test_the_comfort_envelope_is_kept_unless_only_the_vehicles_limits_allow_a_plan():
    """With ``comfort_accel`` = ``comfort_lat`` = 2 m/s^2, a robot setting off at rest for 10 m/s
    speeds up at 2 m/s^2, not the 3 its vehicle allows (the reference asks for far more). A
    robot at 10 m/s held in its lane (a 0.1 m wide corridor) with a cone 14 m ahead brakes within
    the envelope where the vehicle's limits alone had it brake at 2.5 m/s^2; with the cone 12 m
    ahead no plan keeps the envelope, and it still gets one, braking beyond it."""
    cfg = MpcConfig(horizon=HORIZON, dt=DT, slots=SLOTS, comfort_accel=2.0, comfort_lat=2.0)
    assert cfg.envelopes(LIMITS) == [(-2.0, 2.0, 2.0), (LIMITS.a_min, LIMITS.a_max, LIMITS.a_lat_max)]
    assert MpcConfig().envelopes(LIMITS) == [(LIMITS.a_min, LIMITS.a_max, LIMITS.a_lat_max)]
    comfort, free = MpcPlanner(cfg), MpcPlanner(dataclasses.replace(cfg, comfort_accel=0.0, comfort_lat=0.0))
    start = np.array([0.0, 0.0, 0.0, 0.0])
    plan = comfort.plan(ROBOT, start, straight_reference(0.0, 10.0), np.zeros(2), [])
    assert plan.status == "solved" and plan.inputs[:, 0].max() == pytest.approx(2.0, abs=1e-6)
    assert free.plan(ROBOT, start, straight_reference(0.0, 10.0), np.zeros(2), []).inputs[:, 0].max() > 2.5

    lane, moving = np.array([-1e3, 1e3, -0.05, 0.05]), np.array([0.0, 0.0, 0.0, 10.0])
    for ahead, within in ((14.0, True), (12.0, False)):
        cone = Obstacle("cone", "cone", np.array([ahead, 0.0]), np.zeros(2), 0.0, 0.5, 0.5)
        plans = [p.plan(ROBOT, moving, straight_reference(0.0, 10.0), np.zeros(2), [cone], corridor=lane) for p in (comfort, free)]
        assert all(p.status == "solved" for p in plans)
        assert (plans[0].inputs[:, 0].min() >= -2.0 - 1e-6) == within
        assert plans[1].inputs[:, 0].min() < -2.4


def test_a_plan_is_comfortable_up_to_its_first_input_beyond_the_envelope():
    """At 10 m/s on a 2.6 m wheelbase, a steering of atan(0.078) gives 3 m/s^2 of lateral
    acceleration: beyond a 2 m/s^2 envelope from that input on, as braking at 2.5 m/s^2 is; at a
    crawl it is beyond it only when judged at a speed of 10 m/s."""
    inputs = np.array([[1.0, 0.0], [-2.0, 0.0], [0.0, np.arctan(3.0 * 2.6 / 100.0)], [-2.5, 0.0]])
    states = np.zeros((5, 4))
    states[:, 3] = 10.0
    plan = Plan(states, inputs, "solved", 0.0, "fatrop")
    assert plan.comfortable_steps(2.0, 2.0, 2.6) == 2
    assert plan.comfortable_steps(2.0, np.inf, 2.6) == 3
    assert plan.comfortable_steps(np.inf, np.inf, 2.6) == 4
    plan.states[:, 3] = 1.0  # at 1 m/s that steering gives 0.03 m/s^2; not at least 10 m/s
    assert plan.comfortable_steps(np.inf, 2.0, 2.6) == 4
    assert plan.comfortable_steps(np.inf, 2.0, 2.6, speed=10.0) == 2
