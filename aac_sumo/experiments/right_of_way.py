"""Right of way at junctions for controlled cars: a car whose link must yield waits at its line
while a foe with priority could reach the junction before the car has left it.

SUMO's junction logic says, per link of a junction, which other links it must yield to (the
network's ``<request response=...>``, read by sumolib's ``Node.forbids``). A link must yield
when its state says so: ``g`` (green without priority) or ``o`` at a traffic light, ``m``, ``s``,
``=`` or ``w`` at a junction without one; ``G``, ``O`` and ``M`` have priority, and red or yellow
is the signal's stop line (:mod:`aac_sumo.experiments.signals`). At an ``unregulated`` junction
SUMO's drivers yield to no one, so a controlled car yields there to every connection whose way
crosses or joins its own (nobody yields to it); such a junction counts no violation. Two
controlled cars whose links must yield to each other go in the order they reach their lines
(:meth:`RightOfWay.giving_way`).

A foe is a vehicle on a prohibiting link's incoming lane (unless its signal shows red) or inside
the junction on that link's internal lanes. A car approaching a line that must yield sees it as a
standing box (the signals' box, :class:`~aac_sumo.experiments.signals.Holds`, with their yellow
rule: a car that can no longer stop comfortably when the line starts to hold goes on) while a foe
could reach its own line before the car has left the junction plus ``gap`` [s]: the foe at most
speeding up at ``FOE_ACCEL`` to ``FOE_SPEED_FACTOR`` times its lane's limit, the car from its speed
at ``accel`` [m/s^2] up to the junction's speed cap, over its distance to the line, the junction
and its own length. Walkers on crossings are the walker checks' (the committed plans never enter a
walker's reach), not this module's.

``right_of_way_violations`` counts the cars (ours or SUMO's driver's alike) that entered a
junction over a link that must yield while a foe with priority, keeping its speed, reached its
line (or was inside) before the car had left the junction.

Positions in SUMO's network frame [m]; arc lengths along each car's own path [m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aac_sumo.experiments.junction_routes import RoutePath, internal_lanes
from aac_sumo.experiments.signals import Holds, Line, travel_time
from aac_sumo.network import VEHICLE_CLASS, car_lanes
from aac_sumo.sim.sumo_reading import polylines_cross

#: Link states of a connection that must yield to the links its request names.
MINOR = frozenset("gomsw=")
#: A foe's signal states that keep its approaching vehicles out of the junction.
STOPPED = frozenset("rR")
#: A foe is taken to speed up at most at this [m/s^2] (SUMO's default passenger car's accel) ...
FOE_ACCEL = 2.6
#: ... to at most this share of its lane's speed limit (SUMO's speed factors reach 1.2).
FOE_SPEED_FACTOR = 1.2


#: A foe is looked for this far [m] up its incoming lanes (through the junctions before them).
LOOKBACK = 150.0


@dataclass(frozen=True)
class Foe:
    """A link with priority over a car's: its incoming ``approach`` lane id and length [m], the
    ``upstream`` lanes that lead into it, each ``(id, distance [m] from its end to the link's line,
    its length [m])`` (within ``LOOKBACK``), its internal lanes ``inside``, its lane's speed limit
    [m/s] and its signal (``tls`` '' without)."""

    approach: str
    length: float
    upstream: tuple[tuple[str, float, float], ...]
    inside: tuple[str, ...]
    speed: float
    tls: str
    link: int

    @property
    def lanes(self) -> tuple[tuple[str, float, float], ...]:
        """Its incoming lanes as ``upstream``'s, the approach first."""
        return ((self.approach, 0.0, self.length), *self.upstream)


def _upstream(lane, lookback: float) -> tuple[tuple[str, float, float], ...]:
    """The lanes that lead into ``lane`` (through the junction before it; those inside it too),
    each with the distance [m] from its end to ``lane``'s end, while that is under ``lookback``,
    and its length [m]."""
    out, todo, seen = [], [(lane, 0.0)], {lane.getID()}
    while todo:
        here, to_end = todo.pop()
        ahead = to_end + here.getLength()
        if ahead >= lookback:
            continue
        for before in here.getIncoming():
            if before.getID() not in seen and before.getEdge().getFunction() in ("", "internal") and before.allows(VEHICLE_CLASS):
                seen.add(before.getID())
                out.append((before.getID(), ahead, before.getLength()))
                todo.append((before, ahead))
    return tuple(out)


