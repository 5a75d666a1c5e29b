"""The safety stop (beyond the paper): a check that every coordinator can run on the inputs it
is about to apply.

A robot's course is its input once, then braking to a stop while turning towards the heading it
brakes along (its reference's where it is: a car brakes along its lane, as the planner's
fallback does). It must brake instead when, at some stage of that course, its footprint comes
within ``margin`` [m] of another robot's footprint at the same stage, or of an obstacle moving
at constant velocity, closer to it than it is now and than braking at once would bring it at
that stage. (Compared stage by stage: a pedestrian's region grows with time, so late in both
courses it swallows the car whatever it did, and a comparison of the two courses' closest
approaches let a car creep into a walker.) Obstacles that surely stand (cones) count only within
``STANDING_GAP`` (5 cm; SUMO's lane-wise gap to them differs from ours by millimetres on a curve):
they cannot come at the robot, and a car that has stopped within the margin of a
cone, pointing at it, could otherwise never leave (it does not reverse).
Braking at once is always allowed: a robot standing beside a pedestrian who may start walking
may drive away from them. The other robots are taken both on their own such course and braking
at once, since either may happen. A pedestrian's footprint grows on every side by the
planner's ``pedestrian_margin`` [m] plus its ``pedestrian_reach`` [m/s] times the time (not the
reach for a walker who stays on a walkway of her own: the planner's ``walkway_time``). A robot
that fails brakes as gently as passes the check.

Comfort first: a course brakes at the robot's comfort deceleration, so that robots keep the
room to stop without an emergency; the others may brake at once at their hardest. A robot
that no comfortable choice (coasting, a third, two thirds or all of its comfort braking)
lets pass brakes at its comfort deceleration now if braking at its hardest afterwards
passes, else harder (two thirds of its hardest, then all of it): an emergency. Every
steering angle keeps the vehicle limits.

A walking pedestrian whose path lies ahead of a robot is answered by stopping before her path,
or else by passing her when she cannot come within the margin first
(:meth:`SafetyCheck.walker_paths`): the check above only makes a robot no closer than braking
at once.
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.regions import Fleet
from aac_sumo.coordination.walker_paths import STRIP_OVERSHOOT, VEHICLE_KINDS, WalkerPaths, WalkerSpeeds  # noqa: F401 (re-exported)
from aac_sumo.dynamics import heading_hold_steer
from aac_sumo.kernels.safety import braking_courses, gentlest_stops, stop_flags
from aac_sumo.kernels.motion import heading_along
from aac_sumo.mpc.planner import FALLBACK_TURN_TIME
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.world import WorldState, line_binds

#: Gap difference [m] below which a course counts as no closer than braking at once.
BRAKING_TIE = 1e-6
#: A vehicle behind a robot follows it when their headings differ by less than this [rad].
FOLLOW_ANGLE = np.pi / 4


def following(world: WorldState) -> np.ndarray:
    """Which targets of the check (n, 2 n + obstacles: the robots' courses, their braking, then
    the obstacles) each robot leaves out as its followers: the uncontrolled vehicles wholly
    behind it (centre more than half the two lengths behind its centre, along its heading)
    that drive its way (headings within ``FOLLOW_ANGLE``), in its lane or the next. As on a
    road, a follower keeps its distance: predicting it at constant velocity into a braking
    robot made the robot brake the harder, which is no answer to a car closing from behind.
    (Counting the cars close behind in the next lane, so that a robot lets them pass rather
    than cut in, made the robots brake for most of them, with more collisions on the highway:
    docs/coordination.md.)"""
    n, obstacles = len(world.robots), world.obstacles
    out = np.zeros((n, 2 * n + len(obstacles)), dtype=bool)
    if not obstacles:
        return out
    centres, heading = world.robot_centres(), world.states[:, 2]
    length = np.array([r.length for r in world.robots])
    for j, o in enumerate(obstacles):
        if o.kind not in VEHICLE_KINDS or not np.any(o.velocity):
            continue
        rel = o.centre[None, :] - centres
        behind = rel[:, 0] * np.cos(heading) + rel[:, 1] * np.sin(heading) < -0.5 * (length + o.length)
        same_way = np.abs(np.angle(np.exp(1j * (o.heading - heading)))) < FOLLOW_ANGLE
        out[:, 2 * n + j] = behind & same_way
    return out


class SafetyCheck:
    """The safety stop of one period of ``world``, for robots of ``fleet`` driven with the
    planner's ``config`` (period, pedestrian reach); robots brake turning towards ``headings``
    [rad]: (n,), one heading each, or (n, L), their paths' headings every ``spacing`` [m] from
    where they are (:func:`~aac_sumo.kernels.braking_courses`: a car brakes along its curved
    lane), from the steering ``previous_steer`` (n,) [rad] they applied the period before.
    With ``followers``, each robot leaves its uncontrolled followers out (:func:`following`);
    each always leaves out the walkers it stops before or passes (:meth:`walker_paths`).
    ``ignored`` (n, 2 n + obstacles) says which targets each leaves out. ``walker_speeds``
    (name -> slowest and fastest speed [m/s] of late, :class:`WalkerSpeeds`) bound the walkers'
    speeds in :meth:`walker_paths`; without, each walks at her speed now."""

    def __init__(self, world: WorldState, fleet: Fleet, config: MpcConfig, headings: np.ndarray, previous_steer: np.ndarray,
                 followers: bool = False, walker_speeds: dict[str, tuple[float, float]] | None = None, spacing: float = 1.0):
        self.world, self.fleet, self.config = world, fleet, config
        self.table = np.ascontiguousarray(np.asarray(headings, dtype=float).reshape(len(world.robots), -1))
        self.headings, self.spacing = self.table[:, 0], float(spacing)
        self.previous_steer = np.asarray(previous_steer, dtype=float)
        self.ignored = following(world) if followers else np.zeros((len(world.robots), 2 * len(world.robots) + len(world.obstacles)), dtype=bool)
        self.walkers = WalkerPaths(world, fleet, config, self.table, self.spacing, walker_speeds)
        index, _, enter, passing = self.walker_paths()
        self.ignored[:, 2 * len(world.robots) + index] |= np.isfinite(enter) | passing
        lines = np.flatnonzero([o.kind == "signal" for o in world.obstacles])  # another approach's stop line holds no one
        if lines.size:
            held = line_binds(np.array([world.obstacles[k].heading for k in lines])[None, :], world.states[:, 2:3])
            self.ignored[:, 2 * len(world.robots) + lines] |= ~held
        self._around: dict = {}
        self._steer = None

    def braking_steer(self, states: np.ndarray) -> np.ndarray:
        """Steering (n,) [rad] of every robot braking at its comfort deceleration from ``states``
        (n, 4), within its steering limits."""
        fleet, dt = self.fleet, self.config.dt
        target = np.array([heading_along(row, self.spacing, abs(v) * FALLBACK_TURN_TIME) for row, v in zip(self.table, states[:, 3])])
        wanted = heading_hold_steer(states, target, dt, fleet.wheelbase, fleet.steer_limits[:, 0], FALLBACK_TURN_TIME)
        accel = np.clip(-states[:, 3] / dt, -fleet.comfort, fleet.comfort)
        return fleet.limit_steer(wanted, states, accel, self.previous_steer, dt)

    def safe_inputs(self, check: np.ndarray, inputs: np.ndarray, margin: float) -> np.ndarray:
        """Every robot's inputs (n, 2) after the check of robots ``check``: one whose intended
        input fails :meth:`unsafe` gets the gentlest braking (coasting, then a third, two thirds
        and all of its strongest braking) that passes, else full braking, steering as braking
        robots do (compiled: :func:`~aac_sumo.kernels.gentlest_stops`); and one that must stop
        before a walker's path (:meth:`walker_stops`) brakes at least as hard as that needs."""
        world, fleet = self.world, self.fleet
        if self._steer is None:
            self._steer = self.braking_steer(world.states)
        check = np.asarray(check, dtype=np.int64)
        chosen, flagged = self._gentlest(check, np.asarray(inputs, dtype=float), -fleet.comfort, margin)
        if flagged.any():  # no comfortable choice: comfort braking now, an emergency after it, or one now
            urgent = check[flagged]
            chosen[urgent] = [[self.braking(i, fleet.comfort[i]), self._steer[i]] for i in urgent]
            chosen, still = self._gentlest(urgent, chosen, fleet.a_min, margin)
            for i in urgent[still]:
                chosen[i] = [self.braking(i, -fleet.a_min[i]), self._steer[i]]
        stops = self.walker_stops(check, inputs)
        for i in np.flatnonzero(np.isfinite(stops)):
            brake = self.braking(i, stops[i])
            if brake < chosen[i, 0]:
                chosen[i] = [brake, self._steer[i]]
        return chosen

    def walker_paths(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The walkers each robot stops before or passes: :meth:`WalkerPaths.walker_paths
        <aac_sumo.coordination.walker_paths.WalkerPaths.walker_paths>` of this period."""
        return self.walkers.walker_paths()

    def walker_stops(self, check: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """How hard each robot of ``check`` brakes now for a walker's path [m/s^2] (NaN: not):
        :meth:`WalkerPaths.walker_stops <aac_sumo.coordination.walker_paths.WalkerPaths.walker_stops>`."""
        return self.walkers.walker_stops(check, inputs)

    def braking(self, i: int, decel: float) -> float:
        """Robot ``i``'s acceleration [m/s^2] braking at ``decel`` towards standstill this period."""
        return float(self.world.robots[i].model.limits.braking_input(self.world.states[i, 3], self.config.dt, decel)[0])

    def _gentlest(self, check, inputs, a_brake, margin):
        """:func:`~aac_sumo.kernels.gentlest_stops` in the regime where every course and every
        braking at once brakes at ``a_brake`` (n,) [m/s^2]."""
        world, fleet = self.world, self.fleet
        steps, fixed, standing, growing = self.surroundings(a_brake)
        return gentlest_stops(check, inputs, self._steer, world.states, self.table, self.spacing, fleet.wheelbase, a_brake, fleet.a_max,
                              fleet.v_min, fleet.v_max, fleet.steer_limits, fleet.offset, fleet.length, fleet.width, self.config.dt,
                              FALLBACK_TURN_TIME, steps, fixed, standing, growing, margin, BRAKING_TIE, a_brake, self.ignored)

    def unsafe(self, check: np.ndarray, inputs: np.ndarray, margin: float) -> np.ndarray:
        """Which of robots ``check`` must brake instead of applying ``inputs`` (n, 2, every robot's
        input this period as far as known; zero where not), everyone braking comfortably."""
        steps, fixed, standing, growing = self.surroundings()
        rows = self.fleet.footprints(np.arange(len(self.world.robots)), self.stopping_course(inputs, steps, -self.fleet.comfort))  # (n, K+1, 5)
        return stop_flags(np.asarray(check, dtype=np.int64), rows, fixed, standing, growing, margin, BRAKING_TIE, self.ignored)

    def surroundings(self, a_brake: np.ndarray | None = None) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """What every check of this period in the regime of braking at ``a_brake`` (n,) [m/s^2]
        (default: each robot's comfort deceleration) compares against, computed once per regime:
        the number of stages, the footprints (n + obstacles, K+1, 5) of every robot braking at
        once at ``a_brake`` and of every obstacle moving at constant velocity (pedestrians
        grown), and which of the :meth:`unsafe` targets (2 n + obstacles: the robots on their
        courses, then these) are obstacles that stand still for sure, and which are walkers'
        growing regions."""
        a_brake = -self.fleet.comfort if a_brake is None else np.asarray(a_brake, dtype=float)
        key = a_brake.tobytes()
        if key not in self._around:
            world, cfg, fleet = self.world, self.config, self.fleet
            n = len(world.robots)
            steps = int(np.ceil(np.max(np.abs(world.states[:, 3]) / fleet.comfort) / cfg.dt)) + 2  # input acts at stage 2
            halt = fleet.footprints(np.arange(n), self.stopping_course(None, steps, a_brake))
            obs = np.array([o.footprint() for o in world.obstacles]).reshape(-1, 5)
            vel = np.array([o.velocity for o in world.obstacles]).reshape(-1, 2)
            moving = np.repeat(obs[:, None, :], steps + 1, axis=1)
            moving[:, :, :2] += np.arange(steps + 1)[None, :, None] * cfg.dt * vel[:, None, :]
            walkers = np.array([o.kind == "pedestrian" for o in world.obstacles], dtype=bool)
            walkers &= cfg.pedestrian_reach > 0.0 or cfg.pedestrian_margin > 0.0
            reach = np.array([o.step_out_speed(cfg.pedestrian_reach, cfg.walkway_time) for o in world.obstacles]).reshape(-1)
            growth = cfg.pedestrian_margin + reach[:, None] * cfg.dt * np.arange(steps + 1)  # (obstacles, steps+1)
            moving[walkers, :, 2:4] += 2.0 * growth[walkers, :, None]
            standing = (np.hypot(vel[:, 0], vel[:, 1]) == 0.0) & ~walkers
            none = np.zeros(2 * n, dtype=bool)
            self._around[key] = steps, np.concatenate([halt, moving]), np.r_[none, standing], np.r_[none, walkers]
        return self._around[key]

    def stopping_course(self, first: np.ndarray | None, steps: int, a_brake: np.ndarray) -> np.ndarray:
        """States (n, steps+1, 4) of every robot applying ``first`` (n, 2) once (None: braking at
        once), then braking to a stop at ``a_brake`` (n,) [m/s^2], steering towards its heading."""
        world, fleet = self.world, self.fleet
        use_first = first is not None
        first = np.asarray(first, dtype=float) if use_first else np.zeros((len(world.robots), 2))
        return braking_courses(world.states, first, use_first, self.previous_steer, self.table, self.spacing, fleet.wheelbase, a_brake,
                               fleet.a_max, fleet.v_min, fleet.v_max, fleet.steer_limits, self.config.dt, FALLBACK_TURN_TIME, steps)
