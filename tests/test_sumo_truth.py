"""SUMO's own outputs tell the truth about the cars we drive: the speed SUMO gives a car we move
is our model's speed, SUMO warns of no emergency braking it did not do, its trips end when the
cars finish their tasks, and steps.csv marks every car that arrived."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aac_sumo import config
from aac_sumo.cli.app import main
from aac_sumo.experiments.common import robot_spec
from aac_sumo.runs import runner
from aac_sumo.sim.sumo import SumoSimulator
from aac_sumo.sim.sumo_options import SumoOptions

HIGHWAY = Path(__file__).resolve().parents[1] / "sumo_networks" / "highway_work_zone" / "highway_work_zone.net.xml"
SMALL = ["controller.coordinator=independent", "controller.horizon=5"]


def fcd_rows(path: Path) -> pd.DataFrame:
    """fcd.xml as rows ``t, robot, fcd_v, lane``."""
    rows = [(round(float(step.get("time")), 6), v.get("id"), float(v.get("speed")), v.get("lane"))
            for step in ET.parse(path).getroot() for v in step.findall("vehicle")]
    return pd.DataFrame(rows, columns=["t", "robot", "fcd_v", "lane"])


def test_a_car_we_drive_onto_a_slower_lane_keeps_its_speed_in_sumos_eyes(tmp_path):
    """A routed car of a vType with speed factor 0.75 drives straight on at 16 m/s from the
    highway's approach (22.22 m/s) into its work zone (16.67 m/s). SUMO caps the speed it
    derives from a move at the speed it allows the car on the lane (limit times speed factor,
    12.49 m/s there): it showed 12.49 in fcd.xml and warned of emergency braking (35 m/s^2) every
    step. Now its speed is 16 on both edges and across the junction between them, and it warns
    of nothing."""
    routes = tmp_path / "slow.rou.xml"
    routes.write_text('<routes><vType id="slow" length="4.0" width="1.8" speedFactor="0.75" maxSpeed="20"/>'
                      '<vehicle id="car" type="slow" depart="0" departLane="3" departPos="300" departSpeed="16">'
                      '<route edges="approach work after"/></vehicle></routes>')
    robot = robot_spec(config.load("highway_work_zone"), "car", 4.0, 1.8)
    options = SumoOptions(HIGHWAY, [routes], output_dir=tmp_path, outputs=("fcd",))
    sim = SumoSimulator([robot], np.zeros((1, 4)), 0.1, [], options, routed=frozenset({"car"}))
    speeds, lanes = [], []
    try:
        for _ in range(60):  # 96 m: past the work zone's start 50 m ahead
            sim.step(np.zeros((1, 2)))
            speeds.append(sim.api.vehicle.getSpeed("car"))
            lanes.append(sim.api.vehicle.getLaneID("car"))
    finally:
        sim.close()
    assert "approach_3" in lanes and "work_3" in lanes
    assert np.all(np.abs(np.array(speeds) - 16.0) < 1e-9)
    fcd = fcd_rows(tmp_path / "fcd.xml")
    assert (fcd["fcd_v"] == 16.0).all()
    assert "emergency" not in (tmp_path / "sumo.log").read_text().lower()


def test_the_last_car_to_arrive_is_marked_arrived_when_the_run_completes():
    """The run completes at the observation where the last car finishes; steps.csv marks it
    arrived there (it had no row at that time, so 14 of 15 cars were marked)."""
    result = runner.run(config.load("lane_change", SMALL + ["lane_change.vehicles=3", "scenario.duration=40.0"]))
    m, steps = result.metrics, result.steps
    assert m["completed"] is True
    first = steps[steps["arrived"].astype(bool)].groupby("robot")["t"].min()
    assert set(first.index) == set(steps["robot"])
    assert first.max() == pytest.approx(m["task_duration_s"])
    last = steps[steps["t"] == steps["t"].max()]
    assert last["arrived"].astype(bool).all() and last["status"].fillna("").eq("").all()  # no solve then
    before = steps[steps["robot"].isin(last["robot"])].groupby("robot").nth(-2).set_index("robot")
    assert (last.set_index("robot")[["accel", "steer", "mode"]] == before[["accel", "steer", "mode"]]).all().all()  # held


@pytest.mark.slow
def test_the_s2_demo_agrees_with_sumos_tripinfo_and_fcd(tmp_path, capsys):
    """The S2 demo with SUMO's tripinfo and fcd outputs. tripinfo.xml lists all 15 cars, each
    arriving when steps.csv first marks it arrived, within one step (SUMO logs a removal between
    two steps at the next step's time): it had no trip of the 10 cars still driving when the run
    completed, and the others arrived some 15 s late, where they left the road's end. fcd.xml's
    speed of each car at each time is steps.csv's ``v`` then (to fcd's two decimals): it showed
    the speed of the step before. Every row of a car up to its arrival is in
    fcd.xml, none after. SUMO warns of no emergency braking or stop. The demo's own figures are
    those the README gives."""
    out = tmp_path / "s2"
    assert main(["run", "lane_change", "--set", "sumo.outputs=tripinfo,fcd", "--out", str(out)]) == 0
    capsys.readouterr()
    steps = pd.read_csv(out / "steps.csv")
    steps["t"] = steps["t"].round(6)
    dt = 0.1
    arrived = steps[steps["arrived"].astype(bool)].groupby("robot")["t"].min()
    assert steps["robot"].nunique() == 15 and set(arrived.index) == set(steps["robot"])
    trips = {t.get("id"): float(t.get("arrival")) for t in ET.parse(out / "tripinfo.xml").getroot().findall("tripinfo")}
    assert set(trips) == set(arrived.index)
    for name, t in trips.items():
        assert abs(t - arrived[name]) <= dt + 1e-6, name
    fcd = fcd_rows(out / "fcd.xml")
    both = steps.merge(fcd, on=["t", "robot"], how="left")
    before = both["t"] <= both["robot"].map(arrived) + 1e-9  # SUMO has it until the observation it arrived at
    assert both.loc[before, "fcd_v"].notna().all() and both.loc[~before, "fcd_v"].isna().all()
    assert (both.loc[before, "fcd_v"] - both.loc[before, "v"]).abs().max() <= 0.005 + 1e-9
    log = (out / "sumo.log").read_text().lower()
    assert "emergency" not in log
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["completed"] and metrics["collisions"] == 0 and metrics["sim_collisions"] == 0


def test_a_road_without_cones_or_walkers_says_the_task_is_the_lane_changes_alone(capsys):
    """A lane_change run on a network whose route files hold no cones and no walkers (here the
    bundled road with none) says so in one line; the bundled files, with both, say nothing."""
    from aac_sumo.experiments import build
    from aac_sumo.experiments.lane_change import BUNDLED_NET

    notice = "aac-sumo: note: no cones or walkers in the route files: the task is the lane changes alone"
    for sets, said in (([f"sumo.net={BUNDLED_NET}"], True), ([], False)):
        setup = build(config.load("lane_change", SMALL + ["lane_change.vehicles=3", *sets]))
        setup.sim.close()
        err = capsys.readouterr().err.splitlines()
        assert (notice in err) == said and err.count(notice) <= 1
