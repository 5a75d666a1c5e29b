"""Smoothness metrics (accel_p95, lat_accel_p95, jerk_p95) and pedestrian_wait_s: closed-form
checks on synthetic recordings, and the crossing geometry of a real SUMO run."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.metrics import METRIC_KEYS, crossing_ahead, crossing_lane_part, pedestrian_waits, smoothness
from aac_sumo.runs.runner import with_vehicle_columns
from aac_sumo.sim.base import Crossing

NEW_KEYS = ("accel_p95", "lat_accel_p95", "jerk_p95", "pedestrian_wait_s")
DT = 0.1
#: A crossing like the bundled lane change's: over a road along +x whose three 3.2 m lanes have
#: their centres at y = -8.0, -4.8, -1.6, at x = 239, 4 m wide.
CROSSING = Crossing(":X_c0_0", np.array([[239.0, 0.0], [239.0, -9.6]]), 4.0, 3.2)
CAR = dict(centre_offset={"car": 1.35}, length={"car": 4.5})  # rear axle -> centre [m], footprint length [m]


def test_the_new_keys_are_metric_keys():
    assert set(NEW_KEYS) <= set(METRIC_KEYS)


def test_p95_of_absolute_values_over_every_robots_steps_jerk_without_first_steps():
    """Robot a applies accel 0, 1, ..., 9 (jerk 10 m/s^3 after its first step), robot b the
    negatives -0, -1, ..., -9 (jerk -10): |accel| takes 0..9 twice, whose 95th percentile is
    9 (rank 0.95 * 19 = 18.05 of the sorted values: 9 and 9); the first steps' NaN jerk is left
    out, every other |jerk| is 10."""
    accel = np.arange(10.0)
    steps = pd.DataFrame(dict(t=np.tile(np.arange(10) * DT, 2), robot=["a"] * 10 + ["b"] * 10,
                              v=np.full(20, 2.0), steer=np.r_[np.full(10, 0.1), np.full(10, -0.2)],
                              accel=np.r_[accel, -accel]))
    steps = with_vehicle_columns(steps, {"a": 2.0, "b": 2.0}, DT)
    m = smoothness(steps)
    assert m["accel_p95"] == pytest.approx(np.percentile(np.r_[accel, accel], 95)) == pytest.approx(9.0)
    assert m["jerk_p95"] == pytest.approx(10.0)
    assert steps["jerk"].isna().sum() == 2
    lat = np.r_[np.full(10, 4.0 * np.tan(0.1) / 2.0), np.full(10, 4.0 * np.tan(0.2) / 2.0)]  # v^2 |tan| / L
    assert m["lat_accel_p95"] == pytest.approx(np.percentile(lat, 95))
    assert m["lat_accel_p95"] == pytest.approx(4.0 * np.tan(0.2) / 2.0)


def test_p95_is_none_without_samples():
    assert smoothness(pd.DataFrame(columns=["accel", "lat_accel", "jerk"])) == dict(accel_p95=None, lat_accel_p95=None, jerk_p95=None)


def standing(x_front: float, y: float, seconds: float = 10.0, v: float = 0.0) -> pd.DataFrame:
    """A car standing for ``seconds`` on the lane at ``y`` heading +x, its front at ``x_front``."""
    n = int(round(seconds / DT))
    x_axle = x_front - CAR["centre_offset"]["car"] - 0.5 * CAR["length"]["car"]
    return pd.DataFrame(dict(t=np.arange(n) * DT, robot="car", x=x_axle, y=y, heading=0.0, v=v))


def walker(y_of_t) -> pd.DataFrame:
    """A walker on the crossing's centre-line at ``y_of_t(t)`` every step of 10 s."""
    t = np.arange(100) * DT
    return pd.DataFrame(dict(t=t, x=239.0, y=[y_of_t(s) for s in t], length=0.5, width=0.5, heading=-np.pi / 2))


def waits(steps, walkers, **kw):
    return pedestrian_waits(steps, walkers, [CROSSING], dt=DT, stop_speed=0.05, margin=1.0, **CAR, **kw)


def test_a_car_waits_the_seconds_its_lane_of_the_crossing_is_clear():
    """10 s standing 5 m before the crossing in the middle lane (y = -4.8); a walker on that
    lane's part for the first 4 s, then far on the other side: 6 s of waiting for nothing."""
    w = waits(standing(232.0, -4.8), walker(lambda t: -4.8 if t < 4.0 - 1e-9 else -20.0))
    assert w["car"] == pytest.approx(6.0)


def test_a_walker_on_another_lane_does_not_block():
    """The walker stays on the leftmost lane (y = -1.6) and then on the rightmost (y = -8.0):
    neither is the car's middle lane (its part spans y in [-6.4, -3.2]; the walker's body is
    1.35 m beyond it, more than the 1 m margin), so all 10 s count."""
    assert waits(standing(232.0, -4.8), walker(lambda t: -1.6))["car"] == pytest.approx(10.0)
    assert waits(standing(232.0, -4.8), walker(lambda t: -8.0))["car"] == pytest.approx(10.0)
    assert waits(standing(232.0, -4.8), walker(lambda t: -7.0))["car"] == pytest.approx(0.0)  # 0.35 m from it: within the margin


def test_standing_held_by_a_traffic_signal_is_no_wait_for_walkers():
    """The same 10 s before a clear crossing, the first 7 s of them held by a red light."""
    held = {(round(k * DT, 9), "car") for k in range(70)}
    assert waits(standing(232.0, -4.8), walker(lambda t: -20.0), held=held)["car"] == pytest.approx(3.0)


