"""controller.coordinator = "sumo": SUMO's own driver moves the controlled cars
(docs/baselines_sumo.md). Real libsumo, no mocks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aac_sumo import config
from aac_sumo.runs.files import write_run
from aac_sumo.runs import runner
from aac_sumo.config import ScenarioError
from aac_sumo.experiments.lane_change import BUNDLED_NET, BUNDLED_NET_DIR
from aac_sumo.network import sumo_binary
from aac_sumo.sim.sumo import applied_inputs

LENGTH, WIDTH, WHEELBASE = 4.0, 1.8, 2.6  # the bundled scenario's cars
TARGET = {0: 1, 1: 2, 2: 1}  # the bundled road's target lanes (cones close lane 0)


def pure_sumo(seed: int, n: int, steps: int, change_start: float = 5.0) -> dict[tuple[float, str], tuple[float, float, float]]:
    """The bundled scenario's cars in plain libsumo, without aac-sumo: inserted with
    ``vehicle.add`` at the scenario's starts (lane k mod 3, rear axle at the seeded arc length,
    10 m/s, at most 10 m/s as our references), each asked for its target lane with ``changeLane`` once it has driven
    ``change_start`` metres. Footprint centre and heading [rad] by (t, name), t = 0 after the
    insertion step."""
    import libsumo as traci

    rng = np.random.default_rng(seed)
    lane = np.arange(n) % 3
    s0 = np.maximum(10.0 + (np.arange(n) // 3) * 30.0 + lane * 10.0 + rng.uniform(-1.0, 1.0, n), 0.0)
    routes = f"{BUNDLED_NET_DIR / 'cones.rou.xml'},{BUNDLED_NET_DIR / 'pedestrians.rou.xml'}"
    traci.start([sumo_binary("sumo"), "-n", str(BUNDLED_NET), "-r", routes, "--step-length", "0.1", "--seed", str(seed),
                 "--collision.action", "warn", "--collision.mingap-factor", "0", "--collision.check-junctions", "true",
                 "--intermodal-collision.action", "warn", "--time-to-teleport", "-1", "--no-step-log", "--no-warnings"])
    poses = {}
    try:
        traci.route.add("road", ["E0", "E1"])
        traci.vehicletype.copy("DEFAULT_VEHTYPE", "car")
        traci.vehicletype.setLength("car", LENGTH)
        traci.vehicletype.setWidth("car", WIDTH)
        names = [f"veh{k}" for k in range(n)]
        for k, name in enumerate(names):  # the front bumper is (length + wheelbase) / 2 ahead of the rear axle
            traci.vehicle.add(name, "road", "car", depart="now", departLane=str(lane[k]), departPos=repr(float(s0[k] + 0.5 * (LENGTH + WHEELBASE))),
                              departSpeed="10.0")
            traci.vehicle.setMaxSpeed(name, 10.0)  # sumo.driver_speed = -1: our references' cruise speed
        traci.simulationStep()
        t0, asked = traci.simulation.getTime(), set()
        for _ in range(steps + 1):
            t = round(traci.simulation.getTime() - t0, 6)
            present = set(traci.vehicle.getIDList())
            for k, name in enumerate(names):
                if name not in present:
                    continue
                x, y = traci.vehicle.getPosition(name)
                heading = math.radians(90.0 - traci.vehicle.getAngle(name))
                poses[(t, name)] = (x - 0.5 * LENGTH * math.cos(heading), y - 0.5 * LENGTH * math.sin(heading), heading)
                if name not in asked and traci.vehicle.getDistance(name) >= change_start:
                    traci.vehicle.changeLane(name, TARGET[int(lane[k])], 1e6)
                    asked.add(name)
            traci.simulationStep()
    finally:
        traci.close()
    return poses


def assert_same_poses(result, seed: int, n: int) -> None:
    traj = result.trajectories[result.trajectories["kind"] == "controlled"]
    steps = int(round(traj["t"].max() / 0.1))
    pure = pure_sumo(seed, n, steps)
    assert len(traj) > 0 and len(traj) <= len(pure)
    worst = 0.0
    for row in traj.itertuples():
        x, y, heading = pure[(round(row.t, 6), row.name)]
        turn = abs(math.remainder(row.heading - heading, 2 * math.pi))
        worst = max(worst, abs(row.x - x), abs(row.y - y), turn)
    assert worst < 1e-6
    lanes = traj.groupby("name")["y"].agg(["first", "last"])
    assert (abs(lanes["last"] - lanes["first"]) > 3.0).sum() >= 1  # lane changes happened within the span compared


def test_sumo_driver_matches_a_pure_sumo_run_pose_for_pose():
    scenario = config.load("lane_change", ["controller.coordinator=sumo", "lane_change.vehicles=6", "scenario.duration=8.0",
                                           "scenario.seed=3"])
    assert_same_poses(runner.run(scenario), 3, 6)


@pytest.mark.slow
def test_sumo_driver_matches_a_pure_sumo_run_pose_for_pose_on_the_whole_bundled_run():
    result = runner.run(config.load("lane_change", ["controller.coordinator=sumo", "scenario.seed=1"]))
    assert result.metrics["completed"] is True
    assert_same_poses(result, 1, 15)


def test_small_lane_change_with_sumo_driving_completes_with_the_usual_metrics(tmp_path):
    result = runner.run(config.load("lane_change", ["controller.coordinator=sumo", "lane_change.vehicles=3"]))
    m = result.metrics
    assert "error" not in m
    assert m["coordinator"] == "sumo" and m["n_robots"] == 3
    assert m["completed"] is True and m["task_duration_s"] > 0
    assert m["collisions"] == 0 and m["sim_collisions"] == 0
    assert m["solves"] == 0 and m["infeasible_solves"] == 0
    for key in ("accel_p95", "jerk_p95", "lat_accel_p95", "aggressive_driving_rate", "min_pedestrian_clearance_m", "tracking_error_m",
                "min_clearance_m", "pedestrian_wait_s"):
        assert m[key] is not None and np.isfinite(m[key]), key
    steps = result.steps
    assert set(steps["mode"]) == {"sumo"}
    # the recorded inputs are SUMO's motion: speed changes match the accel column
    for _, car in steps.groupby("robot"):
        assert np.allclose(np.diff(car["v"].to_numpy()), car["accel"].to_numpy()[:-1] * 0.1, atol=1e-9)
    write_run(result, tmp_path)
    assert {"metrics.json", "steps.csv", "trajectories.csv"} <= {p.name for p in tmp_path.iterdir()}


def test_sumo_driver_is_refused_on_a_kind_sumo_does_not_host():
    with pytest.raises(ScenarioError, match="controller.coordinator"):
        runner.run(config.load("swarm_rescue", ["controller.coordinator=sumo"]))


def test_applied_inputs_give_back_the_speed_change_and_the_steering_of_the_turn():
    before = np.array([[0.0, 0.0, 0.0, 10.0], [0.0, 0.0, 3.1, 0.0]])
    after = np.array([[1.0, 0.0, 0.1, 10.5], [0.0, 0.0, -3.1, 0.0]])
    u = applied_inputs(before, after, 0.1, np.array([2.6, 2.6]))
    assert u[0, 0] == pytest.approx(5.0) and u[1, 0] == 0.0
    assert 10.0 * math.tan(u[0, 1]) / 2.6 == pytest.approx(1.0)  # yaw rate 1 rad/s
    assert u[1, 1] == 0.0  # standing: no steering to speak of


@pytest.mark.slow
def test_the_highway_work_zone_with_sumo_driving_completes():
    m = runner.run(config.load("highway_work_zone", ["controller.coordinator=sumo"])).metrics
    assert "error" not in m
    assert m["n_robots"] == 100 and m["completed"] is True
    assert m["collisions"] == 0 and m["sim_collisions"] == 0
    assert "lane_changes" not in m  # our gap rule's counts: SUMO's driver judged the gaps


def test_sumo_drives_at_our_cruise_speed_unless_asked_for_its_own():
    """By default SUMO's driver keeps to lane_change.speed (10 m/s), as our references do; with
    sumo.driver_speed = 0 it takes its own desired speed, the lane's 13.89 m/s times its speed factor."""
    base = ["controller.coordinator=sumo", "lane_change.vehicles=3", "scenario.duration=6"]
    ours = runner.run(config.load("lane_change", base)).steps
    own = runner.run(config.load("lane_change", base + ["sumo.driver_speed=0"])).steps
    assert ours["v"].max() <= 10.0 + 1e-9
    assert own["v"].max() > 11.0
