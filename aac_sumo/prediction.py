"""How an obstacle is predicted over the MPC horizon, from what has been observed of it.

* ``constant_velocity``: it keeps its current world-frame velocity.
* ``constant_acceleration``: it keeps its direction of motion and changes its speed at its
  longitudinal acceleration [m/s^2], estimated by :class:`SpeedHistory` from its last observed
  speeds (never from a simulator's script). A decelerating obstacle stops and then stands: its
  predicted speed never reverses through zero.

Both barriers get the same prediction; only the shape of the region around it differs.
"""

from __future__ import annotations

import dataclasses
from collections import deque

import numpy as np

from aac_sumo.barriers import ObstaclePrediction, predict_constant_velocity
from aac_sumo.world import Obstacle, WorldState

PREDICTIONS = ("constant_velocity", "constant_acceleration")


def predict_constant_acceleration(centre, velocity, accel: float, heading: float, length, width, horizon: int, dt: float) -> ObstaclePrediction:
    """Stages ``0..horizon`` of an obstacle at footprint centre ``centre`` [m] with world-frame
    ``velocity`` [m/s] whose speed changes at ``accel`` [m/s^2] along its direction of motion
    (its ``heading`` [rad] when it stands), exactly in continuous time; with ``accel < 0`` it
    stops after ``|v| / |accel|`` seconds and stands there."""
    centre = np.asarray(centre, dtype=float)
    velocity = np.asarray(velocity, dtype=float)
    speed = float(np.hypot(*velocity))
    direction = velocity / speed if speed > 0.0 else np.array([np.cos(heading), np.sin(heading)])
    t = np.arange(horizon + 1) * dt
    if accel < 0.0:
        t = np.minimum(t, speed / -accel)  # moving time up to each stage
    speeds = speed + accel * t
    travelled = speed * t + 0.5 * accel * t**2
    return ObstaclePrediction(
        centres=centre + travelled[:, None] * direction,
        velocities=speeds[:, None] * direction,
        headings=np.full(horizon + 1, float(heading)),
        length=float(length),
        width=float(width),
    )


def predict_obstacle(obstacle: Obstacle, horizon: int, dt: float, model: str = "constant_velocity") -> ObstaclePrediction:
    """The obstacle's centres and velocities over stages ``0..horizon`` [m, m/s]: its given
    ``predicted`` centres if long enough, else ``model`` (one of PREDICTIONS) with its
    estimated ``accel``."""
    if obstacle.predicted is not None and len(obstacle.predicted) >= horizon + 1:
        centres = np.asarray(obstacle.predicted[: horizon + 1], dtype=float)
        vel = np.vstack([np.diff(centres, axis=0) / dt, obstacle.velocity[None, :]])
        vel[-1] = vel[-2] if horizon >= 1 else obstacle.velocity
        return ObstaclePrediction(centres, vel, np.full(horizon + 1, obstacle.heading), obstacle.length, obstacle.width)
    if model == "constant_acceleration":
        return predict_constant_acceleration(obstacle.centre, obstacle.velocity, obstacle.accel, obstacle.heading,
                                             obstacle.length, obstacle.width, horizon, dt)
    if model != "constant_velocity":
        raise ValueError(f"unknown prediction {model!r}; expected one of {PREDICTIONS}")
    return predict_constant_velocity(obstacle.centre, obstacle.velocity, obstacle.heading, obstacle.length, obstacle.width, horizon, dt)


def stage_zero(obstacles: list[Obstacle], horizon: int, dt: float, model: str = "constant_velocity") -> ObstaclePrediction:
    """Stage 0 of :func:`predict_obstacle` for a batch of M obstacles at once, bit for bit:
    centres (M, 1, 2), velocities (M, 1, 2), headings (M, 1), length and width (M, 1). Cheap,
    for ranking obstacles before predicting the few that count."""
    centres = np.array([o.centre for o in obstacles], dtype=float).reshape(-1, 2)
    velocity = np.array([o.velocity for o in obstacles], dtype=float).reshape(-1, 2)
    headings = np.array([o.heading for o in obstacles], dtype=float)
    given = np.array([o.predicted is not None and len(o.predicted) >= horizon + 1 for o in obstacles], dtype=bool)
    if model == "constant_acceleration":
        speed = np.hypot(velocity[:, 0], velocity[:, 1])
        moving = speed > 0.0
        direction = np.column_stack([np.cos(headings), np.sin(headings)])
        direction[moving] = velocity[moving] / speed[moving, None]
        velocity = speed[:, None] * direction
    elif model != "constant_velocity":
        raise ValueError(f"unknown prediction {model!r}; expected one of {PREDICTIONS}")
    for i in np.flatnonzero(given):  # given centres: their first difference (the whole prediction's row 0)
        pred = predict_obstacle(obstacles[i], horizon, dt, model)
        centres[i], velocity[i] = pred.centres[0], pred.velocities[0]
    return ObstaclePrediction(centres[:, None], velocity[:, None], headings[:, None],
                              np.array([[o.length] for o in obstacles], dtype=float).reshape(-1, 1),
                              np.array([[o.width] for o in obstacles], dtype=float).reshape(-1, 1))


def speed_slope(times, speeds) -> float:
    """Least-squares slope [m/s^2] of ``speeds`` [m/s] over ``times`` [s]; 0 with fewer than two."""
    times, speeds = np.asarray(times, dtype=float), np.asarray(speeds, dtype=float)
    if len(times) < 2:
        return 0.0
    dt = times - times.mean()
    return float(dt @ (speeds - speeds.mean()) / (dt @ dt))


class SpeedHistory:
    """The last ``window`` observed speeds of every moving obstacle, by name, and the
    longitudinal acceleration they show (the least-squares slope over the window: with
    ``window = 2`` the backward difference of the last two periods).

    A history restarts when its obstacle was not seen in the previous control period (``dt``
    [s]) or time went backwards. Static obstacles and cones are left as they are."""

    def __init__(self, window: int, dt: float):
        if window < 2:
            raise ValueError("the speed window needs at least two observations")
        self.window, self.dt = window, dt
        self.seen: dict[str, deque] = {}

    def annotate(self, world: WorldState) -> WorldState:
        """A copy of ``world`` whose moving obstacles carry their estimated ``accel``."""
        obstacles = []
        for o in world.obstacles:
            if o.kind in ("static", "cone"):
                obstacles.append(o)
                continue
            history = self.seen.get(o.name)
            if history is None or not (0.0 < world.t - history[-1][0] <= 1.5 * self.dt):
                history = self.seen[o.name] = deque(maxlen=self.window)
            history.append((world.t, float(np.hypot(*o.velocity))))
            times, speeds = zip(*history)
            obstacles.append(dataclasses.replace(o, accel=speed_slope(times, speeds)))
        return dataclasses.replace(world, obstacles=obstacles)
