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

from collections import deque

import numpy as np

from aac_sumo.coordination.anticipation import CLEAR_SPEED, across_extent
from aac_sumo.coordination.regions import Fleet
from aac_sumo.dynamics import heading_hold_steer
from aac_sumo.geometry import rect_corners
from aac_sumo.kernels.safety import braking_courses, gentlest_stops, stop_flags
from aac_sumo.kernels.motion import heading_along
from aac_sumo.mpc.planner import FALLBACK_TURN_TIME
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.world import WorldState


#: Gap difference [m] below which a course counts as no closer than braking at once.
BRAKING_TIE = 1e-6
#: A vehicle behind a robot follows it when their headings differ by less than this [rad].
FOLLOW_ANGLE = np.pi / 4
#: Obstacle kinds that drive as vehicles on their own (SUMO's traffic, scripted agents).
VEHICLE_KINDS = ("scripted", "robot")
#: A walker slower than this [m/s] has no path to stop before (the check's growing region answers it).
WALKER_STILL = 0.1
#: How far [m] into a walker's strip a robot may be (the last braking step's overshoot) and still
#: be held at its edge rather than drive on into her path.
STRIP_OVERSHOOT = 0.05
#: How long [s] the check remembers a walker's speeds (:class:`WalkerSpeeds`).
WALKER_MEMORY = 1.0
#: A robot slower than SET_OFF_SPEED [m/s] that sets off to pass a walker's path is taken to
#: accelerate up to it at SET_OFF_SHARE of its strongest acceleration (the lane change's cars:
#: 1.5 m/s^2, the rate their references ramp at); a faster one keeps its speed.
SET_OFF_SHARE = 0.5
SET_OFF_SPEED = 5.0
#: Standstill gap [m] a robot that passes a walker's path keeps to what stands beyond it.
CLEAR_GAP = 1.0


class WalkerSpeeds:
    """Every walker's slowest and fastest speed [m/s] over the last ``WALKER_MEMORY`` seconds,
    by name. SUMO's walkers change their speed from step to step (1.0, 1.14, 1.0 m/s); the
    check takes the slowest for one walking away from a robot's path and the fastest for one
    walking towards it. A memory restarts when time goes backwards."""

    def __init__(self):
        self.seen: dict[str, deque] = {}

    def update(self, world: WorldState) -> dict[str, tuple[float, float]]:
        """Record ``world``'s walkers and return their speed bounds, by name."""
        out = {}
        for o in world.obstacles:
            if o.kind != "pedestrian":
                continue
            history = self.seen.setdefault(o.name, deque())
            if history and world.t < history[-1][0]:
                history.clear()
            history.append((world.t, float(np.hypot(*o.velocity))))
            while world.t - history[0][0] > WALKER_MEMORY + 1e-9:
                history.popleft()
            speeds = [v for _, v in history]
            out[o.name] = (min(speeds), max(speeds))
        return out


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


