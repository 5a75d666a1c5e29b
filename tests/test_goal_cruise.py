"""Goal cruise (``aac.goal_cruise``): on a path that ends at a goal, a committed plan goes on along
the path on the tracking law before its stopping tail, so that the others see the robot keep
going rather than braking as soon as its one-second plan ends. The continuation never brakes
harder than the tail, never reverses, and is committed only where the exact check passes."""

from __future__ import annotations

import numpy as np
import pytest

from aac_sumo import config
from aac_sumo.coordination.aac import AacCoordinator, AacParams
from aac_sumo.coordination.regions import Fleet
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.references import PathReference
from aac_sumo.runs import runner
from aac_sumo.world import RobotSpec, WorldState

DT, HORIZON = 0.1, 5


def first_commitments(goal_cruise: float, states: np.ndarray, goals: np.ndarray):
    """Every robot's commitment after the first period of committed AAC (one authority: robot 0)."""
    limits = VehicleLimits(a_min=-2.0, a_max=1.0, steer_max=0.6, v_min=-1.0, v_max=1.5)
    robots = [RobotSpec(f"robot{i}", 0.6, 0.4, BicycleModel(0.45, limits)) for i in range(len(states))]
    tasks = [PathReference([s[:2], g], 1.0, decel=0.5, approach=0.9) for s, g in zip(states, goals)]
    aac = AacCoordinator(MpcPlanner(MpcConfig(horizon=HORIZON, dt=DT)), tasks, params=AacParams(commit=True, goal_cruise=goal_cruise))
    aac.fleet = Fleet(robots)
    aac.decide(WorldState(0.0, states, robots))
    return aac, aac.book.items


def test_a_plan_goes_on_along_its_path_for_goal_cruise_before_its_tail():
    states, goals = np.array([[0.0, 0.0, 0.0, 1.0]]), np.array([[30.0, 0.0]])
    _, (without,) = first_commitments(0.0, states, goals)
    aac, (cruising,) = first_commitments(1.0, states, goals)
    assert without.planned == HORIZON
    assert cruising.planned == HORIZON + 10  # 1 s of the tracking law after the plan
    law = cruising.inputs[HORIZON:cruising.planned]
    assert np.all(np.abs(law[:, 1]) < 1e-3)  # straight on along the straight path
    assert np.all(cruising.states[: cruising.planned + 1, 3] > 0.5)  # still going when its tail begins
    assert np.all(cruising.inputs[cruising.planned:, 0] >= -aac.tail_decel()[0] - 1e-12)


def test_near_its_goal_the_continuation_ends_before_it_brakes_harder_than_the_tail():
    states, goals = np.array([[0.0, 0.0, 0.0, 1.0]]), np.array([[1.6, 0.0]])
    aac, (c,) = first_commitments(1.0, states, goals)
    tail = aac.tail_decel()[0]
    assert np.all(c.inputs[:, 0] >= -tail - 1e-9) or c.planned == HORIZON  # the plan itself may brake harder; the law never does
    law = c.inputs[HORIZON:c.planned]
    assert np.all(law[:, 0] >= -tail - 1e-12)
    assert np.all(np.diff(np.sign(c.states[:, 3])) <= 0)  # never backs up: the speed only falls to zero and stays there
    assert np.all(c.states[:, 3] >= -1e-12)


def test_the_continuation_is_committed_only_where_the_exact_check_passes():
    """Robot 1 stands across robot 0's lane 2.4 m ahead: the plan's half second, 1 s more at
    1 m/s and the tail would reach it, so robot 0's continuation is cut (to half, a quarter, or none)."""
    states = np.array([[0.0, 0.0, 0.0, 1.0], [2.4, 0.0, np.pi / 2, 0.0]])
    goals = np.array([[30.0, 0.0], [2.4, 0.01]])
    aac, (c, other) = first_commitments(1.0, states, goals)
    assert c.planned < HORIZON + 10
    assert aac.book.check(0, c, 1, np.zeros((0, 5)))[0] >= aac.book.margin


@pytest.mark.slow
def test_table_one_keeps_its_robots_apart_with_goal_cruise():
    """S1, seed 10, N = 10 (a selection seed), with the scenario's goal_cruise: completes, 0 collisions."""
    scenario = config.load("swarm_rescue", ["scenario.seed=10"])
    assert scenario["aac.goal_cruise"] > 0.0
    result = runner.run(scenario)
    assert result.metrics["completed"] and result.metrics["collisions"] == 0
    assert result.metrics["min_clearance_m"] >= scenario["aac.commit_margin"] - 1e-9
