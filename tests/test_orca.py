"""The ORCA baseline (controller.coordinator = "orca"): RVO2 through the real pyrvo wheel, on the
robots' covering discs, driven by the velocity-tracking law on our bicycles. Collisions are
counted by the simulator on the rectangular footprints, not by ORCA."""

from __future__ import annotations

import numpy as np
import pyrvo
import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.cli.app import main
from aac_sumo.coordination.orca import rectangle_polygon
from aac_sumo.experiments import build
from aac_sumo.metrics import METRIC_KEYS

ORCA = ["controller.coordinator=orca"]


def headon(axis: str) -> config.Scenario:
    """Two robots 10 m apart facing each other on one line (along x or along y), no jitter,
    no debris: the exactly symmetric head-on swap."""
    if axis == "x":
        starts, goals = [[-5.0, 0.0, 0.0], [5.0, 0.0, np.pi]], [[5.0, 0.0], [-5.0, 0.0]]
    else:
        starts, goals = [[0.0, -5.0, np.pi / 2], [0.0, 5.0, -np.pi / 2]], [[0.0, 5.0], [0.0, -5.0]]
    base = config.load("swarm_rescue", ORCA)
    raw = {section: dict(keys) for section, keys in base.data.items()}
    raw["swarm_rescue"] = dict(starts=starts, goals=goals, debris=[], cruise_speed=1.0, goal_tolerance=0.3, start_jitter=0.0)
    raw["scenario"]["duration"] = 25.0
    return config.Scenario.from_dict(raw, "<head-on>")


def rvo2_headon_side() -> float:
    """RVO2 on its own (holonomic discs, radius 0.36 m, the anchor's settings): two agents swap
    along the x axis. Returns agent 0's largest sideways offset to its left (+y: left of +x)."""
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(0.1)
    goals = [(5.0, 0.0), (-5.0, 0.0)]
    for start in [(-5.0, 0.0), (5.0, 0.0)]:
        sim.add_agent(start, 3.0, 10, 2.0, 2.0, 0.36, 1.0, (0.0, 0.0))
    offset = 0.0
    for _ in range(150):
        for i, goal in enumerate(goals):
            gap = np.subtract(goal, sim.get_agent_position(i).to_tuple())
            dist = float(np.hypot(*gap))
            sim.set_agent_pref_velocity(i, tuple(gap / dist * min(1.0, dist)) if dist > 1e-6 else (0.0, 0.0))
        sim.do_step()
        y = sim.get_agent_position(0).y
        offset = y if abs(y) > abs(offset) else offset
    return offset


def test_rvo2_passes_a_head_on_neighbour_on_the_right():
    """RVO2's documented construction: in an exactly symmetric head-on (the relative velocity
    along the line between the agents, det = 0) each agent projects on the right leg of the
    velocity obstacle, so both swerve to their right and pass each other right side to right side."""
    assert rvo2_headon_side() < -0.1


@pytest.mark.parametrize("axis", ["x", "y"])
def test_head_on_swap_passes_on_the_right_as_rvo2_without_collision(axis):
    """Our robots under ORCA do what RVO2's discs do: they pass each other, each swerving to
    its right as RVO2's agents do, without a footprint overlap, and both reach their goals."""
    result = runner.run(headon(axis))
    m = result.metrics
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0 and m["min_clearance_m"] > 0
    steps = result.steps
    r0 = steps[steps["robot"] == "robot0"]
    r1 = steps[steps["robot"] == "robot1"]
    # sideways offset of each rear axle, positive to the left of its direction of travel
    left0 = -r0["x"] if axis == "y" else r0["y"]
    left1 = r1["x"] if axis == "y" else -r1["y"]
    side0 = left0.iloc[np.argmax(np.abs(left0.to_numpy()))]
    side1 = left1.iloc[np.argmax(np.abs(left1.to_numpy()))]
    assert np.sign(side0) == np.sign(side1) == np.sign(rvo2_headon_side()) == -1.0
    assert abs(side0) > 0.1 and abs(side1) > 0.1  # a real swerve, not numerical noise


@pytest.mark.parametrize("scenario, sets", [
    ("swarm_rescue", []),  # 5 robots among 3 debris polygons
    ("circle_swap", ["circle_swap.n_robots=8", "scenario.duration=30"]),
    ("random_crossing", ["scenario.duration=30"]),  # 20 robots among debris
])
def test_a_small_orca_run_on_each_internal_kind_completes_with_every_metric(scenario, sets):
    m = runner.run(config.load(scenario, ORCA + sets)).metrics
    assert set(METRIC_KEYS) <= set(m)
    assert m["coordinator"] == "orca"
    assert m["solves"] == 0 and m["safety_stops"] == 0  # no MPC, no emergency layer
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0
    assert m["compute_ms_mean"] > 0