def setting_off_time(distance, v, accel):
    """Time [s] to drive ``distance`` [m] from speed ``v`` [m/s], accelerating at ``accel``
    [m/s^2] up to ``SET_OFF_SPEED`` when slower, then at constant speed (arrays broadcast)."""
    top = np.maximum(v, SET_OFF_SPEED)
    ramp = (top * top - v * v) / (2.0 * accel)  # [m] until it reaches top speed
    on_ramp = (np.sqrt(v * v + 2.0 * accel * np.minimum(distance, ramp)) - v) / accel
    return on_ramp + np.maximum(distance - ramp, 0.0) / top


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
        self.walker_speeds = walker_speeds or {}
        self.previous_steer = np.asarray(previous_steer, dtype=float)
        self.ignored = following(world) if followers else np.zeros((len(world.robots), 2 * len(world.robots) + len(world.obstacles)), dtype=bool)
        self._walkers = None
        index, _, enter, passing = self.walker_paths()
        self.ignored[:, 2 * len(world.robots) + index] |= np.isfinite(enter) | passing
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
        """Which walking pedestrians each robot answers by stopping before her path, and which it
        passes (computed once per period): the walkers' obstacle indices (m,), and per robot and
        walker (n, m) the deceleration [m/s^2] that stops it before her path, the distance [m] from
        its footprint to her path along its heading (inf where it does not answer her so), and
        whether it passes her.

        Her path is the strip she sweeps walking on at her velocity, as wide as her footprint
        turned any way (its diagonal: she sways as she walks) plus the planner's
        ``pedestrian_margin`` on each side, from where she is on: where the robot crosses it she
        must be able to be by then, walking on or coming back at her reach beyond her speed (not
        where she came from: a walker turning onto a footpath along the road). A robot, moving or
        standing, answers her so when her strip lies ahead of it along its heading, it cannot pass
        (driving on at its speed, or setting off towards ``SET_OFF_SPEED`` at ``SET_OFF_SHARE`` of
        its strongest acceleration, its rear leaves the strip no sooner than she could come
        within the margin of its path at the faster of her speed towards it and
        ``pedestrian_reach``; a walker who walks away from its band beyond the margin is not taken
        to turn back; or what stands or drives ahead of it leaves it no room to leave the strip,
        :meth:`room_ahead`), and
        it can still stop before the strip within its strongest braking, ``v^2 / (2 (D - v dt / 2
        - a dt^2 / 8))`` (the model's Euler steps, ``a`` its strongest braking) with ``D`` that
        distance, or within ``STRIP_OVERSHOOT`` of it (then braking at its strongest; standing
        there, it stays). Such a walker
        is then left out of the check above for that robot (:attr:`ignored`): her growing region
        would make it brake as if it could stop nowhere. A robot that does not stop so passes her
        when it leaves her strip before she could come within the margin of its path walking on
        at her speed (too late to stop before her path, or able to pass even if she started
        towards it at her reach): she is left out too (braking, it would stop in her way). A
        robot goes along the heading its braking course turns to (its lane's: a car in a lane
        change towards the footpath is not heading for a walker on it). Her speed is bounded by
        ``walker_speeds``: the slowest of late where she walks away from the robot's band (she
        comes back the sooner), the fastest where she walks towards it."""
        if self._walkers is not None:
            return self._walkers
        world, fleet, cfg = self.world, self.fleet, self.config
        index = np.array([j for j, o in enumerate(world.obstacles) if o.kind == "pedestrian" and np.hypot(*o.velocity) > WALKER_STILL],
                         dtype=np.int64)
        n = len(world.robots)
        need, enter = np.zeros((n, index.size)), np.full((n, index.size), np.inf)
        passing = np.zeros((n, index.size), dtype=bool)
        moving = np.flatnonzero(world.on_road & (world.states[:, 3] >= 0.0))  # standing ones too: they must not start into her path
        self._walkers = index, need, enter, passing
        if index.size == 0 or moving.size == 0:
            return self._walkers
        dt, margin, reach = cfg.dt, cfg.pedestrian_margin, cfg.pedestrian_reach
        rows = world.robot_footprints()[moving]
        corners = rect_corners(rows)  # (r, 4, 2)
        v, a_go = world.states[moving, 3], fleet.a_max[moving, None]
        ahead = np.column_stack([np.cos(self.headings[moving]), np.sin(self.headings[moving])])  # (r, 2): where its braking course goes
        left = np.column_stack([-ahead[:, 1], ahead[:, 0]])
        walkers = [world.obstacles[j] for j in index]
        size = np.array([[o.length, o.width, o.heading] for o in walkers])
        # each walker as robot r sees her (r, m): in the frame where its path runs straight on along its heading
        centre, velocity, turned = self.unbent(moving, np.array([o.centre for o in walkers]), np.array([o.velocity for o in walkers]))
        course = np.arctan2(velocity[..., 1], velocity[..., 0])
        path = np.stack([np.cos(course), np.sin(course)], axis=-1)  # (r, m, 2)
        across_path = np.stack([-path[..., 1], path[..., 0]], axis=-1)
        half = 0.5 * np.hypot(size[:, 0], size[:, 1]) + margin  # (m,) half the strip's width: her footprint turned any way
        # the strip along the robot's heading: how far until its footprint enters it, and has left it
        side = np.einsum("rkj,rmj->rmk", corners, across_path) - (centre * across_path).sum(axis=2)[:, :, None]  # (r, m, 4)
        rate = np.einsum("rj,rmj->rm", ahead, across_path)  # (r, m): change of those offsets per metre ahead
        lo, hi = side.min(axis=2), side.max(axis=2)
        per_metre = np.maximum(np.abs(rate), 1e-9)
        into = np.where(rate < 0.0, lo - half, -half - hi) / per_metre
        out_of = np.where(rate < 0.0, hi + half, half - lo) / per_metre
        through = (np.abs(rate) > 1e-9) & (out_of > 0.0)  # it has not passed the strip yet
        # when its rear leaves her strip driving on [s]: at its speed, and at least at the speed one period of its strongest
        # acceleration gives (a standing robot may set off only when it can pass so; setting off with a shorter estimate, a
        # car that then stopped again for a queue stood in her path)
        leave = np.where(through, setting_off_time(np.maximum(out_of, 0.0), v[:, None], SET_OFF_SHARE * a_go), 0.0)
        leave = np.where(out_of + CLEAR_GAP <= self.room_ahead(moving)[:, None], leave, np.inf)
        # her way to the band the robot sweeps: how far across it, how fast towards it
        offset = np.einsum("rmj,rj->rm", centre - rows[:, None, :2], left)
        speed_w = np.hypot(*np.array([o.velocity for o in walkers]).T)  # (m,): the unbending only turns them
        bounds = np.array([self.walker_speeds.get(o.name, (w, w)) for o, w in zip(walkers, speed_w)]).reshape(-1, 2)
        slowest, fastest = np.minimum(bounds[:, 0], speed_w), np.maximum(bounds[:, 1], speed_w)
        towards = -np.sign(offset) * np.einsum("rj,rmj->rm", left, velocity)  # at her speed now, scaled to her fastest or slowest of late
        towards = towards * np.where(towards > 0.0, (fastest / speed_w)[None, :], (slowest / speed_w)[None, :])
        gap = np.abs(offset) - across_extent(size[None, :, 0], size[None, :, 1], size[None, :, 2] + turned - rows[:, 4:5]) - 0.5 * rows[:, 3:4]
        step_out = np.array([o.step_out_speed(reach, cfg.walkway_time) for o in walkers])  # (m,): her own reach (walkway_time)
        # she may come at her reach at any moment, or at her own speed where she walks towards the band faster; a walker
        # who walks away from it is not taken to turn back (she has crossed it, or never will)
        closing = np.where(towards < -WALKER_STILL, towards, np.maximum(towards, step_out[None, :]))
        reaches = np.where(gap <= margin, 0.0, np.where(closing > 0.0, (gap - margin) / np.maximum(closing, 1e-9), np.inf))
        # her path ahead of her only: where the robot crosses her strip she could be by then (walking on, or coming back
        # at her reach beyond her speed), not where she came from (a walker turning onto a footpath along the road)
        along_path = np.einsum("rj,rmj->rm", ahead, path)  # (r, m)
        behind = np.einsum("rkj,rmj->rmk", corners, path).max(axis=2) - (centre * path).sum(axis=2) + np.maximum(
            into * along_path, out_of * along_path)
        turn_back = np.maximum(step_out - slowest, 0.0)[None, :]
        ahead_of_her = behind >= -half[None, :] - turn_back * np.where(turn_back > 0.0, leave, 0.0)
        blocked = through & ahead_of_her & (leave >= reaches) & np.isfinite(reaches)  # one who walks away never comes back
        strongest = -fleet.a_min[moving, None]
        room = into - 0.5 * v[:, None] * dt - 0.125 * strongest * dt * dt  # Euler steps overshoot up to a dt^2 / 8
        # it answers her while braking at its strongest still stops it short of her strip, or within STRIP_OVERSHOOT of its
        # edge (where the last braking step left it, or where it stands): it stays there rather than creep into her path
        answered = blocked & (room > -STRIP_OVERSHOOT) & (v[:, None] ** 2 <= 2.0 * strongest * np.maximum(room + STRIP_OVERSHOOT, 0.0))
        decel = np.minimum(v[:, None] ** 2 / (2.0 * np.maximum(room, 1e-9)), strongest)
        # else it passes when it leaves her strip before she comes within the margin of its path walking on at her speed
        # (too late to stop before her path, rather than stop in her way)
        arrives = np.where(towards > 0.0, np.maximum(gap - margin, 0.0) / np.maximum(towards, 1e-9), np.inf)
        need[moving] = np.where(answered, decel, 0.0)
        enter[moving] = np.where(answered, into, np.inf)
        passing[moving] = through & ahead_of_her & ~answered & (v[:, None] > 0.0) & (out_of / np.maximum(v, 1e-12)[:, None] < arrives)
        return self._walkers

    def room_ahead(self, robots: np.ndarray) -> np.ndarray:
        """How far [m] each of ``robots`` (r,) can surely drive on along its braking course's
        heading: to the nearest footprint ahead of it in its way (another robot slower than
        ``CLEAR_SPEED``, or a vehicle, beside it by less than their half widths), plus where that
        one stops braking at its strongest from its speed now (robots) or at once (vehicles); inf
        with none. A robot passes a walker's path only when its rear can leave her strip with this
        much room (a car that set off behind a queue would stop in her path). A robot ahead that
        drives on at ``CLEAR_SPEED`` or faster does not hold it, as in the anticipation
        (:func:`~aac_sumo.coordination.anticipation.crossing_rows`): one that must stop for her
        stops before her path, and the robot behind it too."""
        world, fleet = self.world, self.fleet
        vehicles = [o for o in world.obstacles if o.kind in VEHICLE_KINDS]
        centres = np.vstack([world.robot_centres()] + [o.centre[None, :] for o in vehicles]).reshape(-1, 2)
        length = np.r_[fleet.length, [o.length for o in vehicles]]
        width = np.r_[fleet.width, [o.width for o in vehicles]]
        runout = np.r_[np.maximum(world.states[:, 3], 0.0) ** 2 / (-2.0 * np.minimum(fleet.a_min, -1e-9)), np.zeros(len(vehicles))]
        present = np.r_[world.on_road & (world.states[:, 3] < CLEAR_SPEED), np.ones(len(vehicles), dtype=bool)]  # robots that drive on pass
        ahead = np.column_stack([np.cos(self.headings[robots]), np.sin(self.headings[robots])])  # (r, 2)
        rel = centres[None, :, :] - centres[robots][:, None, :]  # (r, K, 2)
        along = np.einsum("rkj,rj->rk", rel, ahead)
        across = np.abs(rel[..., 1] * ahead[:, None, 0] - rel[..., 0] * ahead[:, None, 1])
        mine = present[None, :] & (along > 0.0) & (across < 0.5 * (width[None, :] + width[robots][:, None]))
        mine[np.arange(len(robots)), robots] = False
        room = along - 0.5 * (length[None, :] + length[robots][:, None]) + runout[None, :]
        return np.where(mine, room, np.inf).min(axis=1)

    def unbent(self, robots: np.ndarray, centre: np.ndarray, velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Walkers' centres (m, 2) [m] and velocities (m, 2) [m/s] as each of ``robots`` (r,)
        sees them with its path unbent onto the straight line along its heading now: each walker
        is placed beside that line as she is beside the path at the nearest of its points every
        ``spacing`` [m] (its headings, :attr:`table`, from the robot's rear axle on; straight on
        beyond them), turned by the path's turn up to there. Returns centres and velocities (r,
        m, 2) and the turns (r, m) [rad]. On a curved road a walker on the sidewalk then walks
        beside the robot's course, as she does beside its lane, instead of across the tangent
        it would brake along (cars braked for walkers walking along a curved sidewalk)."""
        r, m = len(robots), len(centre)
        table, ds = self.table[robots], self.spacing
        if table.shape[1] == 1:
            return (np.broadcast_to(centre, (r, m, 2)).copy(), np.broadcast_to(velocity, (r, m, 2)).copy(), np.zeros((r, m)))
        mid = 0.5 * (table[:, 1:] + table[:, :-1])
        steps = ds * np.stack([np.cos(mid), np.sin(mid)], axis=-1)  # (r, L-1, 2)
        start = self.world.states[robots, :2]
        points = start[:, None, :] + np.concatenate([np.zeros((r, 1, 2)), np.cumsum(steps, axis=1)], axis=1)  # (r, L, 2)
        nearest = np.hypot(*np.moveaxis(centre[None, :, None, :] - points[:, None, :, :], -1, 0)).argmin(axis=2)  # (r, m)
        rows = np.arange(r)[:, None]
        turn = table[:, :1] - table[rows, nearest]  # (r, m)
        cos, sin = np.cos(turn)[..., None], np.sin(turn)[..., None]

        def rotate(vec):
            return np.concatenate([cos * vec[..., :1] - sin * vec[..., 1:], sin * vec[..., :1] + cos * vec[..., 1:]], axis=-1)

        heading = np.column_stack([np.cos(table[:, 0]), np.sin(table[:, 0])])
        base = start[:, None, :] + (nearest * ds)[..., None] * heading[:, None, :]
        return base + rotate(centre[None] - points[rows, nearest]), rotate(np.broadcast_to(velocity, (r, m, 2))), turn

    def walker_stops(self, check: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """The deceleration [m/s^2] (n,; NaN: none) with which each robot of ``check`` brakes now
        to stop before a walker's path (:meth:`walker_paths`): just as hard as that needs, and
        only once one more period of its input ``inputs`` (n, 2) and braking at its comfort
        deceleration (at most the planner's ``comfort_accel`` when set: a calm driver's braking)
        would no longer stop it there (comfort first; waiting for the full comfort deceleration, a
        car that had set off near the zebra then braked at 2.2-3 m/s^2 for a walker, where
        starting one period or two earlier stops it calmly), with the room that
        :meth:`walker_paths` leaves for the last braking step's overshoot (without it, a car at
        1 m/s a quarter metre from her strip was let on and then needed 2.05 m/s^2). A standing
        robot gets 0: it stays where it is."""
        out = np.full(len(self.world.robots), np.nan)
        _, need, enter, _ = self.walker_paths()
        check = np.asarray(check, dtype=np.int64)
        if need.size == 0 or check.size == 0:
            return out
        dt, v = self.config.dt, self.world.states[check, 3:4]
        v1 = np.maximum(v + np.asarray(inputs, dtype=float)[check, 0:1] * dt, 0.0)
        calm = self.fleet.comfort[check, None]
        if self.config.comfort_accel > 0.0:
            calm = np.minimum(calm, self.config.comfort_accel)
        overshoot = 0.125 * -self.fleet.a_min[check, None] * dt * dt  # as walker_paths allows for the Euler steps
        late = np.isfinite(enter[check]) & (v1**2 / (2.0 * calm) + 0.5 * v1 * dt + overshoot > enter[check] - v * dt)
        out[check] = np.where(late.any(axis=1), np.where(late, need[check], -np.inf).max(axis=1), np.nan)
        return out

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
