"""Alternative Authority Control (paper Algorithm 1, as DESIGN.md interprets it).

Two ways of running it:

* **Committed plans** (``commit = true``, the default; beyond the paper): every robot drives
  its commitment, the last plan it made and a stopping tail, and a commitment changes only
  after the exact check of :mod:`~aac_sumo.coordination.commitments` (collision-free by
  construction). One authority per period among all robots (``authorities = 1``), or per
  cluster of robots that can meet within the horizon (``"clusters"``); close pairs, the
  proximity decision and round robin pick it within its group, with the conflict-resolution
  rules of :meth:`AacCoordinator.choose_in_group` and :mod:`~aac_sumo.coordination.make_room`.
* **The paper's stored plans** (``commit = false``), described below.

With ``commit = false``, each control period exactly one active robot holds authority and
solves MPC-(F)CBF (the paper); with ``authorities`` k or ``"clusters"`` (beyond the paper),
one in each of up to k groups of :meth:`AacCoordinator.groups`, or in every cluster of robots
that can meet within the horizon, each planning around its own group only (robots of two
clusters cannot come within reach of each other in N periods, whatever either does, so each
authority gets the inputs it would get alone):

1. **Close pairs** of active robots (centre distance below ``close_distance``, KD-tree). Active
   are the unfinished robots and those whose task goes on after finishing (a car that has
   passed the cones still drives among the others); robots parked at their goal are not.
2. With close pairs, the **proximity decision** picks the authority among the robots in them;
   without, **round robin** gives it to the next active robot after the last holder.
3. Every other robot applies the next input of its stored plan, or the tracking law when its
   plan is used up (robots parked at their goal brake to a stop).
4. Optional **safety stop** (beyond the paper, ``safety_stop``; see
   :mod:`~aac_sumo.coordination.safety`): a non-authority robot whose stored input, followed
   by braking to a stop, would bring its footprint within ``safety_margin`` of another robot's
   or a moving obstacle's footprint (a standing one: into contact), closer than it is now and
   than braking at once, brakes instead (as gently as passes the same check, turning towards
   its reference's heading) and drops its plan.
   The authority robot's first planned input gets the same check after its solve, but against
   actual contact only (its MPC keeps its own margins, and looks only N periods ahead).
   When its solve fails it brakes along its lane (the planner's fallback plan, as the paper's
   robots do), or, with ``fallback = "tracking"`` (beyond the paper; needs the safety stop), it
   applies the tracking law through the full safety check, as a robot without a plan does: a
   car hemmed in by conservative regions may then still creep on where its footprint is safe.
   With ``ignore_followers`` (beyond the paper; needs the safety stop) the authority does not
   avoid the robots straight behind it: they keep their distance through the safety stop, as
   a following car does on a road, and a car slowing for the traffic ahead no longer has to
   outrun the one behind it.
5. The authority robot plans around the obstacles and the swept **convex-hull regions** of the
   others: at stage k, an ellipse containing the hull of a robot's footprints at k and k+1 along
   its known motion (stored plan, else constant velocity; the authority's own current motion
   is what the others assume).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from aac_sumo.coordination.base import Coordinator, Decision, Finished, RobotDecision, check_safety_options, straight_behind
from aac_sumo.coordination.commitments import CommitmentBook, clusters, reach_radii, stopping_commitment
from aac_sumo.coordination.detour import Detours
from aac_sumo.coordination.make_room import STILL_SPEED, MakeRoom
from aac_sumo.coordination.proximity import ProximityParams, close_pairs, proximity_decision
from aac_sumo.coordination.tracking import track, track_course
from aac_sumo.kernels import limited_steer
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import PathReference
from aac_sumo.world import WorldState


#: Periods a robot whose tracking extension failed the check waits before it tries again.
EXTENSION_RETRY = 3
#: A candidate that has not held authority for this many horizons gets it (round robin) before
#: any proximity decision: with committed plans, a robot without turns stands still.
STARVING = 2
#: A robot slower than this share of its cruise speed is held up: its keep-right shift grows at
#: SHIFT_GROWTH [m/s] up to keep_right_max, and shrinks at SHIFT_DECAY [m/s] otherwise.
SLOW_SHARE = 0.3
SHIFT_GROWTH = 0.5
SHIFT_DECAY = 0.1
#: Grid cell [m] of the detour planner, and how often [s] a robot checks its reference for standing footprints.
DETOUR_CELL = 0.1
DETOUR_CHECK = 1.0
#: Creeping (:meth:`AacCoordinator.creep`): a standing authority whose plan leaves it standing
#: tries courses at CREEP_SPEED [m/s] (forwards; backwards while it backs off), steering to each
#: of CREEP_STEER (shares of its steering limit), under the exact check, and takes the one that
#: ends closest to where its reference ends, when that is at least CREEP_GAIN [m] closer.
CREEP_SPEED = 0.3
CREEP_STEER = (-1.0, 0.0, 1.0)
CREEP_GAIN = 0.05


@dataclass(frozen=True)
class AacParams:
    """AAC settings: close-pair distance [m], proximity decision, safety stop (on/off, margin
    [m]), tracking law (lookahead [m], speed gain [1/s]), what an authority whose solve fails
    applies (``brake``: the planner's fallback; ``tracking``: the tracking law through the
    safety stop), whether the authority ignores the robots straight behind it
    (:func:`~aac_sumo.coordination.base.straight_behind`; needs the safety stop), the seed
    of the sampling trees; committed plans (``commit``), their stopping tails' share of the
    strongest braking (``tail_brake``) and the gap every two commitments keep
    (``commit_margin`` [m]); authorities per period (1, k, or ``"clusters"``); the keep-right
    rule (shift, trigger range and growth limit [m]); the make-room lead (on/off, standing
    time that makes a leader, longest lead [s]); and detours (on/off, the clearance [m] they
    keep from standing footprints where there is room; :mod:`~aac_sumo.coordination.detour`)."""

    close_distance: float = 2.0
    proximity: ProximityParams = ProximityParams()
    safety_stop: bool = True
    safety_margin: float = 0.1
    lookahead: float = 1.0
    speed_gain: float = 1.0
    fallback: str = "brake"
    ignore_followers: bool = False
    seed: int = 0
    commit: bool = True
    authorities: int | str = 1
    tail_brake: float = 0.5
    commit_margin: float = 0.05
    keep_right: float = 0.0
    keep_right_range: float = 4.0
    keep_right_max: float = 4.0
    make_room: bool = True
    stall_time: float = 1.0
    lead_time: float = 8.0
    detour: bool = False
    detour_clearance: float = 0.5

    def __post_init__(self):
        check_safety_options(self.safety_stop, self.fallback, self.ignore_followers)
        if self.authorities != "clusters" and not (isinstance(self.authorities, int) and self.authorities >= 1):
            raise ValueError("authorities must be a positive integer or 'clusters'")
        if self.detour and not self.commit:
            raise ValueError("detours need committed plans (commit = true)")


class AacCoordinator(Coordinator):
    name = "aac"

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                 params: AacParams = AacParams()):
        super().__init__(planner, tasks, corridors, finished)
        self.params = params
        self.leaves_followers = params.ignore_followers
        self.rng = np.random.default_rng(params.seed)
        self.cursor = -1
        self.used = np.zeros(len(tasks), dtype=int)  # inputs already applied from each stored plan
        self.period = 0
        self.book: CommitmentBook | None = None
        self.last_turn = np.full(len(tasks), -1)  # period of each robot's last authority
        self.next_extension = np.zeros(len(tasks), dtype=int)  # first period a robot may try a tracking extension again
        self.room: MakeRoom | None = None
        self.extra_shift = np.zeros(len(tasks))  # keep-right growth of robots held up in a crowd [m]
        self._crowded: tuple[float | None, np.ndarray] = (None, np.zeros(len(tasks), dtype=bool))  # (t, crowded_ahead)
        self.last_reason: dict[int, str] = {}  # per group (its first member), why its last authority held it
        self.detours: Detours | None = None

    def admit(self, world: WorldState, i: int) -> None:
        """Robot ``i`` has just come onto the road: it has waited longest for a turn, and its
        commitment becomes its stopping tail from where it is (the one safe course known)."""
        super().admit(world, i)
        self.used[i], self.last_turn[i], self.next_extension[i], self.extra_shift[i] = 0, -1, 0, 0.0
        if self.book is not None:
            self.book.replace(i, self.commitment(world, i, self.period, np.zeros((0, 2))), self.period)

    def _decide(self, world: WorldState) -> Decision:
        if self.params.commit:
            return self._decide_committed(world)
        n, cfg = len(world.robots), self.planner.config
        done = self.finished(world)
        parked = self.parked(world, done)
        active = np.flatnonzero(~parked)  # finished robots that drive on (cars past the cones) still take turns
        records = [RobotDecision(False) for _ in range(n)]
        inputs = np.zeros((n, 2))
        notes: dict = {}
        if active.size == 0:
            for i in range(n):
                inputs[i], records[i].mode = self.hold_inputs(world, i, 1)[0], "hold"
            return Decision(inputs, records, notes=dict(authority="", reason="all finished"))

        start = time.perf_counter()
        turns = self.stored_turns(world, parked, active, records)
        proximity_ms = (time.perf_counter() - start) * 1e3 if any(reason == "proximity" for _, reason, _ in turns) else 0.0
        holding = np.zeros(n, dtype=bool)
        holding[[i for i, _, _ in turns]] = True
        others = np.flatnonzero(world.on_road & ~holding)  # robots off the road stand still, far away
        safety = self.safety_check(world) if self.params.safety_stop else None
        if safety is not None and self.anticipation is not None:
            self.hold_before_strips(safety)
        horizon_inputs = np.zeros((len(others), cfg.horizon + 2, 2))
        for row, j in enumerate(others):
            horizon_inputs[row], records[j].mode = self.intended_inputs(world, j, parked[j], cfg.horizon + 2)

        inputs[others] = horizon_inputs[:, 0]
        if safety is not None:
            inputs = safety.safe_inputs(others, inputs, self.params.safety_margin)
        first = inputs[others]
        stops = np.any(first != horizon_inputs[:, 0], axis=1)
        for row in np.flatnonzero(stops):
            j = others[row]
            after = world.robots[j].model.stopping_inputs(world.states[j, 3] + first[row, 0] * cfg.dt, first[row, 1], cfg.dt, cfg.horizon + 1)
            horizon_inputs[row] = np.vstack([first[row], after])
            records[j].mode = "safety_stop"
            if self.plans[j] is not None:
                self.used[j] = len(self.plans[j].inputs)
        traj = self.fleet.rollout(others, world.states[others], horizon_inputs, cfg.dt)
        self.used[others] += 1
        stopped = int(stops.sum())
        for authority, reason, members in turns:
            mine = np.isin(others, members)
            self.stored_turn(world, authority, reason, others[mine], traj[mine], records, inputs)
        if safety is not None:
            stopped += self.check_authorities(world, [i for i, _, _ in turns], records, inputs, safety)
        notes.update(authority=" ".join(world.robots[i].name for i, _, _ in turns), reason=" ".join(sorted({r for _, r, _ in turns})),
                     safety_stops=stopped, proximity_ms=proximity_ms, authorities=len(turns))
        return Decision(inputs, records, notes=notes)

    def stored_turns(self, world: WorldState, parked: np.ndarray, active: np.ndarray,
                     records: list[RobotDecision]) -> list[tuple[int, str, np.ndarray]]:
        """This period's authorities with stored plans: ``(robot, why, its group's members)``.
        One authority (the paper): :meth:`choose_authority` among all active robots. Several
        (``authorities`` k or ``"clusters"``): one per group of :meth:`groups`, chosen within it
        by :meth:`choose_in_group`."""
        if self.params.authorities == 1:
            authority, reason = self.choose_authority(world, active, records)
            return [(authority, reason, np.arange(len(world.robots)))]
        out = []
        for members, candidates in self.groups(world, parked):
            i, reason = self.choose_in_group(world, members, candidates, records, self.period)
            out.append((i, reason, members))
        self.period += 1
        return out

    def stored_turn(self, world: WorldState, authority: int, reason: str, others: np.ndarray, traj: np.ndarray,
                    records: list[RobotDecision], inputs: np.ndarray) -> None:
        """The ``authority`` plans around the obstacles and the swept regions of ``others`` along
        their known courses ``traj`` (m, N+3, 4), and takes its plan's first input (``inputs``
        and ``records`` changed in place)."""
        cfg = self.planner.config
        avoid = ~straight_behind(world, self.fleet, authority, others) if self.params.ignore_followers else np.ones(len(others), dtype=bool)
        regions = self.fleet.swept_regions(others[avoid], traj[avoid], cfg.horizon, cfg.barrier, cfg.fcbf)
        decided = self.solve(world, authority, world.obstacles + regions, reason)
        decided.score, decided.progress = records[authority].score, records[authority].progress
        records[authority] = decided
        inputs[authority] = self.plans[authority].inputs[0]
        self.used[authority] = 1

    def check_authorities(self, world: WorldState, holders: list[int], records: list[RobotDecision], inputs: np.ndarray,
                          safety) -> int:
        """The safety stop on the first inputs of the authorities ``holders`` (``inputs`` and
        ``records`` changed in place): against contact only, since each plan keeps its own margins
        over its N periods; an authority whose solve failed applies, with ``fallback =
        "tracking"``, the tracking law instead, checked with ``safety_margin`` as a robot without
        a plan is. Returns how many inputs the stop changed."""
        cfg = self.planner.config
        margins = np.zeros(len(holders))
        for row, i in enumerate(holders):
            if records[i].status != "solved" and self.params.fallback == "tracking":
                inputs[i] = track(world.robots[i], world.states[i], self.tasks[i], self.params.lookahead, self.params.speed_gain,
                                  self.last_inputs[i, 1], cfg.dt, target_speed=self.tracking_speed(world, i, self.params.speed_gain),
                                  a_lat=self.tracking_lat())
                self.used[i] = len(self.plans[i].inputs)  # no plan to follow: tracking until its next turn
                records[i].mode, margins[row] = "tracking", self.params.safety_margin
        stopped = 0
        holders = np.asarray(holders, dtype=np.int64)
        for margin in np.unique(margins):
            group = holders[margins == margin]
            checked = safety.safe_inputs(group, inputs, float(margin))
            for i in group[np.any(checked[group] != inputs[group], axis=1)]:
                inputs[i], records[i].mode = checked[i], "safety_stop"
                self.used[i] = len(self.plans[i].inputs)
                stopped += 1
        return stopped

    def choose_authority(self, world: WorldState, active: np.ndarray, records: list[RobotDecision]) -> tuple[int, str]:
        """The authority robot and why; candidates of a proximity decision get their scores recorded."""
        centres = world.robot_centres()
        pairs = close_pairs(centres[active], self.params.close_distance)
        if len(pairs) == 0:
            later = active[active > self.cursor]
            self.cursor = int(later[0] if later.size else active[0])
            return self.cursor, "round_robin"
        candidates = active[np.unique(pairs)]
        n = len(world.robots)
        blockers = np.vstack([centres] + [o.centre[None, :] for o in world.obstacles])
        radius = np.r_[np.full(n, self.params.proximity.collision_radius),
                       [self.params.proximity.collision_radius + 0.5 * np.hypot(o.length, o.width) for o in world.obstacles]]
        owner = np.full(len(blockers), -1)
        owner[candidates] = np.arange(len(candidates))
        goals = np.array([self.tasks[i].points[-1] for i in candidates])
        result = proximity_decision(world.states[candidates, :2], goals, blockers, radius, owner, self.params.proximity, self.rng)
        for row, i in enumerate(candidates):
            records[i].score, records[i].progress = float(result.scores[row]), float(result.progress[row])
        return int(candidates[result.winner]), "proximity"

    def intended_inputs(self, world: WorldState, j: int, parked: bool, steps: int) -> tuple[np.ndarray, str]:
        """Robot ``j``'s inputs (steps, 2) as far as they are known: the rest of its stored
        plan, then zero (constant velocity); the tracking law now when the plan is used up;
        braking when it is ``parked`` (:meth:`~aac_sumo.coordination.base.Coordinator.parked`).
        With ``anticipation``, a stored plan's next acceleration is at most the tracking law's
        (:meth:`~aac_sumo.coordination.base.Coordinator.tracking_speed`, braking at most at the
        comfort deceleration): the plan was made up to a horizon ago, and a car driving it closed
        up on a car that had stopped since (seed 0, N = 5: 2.4 m behind a standing car at 1.7
        m/s, braking at 1 m/s^2), and its next solve braked at 2.8 m/s^2."""
        out = np.zeros((steps, 2))
        task = self.tasks[j]
        if parked:
            return self.hold_inputs(world, j, steps), "hold"
        plan = self.plans[j]
        if plan is not None and self.used[j] < len(plan.inputs):
            rest = plan.inputs[self.used[j]:][:steps]
            out[: len(rest)] = rest
            speed = self.tracking_speed(world, j, self.params.speed_gain)
            if speed is not None:
                lawful = self.params.speed_gain * (speed - world.states[j, 3])
                out[0, 0] = min(out[0, 0], max(lawful, -world.robots[j].model.limits.comfort_decel))
            return out, "plan"
        out[0] = track(world.robots[j], world.states[j], task, self.params.lookahead, self.params.speed_gain, self.last_inputs[j, 1],
                       self.planner.config.dt, target_speed=self.tracking_speed(world, j, self.params.speed_gain), a_lat=self.tracking_lat())
        return out, "tracking"

    def reference(self, world: WorldState, i: int) -> np.ndarray:
        """Robot ``i``'s reference (N+1, 4): a make-room target's or, for a robot that can reverse
        and has stood long (:meth:`~aac_sumo.coordination.make_room.MakeRoom.backing_off`),
        straight back at half its cruise speed (a short horizon finds no way round an obstacle
        it faces at close range); else its task's, shifted ``keep_right`` [m] to the right of its
        direction while another robot's footprint centre lies ahead of it (in the half-plane in
        front, along the reference's heading) within ``keep_right_range`` [m]: a right-hand rule
        that turns head-on meetings and crowded crossings into passing on the right, a
        roundabout in effect. The shift fades out between 4 and 2.5 times ``keep_right`` from
        the goal, so that the robot arrives on its path."""
        if self.room is not None and i in self.room.targets:
            return self.room_reference(world, i)
        if self.room is not None and self.room.backing_off(i) and world.robots[i].model.limits.v_min < 0.0:
            cfg, task = self.planner.config, self.tasks[i]
            x = world.states[i]
            back = -np.arange(cfg.horizon + 1) * cfg.dt * 0.5 * task.speed
            xy = x[:2] + back[:, None] * np.array([np.cos(x[2]), np.sin(x[2])])
            return np.column_stack([xy, np.full(cfg.horizon + 1, x[2]), np.full(cfg.horizon + 1, -0.5 * task.speed)])
        if self.detours is not None and self.detours.routes[i] is not None:
            cfg = self.planner.config
            ref = self.detours.routes[i].horizon(world.states[i], cfg.horizon, cfg.dt)
        else:
            ref = super().reference(world, i)
        shift = self.keep_right_shift(world, i)
        if shift == 0.0 or np.isnan(ref[:, 2]).any():  # no shift on a free heading (the goal approach)
            return ref
        out = ref.copy()
        out[:, :2] += shift * np.column_stack([np.sin(ref[:, 2]), -np.cos(ref[:, 2])])
        return out

    def crowded_ahead(self, world: WorldState) -> np.ndarray:
        """Which robots (n,) have another robot's footprint centre ahead of them (the half-plane
        in front, along their path's heading where they are) within ``keep_right_range``;
        computed once per period (``world.t``)."""
        if self._crowded[0] == world.t:
            return self._crowded[1]
        centres = world.robot_centres()
        heading = np.array([task.heading_at(state[:2]) for task, state in zip(self.tasks, world.states)])
        rel = centres[None, :, :] - centres[:, None, :]  # (i, j, 2)
        along = rel[..., 0] * np.cos(heading)[:, None] + rel[..., 1] * np.sin(heading)[:, None]
        near = (along > 0.0) & (np.hypot(rel[..., 0], rel[..., 1]) < self.params.keep_right_range)
        np.fill_diagonal(near, False)
        self._crowded = (world.t, near.any(axis=1))
        return self._crowded[1]

    def keep_right_shift(self, world: WorldState, i: int) -> float:
        """How far [m] robot ``i``'s reference moves to the right now (see :meth:`reference`)."""
        shift = self.params.keep_right
        if shift <= 0.0:
            return 0.0
        if not self.crowded_ahead(world)[i]:
            return 0.0
        shift += self.extra_shift[i]
        to_goal = float(np.hypot(*(world.states[i, :2] - self.tasks[i].points[-1])))
        return shift * (float(np.clip((to_goal - 1.5 * shift) / (1.5 * shift), 0.0, 1.0)) if self.tasks[i].stop_at_end else 1.0)

    # ----- committed plans (aac.commit = true) -----

    def _decide_committed(self, world: WorldState) -> Decision:
        """Every robot drives its commitment; each group (all active robots, or each cluster)
        gives one robot authority, which plans around the others' commitments and commits to its
        plan only when the plan with its stopping tail passes the exact check."""
        n, cfg, fleet = len(world.robots), self.planner.config, self.fleet
        period = self.period
        self.period += 1
        statics = np.array([o.footprint() for o in world.obstacles if o.kind in ("static", "cone")]).reshape(-1, 5)
        if self.book is None:
            self.book = CommitmentBook(fleet, [self.commitment(world, i, period, np.zeros((0, 2))) for i in range(n)],
                                       self.params.commit_margin)
        done = self.finished(world)
        parked = self.parked(world, done)
        records = [RobotDecision(False, mode=c.stage(period)) for c in self.book.items]
        if self.params.make_room:
            if self.room is None:
                corridor = float(np.max(np.hypot(fleet.length, fleet.width))) + self.params.commit_margin
                self.room = MakeRoom(n, int(round(self.params.stall_time / cfg.dt)), int(round(self.params.lead_time / cfg.dt)), corridor)
            goals = np.array([task.points[-1] for task in self.tasks])
            self.room.update(world.states, world.robot_centres(), goals, ~done, period)
        if self.params.detour:
            if self.detours is None:
                hard = 0.5 * float(np.max(fleet.width)) + self.params.commit_margin
                self.detours = Detours(self.tasks, int(round(self.params.stall_time / cfg.dt)), int(round(DETOUR_CHECK / cfg.dt)),
                                       hard, max(self.params.detour_clearance, hard), DETOUR_CELL)
            self.detours.update(world.states, world.robot_footprints(), done, parked, statics, period)
        if self.params.keep_right > 0.0:
            slow = np.abs(world.states[:, 3]) < SLOW_SHARE * np.array([t.speed for t in self.tasks])
            grow = slow & ~done & self.crowded_ahead(world)
            self.extra_shift = np.where(grow, np.minimum(self.extra_shift + SHIFT_GROWTH * cfg.dt, self.params.keep_right_max - self.params.keep_right),
                                        np.maximum(self.extra_shift - SHIFT_DECAY * cfg.dt, 0.0))
        holders, reasons, cuts, kept = [], [], 0, 0
        for members, candidates in self.groups(world, parked):
            i, reason = self.choose_in_group(world, members, candidates, records, period)
            others = members[members != i]
            decided, cut, keep = self.plan_committed(world, i, others, reason, period, statics)
            decided.score, decided.progress = records[i].score, records[i].progress
            records[i] = decided
            holders.append(world.robots[i].name)
            reasons.append(reason)
            cuts += cut
            kept += keep
        extended = self.extend_by_tracking(world, period, parked, holders, records, statics)
        inputs = self.book.inputs(period)
        stopped = 0
        if self.params.safety_stop:
            stopped = self.committed_safety_stop(world, inputs, records, period, statics)
        notes = dict(authority=" ".join(holders), reason=" ".join(sorted(set(reasons))) if reasons else "all finished",
                     safety_stops=stopped, authorities=len(holders), commit_cuts=cuts, commit_kept=kept, extensions=extended)
        return Decision(inputs, records, notes=notes)

    def path(self, i: int) -> PathReference:
        """Robot ``i``'s reference path: its detour (``detour``), else its task."""
        return self.tasks[i] if self.detours is None else self.detours.path(i)

    def tail_decel(self) -> np.ndarray:
        """Each robot's stopping-tail deceleration [m/s^2]: ``tail_brake`` of its strongest
        braking, at most its comfort deceleration."""
        return np.minimum(self.params.tail_brake * -self.fleet.a_min, self.fleet.comfort)

    def commitment(self, world: WorldState, i: int, period: int, head: np.ndarray):
        """Robot ``i``'s commitment from now: the inputs ``head`` (m, 2), then its stopping tail
        turning towards its reference's heading where the head ends."""
        return stopping_commitment(self.fleet, i, period, world.states[i], head, self.path(i), self.tail_decel()[i], self.last_inputs[i, 1],
                                   self.planner.config.dt)

    def groups(self, world: WorldState, parked: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(members, candidates)`` per authority of this period: with one authority, every
        robot and the active ones; else the clusters of robots that can interact over the
        horizon (:func:`~aac_sumo.coordination.commitments.clusters`) that hold an active robot,
        the longest-waiting first, at most ``authorities`` of them."""
        n, cfg = len(world.robots), self.planner.config
        active = np.flatnonzero(~parked)
        if active.size == 0:
            return []
        if self.params.authorities == 1:
            return [(np.arange(n), active)]
        radii = reach_radii(self.fleet, world.states, cfg.horizon, cfg.dt)  # within the horizon
        out = [(g, g[~parked[g]]) for g in clusters(world.robot_centres(), radii, self.params.commit_margin)]
        out = [(g, c) for g, c in out if c.size]
        if self.params.authorities != "clusters":
            out = sorted(out, key=lambda gc: (self.last_turn[gc[1]].min(), gc[0][0]))[: self.params.authorities]
            out.sort(key=lambda gc: gc[0][0])
        return out

    def choose_in_group(self, world: WorldState, members: np.ndarray, candidates: np.ndarray, records: list[RobotDecision],
                         period: int) -> tuple[int, str]:
        """The authority among ``candidates`` and why: with close pairs among them, the proximity
        decision (blockers: the group's ``members`` and the obstacles; its samples seeded by the
        scenario seed, the period and the candidates' states, so that a group's decision depends
        on nothing outside it); without, the candidate that held authority longest ago (round
        robin; ties go to the lowest index)."""
        centres = world.robot_centres()
        pairs = close_pairs(centres[candidates], self.params.close_distance)
        room = self.room
        leader = room.leader if room is not None else -1
        # robots in the leader's way, parked ones too (they come back once it has passed)
        movers = np.array([j for j in members if j in room.targets], dtype=int) if leader in candidates else np.empty(0, dtype=int)
        waited = period - self.last_turn[candidates]
        before = self.last_reason.get(int(members[0]), "")  # a lead cycles: leader, a robot in its way, anyone
        if leader in candidates and before not in ("leader", "make_room"):
            i, reason = leader, "leader"
        elif before == "leader" and movers.size:
            i, reason = int(movers[np.argmin(self.last_turn[movers])]), "make_room"
        elif len(pairs) == 0 or waited.max() > STARVING * self.planner.config.horizon:
            i, reason = int(candidates[np.argmax(waited)]), "round_robin"
        else:
            near = candidates[np.unique(pairs)]
            blockers = np.vstack([centres[members]] + [o.centre[None, :] for o in world.obstacles])
            r = self.params.proximity.collision_radius
            radius = np.r_[np.full(len(members), r), [r + 0.5 * np.hypot(o.length, o.width) for o in world.obstacles]]
            owner = np.full(len(blockers), -1)
            owner[np.searchsorted(members, near)] = np.arange(len(near))
            goals = np.array([self.tasks[j].points[-1] for j in near])
            entropy = np.frombuffer(np.ascontiguousarray(world.states[near]).tobytes(), dtype=np.uint32)
            rng = np.random.default_rng([self.params.seed, period, *entropy.tolist()])
            result = proximity_decision(world.states[near, :2], goals, blockers, radius, owner, self.params.proximity, rng)
            for row, j in enumerate(near):
                records[j].score, records[j].progress = float(result.scores[row]), float(result.progress[row])
            i, reason = int(near[result.winner]), "proximity"
        self.last_turn[i] = period
        self.last_reason[int(members[0])] = reason
        return i, reason

    def room_reference(self, world: WorldState, i: int) -> np.ndarray:
        """Reference (N+1, 4) of a robot making room for the leader: straight from where it is to
        its make-room target at half its cruise speed, stopping there."""
        cfg, task = self.planner.config, self.tasks[i]
        target = self.room.targets[i]
        if np.hypot(*(target - world.states[i, :2])) < 1e-6:
            target = target + 1e-3
        away = PathReference([world.states[i, :2], target], 0.5 * task.speed, task.decel, approach=np.inf)
        return away.horizon(world.states[i], cfg.horizon, cfg.dt)

    def plan_committed(self, world: WorldState, i: int, others: np.ndarray, reason: str, period: int,
                       statics: np.ndarray) -> tuple[RobotDecision, int, int]:
        """Robot ``i`` plans around ``others``' commitments (swept regions of stages k and k+1)
        and the obstacles, warm-started from its own commitment (from the tracking law's course
        when it stands at the end of its commitment). It commits to the longest
        prefix of its plan (all N inputs first, one fewer each time down to braking at once)
        whose stopping tail passes the exact check; no prefix passing keeps its old commitment.
        A failed solve offers only the planner's braking fallback (the paper's answer to a failed
        solve), under the same check. A robot that stands and whose plan leaves it standing
        creeps instead when it can (:meth:`creep`). Returns its record, whether the plan was cut
        (or replaced by a creep), and whether the old commitment was kept."""
        cfg, book = self.planner.config, self.book
        traj = book.courses(period, others, cfg.horizon + 1)
        obstacles = world.obstacles
        if len(others) + len(obstacles) > cfg.slots:  # the planner's slots only: rank by stage 0, sweep the nearest
            first = self.fleet.swept_ellipses(others, traj[:, :2], 0, cfg.barrier, cfg.fcbf)[:, 0]
            ranked = self.planner.nearest(world.states[i], obstacles, first)  # into obstacles, then others, nearest first
            robots = ranked[ranked >= len(obstacles)] - len(obstacles)
            swept = iter(self.fleet.swept_regions(others[robots], traj[robots], cfg.horizon, cfg.barrier, cfg.fcbf))
            obstacles = [obstacles[k] if k < len(obstacles) else next(swept) for k in ranked]
        else:
            obstacles = obstacles + self.fleet.swept_regions(others, traj, cfg.horizon, cfg.barrier, cfg.fcbf)
        ref = self.reference(world, i)
        own = book.items[i]
        guess = (own.course(period, cfg.horizon), own.inputs_ahead(period, cfg.horizon))
        if own.stage(period) == "hold":  # standing: a standing guess keeps it standing; start from the tracking law instead
            inputs = self.tracking_inputs(world, i, cfg.horizon)
            guess = (self.fleet.rollout(np.array([i]), world.states[[i]], inputs[None], cfg.dt)[0], inputs)
        plan = self.planner.plan(world.robots[i], world.states[i], ref, self.last_inputs[i], obstacles, None,
                                 self.corridors[i], guess=guess)
        self.plans[i] = plan
        record = RobotDecision(True, plan.status, plan.solve_ms, plan.solver, ref, reason=reason, mode=own.stage(period),
                               iterations=plan.iterations, capped=plan.capped)
        cuts = range(cfg.horizon, -1, -1) if plan.status == "solved" else [cfg.horizon]  # a failed solve: the braking fallback
        passed, m = None, cfg.horizon
        for m in cuts:
            candidate = self.commitment(world, i, period, plan.inputs[:m])
            if book.clearance(i, candidate, period, statics) >= book.margin:
                passed = candidate
                break
        if abs(world.states[i, 3]) < STILL_SPEED and self.creep(world, i, period, ref, passed, statics):
            record.mode = "creep"
            return record, 1, 0
        if passed is None:
            return record, 1, 1
        book.replace(i, passed, period)
        record.mode = "mpc"
        return record, int(m < cfg.horizon), 0

    def creep(self, world: WorldState, i: int, period: int, ref: np.ndarray, planned, statics: np.ndarray) -> bool:
        """Robot ``i`` stands, and its MPC's course ``planned`` (a commitment that passed the
        check, or None) gets it no nearer where its reference ``ref`` (N+1, 4) ends: the
        planner's regions (ellipses round swept hulls, grown by ``d_safe``) are conservative,
        and in a crowd packed at the commitments' 5 cm margin they left 62 % of the standing
        authorities' plans within 5 cm of where they stood (100 robots, seed 4), while exact
        footprints left room. It then tries short courses, ``CREEP_SPEED`` forwards (backwards
        while it backs off, :meth:`~aac_sumo.coordination.make_room.MakeRoom.backing_off`),
        steering to each of ``CREEP_STEER``, each with its stopping tail, and commits to the one
        that ends closest to ``ref``'s end, when that is at least ``CREEP_GAIN`` [m] closer than
        ``planned`` ends (than where it stands, without one) and the course passes the same exact
        check as every commitment (:meth:`CommitmentBook.clearance`). Not with uncontrolled
        moving agents about (walkers, scripted or SUMO-driven cars): the check does not hold
        them. Not for a robot making room for a leader: creeping towards its make-room target
        moved robots that had parked at their goals off them for good (100 robots, seed 24;
        20 robots: 48 of 50 seeds completed with it, 49 without). Nor for the leader, which
        drives its MPC's plan while the others make room (creeping, the leader of the 16-robot
        circle swap's seed 3 shuttled by a decimetre for 8 s: a deadlock). Returns whether it
        committed."""
        cfg, book, fleet = self.planner.config, self.book, self.fleet
        if any(o.kind not in ("static", "cone") for o in world.obstacles):
            return False
        if self.room is not None and (i in self.room.targets or i == self.room.leader):
            return False
        target, here = ref[-1, :2], world.states[i, :2]
        best = float(np.hypot(*(here - target)))
        if planned is not None:
            best = min(best, float(np.hypot(*(planned.states[-1, :2] - target))))
        best -= CREEP_GAIN
        choice = None
        backing = self.room is not None and self.room.backing_off(i) and fleet.v_min[i] < 0.0
        for speed in ((-CREEP_SPEED,) if backing else (CREEP_SPEED,)):
            for share in CREEP_STEER:
                head = self.creep_inputs(world, i, speed, share * fleet.steer_limits[i, 0], cfg.horizon)
                candidate = self.commitment(world, i, period, head)
                gap = float(np.hypot(*(candidate.states[-1, :2] - target)))
                if gap < best and book.clearance(i, candidate, period, statics) >= book.margin:
                    best, choice = gap, candidate
        if choice is None:
            return False
        book.replace(i, choice, period)
        return True

    def creep_inputs(self, world: WorldState, i: int, speed: float, steer: float, steps: int) -> np.ndarray:
        """Inputs (steps, 2) of robot ``i`` from where it is towards ``speed`` [m/s] (at most
        its strongest acceleration or braking) and ``steer`` [rad], within its steering limits
        from the steering it applied last."""
        fleet, dt = self.fleet, self.planner.config.dt
        out = np.zeros((steps, 2))
        v, previous = float(world.states[i, 3]), float(self.last_inputs[i, 1])
        for k in range(steps):
            accel = float(np.clip((speed - v) / dt, fleet.a_min[i], fleet.a_max[i]))
            previous = limited_steer(steer, v, accel, previous, fleet.wheelbase[i], fleet.steer_limits[i], dt)
            out[k] = accel, previous
            v += accel * dt
        return out

    def extend_by_tracking(self, world: WorldState, period: int, parked: np.ndarray, holders: list[str],
                           records: list[RobotDecision], statics: np.ndarray) -> int:
        """Robots without authority whose planned course runs out (at most one planned period
        left) go on as the paper's robots without a plan do, on the tracking law, but only when
        that course (N periods of the law, then a stopping tail) passes the same exact check as a
        plan; a robot whose try failed waits ``EXTENSION_RETRY`` periods before the next one. The
        law ignores obstacles, and uncontrolled moving agents are not in the check, so a robot
        that such an agent (growing as the planner grows walkers) may reach meanwhile is not
        extended.
        Returns how many robots extended their commitment."""
        cfg, book = self.planner.config, self.book
        extended = 0
        movers = [o for o in world.obstacles if o.kind not in ("static", "cone")]
        reach = reach_radii(self.fleet, world.states, cfg.horizon, cfg.dt, self.tail_decel()) if movers else None
        mover_centres = np.array([o.centre for o in movers]).reshape(-1, 2)
        mover_extent = np.array([0.5 * np.hypot(o.length, o.width) + cfg.pedestrian_margin for o in movers])
        mover_speed = np.array([(o.step_out_speed(cfg.pedestrian_reach, cfg.walkway_time) if o.kind == "pedestrian" else cfg.pedestrian_reach)
                                + np.hypot(*o.velocity) for o in movers])
        centres = world.robot_centres()
        for j in range(len(world.robots)):
            c = book.items[j]
            if parked[j] or world.robots[j].name in holders or self.next_extension[j] > period:
                continue
            if self.room is not None and j in self.room.targets:
                continue  # making room: it moves aside on its turns, not back onto its path
            if c.stage(period) == "plan" and c.start + c.planned - period > 1:
                continue
            if movers and np.any(np.hypot(*(mover_centres - centres[j]).T) < reach[j] + mover_extent + mover_speed * len(c.inputs) * cfg.dt):
                continue  # an uncontrolled agent (walker, scripted or SUMO-driven car) may meet it: only the MPC drives it on
            key = (self.path(j), float(self.last_inputs[j, 1]), self.keep_right_shift(world, j))  # with its state: the course it tries
            if book.refused_again(j, world.states[j], key, statics):  # the same course against the same standing footprint
                self.next_extension[j] = period + EXTENSION_RETRY
                continue
            if self.path(j).heading_free(world.states[j]):
                continue  # approaching its goal off its path: a manoeuvre for its MPC, not for the forward-only law
            head = self.tracking_inputs(world, j, cfg.horizon)
            candidate = self.commitment(world, j, period, head)
            gap, blocker = book.check(j, candidate, period, statics)
            if gap >= book.margin:
                book.replace(j, candidate, period)
                records[j].mode = "tracking"
                extended += 1
            else:
                self.next_extension[j] = period + EXTENSION_RETRY
                book.refuse(j, world.states[j], key, blocker, period, statics)
        return extended

    def tracking_inputs(self, world: WorldState, j: int, steps: int) -> np.ndarray:
        """Inputs (steps, 2) of robot ``j`` following the tracking law from where it is, on its
        path moved by its keep-right shift of now."""
        return track_course(world.robots[j], world.states[j], self.path(j), self.params.lookahead, self.params.speed_gain,
                            self.last_inputs[j, 1], self.planner.config.dt, steps, self.keep_right_shift(world, j))

    def committed_safety_stop(self, world: WorldState, inputs: np.ndarray, records: list[RobotDecision], period: int,
                              statics: np.ndarray) -> int:
        """The optional safety stop on committed inputs (``inputs`` changed in place): a robot
        it would stop brakes (its input once, then braking at its strongest) only when that
        braking course itself passes the commitments' exact check, and it is then committed to
        it; so the layer never breaks the invariant. Returns how many robots it stopped."""
        moving = np.flatnonzero(np.abs(world.states[:, 3]) > 0.0)
        if moving.size == 0:
            return 0
        checked = self.safety_check(world).safe_inputs(moving, inputs, self.params.safety_margin)
        stopped, cfg = 0, self.planner.config
        for i in moving[np.any(checked[moving] != inputs[moving], axis=1)]:
            braking = stopping_commitment(self.fleet, i, period, world.states[i], checked[i][None], self.tasks[i].heading_at(world.states[i, :2]),
                                          -self.fleet.a_min[i], self.last_inputs[i, 1], cfg.dt)
            if self.book.clearance(i, braking, period, statics) >= self.book.margin:
                self.book.replace(i, braking, period)
                inputs[i], records[i].mode = checked[i], "safety_stop"
                stopped += 1
        return stopped
