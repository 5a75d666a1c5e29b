"""The MPC's terminal stopping condition (``controller.terminal_stop``).

Specification: braking at its strongest from the horizon's end, the ego's covering discs stop
outside the footprint region of every obstacle ahead, placed where that obstacle would stop if it
braked at once. The stopping distance is the Euler model's own, so a car that keeps the condition
and then brakes never needs more than its strongest braking, whatever the horizon.
"""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.mpc.planner import INTRUSION_EPS, MpcPlanner, ego_discs
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.world import Obstacle, RobotSpec

DT, HORIZON, DECEL = 0.1, 5, 6.0
LIMITS = VehicleLimits(a_min=-DECEL, a_max=3.0, steer_max=0.6, v_min=0.0, v_max=30.0)
ROBOT = RobotSpec("ego", length=1.0, width=0.6, model=BicycleModel(wheelbase=0.8, limits=LIMITS))


def euler_stop(speed: float, decel: float, dt: float) -> float:
    """Distance [m] the explicit Euler model travels while braking at ``decel`` from ``speed``."""
    travel = 0.0
    while speed > 0.0:
        travel += speed * dt
        speed = max(speed - decel * dt, 0.0)
    return travel


@given(st.floats(0.0, 30.0), st.floats(1.0, 9.0))
@example(19.0, 4.0)  # the bound is exact here: the Euler sum came out 4e-14 m longer by rounding
def test_the_stopping_distance_bounds_the_euler_model(speed, decel):
    """``(v + b dt / 2)^2 / (2 b)`` is never shorter than the explicit Euler model's braking
    distance, and at most ``b dt^2 / 8`` longer (7.5 mm at 6 m/s^2 and 0.1 s)."""
    bound = (speed + decel * DT / 2) ** 2 / (2 * decel)
    assert -1e-9 <= bound - euler_stop(speed, decel, DT) <= decel * DT**2 / 8 + 1e-9  # equal where v / (b dt) is whole, up to rounding


def plan_towards_standing_obstacle(terminal_stop: bool, obstacle_x: float, speed: float = 10.0, robot: RobotSpec = ROBOT):
    planner = MpcPlanner(MpcConfig(horizon=HORIZON, dt=DT, barrier="cbf", slots=1, terminal_stop=terminal_stop))
    state = np.array([0.0, 0.0, 0.0, speed])
    k = np.arange(HORIZON + 1)
    reference = np.column_stack([speed * DT * k, np.zeros(HORIZON + 1), np.zeros(HORIZON + 1), np.full(HORIZON + 1, speed)])
    cone = Obstacle("cone", "cone", np.array([obstacle_x, 0.0]), np.zeros(2), 0.0, 1.0, 0.6)
    return planner, planner.plan(robot, state, reference, np.zeros(2), [cone])


@pytest.mark.parametrize("obstacle_x", [12.0, 16.0])
def test_a_plan_stops_short_of_a_standing_obstacle_beyond_its_horizon(obstacle_x):
    """At 10 m/s a 0.5 s horizon ends 5 m ahead, far from a cone 12 or 16 m ahead, so the barrier
    alone lets the car cruise on; with the condition the plan's end can still stop short of
    the cone's region (semi-axis 0.5 m grown by the disc radius, d_safe and the settling margin
    b dt^2 / (2 gamma^2): exact along the axis)."""
    offset, radius = ego_discs(ROBOT, 1)
    limit = obstacle_x - 0.5 - (radius + MpcConfig().d_safe + DECEL * DT**2 / (2 * MpcConfig().gamma ** 2))
    stops = {}
    for on in (False, True):
        planner, plan = plan_towards_standing_obstacle(on, obstacle_x)
        assert plan.status == "solved"
        end = plan.states[-1]
        stops[on] = end[0] + offset[0] + (end[3] + DECEL * DT / 2) ** 2 / (2 * DECEL)
    assert stops[True] <= limit + 1e-6
    if obstacle_x == 12.0:  # the barrier alone does not see it: the car would stop in the cone
        assert stops[False] > limit


