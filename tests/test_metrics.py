"""Per-step measurements: time to collision, in closed form."""

import numpy as np
import pytest

from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.metrics import time_to_collision
from aac_sumo.world import Obstacle, RobotSpec, WorldState


def car(name: str) -> RobotSpec:
    return RobotSpec(name, 4.0, 1.8, BicycleModel(2.6, VehicleLimits()))


def test_time_to_collision_is_the_bumper_gap_over_the_closing_speed():
    """Cars 4 m x 1.8 m. Car a (10 m/s) has car b (4 m/s) 12 m ahead bumper to bumper: 12 / 6 =
    2 s, sooner than a walker (0.5 m square, standing 1 m beside the path, within the half-widths
    0.9 + 0.25) whose centre is 25.75 m ahead: (25.75 - 2.25) / 10 = 2.35 s. For b the walker is
    9.75 m ahead: 7.5 / 4 = 1.875 s. Car c drives away from all of them, with a cone behind it
    and nothing ahead: NaN. A cone 3 m beside the road counts for nobody."""
    offset = car("a").centre_offset
    states = np.array([[0.0, 0.0, 0.0, 10.0], [16.0, 0.0, 0.0, 4.0], [0.0, 10.0, np.pi / 2, 5.0]])
    world = WorldState(0.0, states, [car("a"), car("b"), car("c")], [
        Obstacle("walker", "pedestrian", np.array([offset + 25.75, 1.0]), np.zeros(2), 0.0, 0.5, 0.5),
        Obstacle("beside", "cone", np.array([offset + 30.0, 3.0]), np.zeros(2), 0.0, 0.4, 0.4),
        Obstacle("behind", "cone", np.array([0.0, 10.0 + offset - 6.0]), np.zeros(2), 0.0, 0.4, 0.4),
    ])
    np.testing.assert_allclose(time_to_collision(world), [2.0, 1.875, np.nan])


def test_time_to_collision_counts_only_closing_traffic():
    """A car ahead that drives away faster gives none; nor does a walker crossing in front of a
    car that stands (no velocity along its heading, so nothing closes in)."""
    offset = car("a").centre_offset
    states = np.array([[0.0, 0.0, 0.0, 5.0], [10.0, 0.0, 0.0, 6.0], [0.0, 20.0, 0.0, 0.0]])
    world = WorldState(0.0, states, [car("a"), car("b"), car("c")],
                       [Obstacle("walker", "pedestrian", np.array([offset + 5.0, 20.0]), np.array([0.0, 1.2]), 0.0, 0.5, 0.5)])
    np.testing.assert_allclose(time_to_collision(world), [np.nan, np.nan, np.nan])
