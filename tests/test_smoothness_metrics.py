"""Smoothness metrics (accel_p95, lat_accel_p95, jerk_p95): closed-form checks on synthetic recordings."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aac_sumo.metrics import METRIC_KEYS, smoothness
from aac_sumo.runner import with_vehicle_columns

NEW_KEYS = ("accel_p95", "lat_accel_p95", "jerk_p95")
DT = 0.1


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
