"""What both ways of running AAC share: which robot holds authority in each group (close pairs,
the proximity decision, round robin, the make-room lead cycle), the groups themselves (all
robots, or the clusters of robots that can meet within the horizon), and each robot's
reference (its task's, a make-room target's, backing off, a detour, the keep-right shift).

:class:`AacCoordinator` is built for the mode its ``params.commit`` names: committed plans
(:class:`~aac_sumo.coordination.aac.committed.CommittedAac`) or the paper's stored plans
(:class:`~aac_sumo.coordination.aac.stored.StoredPlanAac`).
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.aac.params import AacParams
from aac_sumo.coordination.base import Coordinator, Finished, RobotDecision
from aac_sumo.coordination.commitments import clusters, reach_radii
from aac_sumo.coordination.detour import Detours, plan_detour
from aac_sumo.coordination.make_room import MakeRoom
from aac_sumo.coordination.proximity import ProximityParams, close_pairs, proximity_decision
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import PathReference
from aac_sumo.world import WorldState

#: A candidate that has not held authority for this many horizons gets it (round robin) before
#: any proximity decision: with committed plans, a robot without turns stands still.
STARVING = 2
#: A robot slower than this share of its cruise speed is held up: its keep-right shift grows at
#: SHIFT_GROWTH [m/s] up to keep_right_max, and shrinks at SHIFT_DECAY [m/s] otherwise.
SLOW_SHARE = 0.3
SHIFT_GROWTH = 0.5
SHIFT_DECAY = 0.1
#: The keep-right shift is whole while the goal is more than FADE[1] shifts away and gone within
#: FADE[0] shifts of it. On a path too short for ``keep_right``'s fade to end by FADE_PATH[0] of the
#: path's length from the goal and begin by FADE_PATH[1], both distances shrink by the factor that
#: makes them do so: a robot on a short path keeps some shift where the crowd meets, mid-way.
FADE = (1.5, 3.0)
FADE_PATH = (0.375, 0.625)


class AacCoordinator(Coordinator):
    """Alternative Authority Control: one robot per group plans each period (see the package);
    ``AacCoordinator(...)`` gives the mode's class, registered by ``commit``."""

    name = "aac"
    #: The subclass of each mode, by its ``commit`` (registered by :meth:`__init_subclass__`).
    modes: dict[bool, type] = {}
    commit: bool | None = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.commit is not None:
            AacCoordinator.modes[cls.commit] = cls

    def __new__(cls, *args, **kwargs):  # (also without arguments: copy.deepcopy makes a mode's instance so)
        if cls is AacCoordinator:
            params = kwargs.get("params", args[4] if len(args) > 4 else AacParams())
            cls = AacCoordinator.modes[params.commit]
        return super().__new__(cls)

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                 params: AacParams = AacParams()):
        super().__init__(planner, tasks, corridors, finished)
        self.params = params
        self.leaves_followers = params.ignore_followers
        self.rng = np.random.default_rng(params.seed)  # the paper's one-authority proximity decision
        self.cursor = -1  # its round robin's last holder
        self.period = 0
        self.last_turn = np.full(len(tasks), -1)  # period of each robot's last authority
        self.room: MakeRoom | None = None
        self.extra_shift = np.zeros(len(tasks))  # keep-right growth of robots held up in a crowd [m]
        self._crowded: tuple[float | None, np.ndarray] = (None, np.zeros(len(tasks), dtype=bool))  # (t, crowded_ahead)
        self.last_reason: dict[int, str] = {}  # per group (its first member), why its last authority held it
        self.detours: Detours | None = None
        self.reach = np.zeros(len(tasks))  # each robot's reach disc radius this period [m] (groups)

    def warm_up(self, world: WorldState) -> None:
        """The proximity decision (with its own generator) and a detour, which the first period may
        not need, on tiny instances."""
        proximity_decision(np.zeros((2, 2)), np.ones((2, 2)), np.zeros((1, 2)), np.ones(1), np.array([-1]),
                           ProximityParams(iterations=2), np.random.default_rng(0))
        plan_detour(np.zeros(2), np.array([1.0, 0.0]), np.array([[0.5, 0.3, 0.2, 0.2, 0.0]]), 0.1, 0.3, 0.1)

    def admit(self, world: WorldState, i: int) -> None:
        """Robot ``i`` has just come onto the road: it has waited longest for a turn."""
        super().admit(world, i)
        self.last_turn[i], self.extra_shift[i] = -1, 0.0

    def stored_turns(self, world: WorldState, parked: np.ndarray, active: np.ndarray,
                     records: list[RobotDecision]) -> list[tuple[int, str, np.ndarray]]:
        """This period's authorities with stored plans: ``(robot, why, its group's members)``.
        One authority (the paper): :meth:`choose_authority` among all active robots. Several
        (``authorities`` k or ``"clusters"``): one per group of :meth:`groups`, chosen within it
        by :meth:`choose_in_group`."""
        if self.params.authorities.single:
            authority, reason = self.choose_authority(world, active, records)
            return [(authority, reason, np.arange(len(world.robots)))]
        out = []
        for members, candidates in self.groups(world, parked):
            i, reason = self.choose_in_group(world, members, candidates, records, self.period)
            out.append((i, reason, members))
        self.period += 1
        return out

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

    def groups(self, world: WorldState, parked: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(members, candidates)`` per authority of this period: with one authority, every
        robot and the active ones; else the clusters of robots that can interact over the
        horizon (:func:`~aac_sumo.coordination.commitments.clusters`) that hold an active robot,
        the longest-waiting first, at most ``authorities`` of them."""
        n, cfg = len(world.robots), self.planner.config
        active = np.flatnonzero(~parked)
        if active.size == 0:
            return []
        if self.params.authorities.single:
            return [(np.arange(n), active)]
        radii = self.reach = reach_radii(self.fleet, world.states, cfg.horizon, cfg.dt)  # within the horizon
        out = [(g, g[~parked[g]]) for g in clusters(world.robot_centres(), radii, self.params.commit_margin)]
        out = [(g, c) for g, c in out if c.size]
        if not self.params.authorities.per_cluster:
            out = sorted(out, key=lambda gc: (self.last_turn[gc[1]].min(), gc[0][0]))[: self.params.authorities.count]
            out.sort(key=lambda gc: gc[0][0])
        return out

    def out_of_reach(self, world: WorldState, i: int, candidates: np.ndarray) -> np.ndarray:
        """Those of ``candidates`` whose reach discs of this period (:meth:`groups`) keep more
        than ``commit_margin`` from robot ``i``'s: with ``authorities = "spread"``, they may hold
        authority in the same period as ``i`` (each plans round the others' commitments, and
        each new commitment passes the exact check against those committed before it)."""
        centres = world.robot_centres()
        gap = np.hypot(*(centres[candidates] - centres[i]).T) - self.reach[candidates] - self.reach[i]
        return candidates[gap > self.params.commit_margin]

    def turns_in_group(self, world: WorldState, members: np.ndarray, candidates: np.ndarray, records: list[RobotDecision],
                       period: int):
        """This period's authorities of one group, in turn, as ``(robot, why)``: one
        (:meth:`choose_in_group`), or with ``authorities = "spread"`` then more, each among the
        candidates out of reach of those before it (:meth:`out_of_reach`), and then up to
        ``crowd_authorities`` more, each among the candidates in no close pair with those before
        it (:meth:`apart`); each chosen once the one before has planned, by round robin alone
        (:meth:`longest_waiting`; the lead's cycle and the proximity decision pick the first)."""
        i, reason = self.choose_in_group(world, members, candidates, records, period)
        yield i, reason
        chosen, rest = [i], candidates
        while self.params.authorities.spread and (rest := self.out_of_reach(world, i, rest)).size:
            i, reason = self.longest_waiting(rest, period)
            chosen.append(i)
            yield i, reason
        extra = self.params.crowd_authorities if self.params.authorities.spread else 0
        centres = world.robot_centres() if extra else None
        for _ in range(extra):
            apart = self.apart(centres, np.setdiff1d(candidates, chosen), np.array(chosen))
            if not apart.size:
                return
            i, reason = self.longest_waiting(apart, period)
            chosen.append(i)
            yield i, reason

    def apart(self, centres: np.ndarray, candidates: np.ndarray, chosen: np.ndarray) -> np.ndarray:
        """Those of ``candidates`` whose footprint centre lies at least ``close_distance`` [m]
        from that of every robot in ``chosen``: in no close pair with this period's authorities."""
        gaps = np.hypot(*(centres[candidates, None, :] - centres[None, chosen, :]).transpose(2, 0, 1))
        return candidates[gaps.min(axis=1, initial=np.inf) >= self.params.close_distance]

    def longest_waiting(self, candidates: np.ndarray, period: int) -> tuple[int, str]:
        """Round robin: the candidate that held authority longest ago (ties go to the lowest index)."""
        i = int(candidates[np.argmax(period - self.last_turn[candidates])])
        self.last_turn[i] = period
        return i, "round_robin"

    def choose_in_group(self, world: WorldState, members: np.ndarray, candidates: np.ndarray, records: list[RobotDecision],
                         period: int) -> tuple[int, str]:
        """The authority among ``candidates`` and why: with close pairs among them, the proximity
        decision (blockers: the group's ``members`` and the obstacles; its samples seeded by the
        scenario seed, the period and the candidates' states, so that a group's decision depends
        on nothing outside it); without, the candidate that held authority longest ago (round
        robin, :meth:`longest_waiting`)."""
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
            i, reason = self.longest_waiting(candidates, period)
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

    def reference(self, world: WorldState, i: int, speeds: np.ndarray | None = None) -> np.ndarray:
        """Robot ``i``'s reference (N+1, 4) (``speeds``: as in :meth:`Coordinator.reference`): a
        make-room target's or, for a robot that can reverse and has stood long
        (:meth:`~aac_sumo.coordination.make_room.MakeRoom.backing_off`), straight back at half
        its cruise speed (a short horizon finds no way round an obstacle it faces at close
        range); else its task's, shifted ``keep_right`` [m] to the right of its direction while
        another robot's footprint centre lies ahead of it (in the half-plane in front, along the
        reference's heading) within ``keep_right_range`` [m]: a right-hand rule
        that turns head-on meetings and crowded crossings into passing on the right, a
        roundabout in effect. The shift fades out as the goal nears (``FADE``, ``FADE_PATH``), so
        that the robot arrives on its path."""
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
            ref = super().reference(world, i, speeds)
        shift = self.keep_right_shift(world, i)
        if shift == 0.0 or np.isnan(ref[:, 2]).any():  # no shift on a free heading (the goal approach)
            return ref
        out = ref.copy()
        out[:, :2] += shift * np.column_stack([np.sin(ref[:, 2]), -np.cos(ref[:, 2])])
        return out

    def room_reference(self, world: WorldState, i: int) -> np.ndarray:
        """Reference (N+1, 4) of a robot making room for the leader: straight from where it is to
        its make-room target at half its cruise speed, stopping there."""
        cfg, task = self.planner.config, self.tasks[i]
        target = self.room.targets[i]
        if np.hypot(*(target - world.states[i, :2])) < 1e-6:
            target = target + 1e-3
        away = PathReference([world.states[i, :2], target], 0.5 * task.speed, task.decel, approach=np.inf)
        return away.horizon(world.states[i], cfg.horizon, cfg.dt)

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
        task = self.tasks[i]
        if not task.stop_at_end:
            return shift
        gone, whole = (k * shift * min(1.0, share * task.length / (k * self.params.keep_right)) for k, share in zip(FADE, FADE_PATH))
        to_goal = float(np.hypot(*(world.states[i, :2] - task.points[-1])))
        if whole <= gone:  # a path of no length
            return 0.0
        return shift * float(np.clip((to_goal - gone) / (whole - gone), 0.0, 1.0))
