"""CBF-QP baseline (``controller.coordinator = "cbf_qp"``): the Robotarium-style safety filter.

Each control period every unfinished robot computes a nominal input, the tracking law toward its
reference (:func:`~aac_sumo.coordination.tracking.track`, as the other coordinators' tracking
fallback), and filters it through a small quadratic programme solved by OSQP:

    minimise  (u - u_nom)^T W (u - u_nom)          u = [accel, steer]
    subject to one barrier row per (ego disc, neighbour), and the input limits.

``W = diag(1 / a_scale^2, 1 / steer_max^2)`` with ``a_scale = max(a_max, -a_min)``: a change of
the whole acceleration range costs as much as one of the whole steering range.

**Neighbours.** The other controlled robots whose footprint centres lie within ``cbf_qp.radius``
(each seen as the planner sees a robot it does not coordinate with: moving on at its current
velocity, :meth:`~aac_sumo.world.WorldState.robot_as_obstacle`), and the ``controller.obstacle_slots``
nearest uncontrolled obstacles (debris, scripted vehicles, cones, pedestrians), nearest as the
MPC picks them.

**The barrier** is the MPC's, computed by the MPC's own code (:meth:`MpcPlanner.nearest_regions`
and :func:`~aac_sumo.barriers.stage_parameters`): the safety ellipse of ``controller.barrier``
(``cbf``: footprint ellipse; ``fcbf``: velocity-stretched), predicted with
``controller.prediction``, grown for the ego's covering discs plus ``d_safe`` (pedestrians also by
``pedestrian_margin`` and ``pedestrian_reach``), and the algebraic ``h = (x'/A)^2 + (y'/B)^2 - 1``.

**The condition** is the MPC's discrete one, ``h(k+1) >= (1 - gamma) h(k)``, on the first
transition the input can shape. Under the Euler bicycle model the rear axle's next position
``p(k+1) = p(k) + v(k) dt (cos, sin)`` does not depend on the input at all, so the row of period
k is the condition between stages k+1 and k+2, with the input held for both periods:

    h(c(k+2; u), ob(k+2)) - (1 - gamma) h(c(k+1; u), ob(k+1)) >= 0,

where ``c`` is an ego disc centre (it depends on ``u`` through the heading too). The left side is
linearised in ``u`` at the nominal input (analytic Jacobian). When every period's QP is feasible,
the chain ``h(k+1) >= (1 - gamma) h(k)`` holds from period 1 on, up to the linearisation and the
obstacles' prediction errors. The continuous-time form ``dh/dt >= -gamma h`` does not apply: the
position has relative degree two in the acceleration, so it would need a higher-order barrier
(a different barrier from the MPC's), and the discrete form matches the MPC's row for row.

**Limits.** ``accel`` keeps ``[a_min, a_max]`` and the speed within ``[v_min, v_max]``; the filter
may back off only where the robot may reverse (``robot.allow_reverse``). ``steer`` keeps the
steering rate from the previous period's angle, the angle limit and the lateral-acceleration
limit at the fastest speed the period can reach (:meth:`BicycleModel.limit_steer`).

**Outcome.** A nominal input that already meets every row is the QP's minimiser and is applied
unchanged (mode ``tracking``) without calling OSQP; otherwise OSQP solves it (mode ``cbf_qp``).
Either way the period counts as one solve of that robot. A QP OSQP reports infeasible (or that it
fails to solve) is counted in ``infeasible_solves`` like a failed MPC solve, and the robot applies
the MPC's braking fallback (:meth:`MpcPlanner.fallback`: the hardest braking, ``a_min``, steering
toward its reference's heading; mode ``fallback``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from aac_sumo.barriers import stage_parameters
from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param, section
from aac_sumo.coordination.base import Coordinator, Decision, Finished, RobotDecision
from aac_sumo.coordination.tracking import AimsAhead, track
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner, ego_discs
from aac_sumo.references import PathReference
from aac_sumo.registry import register_coordinator
from aac_sumo.world import Obstacle, RobotSpec, WorldState

#: A row the nominal input violates by less than this is taken as met.
ROW_TOLERANCE = 1e-9


@section("cbf_qp")
@dataclass(frozen=True)
class CbfQpParams(AimsAhead):
    """CBF-QP settings: the neighbour radius [m] (centre to centre) within which another robot
    gets a barrier row, and the nominal tracking law's lookahead [m] and speed gain [1/s]."""

    radius: float = param(5.0, "another robot whose footprint centre is within this of the ego's gets a barrier row [m]", **P)
    lookahead: float = param(1.0, "pure-pursuit lookahead of the nominal tracking law [m]", **P)
    lookahead_time: float = param(0.0, "with > 0, at low speed the lookahead shrinks to the distance covered in this time, but not below "
                                  "lookahead_min: a car that turns a tight corner slowly aims at the corner, not beyond it [s]", **NN)
    lookahead_min: float = param(0.0, "the shortest lookahead with lookahead_time > 0 [m]", **NN)
    speed_gain: float = param(1.0, "speed-error gain of the nominal tracking law [1/s]", **P)


