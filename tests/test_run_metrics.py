"""Honest run metrics, on short closed-loop runs: every coordinator is measured on the same
samples, one-off set-up stays out of the periods' compute time without changing the run, and
every solve's iterations and iteration cap are on record."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from aac_sumo import config, experiments
from aac_sumo.runs import runner
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.mpc.problem import get_problem
from aac_sumo.world import RobotSpec

SHORT = ["scenario.duration=1.0"]
TIMINGS = ["solve_ms"]  # the only step columns that depend on the machine


@pytest.fixture(scope="module", params=["aac", "lfc"])
def short_run(request):
    return runner.run(config.load("swarm_rescue", SHORT + [f"controller.coordinator={request.param}"]))


def test_every_robot_has_its_reference_at_every_step(short_run):
    """Whatever the coordinator solved or not, each row's reference is the projection of the
    robot's rear axle onto its task's path (stage 0 of an MPC reference), and tracking_error_m
    is the mean distance to it over all rows."""
    steps = short_run.steps
    assert len(steps) == short_run.metrics["n_robots"] * len(short_run.periods)
    ref = steps[["ref_x", "ref_y", "ref_heading", "ref_v"]].to_numpy()
    assert np.isfinite(ref).all()
    tasks = experiments.build(short_run.scenario).tasks
    names = [f"robot{i}" for i in range(len(tasks))]
    for row in steps.itertuples():
        state = np.array([row.x, row.y, row.heading, row.v])
        expected = tasks[names.index(row.robot)].horizon(state, 0, short_run.scenario["scenario.dt"])[0]
        np.testing.assert_array_equal([row.ref_x, row.ref_y, row.ref_heading, row.ref_v], expected)
    assert short_run.metrics["tracking_error_m"] == pytest.approx(np.hypot(steps.x - steps.ref_x, steps.y - steps.ref_y).mean())


def test_every_solve_records_its_iterations(short_run):
    """Rows with a solve carry the solver's iteration count (at least one, at most the cap plus
    fatrop's starting point); rows without one carry -1 and are never capped."""
    steps = short_run.steps
    solved = steps["status"].notna()
    assert solved.any()
    cap = short_run.scenario["controller.max_iter"]
    assert steps.loc[solved, "iterations"].between(1, cap + 1).all()
    assert (steps.loc[~solved, "iterations"] == -1).all() and not steps.loc[~solved, "capped"].any()
    assert short_run.metrics["capped_solves"] == int(steps["capped"].sum())


def test_a_solve_stopped_at_its_iteration_cap_is_marked_capped():
    """On an empty road a feasible iterate after two ipopt iterations is still a plan the robot
    may drive (``solved``) but it is marked ``capped``; with room to converge it is not."""
    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.6, v_min=0.0, v_max=12.0)
    robot = RobotSpec("ego", 1.0, 0.6, BicycleModel(0.8, limits))
    k = np.arange(11)
    reference = np.column_stack([0.5 * k, np.zeros(11), np.zeros(11), np.full(11, 5.0)])
    plans = {}
    for max_iter in (2, 100):
        get_problem.cache_clear()
        planner = MpcPlanner(MpcConfig(horizon=10, dt=0.1, solver="ipopt", slots=1, max_iter=max_iter, retry_with_ipopt=False))
        plans[max_iter] = planner.plan(robot, np.array([0.0, 0.0, 0.0, 4.0]), reference, np.zeros(2), [])
    get_problem.cache_clear()
    assert (plans[2].status, plans[2].iterations, plans[2].capped) == ("solved", 2, True)
    assert plans[100].status == "solved" and not plans[100].capped and plans[100].iterations < 100


def test_capped_solves_reach_steps_and_metrics():
    """With ipopt capped at two iterations, solves stop at the cap: steps.csv marks them and
    capped_solves counts them."""
    result = runner.run(config.load("swarm_rescue", ["scenario.duration=0.3", "controller.coordinator=lfc", "controller.solver=ipopt",
                                                     "controller.max_iter=2", "controller.retry_with_ipopt=false",
                                                     "controller.codegen=false"]))
    steps = result.steps
    assert steps["capped"].any()
    assert (steps.loc[steps["capped"], "iterations"] == 2).all()
    assert result.metrics["capped_solves"] == int(steps["capped"].sum()) > 0


@pytest.mark.parametrize("coordinator", ["aac", "lfc"])
def test_the_warm_up_changes_nothing_the_run_decides(coordinator, monkeypatch):
    """A run whose warm-up is skipped records exactly the same steps (timings aside): warming
    up must not touch the run's solvers, random generator or memory."""
    scenario = config.load("swarm_rescue", SHORT + [f"controller.coordinator={coordinator}", "scenario.seed=2"])
    warm = runner.run(scenario)
    monkeypatch.setattr(runner, "warm_up", lambda setup, world: None)
    cold = runner.run(scenario)
    pd.testing.assert_frame_equal(warm.steps.drop(columns=TIMINGS), cold.steps.drop(columns=TIMINGS))
    assert warm.metrics["setup_s"] > 0


LOOP_COMPILES = """
import json, sys
import numba
from aac_sumo import config
from aac_sumo.runs import runner

def loaded():
    return {f"{module}.{name}": sorted(map(str, f.signatures)) for module in list(sys.modules)
            if module.startswith("aac_sumo.kernels.") for name, f in vars(sys.modules[module]).items()
            if isinstance(f, numba.core.registry.CPUDispatcher)}

after_warm_up = {}
warm_up = runner.warm_up
def recording(setup, world):
    warm_up(setup, world)
    after_warm_up.update(loaded())
runner.warm_up = recording
runner.run(config.load(sys.argv[1], sys.argv[2:]))
end = loaded()
print(json.dumps({name: sorted(set(end[name]) - set(after_warm_up.get(name, []))) for name in end if end[name] != after_warm_up.get(name, [])}))
"""


@pytest.mark.parametrize("name, sets", [("swarm_rescue", ["controller.coordinator=aac", "aac.safety_stop=true"]),
                                        ("swarm_rescue", ["controller.coordinator=lfc", "lfc.safety_stop=false"]),
                                        ("random_crossing", ["scenario.seed=0", "scenario.duration=8.0"])])
def test_no_kernel_is_loaded_or_compiled_inside_the_loop(name, sets):
    """In a fresh process every compiled kernel a run calls is loaded (or compiled) by the
    warm-up, before the first period, so the periods' compute time holds none of it. The runs
    are long enough for robots to meet (proximity decisions, safety stops) and, in the random
    crossing, to plan detours round robots that stand."""
    out = subprocess.run([sys.executable, "-c", LOOP_COMPILES, name, "scenario.duration=6.0", *sets],
                         capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {}


def test_deadlock_rule_needs_every_unfinished_robot_to_stay_put_the_whole_window():
    still = [np.array([[0.0, 0.0], [5.0, 5.0]])] * 81
    stuck = runner.stuck
    assert stuck(still, np.array([True, True]), 0.16)
    # robot 1 drives off 1 m and comes back to where it was: not stuck, though it ends where it began
    away = [np.array([[0.0, 0.0], [5.0 + np.sin(np.pi * k / 80), 5.0]]) for k in range(81)]
    assert np.allclose(away[0], away[-1]) and not stuck(away, np.array([True, True]), 0.16)
    # ... unless it has finished: only unfinished robots count, and with none there is no deadlock
    assert stuck(away, np.array([True, False]), 0.16)
    assert not stuck(still, np.array([False, False]), 0.16)
