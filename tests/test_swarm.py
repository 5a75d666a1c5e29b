"""S1 swarm rescue and the circle swap: seeded closed-loop runs with AAC and LFC, scenario
errors, reproducibility and the outputs of a run."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.cli.app import main
from aac_sumo.config import ScenarioError


@pytest.mark.slow
@pytest.mark.parametrize("coordinator", ["aac", "lfc"])
def test_s1_at_horizon_10_completes_without_collisions(coordinator):
    m = runner.run(config.load("swarm_rescue", [f"controller.coordinator={coordinator}", "controller.horizon=10"])).metrics
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0
    assert m["min_clearance_m"] > 0
    assert m["delay_max_s"] is not None and m["delay_jain"] is not None
    assert 0 < m["authority_jain"] <= 1


@pytest.mark.slow
@pytest.mark.parametrize("coordinator", ["aac", "lfc"])
def test_circle_swap_of_8_ends_in_completion_or_a_reported_deadlock(coordinator):
    """Every emergency layer off (the scenario's default). AAC, with committed plans and the
    keep-right rule, must get through; LFC may deadlock, but then says so."""
    m = runner.run(config.load("circle_swap", [f"controller.coordinator={coordinator}", "circle_swap.n_robots=8"])).metrics
    assert m["collisions"] == 0 and m["safety_stops"] == 0
    if coordinator == "aac":
        assert m["completed"] is True, m.get("incomplete_reason")
    assert m["completed"] or m["deadlock"], m.get("incomplete_reason")
    if m["deadlock"]:
        assert m["incomplete_reason"].startswith("deadlock")


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 3])
def test_circle_swap_of_16_completes_with_aac(seed):
    """Seed 3 deadlocked while a make-room leader crept instead of driving its plan."""
    m = runner.run(config.load("circle_swap", ["circle_swap.n_robots=16", "circle_swap.radius=6.0", f"scenario.seed={seed}"])).metrics
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0 and m["safety_stops"] == 0 and m["min_clearance_m"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("n, seed", [(16, 2), (24, 1)])
def test_a_dense_circle_swap_untangles_through_detours(n, seed):
    """On r = 4 m the crowd closes into a jam round the centre; the robots that stall follow
    detours round the standing ones and every robot arrives (both runs reached the 90 s limit
    with ``aac.detour`` off), with no emergency layer and no collision."""
    m = runner.run(config.load("circle_swap", [f"circle_swap.n_robots={n}", "circle_swap.radius=4.0", f"scenario.seed={seed}"])).metrics
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0 and m["safety_stops"] == 0 and m["min_clearance_m"] > 0


def test_short_runs_are_reproducible():
    sets = ["scenario.duration=2.0", "scenario.seed=3"]
    a, b = (runner.run(config.load("swarm_rescue", sets)) for _ in range(2))
    pd.testing.assert_frame_equal(a.steps.drop(columns=["solve_ms"]), b.steps.drop(columns=["solve_ms"]))
    other = runner.run(config.load("swarm_rescue", ["scenario.duration=2.0", "scenario.seed=4"]))
    assert not a.steps[["x", "y"]].equals(other.steps[["x", "y"]])  # the seed moves the starts


def test_plain_paper_behaviour_has_no_safety_stops():
    """With the safety stop off (the paper), a 3 s circle swap of 8 runs to its time limit, every
    robot recorded in all 30 periods and driving towards the centre, and none is ever stopped by
    the safety layer, although at this margin (1.5 m) the same run with it on is stopped
    (so the zero is the setting's doing, not a quiet run's)."""
    sets = ["aac.safety_margin=1.5", "scenario.duration=3.0"]
    plain = runner.run(config.load("circle_swap", ["aac.safety_stop=false", *sets]))
    m, steps = plain.metrics, plain.steps
    assert m.get("error") is None and m["incomplete_reason"] == "time limit 3.0 s reached"
    assert m["n_robots"] == 8 and m["collisions"] == 0
    assert (steps.groupby("robot")["t"].count() == 30).all() and steps["t"].max() == pytest.approx(2.9)
    radius = np.hypot(steps["x"], steps["y"]).groupby(steps["robot"])
    # each robot covered ground towards the centre (0.94-1.04 m: with crowd authorities all eight plan every period
    # and set off on their MPC plans, a little slower than on the tracking law between turns, 1.0-1.1 m)
    assert (radius.first() - radius.last() > 0.9).all()
    assert m["safety_stops"] == 0 and not (steps["mode"] == "safety_stop").any()
    guarded = runner.run(config.load("circle_swap", ["aac.safety_stop=true", *sets])).metrics
    assert guarded["safety_stops"] > 0


@pytest.mark.parametrize("sets, key", [
    (["swarm_rescue.goals=[[15.0, 8.0]]"], "swarm_rescue.goals"),
    (["swarm_rescue.debris=[[1.0, 2.0, 3.0]]"], "swarm_rescue.debris"),
    (["swarm_rescue.goals=[[15.0, 8.0], [15.0, 1.0], [5.0, 5.3], [15.0, 5.0], [15.0, 6.5]]"], "swarm_rescue.goals"),
    (["swarm_rescue.starts=[[0.0, 1.0, 0.0], [0.2, 1.1, 0.0], [0.0, 5.0, 0.0], [0.0, 7.0, 0.0], [0.0, 9.0, 0.0]]",
      "swarm_rescue.start_jitter=0.0"], "swarm_rescue.starts"),
    (["swarm_rescue.cruise_speed=5.0"], "swarm_rescue.cruise_speed"),
])
def test_bad_swarm_scenarios_name_the_key(sets, key):
    with pytest.raises(ScenarioError) as err:
        runner.run(config.load("swarm_rescue", sets))
    assert err.value.key == key
    assert "\n" not in str(err.value)


def test_bad_swarm_scenario_exits_2_with_one_line(capsys):
    assert main(["run", "swarm_rescue", "--set", "swarm_rescue.goals=[[15.0, 8.0]]"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "swarm_rescue.goals" in err[0]


def test_run_writes_the_swarm_picture_and_the_authority_record(tmp_path, capsys):
    assert main(["run", "swarm_rescue", "--set", "scenario.duration=1.5", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "trajectories.png").stat().st_size > 10_000
    steps = pd.read_csv(tmp_path / "steps.csv")
    per_period = steps.groupby("t")["authority"].sum()
    assert (per_period == 1).all()  # AAC: exactly one authority robot each period
    assert set(steps.loc[steps["authority"], "reason"]) <= {"round_robin", "proximity"}
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["coordinator"] == "aac" and metrics["n_robots"] == 5


@pytest.mark.parametrize("coordinator", ["aac", "lfc", "independent"])
@pytest.mark.parametrize("barrier", ["fcbf", "cbf"])
def test_every_coordinator_runs_with_every_barrier(coordinator, barrier):
    m = runner.run(config.load("swarm_rescue", [f"controller.coordinator={coordinator}", f"controller.barrier={barrier}",
                                                "scenario.duration=1.0"])).metrics
    assert "error" not in m
    assert m["coordinator"] == coordinator and m["barrier"] == barrier
    assert m["solves"] > 0 and m["collisions"] == 0


def test_table_rows_average_over_seeds_and_stand_beside_the_paper():
    from aac_sumo.tables import build as tables

    runs = [dict(status="ok", **{"controller.horizon": 10, "controller.coordinator": "aac"}, task_duration_s=t, completed=c,
                 compute_ms_mean=m, min_distance_m=1.0, collisions=0)
            for t, c, m in ((18.0, True, 5.0), (None, False, 7.0), (20.0, True, 9.0))]
    runs.append(dict(status="error", **{"controller.horizon": 10, "controller.coordinator": "aac"}))
    row = tables.horizon_rows(runs, 3, ("task_duration_s", "completed", "compute_ms_mean"), tables.PAPER_TABLE_I,
                              tables.PAPER_I_METRICS)[0]
    assert row["task_duration_s"] == pytest.approx(19.0)  # completed runs only
    assert row["completed"] == pytest.approx(2 / 3)
    assert row["compute_ms_mean"] == pytest.approx(7.0) and row["compute_ms_mean_std"] == pytest.approx(2.0)
    assert (row["paper_task_duration_s"], row["paper_compute_ms_mean"], row["paper_min_distance_m"]) == (18.1, 68.4, 1.13)
    assert row["runs"] == 3 and row["errors"] == 1


def test_a_run_does_not_depend_on_what_the_process_ran_before():
    """The solvers keep state between solves; each run starts from fresh ones."""
    sets = ["controller.coordinator=lfc", "scenario.duration=3.0"]
    first = runner.run(config.load("circle_swap", sets)).steps
    runner.run(config.load("braking", ["braking.speed=10", "controller.barrier=cbf"]))  # same problem shape
    again = runner.run(config.load("circle_swap", sets)).steps
    pd.testing.assert_frame_equal(first.drop(columns=["solve_ms"]), again.drop(columns=["solve_ms"]))