def test_only_cars_standing_up_to_30_m_before_the_crossing_count():
    nobody = walker(lambda t: -20.0)
    assert waits(standing(232.0, -4.8, v=1.0), nobody)["car"] == 0.0  # moving
    assert waits(standing(237.0 - 30.5, -4.8), nobody)["car"] == 0.0  # 30.5 m before its near edge
    assert waits(standing(237.0 - 29.5, -4.8), nobody)["car"] == pytest.approx(10.0)
    assert waits(standing(240.0, -4.8), nobody)["car"] == pytest.approx(10.0)  # its front on the crossing: not past it
    assert waits(standing(242.0, -4.8), nobody)["car"] == 0.0  # passed it
    assert waits(standing(232.0, -14.0), nobody)["car"] == 0.0  # beside the road: the crossing is not on its way


def test_the_lane_part_is_the_crossing_within_half_a_lane_of_the_car():
    part = crossing_lane_part(CROSSING.shape, CROSSING.width, np.array([230.0, -4.8]), 0.0, 1.6)
    assert part.shape == (1, 5)
    assert part[0, :4] == pytest.approx([239.0, -4.8, 3.2, 4.0])
    assert crossing_lane_part(CROSSING.shape, CROSSING.width, np.array([230.0, -20.0]), 0.0, 1.6).shape == (0, 5)
    front = np.array([235.0, -4.8])
    assert crossing_ahead([CROSSING], front - [2.25, 0.0], front, np.pi) is None  # facing away


def test_pedestrian_wait_is_null_without_crossings_internal_simulator():
    m = runner.run(config.load("braking", ["scenario.duration=1.0"])).metrics
    assert m["pedestrian_wait_s"] is None
    assert all(np.isfinite(m[k]) for k in NEW_KEYS[:3])


def test_a_short_lane_change_finds_the_bundled_crossing_and_reports_a_wait():
    """3 s of the bundled lane change in SUMO: the crossing SUMO has is the zebra over E0 at
    x = 239 m (4 m wide, 237-241 m), across the three 3.2 m lanes; the wait is a finite number."""
    result = runner.run(config.load("lane_change", ["controller.coordinator=independent", "controller.horizon=5",
                                                    "lane_change.vehicles=3", "scenario.duration=3.0"]))
    (crossing,) = result.crossings
    assert crossing.name == ":X_c0_0"
    assert crossing.shape[:, 0] == pytest.approx([239.0, 239.0])
    assert 238.0 <= crossing.shape[0, 0] <= 240.0
    assert sorted(crossing.shape[:, 1]) == pytest.approx([-9.6, 0.0])
    assert crossing.width == pytest.approx(4.0) and crossing.lane_width == pytest.approx(3.2)
    m = result.metrics
    assert "error" not in m
    assert np.isfinite(m["pedestrian_wait_s"]) and m["pedestrian_wait_s"] >= 0.0
    assert all(np.isfinite(m[k]) for k in NEW_KEYS[:3])



def test_the_work_zone_highway_finds_its_crossing_over_its_four_car_lanes():
    """2 s of the work-zone highway: its zebra over edge "after" at x = 1499.08 m, 14 m long
    (over the sidewalk and four 3.5 m car lanes); a number, not null."""
    result = runner.run(config.load("highway_work_zone", ["scenario.duration=2.0"]))
    (crossing,) = result.crossings
    assert crossing.shape[:, 0] == pytest.approx([1499.08, 1499.08])
    assert crossing.lane_width == pytest.approx(3.5)
    assert result.metrics["pedestrian_wait_s"] == 0.0


def test_polylines_cross():
    from aac_sumo.sim.sumo_reading import polylines_cross

    zebra = np.array([[239.0, 0.0], [239.0, -9.6]])
    assert polylines_cross(zebra, np.array([[236.5, -4.8], [241.5, -4.8]]))  # the junction's lane through it
    assert not polylines_cross(zebra, np.array([[0.0, -4.8], [236.5, -4.8]]))  # the lane ending before it
    assert polylines_cross(np.array([[0.0, 0.0], [2.0, 2.0], [4.0, 0.0]]), np.array([[3.0, -1.0], [3.0, 3.0]]))
    assert not polylines_cross(zebra, np.array([[240.0, 0.0], [240.0, -9.6]]))  # parallel

def test_table_two_has_the_smoothness_and_waiting_columns_for_both_coordinators(monkeypatch, tmp_path, capsys):
    """No simulation: each planned run returns made-up metrics; table.csv and table.md of Table II
    carry the four new metrics, per coordinator and horizon."""
    from aac_sumo.runs import sweep
    from aac_sumo.cli.app import main

    def run_tasks(tasks, grid_keys, out, *args, **kw):
        out.mkdir(parents=True, exist_ok=True)
        return [dict(t.grid) | {"seed": t.seed, "status": "ok", "completed": True, "collisions": 0, "accel_p95": 1.5,
                                "lat_accel_p95": 0.25, "jerk_p95": 4.0 + (t.scenario["controller.coordinator"] == "lfc"),
                                "pedestrian_wait_s": 3.0} for t in tasks]

    monkeypatch.setattr(sweep, "run_tasks", run_tasks)
    assert main(["table", "lane-change", "--out", str(tmp_path), "--no-progress"]) == 0, capsys.readouterr().err
    rows = pd.read_csv(tmp_path / "table.csv")
    assert set(NEW_KEYS) <= set(rows.columns)
    assert sorted(rows["coordinator"].unique()) == ["aac", "lfc"]
    assert (rows["jerk_p95"] == np.where(rows["coordinator"] == "lfc", 5.0, 4.0)).all()
    assert (rows["pedestrian_wait_s"] == 3.0).all() and (rows["accel_p95"] == 1.5).all()
    text = (tmp_path / "table.md").read_text()
    assert "jerk p95 [m/s³]" in text and "Waiting at clear crossings [car·s]" in text
