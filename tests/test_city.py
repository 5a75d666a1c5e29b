"""The city (scenario kind ``city``) in real libsumo: controlled cars on SUMO routes that turn through
signalised junctions, among SUMO's own cars and walkers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aac_sumo import cli

#: aac.3 turns left at D3 and aac.5 right at D2 (sumo_networks/city/traffic.rou.xml); every other
#: car of the route files is SUMO's to drive.
OURS = ["--set", "sumo.controlled_types=[]", "--set", 'sumo.controlled_ids=["aac.3", "aac.5"]']


def turn(steps: pd.DataFrame, robot: str) -> float:
    """The heading change [rad] of ``robot`` from its first to its last step (left positive)."""
    h = steps.loc[steps["robot"] == robot, "heading"].to_numpy()
    return float(np.angle(np.exp(1j * (h[-1] - h[0]))))


@pytest.mark.slow
def test_two_cars_turn_through_signalised_junctions_to_their_routes_ends_without_running_a_red_light(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", "city", *OURS, "--set", "scenario.duration=150", "--set", "sumo.outputs=tripinfo", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["completed"] and metrics["n_robots"] == 2
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0
    assert metrics["red_light_violations"] == 0
    steps = pd.read_csv(out / "steps.csv")
    assert turn(steps, "aac.3") == pytest.approx(np.pi / 2, abs=0.1)  # a left turn
    assert turn(steps, "aac.5") == pytest.approx(-np.pi / 2, abs=0.1)  # a right turn
    assert steps["accel"].abs().max() <= 3.0 + 1e-9  # never beyond the comfort braking


def test_a_city_run_without_controlled_cars_named_is_one_line_exit_2(tmp_path, capsys):
    code = cli.main(["run", "city", "--set", "sumo.controlled_types=[]", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "sumo.controlled_types" in err and "Traceback" not in err


@pytest.mark.slow
def test_a_car_held_at_a_red_light_sets_off_at_green_across_both_crossings_of_its_right_turn(tmp_path, capsys):
    """aac.11 follows a walker on the sidewalk towards C3, stops at the red and turns right at green:
    a commitment that would stand on a crossing is refused, so it goes on across both."""
    out = tmp_path / "out"
    code = cli.main(["run", "city", "--set", "sumo.controlled_types=[]", "--set", 'sumo.controlled_ids=["aac.11"]',
                     "--set", "scenario.duration=160", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["completed"] and not metrics["deadlock"]
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0 and metrics["red_light_violations"] == 0
    steps = pd.read_csv(out / "steps.csv")
    assert turn(steps, "aac.11") == pytest.approx(-np.pi / 2, abs=0.1)
    assert (steps["v"] < 0.05).any()  # it stood at the red
