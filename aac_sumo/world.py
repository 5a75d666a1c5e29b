"""What a coordinator sees each control period: plain numpy state, no simulator objects.

Frames and units: world frame x right / y up [m], headings [rad] counter-clockwise from +x,
speeds [m/s]. Robot states are ``[x, y, heading, v]`` at the rear-axle midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from aac_sumo.dynamics import BicycleModel

OBSTACLE_KINDS = ("robot", "scripted", "pedestrian", "cone", "static")


@dataclass(frozen=True)
class RobotSpec:
    """A controlled robot: footprint length/width [m] and its bicycle model."""

    name: str
    length: float
    width: float
    model: BicycleModel

    @property
    def centre_offset(self) -> float:
        """Distance [m] from the rear axle forward to the footprint centre (equal overhangs)."""
        return 0.5 * self.model.wheelbase


@dataclass(frozen=True)
class Obstacle:
    """Anything a controlled robot must avoid, seen at the current instant.

    ``centre`` is the footprint centre [m], ``velocity`` world-frame [m/s]. ``predicted`` is an
    optional (M, 2) array of future centres at the control period (M >= horizon + 1, row 0 now);
    without it the planner predicts the obstacle with ``controller.prediction`` (see
    :mod:`aac_sumo.prediction`). ``accel`` is its longitudinal acceleration along its velocity
    [m/s^2] as a coordinator estimated it from the speeds it observed (0 when not estimated).
    """

    name: str
    kind: str
    centre: np.ndarray
    velocity: np.ndarray
    heading: float
    length: float
    width: float
    predicted: np.ndarray | None = None
    accel: float = 0.0

    def footprint(self) -> np.ndarray:
        """Row ``[cx, cy, length, width, heading]``."""
        return np.array([self.centre[0], self.centre[1], self.length, self.width, self.heading])


@dataclass
class WorldState:
    """Controlled robots (states (n, 4), specs) and uncontrolled obstacles at time ``t`` [s]."""

    t: float
    states: np.ndarray
    robots: list[RobotSpec]
    obstacles: list[Obstacle] = field(default_factory=list)

    def robot_centres(self) -> np.ndarray:
        """Footprint centres (n, 2) of the controlled robots."""
        offsets = np.array([r.centre_offset for r in self.robots])
        heading = self.states[:, 2]
        return self.states[:, :2] + offsets[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])

    def robot_footprints(self) -> np.ndarray:
        """Rows ``[cx, cy, length, width, heading]`` (n, 5) of the controlled robots."""
        centres = self.robot_centres()
        dims = np.array([[r.length, r.width] for r in self.robots])
        return np.column_stack([centres, dims, self.states[:, 2]])

    def robot_as_obstacle(self, i: int) -> Obstacle:
        """Controlled robot ``i`` seen by the others, moving at its current velocity."""
        heading, speed = self.states[i, 2], self.states[i, 3]
        direction = np.array([np.cos(heading), np.sin(heading)])
        return Obstacle(
            name=self.robots[i].name,
            kind="robot",
            centre=self.states[i, :2] + self.robots[i].centre_offset * direction,
            velocity=speed * direction,
            heading=float(heading),
            length=self.robots[i].length,
            width=self.robots[i].width,
        )
