"""Single-robot MPC-FCBF planner: the component every coordinator shares.

It turns one robot's state, reference and surrounding obstacles into a plan. Obstacles are
ranked by distance and the nearest ``slots`` fill the compiled problem; unused slots are switched
off. Each solve is warm-started from the robot's shifted previous plan. If the fast solver fails
it retries once with ipopt; if that fails too the robot brakes as hard as it can, turning towards
its reference's heading, and the step is reported as ``infeasible`` or ``failed``. Its settings
are :class:`~aac_sumo.mpc.settings.MpcConfig`, its result a :class:`~aac_sumo.mpc.plan.Plan`.
"""

from __future__ import annotations

import numpy as np

from aac_sumo.barriers import (N_STAGE_FIELDS, N_TERMINAL_FIELDS, ObstaclePrediction, RegionTrack, barrier_value, cbf_axes,
                               inactive_slot, safety_ellipses, stack_predictions, stage_parameters, stopping_barrier, support)
from aac_sumo.dynamics import heading_hold_steer
from aac_sumo.geometry import wrap_angle
from aac_sumo.kernels.motion import rollouts
from aac_sumo.mpc.plan import Plan
from aac_sumo.mpc.problem import NO_LIMIT, OPEN_BAND, WEIGHTS, get_problem
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.prediction import predict_obstacle, stage_zero
from aac_sumo.references import LateralBand
from aac_sumo.world import Obstacle, RobotSpec

#: Relative margin kept outside a region the ego already intrudes on (see MpcPlanner.hold_intrusions);
#: also the room [m] an eased terminal stopping condition leaves braking at once.
INTRUSION_EPS = 1e-3
#: Room [m] a lateral band always leaves the rear axle beyond its stage-1 position: a band edge
#: exactly there leaves a standing car's solve no interior, and interior-point solvers fail on it.
BAND_GIVE = 0.05
#: Time constant [s] with which a braking robot (fallback, safety stop) turns its heading towards
#: its reference's.
FALLBACK_TURN_TIME = 0.5


def ego_discs(robot: RobotSpec, discs: int) -> tuple[np.ndarray, float]:
    """Offsets [m] of ``discs`` covering-disc centres from the rear axle along the heading, and
    their common radius [m]; together they cover the robot's footprint rectangle."""
    piece = robot.length / discs
    offsets = robot.centre_offset - 0.5 * robot.length + piece * (np.arange(discs) + 0.5)
    return offsets, float(np.hypot(0.5 * piece, 0.5 * robot.width))


