"""Predicted motion of controlled robots and the swept safety regions other robots avoid.

A robot's region at MPC stage k contains the convex hull of its footprints at stages k and k+1
(the area it sweeps during that period), grown as an F-CBF (or CBF) ellipse. Rollouts are
compiled (:func:`~aac_sumo.kernels.rollouts`), with the same Euler bicycle model the simulator uses.
"""

from __future__ import annotations

import numpy as np

from aac_sumo.barriers import FcbfParams, RegionTrack, hull_safety_ellipses
from aac_sumo.kernels.motion import footprint_rows, limited_steer, rollouts
from aac_sumo.world import RobotSpec


class Fleet:
    """Per-robot constants as arrays, for vectorised rollouts: wheelbase, acceleration and speed limits,
    rear-axle-to-centre offset, footprint length and width [m, m/s]."""

    def __init__(self, robots: list[RobotSpec]):
        self.names = [r.name for r in robots]
        self.wheelbase = np.array([r.model.wheelbase for r in robots])
        self.a_min = np.array([r.model.limits.a_min for r in robots])
        self.a_max = np.array([r.model.limits.a_max for r in robots])
        self.v_min = np.array([r.model.limits.v_min for r in robots])
        self.v_max = np.array([r.model.limits.v_max for r in robots])
        self.offset = np.array([r.centre_offset for r in robots])
        self.length = np.array([r.length for r in robots])
        self.width = np.array([r.width for r in robots])
        lim = [r.model.limits for r in robots]
        #: Steering limits (n, 3): ``[steer_max, a_lat_max, steer_rate_max]`` (see :func:`~aac_sumo.kernels.limited_steer`).
        self.steer_limits = np.array([[m.steer_max, m.a_lat_max, m.steer_rate_max] for m in lim]).reshape(-1, 3)
        #: Deceleration short of an emergency [m/s^2] (> 0), per robot.
        self.comfort = np.array([m.comfort_decel for m in lim])

    def rollout(self, idx: np.ndarray, states: np.ndarray, inputs: np.ndarray, dt: float) -> np.ndarray:
        """States (m, K+1, 4) of robots ``idx`` from ``states`` (m, 4) under ``inputs`` (m, K, 2)."""
        return rollouts(np.asarray(states, dtype=float), np.asarray(inputs, dtype=float), dt, self.wheelbase[idx], self.v_min[idx], self.v_max[idx])

    def limit_steer(self, steer: np.ndarray, states: np.ndarray, accel: np.ndarray, previous: np.ndarray, dt: float) -> np.ndarray:
        """Every robot's ``steer`` (n,) [rad] within its steering limits at ``states`` (n, 4) and
        ``accel`` (n,), from the steering ``previous`` (n,) applied the period before."""
        return np.array([limited_steer(steer[i], states[i, 3], accel[i], previous[i], self.wheelbase[i], self.steer_limits[i], dt)
                         for i in range(len(self.names))])

    def footprints(self, idx: np.ndarray, states: np.ndarray) -> np.ndarray:
        """Footprint rows ``[cx, cy, length, width, heading]`` (m, K, 5) of robots ``idx`` at
        rear-axle ``states`` (m, K, 4)."""
        return footprint_rows(np.asarray(states, dtype=float), self.offset[idx], self.length[idx], self.width[idx])

    def swept_ellipses(self, idx: np.ndarray, traj: np.ndarray, horizon: int, barrier: str, fcbf: FcbfParams) -> np.ndarray:
        """Safety ellipses ``[cx, cy, a, b, phi]`` (m, horizon+1, 5) of robots ``idx`` along their
        trajectories ``traj`` (m, >= horizon+2, 4): stage k contains the hull of the footprints at
        k and k+1, shaped by the stage velocity."""
        traj = traj[:, : horizon + 2]
        head = traj[:, :-1, 2]
        vel = traj[:, :-1, 3:4] * np.stack([np.cos(head), np.sin(head)], axis=-1)
        return hull_safety_ellipses(self.footprints(idx, traj), vel, head, barrier, fcbf)  # footprints (m, N+2, 5)

    def swept_regions(self, idx: np.ndarray, traj: np.ndarray, horizon: int, barrier: str, fcbf: FcbfParams) -> list[RegionTrack]:
        """One region track per robot ``idx`` of :meth:`swept_ellipses`."""
        return [RegionTrack(self.names[j], e) for j, e in zip(idx, self.swept_ellipses(idx, traj, horizon, barrier, fcbf))]
