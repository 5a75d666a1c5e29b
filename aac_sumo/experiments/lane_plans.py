"""A routed car's lane plan (:mod:`aac_sumo.experiments.routed_cars`): the stretches the cones
close, the lane changes out of them and towards the exit lane, and the path and lateral band that
follow from them. Each change is a quintic smoothstep from one smoothed lane line onto the next;
the band is the lane the car is in, opening onto the next lane ``BAND_SETTLE`` metres before a
change begins and closing onto it as far beyond its end."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from aac_sumo import network
from aac_sumo.experiments.lane_geometry import BAND_SETTLE, SAMPLE_STEP, offset_polyline, smoothstep
from aac_sumo.geometry import along
from aac_sumo.references import LateralBand, PathReference

END_MARGIN = 15.0  # a car has finished this far before the end of its route [m]
CLUSTER_GAP = 60.0  # cones of one lane closer than this along it close one stretch [m]


class Change(NamedTuple):
    """One lane change of a car's plan: onto road lane ``lane``, beginning at arc length
    ``begin`` [m of the car's start lane] over ``length`` [m], and beginning at ``latest`` [m]
    at the latest. ``kind``: ``closure`` (out of a lane the cones close: it must happen),
    ``exit`` (towards the exit lane: given up as a last resort) or ``back`` (turning back from a
    change whose gap closed: not judged)."""

    lane: int
    begin: float
    length: float
    latest: float
    kind: str


def closures(rd: network.Road, centres: list[np.ndarray]) -> dict[int, list[tuple[float, float]]]:
    """Per road lane, the stretches ``(first, last)`` [m of arc length along the lane] that cones
    standing on it (within half its width of its centre line) close."""
    lines = [PathReference(line, 1.0, stop_at_end=False) for line in rd.lanes]
    at: dict[int, list[float]] = {}
    for c in centres:
        fits = [line.project(c) for line in lines]
        lane = int(np.argmin([lateral for _, lateral in fits]))
        s, lateral = fits[lane]
        if lateral <= 0.5 * rd.widths[lane] and 0.0 < s < rd.length(lane):
            at.setdefault(lane, []).append(s)
    out: dict[int, list[tuple[float, float]]] = {}
    for lane, ss in at.items():
        ss = sorted(ss)
        runs = [[ss[0], ss[0]]]
        for s in ss[1:]:
            if s - runs[-1][1] < CLUSTER_GAP:
                runs[-1][1] = s
            else:
                runs.append([s, s])
        out[lane] = [(a, b) for a, b in runs]
    return out


def lane_plan(rd: network.Road, start: int, s0: float, closed: dict[int, list[tuple[float, float]]], exit_lane: int | None,
              change_start: float, change_length: float, lead: float, margin: float, window: float = 0.0) -> list[Change]:
    """The lane changes of a car at arc length ``s0`` of lane ``start`` (see the module's rules;
    arc lengths along lane ``start``)."""
    def scale(lane: int) -> float:  # arc length on lane ``start`` per metre of ``lane``
        return rd.length(start) / rd.length(lane)

    changes: list[Change] = []
    lane, free_from = start, s0 + change_start
    ahead = [(a * scale(start), b * scale(start)) for a, b in closed.get(start, []) if b * scale(start) > s0]
    if ahead:
        first, last = ahead[0]
        def is_open(j):
            return all(b * scale(j) < first or a * scale(j) > last for a, b in closed.get(j, []))
        options = sorted((j for j in range(rd.n_lanes) if j != start and is_open(j)), key=lambda j: (abs(j - start), -j))
        if options:
            lane = options[0]
            length = change_length * abs(lane - start)
            latest = max(free_from, first - lead - length)
            changes.append(Change(lane, max(free_from, latest - window), length, latest, "closure"))
            free_from = changes[-1].begin + length
    ends = [b * scale(j) for j, stretches in closed.items() for a, b in stretches if b * scale(j) > s0]
    if exit_lane is not None and exit_lane != lane:
        begin = max(free_from, max(ends, default=-np.inf) + margin)
        steps = abs(exit_lane - lane)
        for k in range(steps):
            latest = rd.length(start) - END_MARGIN - (steps - k) * change_length
            changes.append(Change(lane + (k + 1) * (1 if exit_lane > lane else -1), begin + k * change_length, change_length,
                                  max(latest, begin + k * change_length), "exit"))
    return changes


def planned_path(rd: network.Road, start: int, s0: float, changes: list[Change]) -> tuple[np.ndarray, np.ndarray]:
    """Rear-axle waypoints (M, 2) [m] from arc length ``s0`` of lane ``start`` to the road's end,
    moving onto each change's lane with a quintic smoothstep (lane positions matched by their
    share of the lane's length, so curved roads work), and the arc length (M,) [m] of lane
    ``start`` of each."""
    la = rd.length(start)
    s = np.r_[np.arange(s0, la, SAMPLE_STEP), la]
    points = along(rd.lanes[start], s)[0]
    for c in changes:
        there = along(rd.lanes[c.lane], s * rd.length(c.lane) / la)[0]
        w = smoothstep((s - c.begin) / c.length)[:, None]
        points = (1.0 - w) * points + w * there
    return points, s


def planned_band(rd: network.Road, start: int, changes: list[Change], margin: float) -> LateralBand:
    """The band over the lane the car is in at each arc length of lane ``start``: it opens onto
    a change's lane over ``BAND_SETTLE`` metres before the change begins, and closes onto it over
    as many beyond its end; ``margin`` [m] inside the edges."""
    la = rd.length(start)
    s = np.r_[np.arange(0.0, la, SAMPLE_STEP), la]

    def edge(lane: int, side: float) -> np.ndarray:  # side -1: its right edge, +1: its left edge
        line = offset_polyline(rd.lanes[lane], 0.5 * side * rd.widths[lane])
        return along(line, s * float(np.hypot(*np.diff(line, axis=0).T).sum()) / la)[0]

    right, left, lane = edge(start, -1.0), edge(start, 1.0), start
    for c in changes:
        opening = smoothstep((s - c.begin + BAND_SETTLE) / BAND_SETTLE)[:, None]
        closing = smoothstep((s - c.begin - c.length) / BAND_SETTLE)[:, None]
        w_right, w_left = (closing, opening) if c.lane > lane else (opening, closing)
        right = (1.0 - w_right) * right + w_right * edge(c.lane, -1.0)
        left = (1.0 - w_left) * left + w_left * edge(c.lane, 1.0)
        lane = c.lane
    return LateralBand(right, left, margin)


@dataclass
class LanePlan:
    """A car's lanes as they stand: its (smoothed) road, start lane and arc length at its
    departure, the changes begun (``done``, they shape its path so far; the last may be under
    way) and those ahead. ``accepted``: the next change's gap was safe at the last judgement;
    ``waiting``: a change was postponed, and the car slows until it has changed when ``slow``;
    ``crossed``: the last change begun has reached its lane (no turning back); ``courtesy_for``:
    the car it lets in ahead of it (-1: none), coming down to that one's speed ``courtesy_v``
    [m/s] at arc length ``courtesy`` [m] (of its start lane)."""

    road: network.Road
    start: int
    s0: float
    done: list[Change] = field(default_factory=list)
    ahead: list[Change] = field(default_factory=list)
    accepted: bool = False
    waiting: bool = False
    slow: bool = True
    crossed: bool = True
    courtesy_for: int = -1
    courtesy: float = -np.inf
    courtesy_v: float = 0.0

    def lane(self) -> int:
        """The lane of the last change begun (the start lane before any)."""
        return self.done[-1].lane if self.done else self.start

    def origin(self) -> int:
        """The lane the last change begun leaves."""
        return self.done[-2].lane if len(self.done) > 1 else self.start

    def final(self) -> int:
        """The lane of the last change planned."""
        return (self.done + self.ahead)[-1].lane if self.done or self.ahead else self.start

    def moving(self) -> bool:
        """Whether a change is under way or the next one's gap was accepted (:meth:`intents` may hold lanes)."""
        return not self.crossed or (bool(self.ahead) and self.accepted)

    def intents(self, s: float, preview: float) -> set[int]:
        """The lanes the car is moving into at arc length ``s`` [m]: those a change under way
        crosses, or those of the next change when its gap was accepted within ``preview`` [m]."""
        if self.done and not self.crossed and s < self.done[-1].begin + self.done[-1].length:
            return crossed_lanes(self.origin(), self.done[-1].lane)
        if self.ahead and self.accepted and s + preview >= self.ahead[0].begin:
            return crossed_lanes(self.lane(), self.ahead[0].lane)
        return set()

    def postpone(self, begin: float) -> None:
        """The next change begins at ``begin`` [m], those after it no sooner than their
        predecessor ends."""
        self.ahead[0] = self.ahead[0]._replace(begin=begin)
        for k in range(1, len(self.ahead)):
            prev = self.ahead[k - 1]
            self.ahead[k] = self.ahead[k]._replace(begin=max(self.ahead[k].begin, prev.begin + prev.length))


def crossed_lanes(a: int, b: int) -> set[int]:
    """The lanes a change from lane ``a`` to lane ``b`` moves into."""
    return set(range(min(a, b), max(a, b) + 1)) - {a}