@dataclass
class FilterResult:
    """The filtered input ``[accel, steer]``, the outcome (``unchanged``: the nominal input met
    every row; ``solved``; or OSQP's status when it did not solve it), OSQP's iterations (0
    without a call) and whether it stopped at its iteration cap."""

    input: np.ndarray
    outcome: str
    iterations: int = 0
    capped: bool = False

    @property
    def ok(self) -> bool:
        return self.outcome in ("unchanged", "solved")


class _Regions:
    """The MPC planner's region code (nearest obstacles, their predicted safety ellipses) on a
    copy of its settings with a two-stage horizon, without building an MPC problem."""

    nearest = MpcPlanner.nearest
    nearest_regions = MpcPlanner.nearest_regions

    def __init__(self, config: MpcConfig):
        self.config = config


def disc_course(robot: RobotSpec, state: np.ndarray, u: np.ndarray, dt: float, offsets: np.ndarray):
    """Disc centres at stages 1 and 2 (each (m, 2)) of a robot at ``state`` holding input ``u``
    for two periods under the Euler bicycle model, and their Jacobians in ``u`` (each (m, 2, 2):
    disc, [x, y], [accel, steer]). ``offsets`` (m,): disc centres ahead of the rear axle [m]."""
    x, y, th, v = (float(c) for c in state[:4])
    a, d = float(u[0]), float(u[1])
    wb = robot.model.wheelbase
    tan_d, sec2 = np.tan(d), 1.0 / np.cos(d) ** 2
    th1 = th + v * tan_d / wb * dt
    v1 = v + a * dt
    th2 = th1 + v1 * tan_d / wb * dt
    p1 = np.array([x + v * np.cos(th) * dt, y + v * np.sin(th) * dt])
    e1, n1 = np.array([np.cos(th1), np.sin(th1)]), np.array([-np.sin(th1), np.cos(th1)])
    e2, n2 = np.array([np.cos(th2), np.sin(th2)]), np.array([-np.sin(th2), np.cos(th2)])
    p2 = p1 + v1 * dt * e1
    dth1 = np.array([0.0, v * dt * sec2 / wb])  # d th1 / d [a, steer]
    dth2 = dth1 + np.array([dt * tan_d / wb * dt, v1 * dt * sec2 / wb])
    dp2 = np.outer(e1, [dt * dt, 0.0]) + np.outer(v1 * dt * n1, dth1)
    offsets = np.asarray(offsets, dtype=float)
    c1 = p1 + offsets[:, None] * e1
    c2 = p2 + offsets[:, None] * e2
    j1 = offsets[:, None, None] * np.outer(n1, dth1)[None]
    j2 = dp2[None] + offsets[:, None, None] * np.outer(n2, dth2)[None]
    return c1, c2, j1, j2


