"""The CBF-QP baseline (controller.coordinator = "cbf_qp"): a tracking input filtered by a QP with
one barrier row per neighbour, solved by OSQP (docs/baselines_cbf_qp.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.barriers import stage_parameters
from aac_sumo.cli.app import main
from aac_sumo.coordination.cbf_qp import barrier_rows, filter_input, input_bounds
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.experiments import build
from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.mpc.planner import ego_discs
from aac_sumo.world import RobotSpec

ROBOT = RobotSpec("ego", 0.6, 0.4, BicycleModel(0.45, VehicleLimits(-2.0, 1.0, 0.6, 0.0, 1.5, 3.0, 2.0, 2.0)))
DT, GAMMA, D_SAFE = 0.1, 0.3, 0.1


def circle_stages(x: float, rho: float, d: float) -> np.ndarray:
    """MPC stage parameters (3, 1, 7) of a standing circular obstacle of radius ``rho`` at ``(x, 0)``
    grown for ego clearance ``d``: a circle of radius ``rho + d``."""
    ellipses = np.tile([x, 0.0, rho, rho, 0.0], (3, 1, 1))
    return stage_parameters(ellipses, d, np.zeros(2))


def test_one_barrier_row_matches_the_hand_computation():
    """Ego at the origin heading +x at v, nominal input (a0, 0), a circle of radius R = rho + d
    centred at (X, 0) ahead. Its one disc sits o = wheelbase/2 ahead of the rear axle, so
    c1 = v dt + o and c2 = v dt + (v + a dt) dt + o on the x axis, h = ((c - X) / R)^2 - 1. The row
    of h(c2) - (1 - gamma) h(c1) >= 0 linearised at a0 is G u >= g with
    G = [2 (c2 - X) dt^2 / R^2, 0] (steering moves the disc across the axis, where dh/dy = 0) and
    g = G u0 - (h2 - (1 - gamma) h1)."""
    v, a0, X, rho = 1.2, 0.5, 2.0, 0.3
    offsets, radius = ego_discs(ROBOT, 1)
    d = radius + D_SAFE
    rows, rhs = barrier_rows(ROBOT, np.array([0.0, 0.0, 0.0, v]), np.array([a0, 0.0]), circle_stages(X, rho, d), GAMMA, DT, offsets)

    o, R = 0.225, rho + d
    c1 = v * DT + o
    c2 = v * DT + (v + a0 * DT) * DT + o
    h1, h2 = ((c1 - X) / R) ** 2 - 1, ((c2 - X) / R) ** 2 - 1
    G = np.array([2 * (c2 - X) * DT**2 / R**2, 0.0])
    np.testing.assert_allclose(rows, [G], atol=1e-12)
    np.testing.assert_allclose(rhs, [G @ [a0, 0.0] - (h2 - (1 - GAMMA) * h1)], atol=1e-12)
    assert G[0] < 0  # braking (smaller a) is what raises h: the row bounds a from above


def test_a_safe_nominal_input_passes_unchanged():
    """Far from the obstacle every row holds at the nominal input, which is then the QP's minimiser."""
    state, nominal = np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.4, 0.05])
    offsets, radius = ego_discs(ROBOT, 1)
    rows, rhs = barrier_rows(ROBOT, state, nominal, circle_stages(10.0, 0.3, radius + D_SAFE), GAMMA, DT, offsets)
    lo, hi = input_bounds(ROBOT, state, 0.05, DT)
    result = filter_input(nominal, rows, rhs, lo, hi, np.array([0.25, 1 / 0.36]))
    assert result.outcome == "unchanged"
    np.testing.assert_array_equal(result.input, nominal)


def test_an_unsafe_nominal_input_is_changed_as_little_as_the_row_needs():
    """Close ahead at full speed, holding the speed breaks the row: OSQP returns the input on the
    row (braking), within the limits."""
    state, nominal = np.array([0.0, 0.0, 0.0, 1.5]), np.array([0.0, 0.0])
    offsets, radius = ego_discs(ROBOT, 1)
    rows, rhs = barrier_rows(ROBOT, state, nominal, circle_stages(1.7, 0.3, radius + D_SAFE), GAMMA, DT, offsets)
    assert rows[0] @ nominal < rhs[0]
    lo, hi = input_bounds(ROBOT, state, 0.0, DT)
    result = filter_input(nominal, rows, rhs, lo, hi, np.array([0.25, 1 / 0.36]))
    assert result.outcome == "solved"
    assert rows[0] @ result.input == pytest.approx(rhs[0], abs=1e-5)  # active: no more change than needed
    assert np.all(result.input >= lo - 1e-9) and np.all(result.input <= hi + 1e-9)
    assert result.input[0] < 0  # it brakes


def test_an_impossible_row_is_reported_infeasible():
    """Inside the region and rushing in: no admissible input meets the row."""
    state, nominal = np.array([0.0, 0.0, 0.0, 1.5]), np.array([1.0, 0.0])
    offsets, radius = ego_discs(ROBOT, 1)
    rows, rhs = barrier_rows(ROBOT, state, nominal, circle_stages(1.2, 0.3, radius + D_SAFE), GAMMA, DT, offsets)
    lo, hi = input_bounds(ROBOT, state, 0.0, DT)
    assert not filter_input(nominal, rows, rhs, lo, hi, np.array([0.25, 1 / 0.36])).ok