class MpcPlanner:
    """Plans one robot at a time with the compiled MPC-FCBF problem for ``config``."""

    def __init__(self, config: MpcConfig):
        self.config = config
        self.problem = get_problem(config.shape(config.solver))
        retry = config.retry_with_ipopt and config.solver != "ipopt"
        self.retry_problem = get_problem(config.shape("ipopt")) if retry else None

    def nearest_regions(self, state: np.ndarray, obstacles: list[Obstacle | ObstaclePrediction | RegionTrack],
                        ego_decel: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Safety ellipses (N+1, k, 5) per stage of the k <= ``slots`` obstacles nearest to
        ``state`` (by the stage-0 distance [m] from its rear axle to the ellipse's centre less the
        larger semi-axis; ties keep the given order), whether each is a robot's swept region (k,),
        and each one's stopping region (k, 5): its footprint ellipse (whatever the barrier: it
        stands there) where it stops at the earliest, braking from now at ``obstacle_decel`` (or
        ``ego_decel`` [m/s^2] when that is 0), grown like the stages for a walker; NaN for swept
        regions (committed courses stop by themselves)."""
        cfg = self.config
        obstacles = [o for o in obstacles if not isinstance(o, Obstacle) or o.binds(float(state[2]))]  # no other approach's stop line
        if len(obstacles) > cfg.slots:
            obstacles = [obstacles[i] for i in self.nearest(state, obstacles)]
        swept = np.array([isinstance(o, RegionTrack) for o in obstacles], dtype=bool)
        ellipses = np.empty((len(obstacles), cfg.horizon + 1, 5))
        stops = np.full((len(obstacles), 5), np.nan)
        if swept.any():
            ellipses[swept] = [o.ellipses[: cfg.horizon + 1] for o in obstacles if isinstance(o, RegionTrack)]
        if not swept.all():
            preds = stack_predictions([o if isinstance(o, ObstaclePrediction) else predict_obstacle(o, cfg.horizon, cfg.dt, cfg.prediction)
                                       for o in obstacles if not isinstance(o, RegionTrack)])
            ellipses[~swept] = safety_ellipses(preds, cfg.barrier, cfg.fcbf)
            velocity = preds.velocities[:, 0]
            decel = cfg.obstacle_decel or ego_decel
            stops[~swept, :2] = preds.centres[:, 0] + velocity * np.hypot(*velocity.T)[:, None] / (2.0 * decel)
            stops[~swept, 2:] = np.column_stack(cbf_axes(preds.length[:, 0], preds.width[:, 0], preds.headings[:, 0]))
        if cfg.pedestrian_reach > 0.0 or cfg.pedestrian_margin > 0.0:
            walker = np.flatnonzero([isinstance(o, Obstacle) and o.kind == "pedestrian" for o in obstacles])
            reach = np.array([obstacles[i].step_out_speed(cfg.pedestrian_reach, cfg.walkway_time) for i in walker])
            growth = cfg.pedestrian_margin + reach[:, None] * cfg.dt * np.arange(cfg.horizon + 1)  # (walkers, K+1)
            ellipses[walker, :, 2:4] += growth[:, :, None]
            stops[walker, 2:4] += growth[:, -1:]
        return ellipses.transpose(1, 0, 2), swept, stops

    def nearest(self, state: np.ndarray, obstacles: list[Obstacle | ObstaclePrediction | RegionTrack],
                more: np.ndarray | None = None) -> np.ndarray:
        """Indices of the ``slots`` obstacles nearest to ``state``, nearest first: by the distance
        [m] from its rear axle to the centre of each one's stage-0 safety ellipse less its larger
        semi-axis (ties keep the given order). Only stage 0 is predicted, in one batch. ``more``
        (m, 5): stage-0 ellipses of further obstacles, indices ``len(obstacles)`` on."""
        cfg = self.config
        now = np.empty((len(obstacles) + (0 if more is None else len(more)), 5))
        if more is not None:
            now[len(obstacles):] = more
        kinds = np.array([0 if isinstance(o, RegionTrack) else 1 if isinstance(o, ObstaclePrediction) else 2 for o in obstacles])
        for i in np.flatnonzero(kinds == 0):
            now[i] = obstacles[i].ellipses[0]
        for i in np.flatnonzero(kinds == 1):
            p = obstacles[i]
            now[i] = safety_ellipses(ObstaclePrediction(p.centres[:1], p.velocities[:1], p.headings[:1], p.length, p.width), cfg.barrier, cfg.fcbf)[0]
        plain = np.flatnonzero(kinds == 2)
        if plain.size:
            now[plain] = safety_ellipses(stage_zero([obstacles[i] for i in plain], cfg.horizon, cfg.dt, cfg.prediction), cfg.barrier, cfg.fcbf)[:, 0]
            if cfg.pedestrian_reach > 0.0 or cfg.pedestrian_margin > 0.0:
                walker = plain[[obstacles[i].kind == "pedestrian" for i in plain]]
                now[walker, 2:4] += cfg.pedestrian_margin
        gaps = np.hypot(now[:, 0] - state[0], now[:, 1] - state[1]) - np.maximum(now[:, 2], now[:, 3])
        return np.argsort(gaps, kind="stable")[: cfg.slots]

    def slot_parameters(self, robot: RobotSpec, state: np.ndarray, regions: np.ndarray, d) -> np.ndarray:
        """Stage parameters (..., N+1, slots, 7) of ``regions`` (N+1, k, 5), k <= slots, grown for
        ego clearance ``d`` [m]: a float, or an array (...) giving one set per clearance. The
        slots after the k regions are switched off."""
        cfg = self.config
        centre = state[:2] + robot.centre_offset * np.array([np.cos(state[2]), np.sin(state[2])])
        d = np.asarray(d, dtype=float)
        params = np.empty(d.shape + (cfg.horizon + 1, cfg.slots, N_STAGE_FIELDS))
        params[...] = inactive_slot(cfg.horizon)[:, None, :]
        params[..., : regions.shape[1], :] = stage_parameters(regions, d[..., None, None], centre)
        return params

    def obstacle_parameters(self, robot: RobotSpec, state: np.ndarray, obstacles: list[Obstacle | ObstaclePrediction | RegionTrack]) -> np.ndarray:
        """Stage parameters (N+1, slots, 7) of the nearest obstacles around ``state``, each
        region grown by the ego's disc radius plus ``d_safe``."""
        _, radius = ego_discs(robot, self.config.discs)
        regions, _, _ = self.nearest_regions(state, obstacles)
        return self.slot_parameters(robot, state, regions, radius + self.config.d_safe)

    def barrier_parameters(self, robot: RobotSpec, state: np.ndarray, u_prev: np.ndarray,
                           obstacles: list[Obstacle | ObstaclePrediction | RegionTrack]) -> tuple[np.ndarray, np.ndarray]:
        """The MPC's obstacle parameters (N+1, slots, 7): the nearest regions, grown for the ego's
        discs, with intrusions held (see :meth:`hold_intrusions`); and the terminal stopping
        parameters (slots, 7) of the same slots (see :meth:`stopping_parameters`)."""
        _, radius = ego_discs(robot, self.config.discs)
        decel = abs(robot.model.limits.a_min)
        regions, swept, stops = self.nearest_regions(state, obstacles, decel)
        # floor: contact, grown by the disc alone
        params, floor = self.slot_parameters(robot, state, regions, radius + np.array([self.config.d_safe, 0.0]))
        swept = np.flatnonzero(swept)  # a robot's swept region already contains its footprint with room to spare
        floor[:, swept, 4:6] = regions[:, swept, 2:4] ** -2.0
        room = np.minimum(floor[:, :, 4] / params[:, :, 4], floor[:, :, 5] / params[:, :, 5]).min(axis=0)
        params = self.hold_intrusions(self.drop_out_of_reach(params, robot, state), robot, state, u_prev, room)
        cfg = self.config
        settle = decel * cfg.dt**2 / (2.0 * cfg.gamma**2)
        return params, self.stopping_parameters(robot, state, regions[0], stops, radius + cfg.d_safe + settle, decel)

    def stopping_parameters(self, robot: RobotSpec, state: np.ndarray, now: np.ndarray, stops: np.ndarray, d: float,
                            decel: float) -> np.ndarray:
        """Terminal stopping parameters (slots, ``N_TERMINAL_FIELDS``) of the slots whose regions
        are ``now`` (k, 5) at stage 0 and ``stops`` (k, 5) where they could stop, grown for ego
        clearance ``d`` [m].

        With ``terminal_stop``, a slot's condition is on when its obstacle's centre lies ahead of
        the ego's (in its direction of travel) and it is no swept region: braking at ``decel``
        [m/s^2] from stage N, the ego's discs stop short of the region where that obstacle would
        stop if it braked at once. This is the stopping-distance rule of car following (the
        leader may brake at any moment, the follower after the horizon); a short horizon's barrier
        alone lets the ego close in until it cannot stop. A region across the ego's line of travel
        (now) is kept ahead of the stopping point along that line (``along``); the stopping point
        could otherwise jump past it. Where even braking now (the Euler model's rollout at
        ``decel``, then its stopping distance) breaks a condition, the condition is eased to what
        braking now achieves (``give``; a region shrinks as in :meth:`hold_intrusions`), so
        braking now always satisfies it.

        :meth:`barrier_parameters` grows the regions by ``b dt^2 / (2 gamma^2)`` more than the stage
        regions (0.33 m at 6 m/s^2, 0.1 s and gamma 0.3): a stage's barrier may shrink by the
        fraction gamma per period, roughly ``v dt <= gamma (s + m)`` at distance ``s + m`` from its
        edge, and a stop at full braking ``b`` (``v = sqrt(2 b s)`` with ``s`` still to go) keeps
        that for every ``s`` once the stop lies ``m = b dt^2 / (2 gamma^2)`` before the edge."""
        cfg = self.config
        params = np.zeros((cfg.slots, N_TERMINAL_FIELDS))
        params[:, :N_STAGE_FIELDS] = inactive_slot(0)[0]
        if not cfg.terminal_stop:
            return params
        offsets, _ = ego_discs(robot, cfg.discs)
        x, y, heading, v = state
        unit = np.array([np.cos(heading), np.sin(heading)])
        forward = unit * (-1.0 if v < 0 else 1.0)
        centre = state[:2] + robot.centre_offset * unit
        ahead = np.flatnonzero(~np.isnan(stops[:, 0]) & ((now[:, :2] - centre) @ forward > 0.0))
        if ahead.size == 0:
            return params
        region = stage_parameters(stops[ahead], d, centre)
        params[ahead, :N_STAGE_FIELDS] = region
        normal = np.array([-forward[1], forward[0]])
        across = np.abs((region[:, :2] - centre) @ normal)
        params[ahead, 7] = across < support(region, normal)
        # braking now: the discs at stage N and their stopping distance
        speeds = np.maximum(abs(v) - decel * cfg.dt * np.arange(cfg.horizon + 1), 0.0)
        discs = state[:2] + (np.sign(v) * cfg.dt * speeds[:-1].sum() + offsets)[:, None] * unit  # (D, 2)
        stop = np.sign(v) * (speeds[-1] + 0.5 * decel * cfg.dt) ** 2 / (2.0 * decel)
        fields = params[None, ahead, :6].transpose(2, 0, 1)
        along = params[ahead, 7]
        end = 1.0 + stopping_barrier(discs[:, None, 0], discs[:, None, 1], *unit, stop, *fields, 0.0, 0.0)
        short = stopping_barrier(discs[:, None, 0], discs[:, None, 1], *unit, stop, *fields, 1.0, 0.0)
        factor = np.where(along > 0, 1.0, (1.0 + INTRUSION_EPS) / np.maximum(end.min(axis=0), 1e-9))
        params[ahead, 4:6] *= np.maximum(factor, 1.0)[:, None]
        lacking = -short.min(axis=0)
        params[ahead, 8] = np.where((along > 0) & (lacking > 0.0), lacking + INTRUSION_EPS, 0.0)
        return params

    def drop_out_of_reach(self, params: np.ndarray, robot: RobotSpec, state: np.ndarray) -> np.ndarray:
        """Switch off the barrier conditions of a stage k >= 1 whose region lies farther from the
        rear axle than the ego can travel by stage k plus its stopping distance now.

        The rear axle travels at most ``sum_i min(v_max, |v| + a_max i dt) dt`` in k periods, and
        a region lies within its largest grown semi-axis of its centre, so there ``h_k > 0`` holds
        whatever the inputs. The stopping distance ``v^2 / (2 |a_min|)`` on top keeps the decay
        condition wherever it still matters beyond the horizon: for a car ahead that may brake, it
        makes the ego slow down in time. Farther away, the algebraic barrier, which grows with the
        squared distance, changes by more than the decay rate allows when a region merely turns or
        changes shape (a car steering 30 m away), and the solve would fail for nothing.
        """
        cfg, lim = self.config, robot.model.limits
        offsets, _ = ego_discs(robot, cfg.discs)
        speed = abs(state[3])
        steps = np.minimum(max(lim.v_max, -lim.v_min), speed + lim.a_max * cfg.dt * np.arange(cfg.horizon)) * cfg.dt
        reach = np.r_[0.0, np.cumsum(steps)] + np.abs(offsets).max() + speed**2 / (2.0 * abs(lim.a_min))  # (N+1,)
        extent = np.minimum(params[:, :, 4], params[:, :, 5]).clip(1e-12) ** -0.5  # the larger semi-axis
        gap = np.hypot(params[:, :, 0] - state[0], params[:, :, 1] - state[1]) - extent
        far = gap > reach[:, None]
        far[0] = False
        params[far, 6] = 0.0
        return params

    def hold_intrusions(self, params: np.ndarray, robot: RobotSpec, state: np.ndarray, u_prev: np.ndarray,
                        room: np.ndarray) -> np.ndarray:
        """Keep the barrier conditions satisfiable where the current state already decides them.

        In the Euler model the rear axle's stage-1 position is fixed by the current state and the
        inputs only turn the discs about it. Where the stage-1 discs (heading predicted with the
        previous steering) already break the first condition ``h1 >= (1 - gamma) h0`` of a slot,
        that row is switched off for this solve. Where they lie inside the region (``q < 1``,
        with ``q = h + 1`` the quadratic form) but only within the ``d_safe`` margin, the slot's
        ``1/A^2, 1/B^2`` are scaled at every stage by ``(1 + eps) / q`` (at most ``room``
        (slots,): down to the safety ellipse grown by the disc radius alone, where contact
        begins; for another robot's swept region, whose ellipse contains its footprint with room
        to spare, down to that ellipse itself): the ego starts just outside the shrunk region and
        may not go deeper than it already is. A disc deeper than the margin keeps the full region, so the solve
        fails and the robot brakes. Other slots keep the paper's conditions; a shrunk region
        grows back as the ego moves away.
        """
        cfg = self.config
        offsets, _ = ego_discs(robot, cfg.discs)
        x, y, heading, v = state
        heading1 = heading + v * np.tan(u_prev[1]) / robot.model.wheelbase * cfg.dt
        pos1 = np.array([x, y]) + v * cfg.dt * np.array([np.cos(heading), np.sin(heading)])
        discs0 = np.array([x, y]) + offsets[:, None] * np.array([np.cos(heading), np.sin(heading)])  # (D, 2)
        discs1 = pos1 + offsets[:, None] * np.array([np.cos(heading1), np.sin(heading1)])
        q0 = 1.0 + barrier_value(discs0[:, None, 0], discs0[:, None, 1], *params[0][None, :, :6].transpose(2, 0, 1))
        q1 = 1.0 + barrier_value(discs1[:, None, 0], discs1[:, None, 1], *params[1][None, :, :6].transpose(2, 0, 1))
        active = params[1, :, 6] > 0
        broken = active & np.any(q1 - 1.0 < (1.0 - cfg.gamma) * (q0 - 1.0), axis=0)
        factor = (1.0 + INTRUSION_EPS) / np.maximum(q1.min(axis=0), 1e-9)
        inside = active & (factor > 1.0) & (factor <= room)
        params[1, broken | inside, 6] = 0.0
        params[:, inside, 4] *= factor[inside]
        params[:, inside, 5] *= factor[inside]
        return params

    def band_rows(self, robot: RobotSpec, corridor, reference: np.ndarray, state: np.ndarray) -> np.ndarray:
        """The MPC's lateral-band rows (N, 4) for stages 1..N; open unless ``corridor`` is a band.

        Each row leaves the stage-1 rear axle (fixed by the current state) at least ``BAND_GIVE``
        of room on both sides: a robot outside its band, or on its edge, may not go more than
        that further out. A robot heading out of its band by ``e`` (against the reference's
        heading) also gets the room it needs to turn back in at full lock, ``R (1 - cos e)``
        with the turning radius ``R = wheelbase / tan(steer_max)``: without it, a car that had
        swerved to its band's edge could not move forward at all (it does not reverse)."""
        n = self.config.horizon
        if not isinstance(corridor, LateralBand):
            return np.tile(OPEN_BAND, (n, 1))
        rows = corridor.limits(reference)
        x, y, heading, v = state
        stage1 = np.array([x, y]) + v * self.config.dt * np.array([np.cos(heading), np.sin(heading)])
        now = rows[:, :2] @ stage1  # the stage-1 rear axle is fixed by the current state
        out = float(wrap_angle(heading - reference[1, 2]))  # > 0: towards the left edge
        turn = robot.model.wheelbase / np.tan(robot.model.limits.steer_max) * (1.0 - np.cos(min(abs(out), 0.5 * np.pi)))
        rows[:, 2] = np.minimum(rows[:, 2], now - BAND_GIVE - (turn if out < 0 else 0.0))
        rows[:, 3] = np.maximum(rows[:, 3], now + BAND_GIVE + (turn if out > 0 else 0.0))
        return rows

    def plan(
        self,
        robot: RobotSpec,
        state: np.ndarray,
        reference: np.ndarray,
        u_prev: np.ndarray,
        obstacles: list[Obstacle | ObstaclePrediction | RegionTrack],
        previous: Plan | None = None,
        corridor: np.ndarray | LateralBand | None = None,
        guess: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> Plan:
        """Plan for ``robot`` at ``state`` tracking ``reference`` (N+1, 4) around ``obstacles``;
        a column of ``reference`` holding NaN (a free heading or speed) is not weighed.

        ``corridor`` optionally bounds the planned rear-axle positions: to the world-frame box
        ``[x_min, x_max, y_min, y_max]`` [m] (a straight lane, say), or across the reference
        to a :class:`~aac_sumo.references.LateralBand` (a road of any shape); a band the robot
        is already outside of is widened so that it may not go further out than now.
        ``guess`` (states (N+1, 4), inputs (N, 2)) is the warm start when given (a committed
        course), instead of ``previous`` shifted by one period."""
        cfg = self.config
        if isinstance(corridor, LateralBand) and not cfg.band:
            raise ValueError("a LateralBand corridor needs a planner built with MpcConfig(band=True)")
        lim = robot.model.limits
        state = np.asarray(state, dtype=float).copy()
        state[3] = np.clip(state[3], lim.v_min, lim.v_max)
        weights = cfg.weights()
        free = np.isnan(reference).any(axis=0)  # a NaN reference column is not weighed
        if free.any():
            reference = np.where(np.isnan(reference), np.r_[state[:2], state[2], 0.0][None, :], reference)
            weights[WEIGHTS["q"]][free] = 0.0  # views: the state rows of Q and of the terminal P
            weights[WEIGHTS["p"]][free] = 0.0
        offsets, _ = ego_discs(robot, cfg.discs)
        barriers, terminal = self.barrier_parameters(robot, state, u_prev, obstacles)
        params = dict(
            wheelbase=robot.model.wheelbase,
            gamma=cfg.gamma,
            disc_offsets=offsets,
            weights=weights,
            x_ref=reference,
            obstacles=barriers,
            terminal=terminal if cfg.terminal_stop else np.zeros(0),
            stop_decel=abs(lim.a_min) if cfg.terminal_stop else np.zeros(0),
            band=self.band_rows(robot, corridor, reference, state) if cfg.band else np.zeros(0),
        )
        usable = cfg.warm_start and previous is not None and len(previous.inputs) == cfg.horizon
        envelopes = cfg.envelopes(lim)

        def attempts():
            """Per envelope (:meth:`MpcConfig.envelopes`, the comfort one first): a warm start
            that fails is retried cold by the same solver (a shifted plan that the moved regions
            cut through often traps it), then, within the vehicle's own limits, by ipopt from the
            first guess; the cold guess is rolled out only when needed."""
            warm = previous.shifted(state) if usable else None
            if cfg.warm_start and guess is not None:
                warm = (np.vstack([state[None], guess[0][1:]]), guess[1])
            cold = None
            for envelope in envelopes:
                if warm is not None:
                    yield self.problem, warm, envelope
                cold = self.coasting(robot, state) if cold is None else cold
                yield self.problem, cold, envelope
                if self.retry_problem is not None and envelope is envelopes[-1]:
                    yield self.retry_problem, warm if warm is not None else cold, envelope

        box = np.array([-np.inf, np.inf, -np.inf, np.inf]) if corridor is None or isinstance(corridor, LateralBand) else np.asarray(corridor, dtype=float)
        total_ms, outcome, used = 0.0, None, cfg.solver
        for problem, start, (a_min, a_max, a_lat) in attempts():
            bounds = ([box[0], box[2], -np.inf, lim.v_min], [box[1], box[3], np.inf, lim.v_max], [a_min, -lim.steer_max], [a_max, lim.steer_max])
            lbx, ubx = problem.bounds(state, u_prev, *bounds)
            params["limits"] = np.minimum([a_lat, lim.steer_rate_max * cfg.dt], NO_LIMIT)
            outcome = problem.solve(problem.parameters(**params), problem.pack(*start, u_prev), lbx, ubx)
            total_ms += outcome.solve_ms
            used = problem.shape.solver
            if outcome.status == "solved":
                return Plan(outcome.states, outcome.inputs, "solved", total_ms, used, outcome.iterations, outcome.detail, outcome.capped)
        states, inputs = self.fallback(robot, state, reference, u_prev)
        return Plan(states, inputs, outcome.status, total_ms, "fallback", outcome.iterations, f"{used}: {outcome.detail}", outcome.capped)

    def fallback(self, robot: RobotSpec, state: np.ndarray, reference: np.ndarray, u_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (N+1, 4) and inputs (N, 2) of the safe fallback: brake as hard as possible to a
        stop, never reversing, while turning the heading towards the reference's (a car brakes
        in its lane instead of drifting across the road at the angle it had). The heading error
        closes with time constant ``FALLBACK_TURN_TIME`` [s], within the steering limits (angle,
        rate from ``u_prev``'s steering, lateral acceleration). A free (NaN) reference heading, as
        near a goal, keeps the robot's heading."""
        cfg, lim = self.config, robot.model.limits
        inputs = np.empty((cfg.horizon, 2))
        states = np.empty((cfg.horizon + 1, 4))
        states[0] = state
        for k in range(cfg.horizon):
            x = states[k]
            heading = reference[k, 2] if np.isfinite(reference[k, 2]) else x[2]
            steer = heading_hold_steer(x, heading, cfg.dt, robot.model.wheelbase, lim.steer_max, FALLBACK_TURN_TIME)
            accel = lim.braking_input(x[3], cfg.dt)[0]
            inputs[k] = [accel, robot.model.limit_steer(steer, x[3], inputs[k - 1, 1] if k else u_prev[1], cfg.dt, accel)]
            states[k + 1] = robot.model.step(x, inputs[k], cfg.dt)
        return states, inputs

    def coasting(self, robot: RobotSpec, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (N+1, 4) of coasting from ``state`` (zero inputs: straight on at constant
        speed) with the planner's model, and those inputs (N, 2): the cold first guess."""
        inputs = np.zeros((self.config.horizon, 2))
        lim = robot.model.limits
        states = rollouts(state[None, :], inputs[None], self.config.dt, np.array([robot.model.wheelbase]),
                          np.array([lim.v_min]), np.array([lim.v_max]))[0]
        return states, inputs