def test_the_inputs_keep_the_vehicle_limits():
    """The tracking law turns ORCA's velocities into bicycle inputs within the limits:
    acceleration, steering angle, steering rate and lateral acceleration."""
    scenario = config.load("circle_swap", ORCA + ["circle_swap.n_robots=8", "scenario.duration=15"])
    steps = runner.run(scenario).steps
    r = scenario.data["robot"]
    assert steps["accel"].between(r["a_min"] - 1e-9, r["a_max"] + 1e-9).all()
    assert steps["steer"].abs().max() <= r["steer_max"] + 1e-9
    assert steps["lat_accel"].abs().max() <= r["a_lat_max"] * 1.05  # the bound is taken at the next period's speed
    rate = steps.groupby("robot")["steer"].diff().abs().dropna()
    assert rate.max() <= r["steer_rate_max"] * scenario["scenario.dt"] + 1e-9


def test_discs_and_debris_as_rvo2_sees_them():
    """Each robot is its covering disc (hypot(length, width) / 2 plus the margin); each piece of
    debris is an RVO2 obstacle polygon, counter-clockwise."""
    setup = build(config.load("swarm_rescue", ORCA + ["orca.radius_margin=0.05"]))
    coord, world = setup.coordinator, setup.sim.observe()
    assert np.allclose(coord.radii(world), np.hypot(0.6, 0.4) / 2 + 0.05)
    coord.decide(world)
    sim = coord._rvo
    assert sim.get_num_agents() == 5 and sim.get_agent_radius(0) == pytest.approx(np.hypot(0.6, 0.4) / 2 + 0.05)
    assert sim.get_num_obstacle_vertices() == 4 * len(world.obstacles)
    corners = np.array(rectangle_polygon((0.0, 0.0), 2.0, 1.0, 0.3))
    area = 0.5 * np.sum(corners[:, 0] * np.roll(corners[:, 1], -1) - np.roll(corners[:, 0], -1) * corners[:, 1])
    assert area == pytest.approx(2.0)  # positive: counter-clockwise


@pytest.mark.parametrize("setting, key", [
    ("orca.neighbour_dist=3", "orca.neighbour_dist"),
    ("orca.time_horizon=0", "orca.time_horizon"),
    ("orca.max_neighbors=ten", "orca.max_neighbors"),
])
def test_a_bad_orca_key_ends_with_exit_2_and_one_line(capsys, setting, key):
    assert main(["run", "circle_swap", "--set", "controller.coordinator=orca", "--set", setting]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and key in err and "Traceback" not in err


def test_orca_on_a_kind_it_does_not_serve_ends_with_exit_2(capsys):
    assert main(["run", "braking", "--set", "controller.coordinator=orca"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "controller.coordinator" in err


def test_orca_is_a_valid_coordinator_before_any_experiment_is_imported():
    """``aac-sumo sweep`` and ``tune`` load the scenario before the experiments register
    their coordinators: the value is declared in the schema itself."""
    import subprocess
    import sys

    code = "from aac_sumo import config; print(config.load('circle_swap', ['controller.coordinator=orca'])['controller.coordinator'])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "orca"


def test_the_halfplane_tracking_law_keeps_a_head_on_swap_apart():
    """With ``orca.tracking = halfplanes`` the speed keeps ORCA's half-planes where the robot
    can: the head-on swap still passes without an overlap and both robots arrive."""
    scenario = headon("x").with_overrides(["orca.tracking=halfplanes"])
    m = runner.run(scenario).metrics
    assert m["completed"] is True, m.get("incomplete_reason")
    assert m["collisions"] == 0 and m["min_clearance_m"] > 0


def test_the_rvo2_disc_table_runs_the_seeds_it_is_given_and_names_them(tmp_path):
    """``python -m aac_sumo.tables.orca_discs --seed S --seeds N``: each of the 9 cells over seeds
    S..S+N-1, in files named for them, the first line naming the command; the same seed gives the
    same run (the table's held-out blocks are comparable with ours)."""
    import pandas as pd

    from aac_sumo.tables import orca_discs

    assert orca_discs.main(["--seed", "7", "--seeds", "1", "--out", str(tmp_path)]) == 0
    runs = pd.read_csv(tmp_path / "orca_rvo2_discs_seeds7-7.csv")
    assert len(runs) == 9 and set(runs["seed"]) == {7}
    assert set(zip(runs["n_robots"], runs["radius"])) == {(n, r) for n in (8, 16, 24) for r in (4.0, 6.0, 8.0)}
    assert "--seed 7 --seeds 1" in (tmp_path / "orca_rvo2_discs_seeds7-7.md").read_text().splitlines()[2]
    again = orca_discs.run(16, 4.0, 7)
    row = runs[(runs["n_robots"] == 16) & (runs["radius"] == 4.0)].iloc[0]
    assert again["completed"] == row["completed"] and again["min_gap_m"] == pytest.approx(row["min_gap_m"], abs=1e-9)


@pytest.mark.parametrize("args, flag", [(["--seed", "-1"], "--seed:"), (["--seeds", "0"], "--seeds:")])
def test_the_rvo2_disc_table_refuses_impossible_seeds_with_exit_2_and_one_line(tmp_path, capsys, args, flag):
    from aac_sumo.tables import orca_discs

    assert orca_discs.main([*args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and flag in err[0] and "expected an integer" in err[0] and args[1] in err[0]
    assert not list(tmp_path.iterdir())  # nothing run, nothing written