def barrier_and_gradient(points: np.ndarray, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``h = (x'/A)^2 + (y'/B)^2 - 1`` (:func:`~aac_sumo.barriers.barrier_value`) of points (m, 2)
    against regions given as MPC stage parameters (k, >= 6), and its gradient in the point:
    (m, k) and (m, k, 2)."""
    dx = points[:, None, 0] - params[None, :, 0]
    dy = points[:, None, 1] - params[None, :, 1]
    c, s = params[None, :, 2], params[None, :, 3]
    xl, yl = c * dx + s * dy, -s * dx + c * dy
    gx, gy = 2.0 * xl * params[None, :, 4], 2.0 * yl * params[None, :, 5]
    h = xl * gx * 0.5 + yl * gy * 0.5 - 1.0
    return h, np.stack([gx * c - gy * s, gx * s + gy * c], axis=-1)


def barrier_rows(robot: RobotSpec, state: np.ndarray, nominal: np.ndarray, stages: np.ndarray, gamma: float, dt: float,
                 offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``G u >= g`` ((m*k, 2), (m*k,)) of the condition ``h(k+2) - (1 - gamma) h(k+1) >= 0``
    for every ego disc (``offsets`` (m,)) and region, linearised in ``u`` at ``nominal``.
    ``stages`` (3, k, 7): the regions' MPC stage parameters at stages 0, 1, 2."""
    c1, c2, j1, j2 = disc_course(robot, state, nominal, dt, offsets)
    h1, g1 = barrier_and_gradient(c1, stages[1])
    h2, g2 = barrier_and_gradient(c2, stages[2])
    value = h2 - (1.0 - gamma) * h1  # (m, k)
    grad = np.einsum("mkp,mpu->mku", g2, j2) - (1.0 - gamma) * np.einsum("mkp,mpu->mku", g1, j1)
    grad = grad.reshape(-1, 2)
    return grad, grad @ nominal - value.reshape(-1)


def input_bounds(robot: RobotSpec, state: np.ndarray, previous_steer: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (2,) of ``[accel, steer]`` this period (see the module's Limits)."""
    lim, v = robot.model.limits, float(state[3])
    v_lo = lim.v_min
    a_hi = min(lim.a_max, (lim.v_max - v) / dt)
    a_lo = min(max(lim.a_min, (v_lo - v) / dt), a_hi)
    fastest = max(abs(v), abs(v + a_lo * dt), abs(v + a_hi * dt))
    bound = float(robot.model.steer_bound(fastest))
    rate = lim.steer_rate_max * dt
    s_lo = float(np.clip(previous_steer - rate, -bound, bound))
    s_hi = float(np.clip(previous_steer + rate, -bound, bound))
    return np.array([a_lo, s_lo]), np.array([a_hi, s_hi])


def filter_input(nominal: np.ndarray, rows: np.ndarray, rhs: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 weights: np.ndarray) -> FilterResult:
    """The input nearest to ``nominal`` in the ``weights`` (2,) norm with ``rows @ u >= rhs`` and
    ``lo <= u <= hi``; OSQP solves it unless ``nominal`` (clipped to the bounds) already meets
    every row."""
    nominal = np.clip(nominal, lo, hi)
    if not len(rows) or np.all(rows @ nominal >= rhs - ROW_TOLERANCE):
        return FilterResult(nominal, "unchanged")
    P = sp.csc_matrix(np.diag(weights))
    A = sp.csc_matrix(np.vstack([rows, np.eye(2)]))
    solver = osqp.OSQP()
    solver.setup(P, -weights * nominal, A, np.concatenate([rhs, lo]), np.concatenate([np.full(len(rhs), np.inf), hi]),
                 verbose=False, eps_abs=1e-7, eps_rel=1e-7, polishing=True, max_iter=4000)
    res = solver.solve(raise_error=False)
    status = str(res.info.status).lower()
    capped = "maximum iterations" in status
    if status in ("solved", "solved inaccurate") and res.x is not None and np.all(np.isfinite(res.x)):
        u = np.clip(res.x, lo, hi)
        if np.all(rows @ u >= rhs - 1e-5 * (1.0 + np.abs(rhs))):
            return FilterResult(u, "solved", int(res.info.iter), capped)
    return FilterResult(nominal, status.replace(" ", "_"), int(res.info.iter), capped)


class CbfQpCoordinator(Coordinator):
    """Every robot filters its tracking input through its own CBF-QP each period (see the module)."""

    name = "cbf_qp"

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                 params: CbfQpParams = CbfQpParams()):
        super().__init__(planner, tasks, corridors, finished)
        self.params = params
        self.stage_config = dataclasses.replace(planner.config, horizon=2)  # stages 0, 1, 2 of the regions
        self.regions = _Regions(self.stage_config)

    def neighbours(self, world: WorldState, i: int, as_obstacles: list[Obstacle]) -> list[Obstacle]:
        """Robot ``i``'s neighbours: the robots on the road within ``radius`` and the nearest
        ``obstacle_slots`` uncontrolled obstacles."""
        centres = world.robot_centres()
        near = np.hypot(*(centres - centres[i]).T) <= self.params.radius
        near &= world.on_road
        near[i] = False
        out = [as_obstacles[j] for j in np.flatnonzero(near)]
        if world.obstacles:
            out += [world.obstacles[k] for k in self.regions.nearest(world.states[i], world.obstacles)]
        return out

    def filter(self, world: WorldState, i: int, nominal: np.ndarray, obstacles: list[Obstacle]) -> FilterResult:
        """Robot ``i``'s ``nominal`` input filtered against ``obstacles``."""
        cfg, robot, state = self.planner.config, world.robots[i], world.states[i]
        lo, hi = input_bounds(robot, state, float(self.last_inputs[i, 1]), cfg.dt)
        nominal = np.clip(nominal, lo, hi)
        offsets, radius = ego_discs(robot, cfg.discs)
        if obstacles:
            view = _Regions(dataclasses.replace(self.stage_config, slots=len(obstacles)))  # every neighbour, none dropped
            ellipses = view.nearest_regions(state, obstacles)[0]  # (3, k, 5)
            centre = state[:2] + robot.centre_offset * np.array([np.cos(state[2]), np.sin(state[2])])
            stages = stage_parameters(ellipses, radius + cfg.d_safe, centre)
            rows, rhs = barrier_rows(robot, state, nominal, stages, cfg.gamma, cfg.dt, offsets)
        else:
            rows, rhs = np.zeros((0, 2)), np.zeros(0)
        lim = robot.model.limits
        weights = np.array([max(lim.a_max, -lim.a_min) ** -2, lim.steer_max**-2])
        return filter_input(nominal, rows, rhs, lo, hi, weights)

    def _decide(self, world: WorldState) -> Decision:
        n, cfg, p = len(world.robots), self.planner.config, self.params
        parked = self.parked(world, self.finished(world))
        inputs = np.zeros((n, 2))
        records = [RobotDecision(False, mode="hold") for _ in range(n)]
        as_obstacles = [world.robot_as_obstacle(j) for j in range(n)]
        for i in np.flatnonzero(parked):
            inputs[i] = self.hold_inputs(world, i, 1)[0]
        for i in np.flatnonzero(~parked):
            start = time.perf_counter()
            robot, state = world.robots[i], world.states[i]
            nominal = track(robot, state, self.tasks[i], p.pursuit, p.speed_gain, self.last_inputs[i, 1], cfg.dt,
                            target_speed=self.tracking_speed(world, i, p.speed_gain), a_lat=self.tracking_lat())
            result = self.filter(world, i, nominal, self.neighbours(world, i, as_obstacles))
            if result.ok:
                inputs[i], mode = result.input, ("tracking" if result.outcome == "unchanged" else "cbf_qp")
                status = "solved"
            else:
                inputs[i] = self.planner.fallback(robot, state, self.reference(world, i), self.last_inputs[i])[1][0]
                mode, status = "fallback", "infeasible" if "infeasible" in result.outcome else result.outcome
            records[i] = RobotDecision(True, status, (time.perf_counter() - start) * 1e3, "osqp", reason="cbf_qp", mode=mode,
                                       iterations=result.iterations, capped=result.capped)
        return Decision(inputs, records, notes=dict(authority="", reason="cbf_qp", safety_stops=0))


register_coordinator("cbf_qp", CbfQpCoordinator, params=CbfQpParams, baseline=True, label="CBF-QP safety filter",
                     doc="a CBF-QP safety filter on the tracking law, a baseline; docs/baselines_cbf_qp.md")