@dataclass(frozen=True)
class YieldLine:
    """One junction link on a car's way: its ``line`` (the incoming lane's end), its signal ``tls``
    and link index ``tl_link`` ('' and -1 without), its static ``state`` (SUMO's link state, read
    without a signal), the arc lengths ``s_in``, ``s_out`` [m] of the junction on the car's path,
    the path's lowest speed cap ``speed`` [m/s] in it, whether it ``counts`` for the metric (not at
    an unregulated junction), and its ``foes``."""

    line: Line
    tls: str
    tl_link: int
    state: str
    s_in: float
    s_out: float
    speed: float
    counts: bool
    foes: tuple[Foe, ...]


def _shape(net, lanes: tuple[str, ...]) -> np.ndarray:
    return np.vstack([np.asarray(net.getLane(lane).getShape(), dtype=float)[:, :2] for lane in lanes]) if lanes else np.zeros((0, 2))


def _foes(net, node, conn) -> tuple[list, bool]:
    """The connections with priority over ``conn`` at ``node`` (car connections only, one per
    incoming and outgoing lane), and whether they count for the metric."""
    others = [c for c in node.getConnections() if c.getFrom().getFunction() == "" and c.getFromLane().allows(VEHICLE_CLASS)
              and c.getToLane().allows(VEHICLE_CLASS) and c.getFromLane() != conn.getFromLane()]
    if node.getType() == "unregulated":
        mine = _shape(net, internal_lanes(net, conn))
        return [c for c in others if c.getToLane() == conn.getToLane() or polylines_cross(mine, _shape(net, internal_lanes(net, c)))], False
    found = []
    for c in others:
        try:
            if node.forbids(c, conn):
                found.append(c)
        except KeyError:  # a junction without requests: no one yields
            return [], True
    return found, True


def may_hold(net, edge: str, nxt: str) -> bool:
    """Whether a car going from ``edge`` to ``nxt`` (edge ids) may have to wait at the junction
    between them, on any lane it may take: at a traffic light, or where its link has foes it
    yields to (:func:`yield_lines`' rule, every crossing way at an unregulated junction)."""
    a = net.getEdge(edge)
    return any(c.getTLSID() or _foes(net, a.getToNode(), c)[0] for c in a.getConnections(net.getEdge(nxt))
               if c.getFromLane().allows(VEHICLE_CLASS) and c.getToLane().allows(VEHICLE_CLASS))


def yield_lines(net, path: RoutePath) -> list[tuple[YieldLine, float]]:
    """Each junction link on ``path`` that may have to yield, with the line's arc length [m]."""
    out, arc = [], np.r_[0.0, np.cumsum(np.hypot(*np.diff(path.points, axis=0).T))]
    for leg, after, span in zip(path.legs, path.legs[1:], path.junctions):
        from_lane, to_lane = car_lanes(net.getEdge(leg.edge))[leg.leave], car_lanes(net.getEdge(after.edge))[after.arrive]
        conn = next(c for c in from_lane.getOutgoing() if c.getToLane() == to_lane)
        node = net.getNode(leg.junction)
        foes, counts = _foes(net, node, conn)
        if not foes:
            continue
        seen, kept = set(), []
        for c in foes:
            key = (c.getFromLane().getID(), c.getToLane().getID())
            if key not in seen:
                seen.add(key)
                kept.append(Foe(c.getFromLane().getID(), c.getFromLane().getLength(), _upstream(c.getFromLane(), LOOKBACK), internal_lanes(net, c),
                                c.getFromLane().getSpeed(), c.getTLSID(), c.getTLLinkIndex()))
        (x0, y0), (x1, y1) = np.asarray(from_lane.getShape(), dtype=float)[-2:, :2]
        line = Line(f"yield {leg.junction}", node.getLinkIndex(conn), from_lane.getID(), np.array([x1, y1]), float(np.arctan2(y1 - y0, x1 - x0)))
        inside = (arc >= span.s_in) & (arc <= span.s_out)
        speed = float(path.limits[inside].min()) if inside.any() else float(path.limits[np.searchsorted(arc, span.s_in)])
        out.append((YieldLine(line, leg.tls, leg.link, conn.getState(), span.s_in, span.s_out, speed, counts, tuple(kept)), span.s_in))
    return out


