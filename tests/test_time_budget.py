"""The road time budget (aac_sumo.views.time_budget): each step's loss against the cruise speed goes to
the first cause that holds there."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aac_sumo.views.time_budget import CAUSES, time_budget

DT = 0.1


def record(cars: dict[str, tuple[float, float, float]], walkers: dict[str, tuple[float, float]], steps: int):
    """Steps and trajectories of cars ``name: (x, y, v)`` driving east at constant speed (rear
    axle; footprint centre 1.3 m ahead) and standing walkers ``name: (x, y)``, for ``steps``."""
    step_rows, traj_rows = [], []
    for k in range(steps):
        t = k * DT
        for name, (x, y, v) in cars.items():
            step_rows.append(dict(t=t, robot=name, x=x + v * t, y=y, heading=0.0, v=v, mode="plan", arrived=False))
            traj_rows.append(dict(t=t, name=name, kind="controlled", x=x + v * t + 1.3, y=y, heading=0.0, v=v, length=4.0, width=1.8))
        for name, (x, y) in walkers.items():
            traj_rows.append(dict(t=t, name=name, kind="pedestrian", x=x, y=y, heading=0.0, v=0.0, length=0.3, width=0.5))
    return pd.DataFrame(step_rows), pd.DataFrame(traj_rows)


def test_a_car_behind_a_slow_car_loses_to_following_what_its_speed_misses():
    """At 5 m/s behind a car at 5 m/s 20 m ahead in its lane, cruise 10 m/s: half of every
    period is lost, all of it to following; the leader, with nothing ahead, loses as much to
    'other'."""
    steps, traj = record({"a": (0.0, 0.0, 5.0), "b": (20.0, 0.0, 5.0)}, {}, 10)
    table = time_budget(steps, traj, 10.0, DT, 0.5)
    assert table.loc["a", "following"] == pytest.approx(0.5) and table.loc["a", "lost"] == pytest.approx(0.5)
    assert table.loc["b", "other"] == pytest.approx(0.5) and table.loc["b", "following"] == 0.0
    assert list(table.columns[: len(CAUSES)]) == list(CAUSES)


def test_a_walker_nearer_than_the_car_ahead_makes_it_yielding_and_one_beside_another_lane_does_not_count_far_off():
    """A walker 10 m ahead of the front, on the road: yielding, ahead of a slow car 40 m on; a
    walker 20 m beside the lane does not count."""
    steps, traj = record({"a": (0.0, 0.0, 2.0), "b": (40.0, 0.0, 2.0)}, {"p": (15.0, 3.0)}, 5)
    table = time_budget(steps, traj, 10.0, DT, 0.5)
    assert table.loc["a", "yielding"] == pytest.approx(0.4) and table.loc["a", "following"] == 0.0
    steps, traj = record({"a": (0.0, 0.0, 2.0)}, {"p": (15.0, 20.0)}, 5)
    assert time_budget(steps, traj, 10.0, DT, 0.5).loc["a", "yielding"] == 0.0


def test_no_loss_above_the_cruise_speed():
    steps, traj = record({"a": (0.0, 0.0, 12.0)}, {}, 4)
    assert np.all(time_budget(steps, traj, 10.0, DT, 0.5)["lost"] == 0.0)
