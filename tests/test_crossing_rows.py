"""A car that could not clear a pedestrian crossing waits before it with the margin
(aac_sumo.coordination.anticipation.crossing_rows)."""

from __future__ import annotations

import numpy as np
import pytest

from aac_sumo.coordination.anticipation import crossing_rows
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.references import PathReference
from aac_sumo.world import Crossing, RobotSpec, WorldState

LIMITS = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
CAR = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, LIMITS))
ZEBRA = Crossing("z", np.array([[100.0, 8.0], [100.0, -8.0]]), 4.0, 3.2)  # across the road at x = 100 m, 4 m wide
FRONT, REAR = 1.3 + 2.0, 2.0 - 1.3  # rear axle to front and to rear [m]


def rows(x: float, stops, crossings=(ZEBRA,)) -> np.ndarray:
    task = PathReference([[0.0, 0.0], [500.0, 0.0]], 10.0, stop_at_end=False)
    world = WorldState(0.0, np.array([[x, 0.0, 0.0, 5.0]]), [CAR], [], crossings=tuple(crossings))
    return crossing_rows(world, 0, task, np.asarray(stops, dtype=float).reshape(-1, 3), 1.0)


@pytest.mark.parametrize("behind_queue, expected", [(101.0, True), (98.5, True), (104.0, False), (90.0, False)])
def test_a_crossing_row_comes_only_when_a_slow_row_would_stop_the_car_on_it(behind_queue, expected):
    """The strip with the 1 m margin runs from x = 97 to 103 m; the car's rear axle clears it at
    103 + 0.7 m. A standing row at 101 m or 98.5 m (rear axle) would stop it on the strip: a row
    at 97 - 3.3 m. One at 104 m lets it clear; one at 90 m stops it before anyway."""
    got = rows(50.0, [[behind_queue, 0.0, 0.0]])
    if expected:
        np.testing.assert_allclose(got, [[97.0 - FRONT, 0.0, 0.0]])
    else:
        assert got.shape == (0, 3)


def test_no_row_for_a_moving_leader_for_a_car_already_on_the_strip_or_without_crossings():
    assert rows(50.0, [[101.0, 5.0, 1.0]]).shape == (0, 3)  # the queue moves on at 5 m/s
    assert rows(95.0, [[101.0, 0.0, 0.0]]).shape == (0, 3)  # its front is on the strip: it drives through
    assert rows(50.0, [[101.0, 0.0, 0.0]], crossings=()).shape == (0, 3)
