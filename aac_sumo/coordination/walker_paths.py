"""Walkers' paths for the safety stop (:class:`~aac_sumo.coordination.safety.SafetyCheck`): which
walking pedestrians each robot answers by stopping before her path, and which it passes
(:meth:`WalkerPaths.walker_paths`), how hard it brakes for that (:meth:`WalkerPaths.walker_stops`),
and the walkers' speeds of late (:class:`WalkerSpeeds`).

Frames: world coordinates [m]; a robot's course runs along the headings its braking course
turns to (its lane's), and each walker is seen with that course unbent onto the straight line
along the robot's heading (:meth:`WalkerPaths.unbent`).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from aac_sumo.coordination.anticipation import CLEAR_SPEED, across_extent
from aac_sumo.coordination.regions import Fleet
from aac_sumo.geometry import rect_corners
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.world import WorldState

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


def setting_off_time(distance, v, accel):
    """Time [s] to drive ``distance`` [m] from speed ``v`` [m/s], accelerating at ``accel``
    [m/s^2] up to ``SET_OFF_SPEED`` when slower, then at constant speed (arrays broadcast)."""
    top = np.maximum(v, SET_OFF_SPEED)
    ramp = (top * top - v * v) / (2.0 * accel)  # [m] until it reaches top speed
    on_ramp = (np.sqrt(v * v + 2.0 * accel * np.minimum(distance, ramp)) - v) / accel
    return on_ramp + np.maximum(distance - ramp, 0.0) / top


class WalkerPaths:
    """The walkers' paths of one period of ``world`` for robots of ``fleet`` driven with the
    planner's ``config`` (period, pedestrian margin and reach, walkway time); ``table`` (n, L)
    holds each robot's braking-course headings [rad] every ``spacing`` [m] from its rear axle on
    (one column: straight on along its heading now); ``walker_speeds`` (name -> slowest and
    fastest speed [m/s] of late, :class:`WalkerSpeeds`) bound the walkers' speeds; without, each
    walks at her speed now. Computed once per period, on first use."""

    def __init__(self, world: WorldState, fleet: Fleet, config: MpcConfig, table: np.ndarray, spacing: float,
                 walker_speeds: dict[str, tuple[float, float]] | None = None):
        self.world, self.fleet, self.config = world, fleet, config
        self.table, self.spacing = table, float(spacing)
        self.headings = table[:, 0]
        self.walker_speeds = walker_speeds or {}
        self._walkers = None

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
        is then left out of the safety check for that robot (:attr:`SafetyCheck.ignored <aac_sumo.coordination.safety.SafetyCheck.ignored>`): her growing region
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
