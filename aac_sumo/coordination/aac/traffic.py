"""Braking for SUMO's cars that leave what the exact check assumes of them (a mixin of
:class:`~aac_sumo.coordination.aac.committed.CommittedAac`).

The check holds an uncontrolled vehicle ahead as braking at ``aac.traffic_decel`` along its
lane (:func:`~aac_sumo.coordination.commitments.braking_courses`). One that changes lanes into a
car's way, or brakes harder, can leave a car's commitment running into its course; that car
then renews its continuation, or brakes.

Frames and units: world frame [m], speeds [m/s], decelerations [m/s^2], periods of ``dt`` [s].
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.base import RobotDecision
from aac_sumo.coordination.commitments import stopping_commitment
from aac_sumo.world import WorldState


class TrafficBraking:
    """The traffic-braking step of committed AAC (needs the coordinator's ``book``, ``fleet``,
    ``params``, ``planner``, ``last_inputs``, ``path``, ``tail_decel`` and
    ``continued_commitment``)."""

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
            best, choice = current, None
            for decel in (self.tail_decel()[i], self.tail_decel(self.params.firm_tail > self.params.tail_brake)[i], strongest[i]):
                candidate = stopping_commitment(self.fleet, i, period, world.states[i], np.zeros((0, 2)), self.path(i), decel,
                                                self.last_inputs[i, 1], self.planner.config.dt)
                if book.clearance(i, candidate, period, statics, walkers=False, traffic=False) < book.margin:
                    continue  # braking is never refused for a walker, but it keeps the commitments apart
                rows = book.footprints(i, candidate, period)
                gap = room(rows, rows)
                if gap > best:
                    best, choice = gap, candidate
                if gap >= book.margin:
                    break
            if choice is not None:
                book.replace(int(i), choice, period)
                records[i].mode = "traffic_brake"
                braked += 1
        return braked
