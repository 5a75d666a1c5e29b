"""Kinematic bicycle model of the paper (forward-Euler, rear-axle reference point).

State ``[x, y, heading, v]``: rear-axle midpoint in the world frame [m], heading [rad,
counter-clockwise from +x], longitudinal speed [m/s]. Input ``[accel, steer]``: [m/s^2], front
wheel angle [rad]. One definition serves numpy (simulation) and casadi (MPC).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.geometry import wrap_angle

NX = 4
NU = 2


def bicycle_step(state, control, dt: float, wheelbase, xp=np):
    """One Euler step of the paper's discrete bicycle model.

    ``xp`` is the math namespace: ``numpy`` for arrays of shape (..., 4) / (..., 2), or
    ``casadi`` for symbolic column vectors. Returns the next state in the same namespace.
    """
    x, y, heading, v = _components(state, NX, xp)
    accel, steer = _components(control, NU, xp)
    nxt = (
        x + v * xp.cos(heading) * dt,
        y + v * xp.sin(heading) * dt,
        heading + v * xp.tan(steer) / wheelbase * dt,
        v + accel * dt,
    )
    return np.stack(nxt, axis=-1) if xp is np else xp.vertcat(*nxt)


def heading_hold_steer(states, heading_ref, dt: float, wheelbase, steer_max, turn_time: float) -> np.ndarray:
    """Steering angles [rad] (...) that turn each state's heading (states (..., 4)) towards
    ``heading_ref`` (...) [rad] with time constant ``turn_time`` [s] under :func:`bicycle_step`,
    within ``steer_max``; zero at standstill. The heading error never changes side."""
    states = np.asarray(states, dtype=float)
    error = wrap_angle(np.asarray(heading_ref, dtype=float) - states[..., 2])
    turn = min(1.0, dt / turn_time) * error  # heading change wanted this period
    speed = states[..., 3]
    steer = np.arctan2(np.asarray(wheelbase) * turn * np.sign(speed), np.abs(speed) * dt)
    return np.where(speed != 0.0, np.clip(steer, -np.asarray(steer_max), steer_max), 0.0)


def _components(vec, n: int, xp):
    """The ``n`` entries of a numpy (..., n) array or a casadi column vector."""
    return [vec[..., i] for i in range(n)] if xp is np else [vec[i] for i in range(n)]


@dataclass(frozen=True)
class VehicleLimits:
    """Input and speed bounds of one robot. Speeds in m/s, accelerations in m/s^2, steer in rad."""

    a_min: float = -6.0
    a_max: float = 3.0
    steer_max: float = 0.6
    v_min: float = 0.0
    v_max: float = 20.0

    def clip_input(self, control: np.ndarray) -> np.ndarray:
        """Clip ``[accel, steer]`` (shape (..., 2)) to the bounds."""
        lo = np.array([self.a_min, -self.steer_max])
        hi = np.array([self.a_max, self.steer_max])
        return np.clip(control, lo, hi)

    def braking_input(self, speed: float, dt: float) -> np.ndarray:
        """Hardest admissible braking within ``dt`` toward the admissible speed nearest to
        standstill (0, or ``v_min`` when that is positive), zero steer; it never drives a robot
        through zero speed into the other direction."""
        target = min(max(0.0, self.v_min), self.v_max)
        return np.array([min(max((target - speed) / dt, self.a_min), self.a_max), 0.0])

    def stopping_inputs(self, speed: float, dt: float, steps: int) -> np.ndarray:
        """Inputs (steps, 2) of :meth:`braking_input` applied period after period until standstill."""
        out = np.zeros((steps, 2))
        for k in range(steps):
            out[k] = self.braking_input(speed, dt)
            speed += out[k, 0] * dt
        return out


@dataclass(frozen=True)
class BicycleModel:
    """Bicycle model of one robot: geometry, limits and the numpy step used by simulators."""

    wheelbase: float
    limits: VehicleLimits

    def step(self, state: np.ndarray, control: np.ndarray, dt: float) -> np.ndarray:
        """Advance with clipped inputs; the speed is kept inside ``[v_min, v_max]``."""
        nxt = bicycle_step(state, self.limits.clip_input(control), dt, self.wheelbase)
        nxt[..., 3] = np.clip(nxt[..., 3], self.limits.v_min, self.limits.v_max)
        return nxt


class FleetModel:
    """The :meth:`BicycleModel.step` of several robots at once, each with its own geometry and
    limits (``models``, one per robot), on state rows (n, 4) and input rows (n, 2)."""

    def __init__(self, models: list[BicycleModel]):
        self.wheelbase = np.array([m.wheelbase for m in models])
        self.input_lo = np.array([[m.limits.a_min, -m.limits.steer_max] for m in models]).reshape(-1, 2)
        self.input_hi = np.array([[m.limits.a_max, m.limits.steer_max] for m in models]).reshape(-1, 2)
        self.v_min = np.array([m.limits.v_min for m in models])
        self.v_max = np.array([m.limits.v_max for m in models])

    def step(self, states: np.ndarray, inputs: np.ndarray, dt: float) -> np.ndarray:
        """Next states (n, 4) of every robot, inputs clipped and speeds kept in bounds."""
        nxt = bicycle_step(states, np.clip(inputs, self.input_lo, self.input_hi), dt, self.wheelbase)
        nxt[:, 3] = np.clip(nxt[:, 3], self.v_min, self.v_max)
        return nxt
