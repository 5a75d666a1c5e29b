"""Random crossing: the seeded draw of starts, goals and debris, its guarantees, infeasible
requests, and a short run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.cli.app import main
from aac_sumo.config import ScenarioError
from aac_sumo.experiments import build
from aac_sumo.experiments.random_crossing import area_side, draw
from aac_sumo.geometry import OrientedRect, pairwise_rect_clearance, point_rect_signed_distance


def scenario(*sets: str) -> config.Scenario:
    return config.load("random_crossing", list(sets))


def footprints(scn: config.Scenario, starts: np.ndarray) -> np.ndarray:
    r = scn.data["robot"]
    offset = 0.5 * r["wheelbase"]
    centres = starts[:, :2] + offset * np.column_stack([np.cos(starts[:, 2]), np.sin(starts[:, 2])])
    return np.column_stack([centres, np.full(len(starts), r["length"]), np.full(len(starts), r["width"]), starts[:, 2]])


def test_same_seed_same_draw_and_other_seeds_differ():
    a, b = draw(scenario("scenario.seed=7")), draw(scenario("scenario.seed=7"))
    for field in ("starts", "goals", "debris"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    c = draw(scenario("scenario.seed=8"))
    assert not np.allclose(a.starts, c.starts) and not np.allclose(a.goals, c.goals)
    assert not np.allclose(a.debris, c.debris)


def test_defaults_give_20_robots_and_debris():
    d = draw(scenario())
    assert d.starts.shape == (20, 3) and d.goals.shape == (20, 2)
    assert len(d.debris) == round(2.0 * d.side**2 / 100) >= 1


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 12))
def test_draw_keeps_its_clearances(seed, n):
    scn = scenario(f"scenario.seed={seed}", f"random_crossing.n_robots={n}")
    p, d = scn.data["random_crossing"], draw(scn)
    gap = p["clearance"]
    rows = footprints(scn, d.starts)
    # Starts: footprints apart by at least the clearance, none near debris, all inside the area.
    between = pairwise_rect_clearance(rows, rows)
    between[np.arange(n), np.arange(n)] = np.inf
    assert between.min() >= gap - 1e-9
    if len(d.debris):
        assert pairwise_rect_clearance(rows, d.debris).min() >= gap - 1e-9
        for rect in d.debris:
            assert point_rect_signed_distance(d.goals, OrientedRect(*rect)).min() > gap
    assert np.all(np.abs(d.starts[:, :2]) < d.side / 2) and np.all(np.abs(d.goals) < d.side / 2)
    # Goals apart; each far across the area from its start; robots face their goals.
    dist = np.hypot(*(d.goals[:, None] - d.goals[None]).transpose(2, 0, 1))
    dist[np.arange(n), np.arange(n)] = np.inf
    assert dist.min() >= gap
    delta = d.goals - d.starts[:, :2]
    assert np.all(np.hypot(*delta.T) >= p["min_travel_fraction"] * d.side - 1e-9)
    np.testing.assert_allclose(d.starts[:, 2], np.arctan2(delta[:, 1], delta[:, 0]))


def test_straight_paths_keep_clear_of_debris():
    scn = scenario("scenario.seed=3", "random_crossing.n_robots=15", "random_crossing.debris_density=5.0")
    d = draw(scn)
    assert len(d.debris) >= 4
    t = np.linspace(0.0, 1.0, 400)[:, None]
    for start, goal in zip(d.starts[:, :2], d.goals):
        points = start + t * (goal - start)
        for rect in d.debris:
            assert point_rect_signed_distance(points, OrientedRect(*rect)).min() >= 0.5 - 1e-9


def test_area_grows_with_n_at_constant_density():
    sides = [area_side(scenario(f"random_crossing.n_robots={n}")) for n in (5, 20, 100)]
    assert sides[0] < sides[1] < sides[2]
    np.testing.assert_allclose(np.array(sides) ** 2 / [5, 20, 100], 6.0)
    d = draw(scenario("random_crossing.n_robots=5"))
    assert np.abs(d.goals).max() < sides[0] / 2


def test_a_density_sets_the_area_instead_of_the_area_per_robot():
    """5 robots per 100 m^2: 20 m^2 a robot, so 20 robots take a 20 m x 20 m square (6 m^2 a
    robot, the scenario's own, gives sqrt(120) m); 0, the default, leaves area_per_robot in charge."""
    assert area_side(scenario("random_crossing.density=5")) == pytest.approx(20.0)
    assert area_side(scenario("random_crossing.density=5", "random_crossing.area_per_robot=1.0")) == pytest.approx(20.0)
    assert area_side(scenario()) == pytest.approx(np.sqrt(120.0))
    d = draw(scenario("random_crossing.density=5"))
    assert np.abs(d.starts[:, :2]).max() < 10.0 and np.abs(d.goals).max() < 10.0


@pytest.mark.parametrize("sets, key", [
    (["random_crossing.n_robots=200", "random_crossing.area_per_robot=0.5"], "random_crossing.n_robots"),
    (["random_crossing.debris_density=30.0", "random_crossing.debris_min_size=4.0",
      "random_crossing.debris_max_size=5.0"], "random_crossing.debris_density"),
    (["random_crossing.min_travel_fraction=1.2"], "random_crossing.min_travel_fraction"),
    (["random_crossing.path_clearance=5.0"], "random_crossing.path_clearance"),
    (["random_crossing.n_robots=2", "random_crossing.area_per_robot=0.5"], "random_crossing.area_per_robot"),
    (["random_crossing.n_robots=2", "random_crossing.density=200"], "random_crossing.density"),
    (["random_crossing.debris_max_size=0.3"], "random_crossing.debris_max_size"),
    (["random_crossing.cruise_speed=5.0"], "random_crossing.cruise_speed"),
])
def test_infeasible_requests_name_the_key(sets, key):
    with pytest.raises(ScenarioError) as err:
        build(scenario(*sets))
    assert err.value.key == key
    assert "\n" not in str(err.value) and "random_crossing.toml" in str(err.value)


@pytest.mark.parametrize("value", ["1", "1001"])
def test_n_robots_range(value):
    with pytest.raises(ScenarioError) as err:
        scenario(f"random_crossing.n_robots={value}")
    assert err.value.key == "random_crossing.n_robots"


def test_crowded_request_exits_2_with_one_line(capsys):
    argv = ["run", "random_crossing", "--set", "random_crossing.n_robots=30", "--set", "random_crossing.area_per_robot=1.5"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "random_crossing.n_robots" in err[0] and "could not place robot" in err[0]


def test_cli_subprocess_exit_status_2(tmp_path):
    exe = Path(sys.executable).with_name("aac-sumo")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "aac_sumo.cli"]
    proc = subprocess.run(cmd + ["run", "random_crossing", "--set", "random_crossing.n_robots=60",
                                 "--set", "random_crossing.area_per_robot=1.0", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "random_crossing.n_robots" in lines[0]


def test_short_run_with_4_robots():
    result = runner.run(scenario("random_crossing.n_robots=4", "scenario.duration=2.0"))
    m = result.metrics
    assert m["n_robots"] == 4 and m["scenario"] == "random_crossing"
    assert m["collisions"] == 0 and m["safety_stops"] == 0
    moved = result.steps.groupby("robot")[["x", "y"]].agg(lambda c: c.iloc[-1] - c.iloc[0])
    assert np.hypot(moved["x"], moved["y"]).max() > 0.3
