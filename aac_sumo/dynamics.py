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
    """Input and speed bounds of one robot. Speeds in m/s, accelerations in m/s^2, steer in rad.

    ``a_lat_max`` bounds the lateral acceleration ``v^2 |tan(steer)| / L`` (friction and comfort),
    ``steer_rate_max`` [rad/s] how fast the steering angle may change, and ``a_comfort`` the
    deceleration used unless an emergency needs more (never more than ``-a_min``, the friction
    limit of braking). The defaults leave all three unbounded: the paper's model.
    """

    a_min: float = -6.0
    a_max: float = 3.0
    steer_max: float = 0.6
    v_min: float = 0.0
    v_max: float = 20.0
    a_lat_max: float = np.inf
    steer_rate_max: float = np.inf
    a_comfort: float = np.inf

    @property
    def comfort_decel(self) -> float:
        """The deceleration [m/s^2] (> 0) of braking short of an emergency."""
        return min(self.a_comfort, -self.a_min)

    def clip_input(self, control: np.ndarray) -> np.ndarray:
        """Clip ``[accel, steer]`` (shape (..., 2)) to the bounds."""
        lo = np.array([self.a_min, -self.steer_max])
        hi = np.array([self.a_max, self.steer_max])
        return np.clip(control, lo, hi)

    def braking_input(self, speed: float, dt: float, decel: float | None = None) -> np.ndarray:
        """Braking within ``dt`` at ``decel`` [m/s^2] (default: the hardest, ``-a_min``) toward
        the admissible speed nearest to standstill (0, or ``v_min`` when that is positive), zero
        steer; it never drives a robot through zero speed into the other direction."""
        decel = -self.a_min if decel is None else decel
        target = min(max(0.0, self.v_min), self.v_max)
        return np.array([min(max((target - speed) / dt, -decel), self.a_max), 0.0])

    def stopping_inputs(self, speed: float, dt: float, steps: int, decel: float | None = None) -> np.ndarray:
        """Inputs (steps, 2) of :meth:`braking_input` at ``decel`` applied period after period
        until standstill."""
        out = np.zeros((steps, 2))
        for k in range(steps):
            out[k] = self.braking_input(speed, dt, decel)
            speed += out[k, 0] * dt
        return out


@dataclass(frozen=True)
class BicycleModel:
    """Bicycle model of one robot: geometry, limits and the numpy step used by simulators."""

    wheelbase: float
    limits: VehicleLimits

    def steer_bound(self, speed) -> np.ndarray:
        """The largest |steer| [rad] that keeps the lateral acceleration ``v^2 |tan(steer)| / L``
        within ``a_lat_max`` at ``speed`` [m/s] (any shape), and within ``steer_max``."""
        lim = self.limits
        speed = np.abs(np.asarray(speed, dtype=float))
        bound = np.arctan2(lim.a_lat_max * self.wheelbase, speed**2)  # pi/2 at standstill, without dividing by zero
        return np.minimum(bound, lim.steer_max)

    def limit_steer(self, steer, speed, previous, dt: float, accel=0.0) -> np.ndarray:
        """``steer`` [rad] limited to ``previous`` +- ``steer_rate_max * dt``, then to the lateral
        limit at the larger of ``speed`` and the speed after ``accel`` for ``dt`` (so that
        holding the angle stays within it next period); the lateral limit wins where the two
        conflict. Elementwise on arrays."""
        rate = self.limits.steer_rate_max * dt
        previous = np.asarray(previous, dtype=float)
        steer = np.clip(steer, previous - rate, previous + rate)
        speed = np.asarray(speed, dtype=float)
        bound = self.steer_bound(np.maximum(np.abs(speed), np.abs(speed + np.asarray(accel) * dt)))
        return np.clip(steer, -bound, bound)

    def stopping_inputs(self, speed: float, previous_steer: float, dt: float, steps: int, decel: float | None = None) -> np.ndarray:
        """Inputs (steps, 2) of braking at ``decel`` (default: the comfort deceleration) until
        standstill (:meth:`VehicleLimits.stopping_inputs`), the steering returning to straight
        from ``previous_steer`` [rad] within the steering limits."""
        out = self.limits.stopping_inputs(speed, dt, steps, self.limits.comfort_decel if decel is None else decel)
        steer = previous_steer
        for k in range(steps):
            steer = out[k, 1] = float(self.limit_steer(0.0, speed, steer, dt, out[k, 0]))
            speed += out[k, 0] * dt
        return out

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
