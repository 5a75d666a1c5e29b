"""Manoeuvring: a robot in a jam for ``manoeuvre_time`` takes, when it holds authority and its plan
and creeping leave it standing (or, with ``livelock_time``, when it has rocked that long beside
its goal without getting nearer), the first ``ESCAPE`` metres of a way to its goal planned on exact
footprints (:mod:`~aac_sumo.coordination.manoeuvre`), and drives them without replanning (a mixin
of :class:`~aac_sumo.coordination.aac.committed.CommittedAac`). With ``manoeuvre_subgoal``, a robot
far from its goal that finds no way to it searches one to a point that far towards it instead.

Frames and units: world frame [m], speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

from collections import deque

import numpy as np

from aac_sumo.coordination.base import RobotDecision
from aac_sumo.coordination.manoeuvre import INCHING, LENGTHS, ManoeuvrePlanner
from aac_sumo.coordination.regions import Fleet
from aac_sumo.world import WorldState

#: Periods a robot whose manoeuvre search found no way (or whose manoeuvre the check refused)
#: waits before it searches again.
RETRY = 20
#: A robot that got no further than this [m] in ``manoeuvre_time`` has stalled.
STALL = 0.2
#: Robots whose centres lie this close [m] stall together (:meth:`Manoeuvring.stalled`).
JAM_RADIUS = 2.0
#: A commitment that takes a standing robot less far than this [m] leaves it standing.
STAYS = 0.1
#: A manoeuvre is driven without the stops between legs of one direction, at these shares of the
#: robot's cruise speed, where that course passes the check and still ends where the legs do; else as searched.
SMOOTH = (1.0, 0.5)
#: A robot drives the legs of its manoeuvre up to ESCAPE [m] of driving (at least one), then plans
#: again; a smoothed course of a cut manoeuvre ends within ESCAPE_END [m] of where the legs end.
ESCAPE = 1.5
ESCAPE_END = 0.2
#: The manoeuvre ends this far [m] inside the goal's arrival radius.
INSIDE = 0.05
#: With ``manoeuvre_subgoal``, a robot far from its goal that finds no way to it searches one to
#: within SUBGOAL_TOLERANCE [m] of the point that far along the straight line to its goal.
SUBGOAL_TOLERANCE = 0.5


def quiet(centres: np.ndarray, rows: np.ndarray, idle: np.ndarray) -> np.ndarray:
    """For each robot of ``rows``, whether every robot whose footprint centre (``centres``, n by 2
    [m]) lies within ``JAM_RADIUS`` of its own is ``idle`` (n,), itself included."""
    near = np.hypot(*(centres[rows, None] - centres[None]).transpose(2, 0, 1)) <= JAM_RADIUS
    return np.all(idle[None] | ~near, axis=1)


class Manoeuvring:
    """The manoeuvring step of committed AAC (needs the coordinator's ``book``, ``fleet``,
    ``planner``, ``params``, ``tasks``, ``last_inputs``, ``commitment``, ``finished`` and
    ``plan_committed``)."""

    def warm_up(self, world: WorldState) -> None:
        """A manoeuvre's compiled search, which the first period does not need, on a tiny instance."""
        super().warm_up(world)
        if self.params.manoeuvre:
            f = self.fleet if self.fleet is not None else Fleet(world.robots)
            ManoeuvrePlanner(f.wheelbase[0], f.steer_limits[0], f.v_min[0], f.v_max[0], f.a_min[0], f.a_max[0], f.length[0], f.width[0],
                             f.offset[0], self.planner.config.dt).plan(np.zeros(4), 0.0, np.array([0.5, 0.0]), 0.3,
                                                                       np.array([[0.0, 1.5, 0.2, 0.2, 0.0]]), 0.05)

    def take_turn(self, world: WorldState, i: int, others: np.ndarray, reason: str, period: int,
                  statics: np.ndarray) -> tuple[RobotDecision, int, int]:
        """Robot ``i``'s turn of authority: on a manoeuvre, it drives on with it; else it plans
        (:meth:`plan_committed`), and when that leaves it standing after it has stalled
        (:meth:`stalled`), or it is livelocked, it manoeuvres where a way is found and passes the exact check.
        A robot still rocking brakes to rest first, within its manoeuvre.
        Returns its record, whether its plan was cut (or replaced), and whether its commitment
        was kept, as :meth:`plan_committed`."""
        if not self.params.manoeuvre:
            return self.plan_committed(world, i, others, reason, period, statics)
        self._count_standing(world, period)
        if self.manoeuvre_end[i] > period:
            return RobotDecision(True, reason=reason, mode="manoeuvre"), 0, 1
        record, cut, kept = self.plan_committed(world, i, others, reason, period, statics)
        stays = np.hypot(*(self.book.items[i].states[-1, :2] - world.states[i, :2])) < STAYS
        if (stays or self.livelocked[i]) and record.mode != "creep" and self.manoeuvre(world, i, period, statics):
            record.mode = "manoeuvre"
            return record, 1, 0
        return record, cut, kept

    def _count_standing(self, world: WorldState, period: int) -> None:
        """Once a period: remember where each robot stands, and which have stalled (:meth:`stalled`)."""
        n = len(world.robots)
        if getattr(self, "trail", None) is None:
            self.trail = deque(maxlen=int(round(self.params.manoeuvre_time / self.planner.config.dt)) + 1)
            self.manoeuvre_end, self.next_manoeuvre = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
            self.manoeuvres = [[ManoeuvrePlanner(self.fleet.wheelbase[j], self.fleet.steer_limits[j], self.fleet.v_min[j], self.fleet.v_max[j],
                                                 self.fleet.a_min[j], self.fleet.a_max[j], self.fleet.length[j], self.fleet.width[j],
                                                 self.fleet.offset[j], self.planner.config.dt, lengths) for lengths in (LENGTHS, INCHING)]
                               for j in range(n)]
            self._counted = self._searched = -1
            self.goals = np.array([task.points[-1] for task in self.tasks])
            self.best = np.hypot(*(world.states[:, :2] - self.goals).T)  # nearest to its goal so far [m], and when
            self.best_period = np.full(n, period)
        if self._counted == period:
            return
        self._counted = period
        self.trail.append(world.states[:, :2].copy())
        self.jammed, self.livelocked = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        done, centres = np.asarray(self.finished(world), dtype=bool), world.robot_centres()
        dist = np.hypot(*(world.states[:, :2] - self.goals).T)
        nearer = dist < self.best - STALL
        self.best[nearer], self.best_period[nearer] = dist[nearer], period
        if self.params.livelock_time > 0.0:
            idle = (period - self.best_period >= int(round(self.params.livelock_time / self.planner.config.dt))) | done
            rows = np.flatnonzero(idle & ~done)
            self.livelocked[rows] = quiet(centres, rows, idle)
        if len(self.trail) == self.trail.maxlen:
            path = np.asarray(self.trail)
            still = (np.hypot(*(path - path[0]).transpose(2, 0, 1)).max(axis=0) <= STALL) | done
            gained = np.hypot(*(path[0] - self.goals).T) - np.hypot(*(path[-1] - self.goals).T)
            idle = (gained <= STALL) | done  # moving, but none the nearer its goal (making room, rocking)
            rows = np.flatnonzero(still)  # only a robot that stood can be in a jam: no n-by-n distances
            self.jammed[rows] = quiet(centres, rows, idle)
        self.jammed |= self.livelocked

    def stalled(self, i: int) -> bool:
        """Whether robot ``i`` is in a jam: it got no further than ``STALL`` [m] from where it
        stood ``manoeuvre_time`` ago, at any period since (a robot rocking on the spot stalls
        too), and no unfinished robot whose centre lies within ``JAM_RADIUS`` of its own got
        more than ``STALL`` nearer its goal meanwhile (one that waits while its neighbours move
        on does not stall; neighbours that only make room for a leader, or rock, move on
        nowhere). With ``livelock_time`` also a robot that moves but has got no ``STALL`` nearer
        its goal for that long, nor has any unfinished robot near it (livelocked: rocking back
        and forth beside its goal between the approach and the back-off)."""
        return bool(self.jammed[i])

    def manoeuvre(self, world: WorldState, i: int, period: int, statics: np.ndarray) -> bool:
        """Robot ``i``, stalled (:meth:`stalled`), searches a manoeuvre to its
        goal round every standing obstacle and every other robot's footprints along the rest of
        its commitment (held as standing), or where none is found and ``manoeuvre_subgoal`` > 0, to within
        ``SUBGOAL_TOLERANCE`` of the point that far along the straight line to its goal (when it lies farther
        than that), and commits to its first ``ESCAPE`` [m], smoothed
        where it can be (``SMOOTH``), when that passes the exact check.
        Not with uncontrolled moving agents about (the check does not hold them), and one search
        a period at most. Returns whether it committed."""
        if period < self.next_manoeuvre[i] or self._searched == period or not self.stalled(i):
            return False
        if any(o.kind not in ("static", "cone") for o in world.obstacles):
            return False
        task, book = self.tasks[i], self.book
        others = [book.footprints(j, c, period) for j, c in enumerate(book.items) if j != i]
        obstacles = np.vstack([np.asarray(statics, dtype=float).reshape(-1, 5), *others])
        steer, goal = float(self.last_inputs[i, 1]), task.points[-1]
        brake, rest = self.manoeuvres[i][0].to_rest(world.states[i], steer)  # a robot rocking on the spot stops first
        targets, way, sub = [(goal, task.arrive - INSIDE)], goal - rest[:2], self.params.manoeuvre_subgoal
        if sub > 0.0 and np.hypot(*way) > sub + SUBGOAL_TOLERANCE:  # far from its goal: a way out towards it, where none reaches it
            targets.append((rest[:2] + sub * way / np.hypot(*way), SUBGOAL_TOLERANCE))
        legs, whole = None, True
        for target, tolerance in targets:
            for planner in self.manoeuvres[i]:  # arcs of 0.3 m and more; where they find no way, inching too
                legs = planner.search(rest, steer, target, tolerance, obstacles, book.margin)
                if legs is not None:
                    break
            if legs is not None:
                break
            whole = False
        self.next_manoeuvre[i], self._searched = period + RETRY, period
        if not legs:
            return False
        reach = np.cumsum([planner.distances[d] for d, _ in legs])
        legs = legs[: max(int(np.searchsorted(reach, ESCAPE, side="right")), 1)]  # the way out; then its MPC again
        searched = np.vstack([brake, planner.stop_and_go(legs, steer)])
        whole = whole and len(legs) == len(reach)
        end, near = (goal, task.arrive) if whole else (self.commitment(world, i, period, searched).states[-1, :2], ESCAPE_END)
        for inputs in [np.vstack([brake, planner.smooth(legs, steer, share * task.speed)]) for share in SMOOTH] + [searched]:
            candidate = self.commitment(world, i, period, inputs)
            if np.hypot(*(candidate.states[-1, :2] - end)) <= near and book.clearance(i, candidate, period, statics) >= book.margin:
                break
        else:
            return False
        book.replace(i, candidate, period)
        self.manoeuvre_end[i] = period + len(inputs)
        return True
