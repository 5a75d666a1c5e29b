"""Creeping: a standing AAC authority whose MPC plan leaves it standing tries short exact-checked
courses instead, and a standing car whose continuation a car standing beside it refuses
nudges away from it (a mixin of :class:`~aac_sumo.coordination.aac.committed.CommittedAac`).

Frames and units: world frame [m], speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.make_room import STILL_SPEED
from aac_sumo.coordination.tracking import creep_inputs
from aac_sumo.world import WorldState

#: Creeping (:meth:`Creeping.creep`): a standing authority whose plan leaves it standing
#: tries courses at CREEP_SPEED [m/s] (forwards; backwards while it backs off), steering to each
#: of CREEP_STEER (shares of its steering limit), under the exact check, and takes the one that
#: ends closest to where its reference ends, when that is at least CREEP_GAIN [m] closer.
CREEP_SPEED = 0.3
CREEP_STEER = (-1.0, 0.0, 1.0)
CREEP_GAIN = 0.05
#: Nudging (:meth:`Creeping.nudged`): a standing car whose continuation leaves it standing (moves it
#: at most NUDGE [m]) or is refused, within NUDGE_NEAR [m] above the margin of a standing robot,
#: tries the tracking law on its path moved to where it stands and NUDGE [m] further away from it.
NUDGE = 0.25
NUDGE_NEAR = 0.5


class Creeping:
    """The creeping step of committed AAC (needs the coordinator's ``book``, ``room``,
    ``fleet``, ``planner``, ``params``, ``last_inputs``, ``commitment``, ``path``, ``nearest`` and
    ``tracking_inputs``)."""

    def nudged(self, world: WorldState, i: int, period: int, statics: np.ndarray, continuation):
        """Robot ``i``'s ``continuation`` (None: refused), or where it stands and that leaves it
        standing (or none passed) beside a robot that stands too, nearer than the margin plus
        ``NUDGE_NEAR`` (:attr:`nearest`), its nudge away from that robot where the check passes:
        two cars stopped side by side at the margin, one angled into the other's lane where its
        path goes, refused each other's every course, as the angled car's continuation stopped it
        behind the other (the highway, one authority a period, seed 4: from 216 s until the run
        deadlocked). The nudge is the tracking law's course for the horizon, within the comfort
        envelope (:meth:`tracking_inputs`; it set off at 3 m/s^2 in the city), on the robot's path
        moved to where it stands and ``NUDGE`` [m] further away from that robot, so that it first
        turns away from it (the angled car along the lane it stands in), then its stopping tail."""
        state, (gap, j) = world.states[i], self.nearest
        if abs(state[3]) >= STILL_SPEED or not (0 <= j < len(self.book.items) and j != i) or abs(world.states[j, 3]) >= STILL_SPEED:
            return continuation
        if gap >= self.book.margin + NUDGE_NEAR or (continuation is not None and np.hypot(*(continuation.states[-1, :2] - state[:2])) > NUDGE):
            return continuation
        path, centres, cfg = self.path(i), world.robot_centres(), self.planner.config
        x, y, heading = path.pose_at(path.project(state[:2])[0])[0]
        right = (state[0] - x) * np.sin(heading) - (state[1] - y) * np.cos(heading)  # how far right of its path it stands [m]
        d = centres[j] - centres[i]
        left = np.cos(heading) * d[1] - np.sin(heading) * d[0] > 0.0  # the other robot lies to its left
        head = self.tracking_inputs(world, i, cfg.horizon, comfort=True, shift=right + (NUDGE if left else -NUDGE))
        candidate = self.commitment(world, i, period, head)
        return candidate if self.book.clearance(i, candidate, period, statics) >= self.book.margin else continuation

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
                head = creep_inputs(float(world.states[i, 3]), speed, share * fleet.steer_limits[i, 0], float(self.last_inputs[i, 1]),
                                    fleet.a_min[i], fleet.a_max[i], fleet.wheelbase[i], fleet.steer_limits[i], cfg.dt, cfg.horizon)
                candidate = self.commitment(world, i, period, head)
                gap = float(np.hypot(*(candidate.states[-1, :2] - target)))
                if gap < best and book.clearance(i, candidate, period, statics) >= book.margin:
                    best, choice = gap, candidate
        if choice is None:
            return False
        book.replace(i, choice, period)
        return True
