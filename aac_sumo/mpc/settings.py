"""The MPC planner's settings (:class:`MpcConfig`): horizon, solver, barrier, weights, prediction,
comfort envelope; every field has a default and the scenario's ``[controller]`` section sets them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.barriers import FcbfParams
from aac_sumo.mpc.problem import ProblemShape


@dataclass(frozen=True)
class MpcConfig:
    """Everything the planner needs besides the robot and its surroundings.

    ``band`` builds the problem with the lateral-band rows that a
    :class:`~aac_sumo.references.LateralBand` corridor needs.
    Weights are diagonal: Q on ``[x, y, heading, v]`` errors, R on ``[accel, steer]``, S on input
    changes, and the terminal P = ``terminal_scale`` * Q. ``d_safe`` [m] is added to the ego disc
    radius. ``gamma`` in (0, 1] is the barrier decay rate per control period ``dt`` [s].
    ``pedestrian_reach`` [m/s] grows a pedestrian's region at stage k by ``pedestrian_reach * k *
    dt`` in every direction: a walker may start, stop or turn at any moment; ``pedestrian_margin``
    [m] grows it at every stage (pedestrians have priority: cars keep clear of them).
    ``walkway_time`` [s]: a walker on a walkway of her own far from its ends does not step out
    (:meth:`~aac_sumo.world.Obstacle.step_out_speed`; 0: every walker may).
    ``warm_start`` starts each solve from the robot's previous plan, shifted by one period,
    instead of the zero-input rollout (a failed warm start is retried cold either way).
    ``prediction`` is how obstacles move over the horizon (see :mod:`aac_sumo.prediction`);
    with ``constant_acceleration`` the coordinator estimates each one's acceleration from its
    last ``prediction_window`` observed speeds.
    ``terminal_stop`` adds the terminal stopping condition (see :meth:`MpcPlanner.stopping_parameters`):
    braking at its strongest from the horizon's end, the ego stops short of where each obstacle
    ahead could stop at the earliest, braking at ``obstacle_decel`` [m/s^2] from now (0: as
    hard as the ego can).
    ``comfort_accel`` and ``comfort_lat`` [m/s^2] (0: off) are the comfort envelope the planner
    tries first: |acceleration| and lateral acceleration within them (and within the vehicle's
    limits). Only when no solve finds a plan inside it does the planner use the vehicle's full
    limits, so a harder input is one that the situation called for.
    """

    horizon: int = 10
    dt: float = 0.1
    solver: str = "fatrop"
    barrier: str = "fcbf"
    gamma: float = 0.3
    d_safe: float = 0.2
    fcbf: FcbfParams = FcbfParams()
    slots: int = 8
    discs: int = 1
    q_pos: float = 1.0
    q_heading: float = 1.0
    q_speed: float = 1.0
    r_accel: float = 0.1
    r_steer: float = 0.1
    s_accel: float = 0.1
    s_steer: float = 1.0
    terminal_scale: float = 5.0
    max_iter: int = 100
    max_cpu_time: float = 60.0
    retry_with_ipopt: bool = True
    codegen: bool = False
    warm_start: bool = True
    band: bool = False
    pedestrian_reach: float = 0.0
    pedestrian_margin: float = 0.0
    walkway_time: float = 0.0
    prediction: str = "constant_velocity"
    prediction_window: int = 2
    terminal_stop: bool = False
    obstacle_decel: float = 0.0
    comfort_accel: float = 0.0
    comfort_lat: float = 0.0

    def weights(self) -> np.ndarray:
        q = np.array([self.q_pos, self.q_pos, self.q_heading, self.q_speed])
        return np.concatenate([q, [self.r_accel, self.r_steer], [self.s_accel, self.s_steer], self.terminal_scale * q])

    def envelopes(self, limits) -> list[tuple[float, float, float]]:
        """The input envelopes ``(a_min, a_max, a_lat_max)`` [m/s^2] the planner tries in turn
        for a robot with vehicle ``limits``: the comfort envelope first when one is set, then the
        vehicle's own."""
        full = (limits.a_min, limits.a_max, limits.a_lat_max)
        if self.comfort_accel <= 0.0 and self.comfort_lat <= 0.0:
            return [full]
        accel = self.comfort_accel if self.comfort_accel > 0.0 else np.inf
        lat = self.comfort_lat if self.comfort_lat > 0.0 else np.inf
        comfort = (max(limits.a_min, -accel), min(limits.a_max, accel), min(limits.a_lat_max, lat))
        return [comfort, full] if comfort != full else [full]

    def shape(self, solver: str) -> ProblemShape:
        """Problem shape for ``solver``; only the fast path is compiled to C when ``codegen``."""
        codegen = self.codegen and solver == self.solver
        return ProblemShape(self.horizon, self.slots, self.discs, solver, self.dt, self.max_iter, self.max_cpu_time, codegen, self.band,
                            self.terminal_stop)
