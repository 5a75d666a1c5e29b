"""The MPC planner's settings (:class:`MpcConfig`): horizon, solver, barrier, weights, prediction,
comfort envelope; every field has a default and the scenario's ``[controller]`` section sets them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.barriers import FcbfParams
from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param, section
from aac_sumo.mpc.problem import N_WEIGHTS, WEIGHTS, ProblemShape


@section("controller")
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

    barrier: str = param("fcbf", "F-CBF (velocity-stretched ellipse) or plain CBF (footprint ellipse)", type=("fcbf", "cbf"))
    horizon: int = param(10, "MPC horizon N [steps]", check=lambda n: 1 <= n <= 100, expect="in 1..100")
    solver: str = param("fatrop", "NLP solver of the fast path", type=("fatrop", "sqp", "ipopt"))
    retry_with_ipopt: bool = param(True, "retry a failed fast-path solve once with ipopt")
    warm_start: bool = param(True, "start each solve from the previous plan shifted by one period (else from the "
                             "zero-input rollout); a failed warm start is retried cold")
    codegen: bool = param(False, "compile the fast path to C with gcc (cached on disk; ~2x faster solves)")
    gamma: float = param(0.3, "discrete barrier decay rate", check=lambda g: 0 < g <= 1, expect="in (0, 1]")
    d_safe: float = param(0.2, "margin added to the ego's covering-disc radius [m]", **NN)
    fcbf: FcbfParams = param(FcbfParams(), "the F-CBF ellipse's shape", nested=True)
    pedestrian_reach: float = param(0.0, "pedestrians may start, stop or turn at any moment: their regions grow by this speed times the look-ahead time in every direction [m/s]", **NN)
    pedestrian_margin: float = param(0.0, "extra clearance every robot keeps from pedestrians, on top of d_safe [m]", **NN)
    walkway_time: float = param(0.0, "a pedestrian on a walkway of her own (a sidewalk or footpath, not a crossing) who cannot reach either of its ends within this time at her speed plus pedestrian_reach stays on it: her region does not grow by pedestrian_reach; 0 = never [s]", **NN)
    prediction: str = param("constant_velocity",
                            "how obstacles move over the horizon, the same for every barrier: constant_velocity, or "
                            "constant_acceleration (each keeps its direction and changes its speed at the acceleration "
                            "estimated from its last prediction_window observed speeds, stopping at zero, never reversing)",
                            type=("constant_velocity", "constant_acceleration"))
    prediction_window: int = param(2, "observed speeds (one per control period) whose least-squares slope is an "
                                   "obstacle's estimated acceleration; 2 = the backward difference",
                                   check=lambda n: 2 <= n <= 50, expect="in 2..50")
    terminal_stop: bool = param(False, "terminal stopping condition: braking at its strongest after the horizon, the robot stops short of "
                                "where each obstacle ahead of it could stop at the earliest (the car-following stopping-distance rule; "
                                "docs/braking.md)")
    obstacle_decel: float = param(0.0, "strongest braking assumed of obstacles for terminal_stop [m/s^2]; 0 = as hard as the robot itself can", **NN)
    comfort_accel: float = param(0.0, "comfort envelope the MPC plans within first: |acceleration| at most this; only when no "
                                 "plan fits does it use the vehicle's full limits (0: off) [m/s^2]", **NN)
    comfort_lat: float = param(0.0, "the comfort envelope's lateral acceleration v^2 |tan(steer)| / wheelbase (0: off) [m/s^2]", **NN)
    slots: int = param(8, "obstacles the MPC considers (nearest first)", key="obstacle_slots", check=lambda n: 1 <= n <= 64, expect="in 1..64")
    discs: int = param(1, "discs covering the ego footprint", key="ego_discs", check=lambda n: 1 <= n <= 5, expect="in 1..5")
    q_pos: float = param(1.0, "Q weight on position error [1/m^2]", **NN)
    q_heading: float = param(1.0, "Q weight on heading error [1/rad^2]", **NN)
    q_speed: float = param(1.0, "Q weight on speed error [s^2/m^2]", **NN)
    r_accel: float = param(0.1, "R weight on acceleration", **NN)
    r_steer: float = param(0.1, "R weight on steering angle", **NN)
    s_accel: float = param(0.1, "S weight on acceleration change", **NN)
    s_steer: float = param(1.0, "S weight on steering change", **NN)
    terminal_scale: float = param(5.0, "terminal weight P = terminal_scale * Q", **NN)
    max_iter: int = param(100, "iteration cap per solve", check=lambda n: 1 <= n <= 100_000, expect="in 1..100000")
    max_cpu_time: float = param(60.0, "CPU-time cap per ipopt solve [s]; keep it above what max_iter allows, or results depend on machine speed", **P)
    workers: int = param(0, "threads for the coordinator's work that runs without Python's lock (committed plans' detours); "
                         "0 = one per core; the decisions are the same for any count", check=lambda n: n >= 0, expect="at least 0")
    dt: float = param(0.1, "control period [s]", key="scenario.dt")
    band: bool = param(False, "build the problem with the lateral-band rows a LateralBand corridor needs", internal=True)

    def weights(self) -> np.ndarray:
        """The problem's weight vector, filled by the names of :data:`~aac_sumo.mpc.problem.WEIGHTS`."""
        q = np.array([self.q_pos, self.q_pos, self.q_heading, self.q_speed])
        w = np.full(N_WEIGHTS, np.nan)
        w[WEIGHTS["q"]] = q
        w[WEIGHTS["r"]] = [self.r_accel, self.r_steer]
        w[WEIGHTS["s"]] = [self.s_accel, self.s_steer]
        w[WEIGHTS["p"]] = self.terminal_scale * q
        assert not np.isnan(w).any()
        return w

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
