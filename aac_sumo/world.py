"""What a coordinator sees each control period: plain numpy state, no simulator objects.

Frames and units: world frame x right / y up [m], headings [rad] counter-clockwise from +x,
speeds [m/s]. Robot states are ``[x, y, heading, v]`` at the rear-axle midpoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from aac_sumo.dynamics import BicycleModel

#: ``signal``: a red or yellow traffic light's stop line, a standing box that an experiment shows the coordinators
#: (:mod:`aac_sumo.experiments.signals`); no simulator holds one, so nothing collides with it.
OBSTACLE_KINDS = ("robot", "scripted", "pedestrian", "cone", "static", "signal")
#: A stop line binds only the robots that come up to it along its lane: whose heading is within 60 degrees of its own
#: (the cosine of the difference above this). A car turning or crossing in front of another approach's line passes it.
LINE_BINDS_COS = 0.5


def line_binds(line_heading, heading):
    """Whether a stop line with heading ``line_heading`` [rad] binds a robot heading ``heading``
    [rad] (either may be an array): see :data:`LINE_BINDS_COS`."""
    return np.cos(np.asarray(heading) - np.asarray(line_heading)) > LINE_BINDS_COS


#: Where robots that are not on the road stand [m]: far from any network, 1 km apart.
PARKING = np.array([-1.0e6, -1.0e6])
PARKING_STEP = 1.0e3


def parking_spot(i: int) -> np.ndarray:
    """The state ``[x, y, heading, v]`` of robot ``i`` while it is not on the road: standing at
    its own spot far from everything else."""
    return np.array([PARKING[0] - PARKING_STEP * i, PARKING[1], 0.0, 0.0])


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
    ``walkway`` is, for a pedestrian on a walkway of her own (a lane only pedestrians may use,
    not a crossing or a junction's walking area), how far [m] its two ends lie from her along
    it; None elsewhere. ``signalled`` is, for a vehicle whose blinker signals a lane change it has
    not begun (SUMO's drivers wait for a gap with it on), its footprint row ``[cx, cy, length,
    width, heading]`` over its lane and the next lane on that side; None otherwise. ``course``
    is, for a vehicle SUMO drives, the polyline (K, 2) [m] its footprint centre follows ahead
    along its route's lanes, through the junctions' internal lanes (row 0: its centre now);
    None (and while it changes lanes): it goes on straight along its velocity.
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
    walkway: tuple[float, float] | None = None
    signalled: np.ndarray | None = None
    course: np.ndarray | None = None

    def step_out_speed(self, reach: float, walkway_time: float) -> float:
        """How fast [m/s] this pedestrian may step out of her way on top of her velocity:
        ``reach``, unless she walks on a walkway of her own whose ends she cannot reach within
        ``walkway_time`` [s] at her speed plus ``reach``: she stays on it (as SUMO's walkers
        do, who leave a footpath only at its end), so 0."""
        if self.walkway is None or walkway_time <= 0.0:
            return reach
        return 0.0 if min(self.walkway) > (np.hypot(*self.velocity) + reach) * walkway_time else reach

    def binds(self, heading: float) -> bool:
        """Whether this obstacle holds a robot heading ``heading`` [rad]: every obstacle but a
        stop line (kind ``signal``), which holds only the robots that come up to it along its lane
        (:func:`line_binds`)."""
        return self.kind != "signal" or bool(line_binds(self.heading, heading))

    def footprint(self) -> np.ndarray:
        """Row ``[cx, cy, length, width, heading]``."""
        return np.array([self.centre[0], self.centre[1], self.length, self.width, self.heading])


@dataclass(frozen=True)
class Crossing:
    """A pedestrian crossing of the map, world frame: its centre-line ``shape`` (m, 2) [m], the
    strip of its ``width`` [m] round it where walkers cross, and ``lane_width`` [m], the width
    of the vehicle lanes it crosses (the band of a car's lane across the crossing)."""

    name: str
    shape: np.ndarray
    width: float
    lane_width: float


@dataclass
class WorldState:
    """Controlled robots (states (n, 4), specs) and uncontrolled obstacles at time ``t`` [s].

    ``present`` (n,) says which robots are on the road now (None: all). A robot that is not,
    a SUMO vehicle before its departure or after it left, stands still far away from
    everything (:func:`parking_spot`), so that no geometry sees it; coordinators give it no
    turn and the runner records nothing of it. ``crossings``: the map's pedestrian crossings
    (static; none without a map)."""

    t: float
    states: np.ndarray
    robots: list[RobotSpec]
    obstacles: list[Obstacle] = field(default_factory=list)
    present: np.ndarray | None = None
    crossings: tuple[Crossing, ...] = ()

    @property
    def on_road(self) -> np.ndarray:
        """``present``, as a bool array (n,) also when it is None."""
        return np.ones(len(self.robots), dtype=bool) if self.present is None else np.asarray(self.present, dtype=bool)

    @cached_property
    def _shapes(self) -> np.ndarray:
        """Per robot ``[centre_offset, length, width]`` (n, 3) [m], gathered once."""
        return np.array([[r.centre_offset, r.length, r.width] for r in self.robots], dtype=float).reshape(-1, 3)

    def robot_centres(self) -> np.ndarray:
        """Footprint centres (n, 2) of the controlled robots."""
        heading = self.states[:, 2]
        return self.states[:, :2] + self._shapes[:, :1] * np.column_stack([np.cos(heading), np.sin(heading)])

    def robot_footprints(self) -> np.ndarray:
        """Rows ``[cx, cy, length, width, heading]`` (n, 5) of the controlled robots."""
        return np.column_stack([self.robot_centres(), self._shapes[:, 1:], self.states[:, 2]])

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