def test_the_row_binds_late_because_the_input_moves_the_disc_only_by_a_dt2():
    """The one-step condition is myopic (docs/baselines_cbf_qp.md): at full speed toward a
    standing obstacle, the nominal input passes at 1.8 m, is braked at 1.7 m, and no admissible
    input meets the row at 1.6 m."""
    state, nominal = np.array([0.0, 0.0, 0.0, 1.5]), np.array([0.0, 0.0])
    offsets, radius = ego_discs(ROBOT, 1)
    lo, hi = input_bounds(ROBOT, state, 0.0, DT)
    outcomes = []
    for x in (1.8, 1.7, 1.6):
        rows, rhs = barrier_rows(ROBOT, state, nominal, circle_stages(x, 0.3, radius + D_SAFE), GAMMA, DT, offsets)
        outcomes.append(filter_input(nominal, rows, rhs, lo, hi, np.array([0.25, 1 / 0.36])).outcome)
    assert outcomes == ["unchanged", "solved", "primal_infeasible"]


def test_two_robots_head_on_stay_collision_free():
    """Two robots driving at each other on one line (internal simulator): the filter keeps them apart."""
    sets = ["controller.coordinator=cbf_qp", "swarm_rescue.starts=[[0.0, 0.0, 0.0], [8.0, 0.0, 3.14159]]",
            "swarm_rescue.goals=[[8.0, 0.0], [0.0, 0.0]]", "swarm_rescue.debris=[]", "swarm_rescue.start_jitter=0.0",
            "scenario.duration=12.0"]
    result = runner.run(config.load("swarm_rescue", sets))
    m = result.metrics
    assert m["collisions"] == 0 and m["min_clearance_m"] > 0
    assert m["solves"] > 0 and (result.steps["mode"] == "cbf_qp").any()  # the filter did act
    assert m["min_distance_m"] < 2.0  # they did come close


@pytest.mark.parametrize("kind, sets", [
    ("swarm_rescue", []),
    ("circle_swap", ["circle_swap.n_robots=4", "scenario.duration=20.0"]),
    ("random_crossing", ["random_crossing.n_robots=6", "scenario.duration=20.0"]),
    ("braking", ["braking.speed=5.0"]),
])
def test_a_small_run_of_every_internal_kind_gives_the_usual_metrics(kind, sets):
    m = runner.run(config.load(kind, ["controller.coordinator=cbf_qp", *sets])).metrics
    assert set(METRIC_KEYS) <= set(m)
    assert m["coordinator"] == "cbf_qp" and m["solves"] > 0
    assert m["infeasible_solves"] <= m["solves"]
    assert m["completed"] or m["incomplete_reason"], m


def test_the_swarm_rescue_completes_without_collisions():
    m = runner.run(config.load("swarm_rescue", ["controller.coordinator=cbf_qp"])).metrics
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0


def test_the_coordinator_is_built_from_its_section():
    scenario = config.load("swarm_rescue", ["controller.coordinator=cbf_qp", "cbf_qp.radius=2.5", "cbf_qp.lookahead=0.8"])
    coord = build(scenario).coordinator
    assert coord.name == "cbf_qp" and coord.params.radius == 2.5 and coord.params.lookahead == 0.8


@pytest.mark.parametrize("setting", ["cbf_qp.radius=-1", "cbf_qp.radius=far", "cbf_qp.neighbours=3"])
def test_bad_cbf_qp_keys_exit_2_with_one_line(setting, capsys):
    assert main(["run", "swarm_rescue", "--set", "controller.coordinator=cbf_qp", "--set", setting, "--out", "/nonexistent/x"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and setting.split("=")[0] in err


def test_the_results_table_counts_runs_as_the_docs_say():
    """docs/results/cbf_qp_seeds0-4.md: completions, deadlocks and collisions are counted in runs
    and episodes; the task time is the mean over completed runs only."""
    import pandas as pd

    from aac_sumo.tables.cbf_qp import summarise

    runs = pd.DataFrame({
        "case": ["c"] * 3, "controller.barrier": ["fcbf"] * 3, "status": ["ok"] * 3,
        "completed": [True, False, False], "deadlock": [False, True, True], "collisions": [0, 2, 0],
        "sim_collisions": [None] * 3, "task_duration_s": [10.0, None, None], "infeasibility_rate": [0.0, 0.5, 0.1],
        "min_clearance_m": [0.2, -0.1, 0.05], "min_distance_m": [1.0, 0.5, 0.7], "min_pedestrian_clearance_m": [None] * 3,
        "compute_ms_median": [1.0, 2.0, 3.0], "emergency_brakes": [0, 1, 0],
    })
    row = summarise(runs).iloc[0]
    assert (row.runs, row.completed, row.deadlocks, row.collision_runs, row.collisions) == (3, 1, 2, 1, 2)
    assert row.task_duration_s == 10.0 and row.min_clearance_m == -0.1 and row.sim_collisions is None
    assert row.infeasibility_rate == pytest.approx(0.2)


def test_a_fresh_cli_process_accepts_cbf_qp_in_a_saved_run(tmp_path):
    """The coordinator is registered when the experiments are imported: a new process that only
    reads a saved scenario.toml (compare, animate) must know it too."""
    import os
    import subprocess
    import sys

    run = tmp_path / "run"
    assert main(["run", "swarm_rescue", "--set", "controller.coordinator=cbf_qp", "--set", "scenario.duration=1.0", "--out", str(run)]) == 0
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    done = subprocess.run([sys.executable, "-m", "aac_sumo.cli", "compare", str(run), str(run), "--out", str(tmp_path / "cmp")],
                          capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