def clear_time(to_line: float, through: float, speed: float, accel: float, top: float) -> float:
    """Time [s] for a car ``to_line`` [m] before a junction whose speed cap is ``top`` [m/s] to
    cover ``to_line`` and then ``through`` [m] (the junction and its own length), from ``speed``
    [m/s] speeding up at ``accel`` [m/s^2]. A car faster than the cap reaches the line at most at
    its own speed and goes through at the cap."""
    if speed <= top:
        return travel_time(to_line + through, speed, accel, top)
    return max(to_line, 0.0) / speed + through / top


class RightOfWay:
    """The yield lines' boxes and the violations (see the module); ``gap`` [s] is the car's time
    margin before a foe's arrival, ``accel`` [m/s^2] how fast a car is taken to speed up."""

    def __init__(self, gap: float, accel: float):
        self.gap, self.accel = gap, accel
        self.holds = Holds()
        self.before: dict[tuple[int, tuple], float] = {}  # (car, line) -> its front's distance to the line last period [m]
        self.pending: dict[tuple[int, tuple], tuple[float, float]] = {}  # (car, line) -> (s_out - s_in [m], earliest foe arrival [s])
        self.violations = 0

    @staticmethod
    def lanes(approach: dict[int, list[tuple[YieldLine, float]]]) -> tuple[str, ...]:
        """The lanes whose vehicles :meth:`boxes` reads."""
        return tuple(sorted({lane for lines in approach.values() for y, _ in lines for foe in y.foes
                             for lane in (*(lane for lane, _, _ in foe.lanes), *foe.inside)}))

    @staticmethod
    def minor(y: YieldLine, states: dict[str, str]) -> bool:
        """Whether ``y``'s link must yield now: its signal's state, or its static one; always at an
        unregulated junction (``counts`` false)."""
        return not y.counts or (states[y.tls][y.tl_link] if y.tls else y.state) in MINOR

    def arrivals(self, y: YieldLine, states: dict[str, str], vehicles: dict[str, list[tuple[str, float, float]]], me: str,
                 keep_speed: bool, waiting: frozenset[str] = frozenset()) -> float:
        """The earliest time [s from now] a foe of ``y`` reaches its line (0: inside): speeding up
        as the module says, or ``keep_speed``; inf without foes. A foe link whose first vehicle is
        one of ``waiting`` (controlled cars that give way to this one) brings no one: those behind
        it wait too."""
        first = math.inf
        for foe in y.foes:
            if any(vid != me for lane in foe.inside for vid, _, _ in vehicles.get(lane, ())):
                return 0.0
            if foe.tls and states[foe.tls][foe.link] in STOPPED:
                continue
            coming = sorted((to_line + max(length - pos, 0.0), vid, speed) for lane, to_line, length in foe.lanes
                            for vid, pos, speed in vehicles.get(lane, ()) if vid != me)
            if coming and coming[0][1] in waiting:
                continue
            for room, _, speed in coming:
                t = room / speed if keep_speed and speed > 0.1 else math.inf if keep_speed else \
                    travel_time(room, speed, FOE_ACCEL, FOE_SPEED_FACTOR * foe.speed)
                first = min(first, t)
        return first

    def giving_way(self, nearest: dict[tuple, tuple[int, float]], ylines: dict[tuple, YieldLine], names: list[str],
                   speeds: np.ndarray, comfort: np.ndarray, hardest: np.ndarray) -> dict[tuple, frozenset[str]]:
        """Per line, the controlled cars that give way to its first car ``k``: where two links must
        yield to each other (at an unregulated junction every crossing pair), the car that reaches
        its line first at ``accel`` goes (ties by name), as SUMO's all-way stops do, and the other
        waits, if it can still stop before its line (at ``comfort`` [m/s^2], at an unregulated
        junction ``hardest``, as :meth:`boxes` lets cars through) and was not let through.
        ``nearest``: per line, its first car and that car's front's distance to it [m]. Without
        this, two cars facing each other at an unregulated junction each wait for the other."""
        entries = {}
        for key, (k, d) in nearest.items():
            y = ylines[key]
            entries[key] = (travel_time(d, float(speeds[k]), self.accel, y.speed), names[k])
        out = {}
        for key, (k, _) in nearest.items():
            y, mine = ylines[key], entries[key]
            out[key] = frozenset(
                entries[other][1] for other, (j, d) in nearest.items()
                if other != key and ylines[other].line.tls == y.line.tls and entries[other] > mine
                and any(foe.approach == y.line.lane for foe in ylines[other].foes)
                and any(foe.approach == ylines[other].line.lane for foe in y.foes)
                and speeds[j] ** 2 < 2.0 * (comfort if ylines[other].counts else hardest)[j] * d
                and j not in self.holds.through.get(other, ()))
        return out

    def boxes(self, t: float, approach: dict[int, list[tuple[YieldLine, float]]], states: dict[str, str],
              vehicles: dict[str, list[tuple[str, float, float]]], names: list[str], speeds: np.ndarray, comfort: np.ndarray,
              lengths: np.ndarray, hardest: np.ndarray | None = None) -> list:
        """The boxes of the yield lines that hold now. ``approach``: per car on the road, its
        yield lines with its front's distance [m] to each (negative: beyond it, until its rear
        has left the junction); ``states``: the signals' link states; ``vehicles``: per lane of
        :meth:`lanes`, ``(id, front's lane position [m], speed [m/s])``; ``names`` SUMO's ids,
        ``speeds`` [m/s], ``comfort`` decelerations [m/s^2], ``lengths`` [m] per car. A line that
        starts to hold lets through the cars that cannot stop before it at ``comfort``; at an
        unregulated junction (foes seen late: a source lane's start may lie near) only those that
        cannot stop at ``hardest`` [m/s^2] (default ``comfort``). Counts the violations of cars
        whose rear left a junction since the last period."""
        seen: dict[tuple, list[tuple[int, float]]] = {}
        ylines: dict[tuple, YieldLine] = {}
        for k, lines in approach.items():
            for y, d in lines:
                key = y.line.key
                ylines[key] = y
                self.holds.lines.setdefault(key, y.line)
                seen.setdefault(key, []).append((k, d))
                self.count(t, k, y, d, states, vehicles, names[k], float(lengths[k]))
        nearest = {key: min((d, k) for k, d in cars if d >= 0.0)[::-1] for key, cars in seen.items()
                   if any(d >= 0.0 for _, d in cars) and self.minor(ylines[key], states)}
        waiting = self.giving_way(nearest, ylines, names, speeds, comfort, comfort if hardest is None else hardest)
        holding = dict.fromkeys(seen, False)
        for key, (k, d) in nearest.items():
            y = ylines[key]
            clear = clear_time(d, (y.s_out - y.s_in) + float(lengths[k]), float(speeds[k]), self.accel, y.speed)
            holding[key] = self.arrivals(y, states, vehicles, names[k], False, waiting[key]) < clear + self.gap
        regulated = {key: cars for key, cars in seen.items() if ylines[key].counts}
        unregulated = {key: cars for key, cars in seen.items() if not ylines[key].counts}
        return (self.holds.boxes(holding, regulated, speeds, comfort, lengths)
                + self.holds.boxes(holding, unregulated, speeds, comfort if hardest is None else hardest, lengths))

    def count(self, t: float, k: int, y: YieldLine, d: float, states: dict[str, str], vehicles: dict, name: str,
              length: float) -> None:
        """Car ``k`` at distance ``d`` [m] from ``y``'s line at ``t`` [s]: on entering over a link
        that must yield, the foes' earliest arrival keeping their speeds; once its rear has left
        the junction, a violation if that arrival came first."""
        key = (k, y.line.key)
        last, self.before[key] = self.before.get(key), d
        if y.counts and last is not None and last >= 0.0 > d and self.minor(y, states):
            self.pending[key] = (y.s_out - y.s_in, t + self.arrivals(y, states, vehicles, name, True))
        if key in self.pending and d < -(self.pending[key][0] + length):
            self.violations += int(self.pending.pop(key)[1] < t)
