"""Braking for SUMO's cars that leave what the exact check assumes of them (a mixin of
:class:`~aac_sumo.coordination.aac.committed.CommittedAac`).

The check holds an uncontrolled vehicle ahead as braking at ``aac.traffic_decel`` along its
lane (:func:`~aac_sumo.coordination.traffic_courses.braking_courses`). One that changes lanes into a
car's way, or brakes harder, can leave a car's commitment running into its course; that car
then renews its continuation, or brakes.

With ``aac.traffic_reaction`` a commitment is held against those vehicles only as its reaction
(its first period, then braking at the firm tail), so the car must be able to take that reaction
up whenever a vehicle ahead brakes, even where a car behind it committed only against its
gentler commitment. It does: it takes up its reaction of the period before
(:attr:`~aac_sumo.coordination.commitments.CommitmentBook.fallbacks`), and every robot whose
commitment or reaction that meets takes up its own in the same period; the reactions of every two
robots keep the margin (the exact check), so those that brake keep it from each other.

Frames and units: world frame [m], speeds [m/s], decelerations [m/s^2], periods of ``dt`` [s].
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.base import RobotDecision
from aac_sumo.coordination.commitments import stopping_commitment
from aac_sumo.coordination.traffic_courses import traffic_clearances
from aac_sumo.world import WorldState

#: Where a vehicle broke what the check assumes, a car on the reactive hold stops at the first of
#: these shares of its strongest braking that leaves the margin (about half of the highway's
#: strongest stops were SUMO cars cutting in ahead, whom a 3-4 m/s^2 stop lets pull away), else at
#: the one that leaves the most room.
HARDER_STOPS = (0.5, 2.0 / 3.0, 5.0 / 6.0, 1.0)

#: With ``reaction_brake``, a firmer stop is taken where no stop keeps the margin only if it
#: leaves at least this much more room [m].
ROOM_GAIN = 0.1

#: ... and only among the stops that drive at most this much [m] further from their first contact
#: with a vehicle ahead than the one that drives least.
CONTACT_GAIN = 0.5


class TrafficBraking:
    """The traffic-braking step of committed AAC (needs the coordinator's ``book``, ``fleet``,
    ``params``, ``planner``, ``last_inputs``, ``path``, ``tail_decel`` and
    ``continued_commitment``)."""

    def reaction_decel(self) -> np.ndarray:
        """Each robot's reaction deceleration [m/s^2] (``traffic_reaction``): ``reaction_brake``
        of its strongest braking, else its firm tail's (``firm_tail``), else its gentle tail's."""
        if self.params.reaction_brake > 0.0:
            return self.params.reaction_brake * -self.fleet.a_min
        return self.tail_decel(self.params.firm_tail > self.params.tail_brake)

    def held_decel(self, calm: float) -> np.ndarray:
        """Each robot's deceleration [m/s^2] the check holds it to behind an uncontrolled vehicle:
        its reaction's (``traffic_reaction``), else its gentle tail's within ``calm``, the
        comfort envelope of its continuation."""
        return self.reaction_decel() if self.params.traffic_reaction else np.minimum(self.tail_decel(), calm)

    def brake_for_traffic(self, world: WorldState, period: int, parked: np.ndarray, records: list[RobotDecision],
                          statics: np.ndarray) -> int:
        """Robots whose commitment already meets the braking course of an uncontrolled vehicle
        ahead (one that changed lanes into its way, or braked harder than ``traffic_decel``:
        outside what the check assumes), or with ``walker_brake`` a walker's region (a walker
        SUMO sets down beside the road, or one who leaves what the check assumed of her), renew
        their continuation where it passes the check (a faster car that cut in pulls away), and
        otherwise brake to a stop at once: with the gentle tail, else the firm one, where that
        keeps the margin from them, else at their strongest where that leaves more room; each
        only where it leaves more room than the commitment and keeps ``commit_margin`` from every
        other commitment and standing obstacle (mode ``traffic_brake``). Returns how many
        braked."""
        book, braked = self.book, 0
        strongest = -self.fleet.a_min
        walkers = book.walkers if self.params.walker_brake and book.walkers is not None and len(book.walkers.centres) else None

        def room(rows: np.ndarray, held: np.ndarray) -> float:  # least room [m] to the vehicles ahead and the walkers
            gap = book.traffic_gap(held, period) if book.traffic else np.inf
            return gap if walkers is None else min(gap, book.margin + walkers.slack(rows))

        for i in np.flatnonzero(~parked & world.on_road):
            own = book.items[i]
            current = room(book.footprints(i, own, period), book.traffic_rows(i, own, period))
            if current >= book.margin:
                continue
            renewed = self.continued_commitment(world, int(i), period, np.zeros((0, 2)), statics)
            if renewed is not None:  # it may drive on: the vehicle pulls away, or a firmer tail leaves the room
                book.replace(int(i), renewed, period)
                records[i].mode = "tracking"
                continue
            if book.reaction is not None and book.fallbacks is not None:  # the reaction it was held to, taken up
                braked += self.take_up_reaction(world, int(i), period, records, statics, room)
                continue
            decels = (self.tail_decel()[i], self.tail_decel(self.params.firm_tail > self.params.tail_brake)[i], strongest[i])
            choice = self.gentlest_stop(world, int(i), period, decels, current, statics, room)
            if choice is not None:
                book.replace(int(i), choice, period)
                records[i].mode = "traffic_brake"
                braked += 1
        if book.reaction is not None and book.fallbacks is not None:
            braked += self.brake_behind(world, period, parked, records, statics)
        return braked

    def gentlest_stop(self, world: WorldState, i: int, period: int, decels, room_now: float, statics: np.ndarray, room):
        """Robot ``i``'s stop from now at the first of ``decels`` [m/s^2] whose ``room`` to the
        vehicles ahead (and the walkers) reaches the margin, else at the one that leaves the most
        room above ``room_now`` [m]; each only where it keeps the margin from the other
        commitments and standing obstacles (braking is never refused for a walker). None when no
        stop leaves more room than ``room_now``."""
        book, best, choice = self.book, room_now, None
        for decel in decels:
            candidate = self.stop_from_now(world, i, period, float(decel))
            rows = book.footprints(i, candidate, period)
            gap = room(rows, rows)
            if gap > best and book.clearance(i, candidate, period, statics, walkers=False, traffic=False) >= book.margin:
                best, choice = gap, candidate
                if gap >= book.margin:
                    break
        return choice

    def stop_from_now(self, world: WorldState, i: int, period: int, decel: float):
        """Robot ``i``'s commitment to brake from now to a stop at ``decel`` [m/s^2] along its path."""
        return stopping_commitment(self.fleet, i, period, world.states[i], np.zeros((0, 2)), self.path(i), decel, self.last_inputs[i, 1],
                                   self.planner.config.dt)

    def take_up_reaction(self, world: WorldState, i: int, period: int, records: list[RobotDecision], statics: np.ndarray,
                         room) -> int:
        """Robot ``i``, whose reaction no longer keeps the margin from a vehicle ahead (or a
        walker), brakes: with its gentle tail from now where that passes the whole check (with
        ``reaction_brake``, then the firmer :meth:`graded_stops`), else on
        its fallback (its reaction of the period before, clear of that vehicle's course then, so
        of the vehicle now, as long as it keeps to what the check assumes), else, where a vehicle
        broke that assumption, as gently as ``HARDER_STOPS`` allows where that leaves more room
        and keeps the margin from the other commitments. Braking is never refused for a walker.
        Returns 1 when it braked."""
        book = self.book
        choice = self.graded_stop(world, i, period, statics, room)
        if choice is None and self.params.reaction_brake > 0.0:
            choice = self.least_harm_stop(world, i, period, statics, room)
        if choice is None:
            choice = book.fallbacks[i]
            rows = book.footprints(i, choice, period)
            if room(rows, rows) < book.margin:  # a vehicle cut in or braked harder than the check assumes: a harder stop
                decels = -np.asarray(HARDER_STOPS) * self.fleet.a_min[i]
                harder = self.gentlest_stop(world, i, period, decels, room(rows, rows), statics, room)
                choice = choice if harder is None else harder
        book.replace(i, choice, period)
        records[i].mode = "traffic_brake"
        return 1

    def graded_stops(self, i: int) -> np.ndarray:
        """Robot ``i``'s decelerations [m/s^2] to try before its reaction, gentlest first: its
        gentle tail, and with ``reaction_brake`` its firm tail and the ``HARDER_STOPS`` below
        its reaction's."""
        gentle = float(self.tail_decel()[i])
        if self.params.reaction_brake <= 0.0:
            return np.array([gentle])
        firmer = np.append(self.tail_decel(True)[i], -np.asarray(HARDER_STOPS) * self.fleet.a_min[i])
        return np.append(gentle, np.unique(firmer[(firmer > gentle) & (firmer < self.reaction_decel()[i])]))

    def graded_stop(self, world: WorldState, i: int, period: int, statics: np.ndarray, room=None):
        """Robot ``i``'s stop from now at the first of :meth:`graded_stops` that passes the whole
        check but the walkers' (and, with ``room``, keeps the margin to the vehicles ahead and the
        walkers), else None."""
        book = self.book
        for decel in self.graded_stops(i):
            candidate = self.stop_from_now(world, i, period, float(decel))
            if not self.clears_behind(i, candidate, period, statics):
                continue
            if room is None or room(book.footprints(i, candidate, period), book.traffic_rows(i, candidate, period)) >= book.margin:
                return candidate
        return None

    def least_harm_stop(self, world: WorldState, i: int, period: int, statics: np.ndarray, room):
        """Where no stop keeps the margin to a vehicle ahead (one that cut in, or braked harder
        than the check assumes) or a walker: of robot ``i``'s :meth:`graded_stops` that keep the
        margin from the other robots, its fallback and its reaction from now, those that drive
        least from their first contact with a vehicle ahead (within ``CONTACT_GAIN``,
        :meth:`contact_travel`: a slow car cutting in ahead is met slower, or not at all, the
        harder the car brakes), and of those the gentlest whose ``room`` comes
        within ``ROOM_GAIN`` of the most any leaves (braking harder where it gains nothing is
        discomfort alone: a car cutting in diagonally meets every stop alike)."""
        book = self.book
        options = [self.stop_from_now(world, i, period, float(d)) for d in self.graded_stops(i)]
        options = [c for c in options if self.clears_behind(i, c, period, statics, traffic=False)] + [book.fallbacks[i]]
        strongest = self.stop_from_now(world, i, period, float(self.reaction_decel()[i]))
        if self.clears_behind(i, strongest, period, statics, traffic=False):
            options.append(strongest)
        rows = [book.footprints(i, c, period) for c in options]
        contact = np.array([self.contact_travel(c, r, period) for c, r in zip(options, rows)])
        rooms = np.where(contact <= contact.min() + CONTACT_GAIN, [room(r, r) for r in rows], -np.inf)
        return options[int(np.flatnonzero(rooms >= rooms.max() - ROOM_GAIN)[0])]

    def contact_travel(self, commitment, rows: np.ndarray, period: int) -> float:
        """How far [m] the car drives along ``commitment`` (footprint ``rows`` from ``period`` on)
        from its first overlap with the braking course of a vehicle ahead
        (:func:`~aac_sumo.coordination.traffic_courses.traffic_clearances`) until it stands: how
        fast it meets it and how far into it; 0 without an overlap."""
        if not self.book.traffic:
            return 0.0
        overlap = np.flatnonzero(traffic_clearances(rows, self.book.traffic, self.book.lines) < 0.0)
        if overlap.size == 0:
            return 0.0
        speeds = np.abs(commitment.course(period, len(rows))[overlap[0]:, 3])
        return float(np.sum(speeds)) * self.planner.config.dt

    def clears_behind(self, i: int, candidate, period: int, statics: np.ndarray, traffic: bool = True) -> bool:
        """Whether robot ``i``'s stop ``candidate`` passes the check (the walkers' aside; without
        ``traffic``, the vehicles' too), where
        a robot whose commitment it meets may take up its fallback instead (with
        ``reaction_brake``; :meth:`brake_behind` then gives it that, or a gentler stop): a car
        that brakes need not wait for the cars behind it, whose reactions keep the margin from
        its own. The book is left as it was."""
        book, n, swapped = self.book, len(self.book.items), []
        try:
            while True:
                gap, j = book.check(i, candidate, period, statics, walkers=False, traffic=traffic)
                if gap >= book.margin:
                    return True
                if (self.params.reaction_brake <= 0.0 or not 0 <= j < n or book.fallbacks[j] is book.items[j]
                        or any(k == j for k, _ in swapped)):
                    return False
                swapped.append((j, book.items[j]))
                book.replace(j, book.fallbacks[j], period)
        finally:
            for j, c in reversed(swapped):
                book.replace(j, c, period)

    def brake_behind(self, world: WorldState, period: int, parked: np.ndarray, records: list[RobotDecision], statics: np.ndarray) -> int:
        """With ``traffic_reaction``: every robot whose commitment or reaction now comes within
        the margin of another robot's (one that braked for a vehicle, or whose reaction its own
        has caught up with) takes up its fallback, until none does (each at most once; robots
        on their fallbacks keep the margin from each other, as their reactions did). Returns how
        many did (mode ``traffic_brake``)."""
        book, n, count = self.book, len(self.book.items), 0
        taken = np.zeros(n, dtype=bool)
        active = np.flatnonzero(~parked & world.on_road)
        changed = True
        while changed:
            changed = False
            for j in active:
                if taken[j] or book.fallbacks[j] is book.items[j]:  # already on it: nothing to take up
                    continue
                gap, blocker = book.check(int(j), book.items[j], period, statics, walkers=False, traffic=False)
                if gap >= book.margin or not 0 <= blocker < n:
                    continue
                graded = self.graded_stop(world, int(j), period, statics) if self.params.reaction_brake > 0.0 else None
                book.replace(int(j), book.fallbacks[j] if graded is None else graded, period)
                records[j].mode = "traffic_brake"
                taken[j], changed = True, True
                count += 1
        return count