def test_a_car_that_cannot_stop_in_time_any_more_brakes_at_once():
    """Where even braking now ends in the region, the condition asks for no more than that (within
    the millimetre of room an interior-point solver needs), so the solve stays feasible and brakes. (The
    car cannot steer here: it would swerve instead.)"""
    straight = RobotSpec("ego", 1.0, 0.6, BicycleModel(0.8, VehicleLimits(a_min=-DECEL, a_max=3.0, steer_max=1e-4, v_min=0.0, v_max=30.0)))
    _, plan = plan_towards_standing_obstacle(True, 10.0, robot=straight)
    assert plan.status == "solved"
    speeds = np.maximum(10.0 - DECEL * DT * np.arange(HORIZON + 1), 0.0)
    braking_now = DT * speeds[:-1].sum() + (speeds[-1] + DECEL * DT / 2) ** 2 / (2 * DECEL)
    end = plan.states[-1]
    assert end[0] + (end[3] + DECEL * DT / 2) ** 2 / (2 * DECEL) <= braking_now + INTRUSION_EPS + 1e-6
    assert braking_now > 10.0 - 0.4 - 0.5 - (ego_discs(ROBOT, 1)[1] + MpcConfig().d_safe)  # it cannot stop short any more
    assert plan.inputs[0, 0] < -5.0


def test_obstacles_behind_do_not_count():
    """A car behind the ego (closing in) does not make it brake: the rule is the follower's."""
    planner = MpcPlanner(MpcConfig(horizon=HORIZON, dt=DT, barrier="cbf", slots=1, terminal_stop=True))
    state = np.array([0.0, 0.0, 0.0, 10.0])
    follower = Obstacle("car", "vehicle", np.array([-6.0, 0.0]), np.array([12.0, 0.0]), 0.0, 1.0, 0.6)
    _, terminal = planner.barrier_parameters(ROBOT, state, np.zeros(2), [follower])
    assert terminal[0, 6] == 0.0


BRAKING = ["controller.horizon=5", "controller.terminal_stop=true", "controller.coordinator=independent"]


@pytest.mark.parametrize("barrier", ["cbf", "fcbf"])
def test_a_short_horizon_follows_a_hard_braking_lead_without_collision(barrier):
    """Stress campaign run 119 (20 m/s, 14.1 m apart, the lead braking at 5.92 m/s^2) collided at
    horizon 5 without the condition (docs/reliability.md); with it, both barriers stop behind the
    lead. The lead brakes almost as hard as the ego can, so the ego ends braking at its strongest:
    where only that satisfies the condition, the solver may find no interior and the fallback
    brakes instead, as hard."""
    sets = BRAKING + [f"controller.barrier={barrier}", "braking.speed=20.04", "braking.gap=14.1", "braking.lead_decel=5.92",
                      "scenario.seed=84035", "scenario.duration=8"]
    result = runner.run(config.load("braking", sets))
    assert result.metrics["collisions"] == 0 and result.metrics["min_clearance_m"] > 0
    unsolved = result.steps[~result.steps["status"].fillna("").isin(["solved", ""])]  # failed solves ("": no solve, the arrival row)
    assert (unsolved["accel"] == -DECEL).all()


@pytest.mark.slow
@settings(max_examples=8, deadline=None)
@given(st.floats(5.0, 25.0), st.floats(5.0, 15.0), st.floats(2.0, 6.0), st.sampled_from(["cbf", "fcbf"]))
def test_braking_draws_of_the_stress_campaign_never_collide(speed, gap, lead_decel, barrier):
    """The stress campaign's braking distributions at horizon 5: a lead that brakes no harder than
    the ego can is never hit."""
    sets = BRAKING + [f"controller.barrier={barrier}", f"braking.speed={speed}", f"braking.gap={gap}",
                      f"braking.lead_decel={lead_decel}", "scenario.duration=10"]
    m = runner.run(config.load("braking", sets)).metrics
    assert m["collisions"] == 0 and m["min_clearance_m"] > 0
