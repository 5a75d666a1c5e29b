"""The simple tracking law of robots that hold no usable plan: pure pursuit on the reference
path plus a proportional speed loop. No obstacle avoidance; it only keeps robots on their task."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.kernels.motion import limited_steer, tracking_course
from aac_sumo.references import PathReference
from aac_sumo.world import RobotSpec


@dataclass(frozen=True)
class Pursuit:
    """Where pure pursuit aims: ``distance`` [m] beyond the projection; with ``time`` > 0 [s],
    only as far as the car covers in that time at its speed where that is shorter, but at least
    ``least`` [m] (:func:`~aac_sumo.kernels.motion.pursuit_distance`). A fixed distance on a corner
    of a few metres' radius aims at the street beyond it: a car that turns it slowly swings wide."""

    distance: float
    time: float = 0.0
    least: float = 0.0

    def args(self) -> tuple[float, float, float]:
        """The compiled tracking law's ``lookahead, lookahead_time, lookahead_min``."""
        return float(self.distance), float(self.time), float(self.least)


class AimsAhead:
    """Settings with a tracking law's ``lookahead`` [m], ``lookahead_time`` [s] and
    ``lookahead_min`` [m] (a mixin of the coordinators' settings dataclasses)."""

    @property
    def pursuit(self) -> Pursuit:
        """Where the tracking law aims (:class:`Pursuit`)."""
        return Pursuit(self.lookahead, self.lookahead_time, self.lookahead_min)


def pursuit(lookahead: float | Pursuit) -> Pursuit:
    """``lookahead`` as a :class:`Pursuit` (a float: a fixed distance [m])."""
    return lookahead if isinstance(lookahead, Pursuit) else Pursuit(float(lookahead))


def track(robot: RobotSpec, state: np.ndarray, task: PathReference, lookahead: float | Pursuit, speed_gain: float,
          previous_steer: float, dt: float, offset: float = 0.0, target_speed: float | None = None,
          a_lat: float | None = None) -> np.ndarray:
    """Input ``[accel, steer]`` steering the rear axle toward the path point ``lookahead`` [m] (a
    :class:`Pursuit`: as that says) ahead of its projection (moved ``offset`` [m] to the right of the path) and driving the
    speed toward the reference speed there (or ``target_speed`` [m/s] when given); within the task's ``approach`` distance of its
    goal, toward the goal at the speed that stops there. It brakes at most at the robot's
    comfort deceleration, and its steering keeps the vehicle limits (angle, lateral
    acceleration, and rate from ``previous_steer`` [rad], the steering applied the period ``dt``
    [s] before), and its lateral acceleration keeps within ``a_lat`` [m/s^2] too when given (a
    comfort limit)."""
    return track_course(robot, state, task, lookahead, speed_gain, previous_steer, dt, 1, offset, target_speed, a_lat)[0]


def track_course(robot: RobotSpec, state: np.ndarray, task: PathReference, lookahead: float | Pursuit, speed_gain: float,
                 previous_steer: float, dt: float, steps: int, offset: float = 0.0, target_speed: float | None = None,
                 a_lat: float | None = None, a_up: float | None = None) -> np.ndarray:
    """Inputs (steps, 2) of :func:`track` applied for ``steps`` periods from ``state`` under the
    robot's model (compiled: :func:`~aac_sumo.kernels.tracking_course`), speeding up at most at
    ``a_up`` [m/s^2] too when given (a comfort limit)."""
    x, y, h, v = (float(c) for c in state[:4])
    return tracking_course(x, y, h, v, int(steps), float(dt), *tracking_bounds(robot, a_lat, a_up), float(previous_steer), *task.arrays(),
                           float(task.speed), float(task.decel),
                           bool(task.stop_at_end), float(task.approach), *pursuit(lookahead).args(), float(speed_gain), float(offset),
                           np.nan if target_speed is None else float(target_speed))


def tracking_bounds(robot: RobotSpec, a_lat: float | None = None, a_up: float | None = None) -> tuple[float, ...]:
    """The robot's model as the compiled tracking law takes it: wheelbase [m], a_min, a_max
    (``a_up`` [m/s^2] when given and lower) [m/s^2], steer_max [rad], v_min, v_max [m/s], a_lat_max
    and the lateral limit it steers within (``a_lat`` [m/s^2] when given and lower),
    steer_rate_max [rad/s], comfort_decel [m/s^2]."""
    lim = robot.model.limits
    comfort = lim.a_lat_max if a_lat is None else min(lim.a_lat_max, a_lat)
    a_max = lim.a_max if a_up is None else min(lim.a_max, a_up)
    return tuple(float(b) for b in (robot.model.wheelbase, lim.a_min, a_max, lim.steer_max, lim.v_min, lim.v_max, lim.a_lat_max,
                                    comfort, lim.steer_rate_max, lim.comfort_decel))


def creep_inputs(v: float, speed: float, steer: float, previous_steer: float, a_min: float, a_max: float, wheelbase: float,
                 steer_limits: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """Inputs (steps, 2) of a robot at speed ``v`` [m/s] towards ``speed`` [m/s] (accelerating
    within [``a_min``, ``a_max``] [m/s^2]) and ``steer`` [rad], within its ``steer_limits`` from
    the steering it applied last, ``previous_steer`` [rad]; ``dt`` [s] the period."""
    out = np.zeros((steps, 2))
    for k in range(steps):
        accel = float(np.clip((speed - v) / dt, a_min, a_max))
        previous_steer = limited_steer(steer, v, accel, previous_steer, wheelbase, steer_limits, dt)
        out[k] = accel, previous_steer
        v += accel * dt
    return out
