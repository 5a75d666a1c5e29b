"""Livelock, a case of the manoeuvre's jam rule: a robot that moves but gets no nearer its goal
for ``livelock_time`` (rocking back and forth beside it), with no unfinished robot near it doing
better, counts as stalled, so that it may manoeuvre although it never stands still."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.coordination.aac import AacCoordinator, AacParams
from aac_sumo.coordination.aac.manoeuvring import JAM_RADIUS, quiet
from aac_sumo.coordination.regions import Fleet
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.references import PathReference
from aac_sumo.runs import runner
from aac_sumo.world import RobotSpec, WorldState

DT = 0.1


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 30))
def test_a_robot_is_quiet_when_every_robot_near_it_is_idle(seed, n):
    rng = np.random.default_rng(seed)
    centres, idle = rng.uniform(-5.0, 5.0, (n, 2)), rng.random(n) < 0.6
    rows = np.flatnonzero(rng.random(n) < 0.5)
    got = quiet(centres, rows, idle)
    for r, q in zip(rows, got):
        near = np.hypot(*(centres - centres[r]).T) <= JAM_RADIUS
        assert q == bool(np.all(idle[near]))
        assert not (q and not idle[r])  # a robot that is not idle itself is never quiet


def coordinator(livelock_time: float, states: np.ndarray, goals: np.ndarray) -> tuple[AacCoordinator, list]:
    robots = [RobotSpec(f"robot{i}", 0.6, 0.4, BicycleModel(0.45, VehicleLimits(a_min=-2.0, a_max=1.0, steer_max=0.6, v_min=-1.0, v_max=1.5))) for i in range(len(states))]
    tasks = [PathReference([s[:2], g], 1.0) for s, g in zip(states, goals)]
    params = AacParams(commit=True, manoeuvre=True, manoeuvre_time=1.0, livelock_time=livelock_time)
    aac = AacCoordinator(MpcPlanner(MpcConfig(horizon=5, dt=DT)), tasks, params=params)
    aac.fleet = Fleet(robots)
    return aac, robots


def livelocked_after(livelock_time: float, neighbour_moves_on: bool, periods: int = 40) -> list[np.ndarray]:
    """Robot 0 rocks by +-0.5 m across the line to its goal, 3 m off; robot 1 stands beside it,
    or creeps on towards its own goal at 0.2 m/s (staying beside it). Each period's livelocked flags."""
    states = np.array([[0.0, 0.0, np.pi / 2, 0.5], [1.0, -1.0, np.pi / 2, 0.0]])
    goals = np.array([[3.0, 0.0], [1.0, 10.0]])
    aac, robots = coordinator(livelock_time, states, goals)
    flags = []
    for k in range(periods):
        s = states.copy()
        s[0, 1] = 0.5 * np.sin(0.3 * k)
        if neighbour_moves_on:
            s[1, 1] += 0.02 * k
        aac._count_standing(WorldState(k * DT, s, robots), k)
        flags.append(aac.livelocked.copy())
        assert aac.stalled(0) == aac.livelocked[0] or aac.jammed[0]
    return flags


def test_a_robot_rocking_beside_its_goal_is_livelocked_after_livelock_time():
    flags = livelocked_after(2.0, neighbour_moves_on=False)
    first = next(k for k, f in enumerate(flags) if f[0])
    assert first == 20  # 2 s of periods of 0.1 s without getting 0.2 m nearer its goal
    assert all(f[0] for f in flags[first:])
    assert not any(f[1] for f in flags[:20])  # robot 1 stood as long, and became livelocked only with it


def test_no_livelock_while_a_neighbour_moves_on_or_with_the_rule_off():
    assert not any(f[0] for f in livelocked_after(2.0, neighbour_moves_on=True))
    assert not any(f.any() for f in livelocked_after(0.0, neighbour_moves_on=False))


@pytest.mark.slow
def test_the_densest_swap_whose_last_robot_rocked_for_a_minute_completes():
    """24 robots on r = 4 m, seed 8 (commit 6de886a, 2026-12-07): the last robot rocked between
    the goal approach (backwards) and the back-off, 0.6-1.3 m from its goal, from 28 s to the 90 s
    limit, moving too far for the jam rule; as livelocked it manoeuvres in."""
    scenario = config.load("circle_swap", ["circle_swap.n_robots=24", "circle_swap.radius=4", "scenario.seed=8"])
    assert scenario["aac.livelock_time"] > 0.0
    result = runner.run(scenario)
    assert result.metrics["completed"] and result.metrics["collisions"] == 0
    assert result.metrics["min_clearance_m"] >= scenario["aac.commit_margin"] - 1e-9
