"""AAC with committed plans (``aac.commit = true``, the default; beyond the paper).

Every robot drives its commitment, the last plan it made and a stopping tail, and a commitment
changes only after the exact check of :mod:`~aac_sumo.coordination.commitments`
(collision-free by construction). One authority per period among all robots, or one per
cluster of robots that can meet within the horizon
(:class:`~aac_sumo.coordination.aac.params.Authorities`); close pairs, the proximity decision
and round robin pick it within its group, with the conflict-resolution rules of
:meth:`~aac_sumo.coordination.aac.authority.AacCoordinator.choose_in_group` and
:mod:`~aac_sumo.coordination.make_room`. A standing authority whose plan leaves it standing
may creep, and one that has stood long may manoeuvre; robots whose plan runs out extend their
commitment on the tracking law where the exact check allows; detours route robots round standing footprints;
with ``goal_cruise`` a plan towards a goal goes on along its path before its tail
(:mod:`~aac_sumo.coordination.aac.goal_cruise`).
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.aac.authority import SHIFT_DECAY, SHIFT_GROWTH, SLOW_SHARE, AacCoordinator
from aac_sumo.coordination.aac.creeping import Creeping
from aac_sumo.coordination.aac.goal_cruise import GoalCruise
from aac_sumo.coordination.aac.manoeuvring import Manoeuvring
from aac_sumo.coordination.aac.queueing import Queueing
from aac_sumo.coordination.aac.traffic import TrafficBraking
from aac_sumo.coordination.base import Decision, RobotDecision
from aac_sumo.coordination.commitments import CommitmentBook, reach_radii, stopping_commitment
from aac_sumo.coordination.traffic_courses import braking_courses, signalled_courses, standing_points, stop_lines
from aac_sumo.coordination.detour import Detours
from aac_sumo.coordination.make_room import STILL_SPEED, MakeRoom
from aac_sumo.coordination.anticipation import near_pedestrian, stop_points
from aac_sumo.coordination.tracking import track_course, tracking_bounds
from aac_sumo.coordination.walker_reach import WalkerReach
from aac_sumo.kernels.motion import continuation_inputs
from aac_sumo.references import PathReference
from aac_sumo.world import WorldState

#: Periods a robot whose tracking extension failed the check waits before it tries again.
EXTENSION_RETRY = 3
#: With ``cruise`` (a road), a robot without authority renews its continuation every
#: RENEW_EVERY periods where the new one passes the exact check and takes it further along its path than its
#: commitment (:data:`~aac_sumo.coordination.aac.queueing.RENEW_GAIN`): a car whose queue has set off follows it at once.
#: A car slower than its path's speed by more than RENEW_SLOW [m/s] renews every period (a queue setting off: each car renews after the one ahead of it, front first, in the same period).
RENEW_EVERY = 5
RENEW_SLOW = 1.0
#: A continuation aims at the anticipation's speed cap where the car will be CONTINUATION_LAG [s]
#: on (at least a period), and reaches it in that time within the comfort envelope and ``continuation_jerk``
#: (0.1 s against 0.3 s: tasks up to 0.8 s shorter on S2's seeds 10-14 with the bound, as its continuations pass the check more often).
CONTINUATION_LAG = 0.1
#: A continuation stops its rear axle this much [m] behind where it must (on top of its front and
#: ``commit_margin``) for the uncontrolled vehicles ahead (:func:`~aac_sumo.coordination.traffic_courses.standing_points`).
TRAFFIC_SPARE = 0.5
#: Its speed stays where braking at HARD_SHARE of the deceleration the check holds it to stops it
#: there (the speed law reaches its target with a lag: at the whole of it, it crossed the bound by up to 0.7 m).
HARD_SHARE = 0.9
#: Grid cell [m] of the detour planner, and how often [s] a robot checks its reference for standing footprints.
DETOUR_CELL = 0.1
DETOUR_CHECK = 1.0


class CommittedAac(Manoeuvring, Creeping, GoalCruise, Queueing, TrafficBraking, AacCoordinator):
    """AAC with committed plans (see the module)."""

    commit = True

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.book: CommitmentBook | None = None
        self.next_extension = np.zeros(len(self.tasks), dtype=int)  # first period a robot may try a tracking extension again
        self.behind_traffic = np.zeros(len(self.tasks), dtype=bool)  # whose last continuation stopped for an uncontrolled vehicle ahead
        self.nearest = (np.inf, -1)  # (clearance [m], what gives it) of the last candidate checked in passing()

    def admit(self, world: WorldState, i: int) -> None:
        """Robot ``i`` has just come onto the road: its commitment becomes its stopping tail from
        where it is (the one safe course known)."""
        super().admit(world, i)
        self.next_extension[i] = 0
        if self.book is not None:
            self.book.replace(i, self.commitment(world, i, self.period, np.zeros((0, 2))), self.period)

    def _decide(self, world: WorldState) -> Decision:
        """Every robot drives its commitment; each group (all active robots, or each cluster)
        gives one robot authority, which plans around the others' commitments and commits to its
        plan only when the plan with its stopping tail passes the exact check."""
        n, cfg, fleet = len(world.robots), self.planner.config, self.fleet
        period = self.period
        self.period += 1
        statics = np.array([o.footprint() for o in world.obstacles if o.kind in ("static", "cone")]).reshape(-1, 5)
        walkers = WalkerReach.of(world, cfg.pedestrian_margin, cfg.pedestrian_reach, cfg.walkway_time, cfg.dt, self.params.walkway_to_end)
        first = self.book is None
        if first:
            self.book = CommitmentBook(fleet, [self.commitment(world, i, period, np.zeros((0, 2))) for i in range(n)],
                                       self.params.commit_margin)
        self.book.walkers, self.book.paths = walkers, [self.path(i) for i in range(n)]
        self.book.traffic, self.book.lines = braking_courses(world.obstacles, self.params.traffic_decel, cfg.dt), stop_lines(world.obstacles)
        self.signalled = signalled_courses(world.obstacles, self.params.traffic_decel, cfg.dt)
        if self.params.traffic_reaction:
            self.book.reaction = (self.reaction_decel(), cfg.dt)
        self.book.beside = self.params.traffic_beside
        self.book.park(~world.on_road, world.states, period)
        self.book.hold_fallbacks(period)
        for i in self.front_first(world) if first else ():  # with cruise, every car drives on from the start where the check lets it
            start = self.continued_commitment(world, int(i), period, np.zeros((0, 2)), statics)
            if start is not None:
                self.book.replace(i, start, period)
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
                                       hard, max(self.params.detour_clearance, hard), DETOUR_CELL, cfg.workers)
            self.detours.update(world.states, world.robot_footprints(), done, parked, statics, period)
        if self.params.keep_right > 0.0:
            slow = np.abs(world.states[:, 3]) < SLOW_SHARE * np.array([t.speed for t in self.tasks])
            grow = slow & ~done & self.crowded_ahead(world)
            self.extra_shift = np.where(grow, np.minimum(self.extra_shift + SHIFT_GROWTH * cfg.dt, self.params.keep_right_max - self.params.keep_right),
                                        np.maximum(self.extra_shift - SHIFT_DECAY * cfg.dt, 0.0))
        holders, reasons, cuts, kept = [], [], 0, 0
        for members, candidates in self.groups(world, parked):
            for i, reason in self.turns_in_group(world, members, candidates, records, period):
                others = members[members != i]
                decided, cut, keep = self.take_turn(world, i, others, reason, period, statics)
                decided.score, decided.progress = records[i].score, records[i].progress
                records[i] = decided
                holders.append(world.robots[i].name)
                reasons.append(reason)
                cuts += cut
                kept += keep
        extended = self.extend_by_tracking(world, period, parked, holders, records, statics)
        braked = (self.brake_for_traffic(world, period, parked, records, statics)
                  if self.book.traffic or self.params.walker_brake or self.book.reaction is not None else 0)
        inputs = self.book.inputs(period)
        stopped = 0
        if self.params.safety_stop:
            stopped = self.committed_safety_stop(world, inputs, records, period, statics)
        notes = dict(authority=" ".join(holders), reason=" ".join(sorted(set(reasons))) if reasons else "all finished",
                     safety_stops=stopped, authorities=len(holders), commit_cuts=cuts, commit_kept=kept, extensions=extended,
                     traffic_brakes=braked)
        return Decision(inputs, records, notes=notes)

    def yielding(self, world: WorldState, i: int) -> bool:
        """Whether robot ``i`` keeps to its lane (:meth:`Coordinator.yielding`) for its whole
        commitment: within ``yield_distance`` of a walker, plus how far it drives over the horizon
        and ``cruise`` at its speed now (a committed plan is driven to its end, not only its first
        input, and its continuation goes on from where the plan leaves the car)."""
        rules, cfg = self.anticipation, self.planner.config
        reach = abs(float(world.states[i, 3])) * (cfg.horizon * cfg.dt + self.params.cruise)
        return rules is not None and near_pedestrian(world, i, rules.yield_distance + reach)

    def path(self, i: int) -> PathReference:
        """Robot ``i``'s reference path: its detour (``detour``), else its task."""
        return self.tasks[i] if self.detours is None else self.detours.path(i)

    def tail_decel(self, firm: bool = False) -> np.ndarray:
        """Each robot's stopping-tail deceleration [m/s^2]: ``tail_brake`` (``firm``:
        ``firm_tail``) of its strongest braking, at most its comfort deceleration."""
        share = self.params.firm_tail if firm else self.params.tail_brake
        return np.minimum(share * -self.fleet.a_min, self.fleet.comfort)

    def commitment(self, world: WorldState, i: int, period: int, head: np.ndarray, firm: bool = False):
        """Robot ``i``'s commitment from now: the inputs ``head`` (m, 2), then its stopping tail
        (``firm``: the firm one) turning towards its reference's heading where the head ends."""
        return stopping_commitment(self.fleet, i, period, world.states[i], head, self.path(i), self.tail_decel(firm)[i], self.last_inputs[i, 1],
                                   self.planner.config.dt)

    def passing(self, world: WorldState, i: int, period: int, head: np.ndarray, statics: np.ndarray):
        """Robot ``i``'s commitment to ``head`` (m, 2) with its gentle tail when that passes the
        exact check, else, where an uncontrolled vehicle ahead refused it, with its firm tail
        (``firm_tail``) when that passes, else None."""
        candidate = self.commitment(world, i, period, head)
        gap, blocker = self.nearest = self.book.check(i, candidate, period, statics)
        if gap >= self.book.margin:
            return candidate
        if blocker == -3 and self.params.firm_tail > self.params.tail_brake:  # only a vehicle ahead asks for a firmer tail
            candidate = self.commitment(world, i, period, head, True)
            if self.book.clearance(i, candidate, period, statics) >= self.book.margin:
                return candidate
        return None

    def continued_commitment(self, world: WorldState, i: int, period: int, head: np.ndarray, statics: np.ndarray,
                             speeds: np.ndarray | None = None):
        """Robot ``i``'s commitment to ``head`` (m, 2) continued along its path before its stopping tail, for
        ``cruise`` [s], else half or a quarter of it: the longest that passes the exact check; where a walker refused
        ``cruise`` (most often: it stood on a crossing) and nothing shorter passes, twice or three times it (across).
        The continuation is the tracking law's steering with the speed that reaches, in ``CONTINUATION_LAG`` and within
        ``continuation_jerk``, the anticipation's speed cap where the car will be then (:mod:`~aac_sumo.coordination.anticipation`,
        as the MPC's reference), with what moves along the path going on at its speed, for the other robots the speed
        their commitments have ``LEAD_LOOK`` on (:meth:`~aac_sumo.coordination.aac.queueing.Queueing.lead_speeds`;
        ``speeds``: those, already computed this period), braking at most at the comfort envelope and speeding up at
        most at the anticipation's ``accel``, and staying where it can stop (at ``HARD_SHARE`` of :meth:`held_decel`)
        behind where each uncontrolled vehicle ahead could stand, also in the lane its blinker signals
        (:func:`~aac_sumo.coordination.traffic_courses.standing_points`, :func:`~aac_sumo.coordination.traffic_courses.signalled_courses`).
        None without ``cruise``, without anticipation, on a path that ends in a stop, or when nothing passes (a car on a
        road does not crawl between its turns: a tail right after each plan braked it at every turn it did not get)."""
        cfg, task = self.planner.config, self.path(i)
        periods, self.nearest = int(round(self.params.cruise / cfg.dt)), (np.inf, -1)
        if periods <= 0 or self.anticipation is None or task.stop_at_end or task.heading_free(world.states[i]):
            return None
        head = np.asarray(head, dtype=float).reshape(-1, 2)
        rules, robot = self.anticipation, world.robots[i]
        seen = self.lead_speeds(world, i, period) if speeds is None else speeds
        stops = stop_points(world, i, task, rules, self.held[i], courses=self.courses, speeds=seen)  # [s_stop, v_lead, grow]: what it must stay behind
        x, y, h, v = self.fleet.rollout(np.array([i]), world.states[[i]], head[None], cfg.dt)[0, -1]
        steer, accel = (float(head[-1, 1]), float(head[-1, 0])) if len(head) else (float(self.last_inputs[i, 1]), float(self.last_inputs[i, 0]))
        calm = cfg.comfort_accel if cfg.comfort_accel > 0.0 else float(self.fleet.comfort[i])  # brakes within the comfort envelope
        hard = standing_points(task, self.book.traffic + self.signalled, self.book.lines, world.robot_centres()[i], float(world.states[i, 2]),
                               0.5 * robot.width + self.book.margin,
                               robot.centre_offset + 0.5 * robot.length + self.book.margin + TRAFFIC_SPARE)
        self.behind_traffic[i] = len(hard) > 0
        args = (len(head), cfg.dt, np.ascontiguousarray(stops, dtype=float), float(rules.decel), float(rules.accel), float(calm),
                max(CONTINUATION_LAG, cfg.dt), *tracking_bounds(robot, self.tracking_lat()), steer, *task.arrays(), float(task.speed),
                float(task.decel), *self.params.pursuit.args(), float(self.params.speed_gain), float(self.keep_right_shift(world, i)), hard,
                float(HARD_SHARE * self.held_decel(calm)[i]), accel, float(self.params.continuation_jerk))
        more = continuation_inputs(float(x), float(y), float(h), float(v), periods, *args)
        longer = (2 * periods, 3 * periods) if self.book.walkers is not None and len(self.book.walkers.strips) else ()
        first = None  # what refused the whole cruise: a walker (-2), most often its standing on a crossing, asks for longer
        for k in (periods, periods // 2, periods // 4, *longer):
            if k <= 0 or (k > periods and first[1] != -2):
                continue
            if k > len(more):  # the same law further on (it looks only back): computed only when asked for
                more = continuation_inputs(float(x), float(y), float(h), float(v), longer[-1], *args)
            candidate = self.passing(world, i, period, np.vstack([head, more[:k]]), statics)
            if candidate is not None:
                return candidate
            first = self.nearest if first is None else first
        return None

    def plan_committed(self, world: WorldState, i: int, others: np.ndarray, reason: str, period: int,
                       statics: np.ndarray) -> tuple[RobotDecision, int, int]:
        """Robot ``i`` plans around ``others``' commitments (swept regions of stages k and k+1)
        and the obstacles, warm-started from its own commitment (from the tracking law's course
        when it stands at the end of its commitment). It commits to the longest
        prefix of its plan (all N inputs first, continued along its path with ``cruise``, see
        :meth:`continued_commitment`; then one fewer each time down to braking at once) whose
        stopping tail passes the exact check; no prefix passing keeps its old commitment.
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
        seen = None if self.anticipation is None else self.lead_speeds(world, i, period)
        ref = self.reference(world, i, seen)
        own = book.items[i]
        guess = (own.course(period, cfg.horizon), own.inputs_ahead(period, cfg.horizon))
        if own.stage(period) == "hold":  # standing: a standing guess keeps it standing; start from the tracking law instead
            inputs = self.tracking_inputs(world, i, cfg.horizon)
            guess = (self.fleet.rollout(np.array([i]), world.states[[i]], inputs[None], cfg.dt)[0], inputs)
        plan = self.planner.plan(world.robots[i], world.states[i], ref, self.last_inputs[i], obstacles, None,
                                 self.corridor(world, i), guess=guess)
        self.plans[i] = plan
        record = RobotDecision(True, plan.status, plan.solve_ms, plan.solver, ref, reason=reason, mode=own.stage(period),
                               iterations=plan.iterations, capped=plan.capped)
        # a failed solve: the braking fallback; with cruise (a road), nothing: the car drives on its commitment (braking
        # at 6 m/s^2 on every failed solve stopped cars on the crossing, where a walker then came within 0.46 m)
        cuts = range(cfg.horizon, -1, -1) if plan.status == "solved" else [cfg.horizon] if self.params.cruise <= 0.0 else []
        calm = cfg.horizon
        if self.params.cruise > 0.0 and plan.status == "solved":
            envelope = (cfg.comfort_accel or np.inf, cfg.comfort_lat or np.inf, float(self.fleet.wheelbase[i]))
            calm = plan.comfortable_steps(*envelope, self.path(i).speed)  # no full lock at a crawl: a car sets off from it across its lane
            if calm == 0:  # unless it must steer more to go anywhere (standing before a merge): comfort at its own speed
                calm = plan.comfortable_steps(*envelope)
        if calm < cfg.horizon:  # on a road, a plan beyond the comfort envelope is never needed: the commitment is safe
            cuts = range(calm, -1, -1)
        passed, m = None, cfg.horizon
        if plan.status == "solved" and calm == cfg.horizon:
            passed = self.continued_commitment(world, i, period, plan.inputs, statics, seen)
        if passed is None and self.book.traffic and self.behind_traffic[i]:  # behind a SUMO car: its continuation from now
            passed = self.continued_commitment(world, i, period, np.zeros((0, 2)), statics, seen)
        if passed is None and plan.status == "solved" and self.params.goal_cruise > 0.0 and self.path(i).stop_at_end:
            passed = self.cruising_to_goal(world, i, period, plan.inputs, statics)
        for m in cuts if passed is None else ():
            passed = self.passing(world, i, period, plan.inputs[:m], statics)
            if passed is not None:
                break
        if abs(world.states[i, 3]) < STILL_SPEED and self.creep(world, i, period, ref, passed, statics):
            record.mode = "creep"
            return record, 1, 0
        if passed is None:
            return record, 1, 1
        book.replace(i, passed, period)
        record.mode = "mpc"
        return record, int(m < cfg.horizon), 0

    def extend_by_tracking(self, world: WorldState, period: int, parked: np.ndarray, holders: list[str],
                           records: list[RobotDecision], statics: np.ndarray) -> int:
        """Robots without authority whose planned course runs out (at most one planned period
        left) go on as the paper's robots without a plan do, on the tracking law, but only when
        that course (N periods of the law, continued with ``cruise`` as a plan is, then a stopping
        tail; with ``goal_cruise``, that much longer first) passes the same exact check as a plan; a robot whose try failed waits ``EXTENSION_RETRY`` periods before the next one. The
        law ignores obstacles, and uncontrolled vehicles are not in the check (walkers are), so a
        robot that such a vehicle (growing at the walkers' reach) may reach meanwhile is not
        extended. With ``cruise``, a robot renews its continuation every ``RENEW_EVERY``
        periods (every period while it is ``RENEW_SLOW`` below its path's speed) where the new
        one passes and takes the car further (:meth:`~aac_sumo.coordination.aac.queueing.Queueing.gains`),
        the robots furthest along their paths first. Returns how many robots extended their commitment."""
        cfg, book, extended = self.planner.config, self.book, 0
        movers = [o for o in world.obstacles if o.kind not in ("static", "cone", "pedestrian")]  # walkers: in the exact check
        reach = reach_radii(self.fleet, world.states, cfg.horizon, cfg.dt, self.tail_decel()) if movers else None
        mover_centres = np.array([o.centre for o in movers]).reshape(-1, 2)
        mover_extent = np.array([0.5 * np.hypot(o.length, o.width) + cfg.pedestrian_margin for o in movers])
        mover_speed = np.array([(o.step_out_speed(cfg.pedestrian_reach, cfg.walkway_time) if o.kind == "pedestrian" else cfg.pedestrian_reach)
                                + np.hypot(*o.velocity) for o in movers])
        centres = world.robot_centres()
        order = self.front_first(world) if self.params.cruise > 0.0 else range(len(world.robots))
        for j in order:
            c = book.items[j]
            if parked[j] or world.robots[j].name in holders or self.next_extension[j] > period:
                continue
            if self.room is not None and j in self.room.targets:
                continue  # making room: it moves aside on its turns, not back onto its path
            renewing = c.stage(period) == "plan" and c.start + c.planned - period > 1
            due = ((period + j) % RENEW_EVERY == 0 or world.states[j, 3] < self.path(j).speed - RENEW_SLOW
                   or self.behind_traffic[j])  # behind a SUMO car: every period, as the car ahead has not braked
            if renewing and not (self.params.cruise > 0.0 and due):
                continue
            longer = self.nudged(world, j, period, statics, self.continued_commitment(world, j, period, np.zeros((0, 2)), statics))
            if renewing and (longer is None or not self.gains(j, longer, c, period)):
                continue  # a renewal only where it takes the car further than its commitment does
            if longer is not None:
                book.replace(j, longer, period)
                records[j].mode = "tracking"
                extended += 1
                continue
            if movers and np.any(np.hypot(*(mover_centres - centres[j]).T) < reach[j] + mover_extent + mover_speed * len(c.inputs) * cfg.dt):
                continue  # an uncontrolled agent (walker, scripted or SUMO-driven car) may meet it: only the MPC drives it on
            key = (self.path(j), float(self.last_inputs[j, 1]), self.keep_right_shift(world, j))  # with its state: the course it tries
            if book.refused_again(j, world.states[j], key, statics):  # the same course against the same standing footprint
                self.next_extension[j] = period + EXTENSION_RETRY
                continue
            if self.path(j).heading_free(world.states[j]):
                continue  # approaching its goal off its path: a manoeuvre for its MPC, not for the forward-only law
            course = self.tracking_inputs(world, j, cfg.horizon + self.goal_cruise_periods(j), comfort=True)
            if len(course) > cfg.horizon:  # its cruise, as a plan's (GoalCruise.gentle_cruise)
                v = float(world.states[j, 3] + course[:cfg.horizon, 0].sum() * cfg.dt)
                course = np.vstack([course[:cfg.horizon], self.gentle_cruise(j, v, course[cfg.horizon:])])
            candidate = self.commitment(world, j, period, course)
            gap, blocker = book.check(j, candidate, period, statics)
            if gap < book.margin and len(course) > cfg.horizon:  # the law's course without its cruise
                candidate = self.commitment(world, j, period, course[:cfg.horizon])
                gap, blocker = book.check(j, candidate, period, statics)
            if gap >= book.margin:
                book.replace(j, candidate, period)
                records[j].mode = "tracking"
                extended += 1
            else:
                self.next_extension[j] = period + EXTENSION_RETRY
                book.refuse(j, world.states[j], key, blocker, period, statics)
        return extended

    def tracking_inputs(self, world: WorldState, j: int, steps: int, comfort: bool = False, shift: float | None = None) -> np.ndarray:
        """Inputs (steps, 2) of robot ``j`` on the tracking law from where it is, on its path moved ``shift`` [m] right (its keep-right
        shift of now by default); with ``comfort``, within the planner's comfort envelope (a course it drives: it set off at 3 m/s^2)."""
        cfg = self.planner.config
        up, lat = (cfg.comfort_accel if comfort and cfg.comfort_accel > 0.0 else None), (self.tracking_lat() if comfort else None)
        return track_course(world.robots[j], world.states[j], self.path(j), self.params.pursuit, self.params.speed_gain, self.last_inputs[j, 1],
                            cfg.dt, steps, self.keep_right_shift(world, j) if shift is None else shift, a_lat=lat, a_up=up)

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
            if self.book.clearance(i, braking, period, statics, walkers=False) >= self.book.margin:  # braking is never refused for a walker
                self.book.replace(i, braking, period)
                inputs[i], records[i].mode = checked[i], "safety_stop"
                stopped += 1
        return stopped
