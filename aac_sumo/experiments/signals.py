"""Traffic lights for controlled cars: a red or yellow signal ahead is a stop line the car must not cross.

SUMO's drivers treat a signal so: at green they go; when it turns yellow, a driver who can still
stop before the line at a comfortable deceleration stops, one who cannot drives on; at red
everyone stops. Here each stop line (one incoming lane's link of a traffic light, the lane's end
in SUMO's network frame [m]) is shown to the coordinators, while it holds traffic, as a standing
vehicle-sized box of kind ``signal`` just beyond the line: the committed plans, the anticipation
and the MPC then stop a car behind it as behind a standing car, and nothing crosses it.

When a line's signal leaves green, the cars that cannot stop before it at their comfort
deceleration are let through, and at yellow (with a :class:`YellowRule`) also those that would
need more than the rule's gentle deceleration to stop there but reach the line before the yellow
ends; the box appears once the last of them has passed it. With the rule's ``preview``, a line
holds already that long before its yellow (the light's program says when, :func:`green_left`):
the cars that reach the line before the yellow ends go on, chosen afresh each period while the
light is green, and the others stop, gently, before the yellow comes (a car 35-48 m before a line
at 13.9 m/s when a 3 s yellow begins could neither pass before red nor stop at 2 m/s^2). A car whose
front crosses a line while its signal shows red, or yellow when it was not let through (the line
held it), counts as a red-light violation.

Arc lengths [m] are along each car's own path (its rear axle's projection plus its front
overhang gives its front); a car's stop lines are those on its path ahead of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aac_sumo.world import Obstacle

#: SUMO's link states that let a car go (green with and without priority, off: no signal).
GO = frozenset("GgOo")
#: Those that stop it: red, red-yellow; yellow stops those that can stop comfortably.
RED = frozenset("rRu")
#: Length [m] of the box that stands for a stop line along the lane, and its width [m]: a car's,
#: so that a car passing in the next lane keeps its clearance from it.
BOX_LENGTH = 1.0
BOX_WIDTH = 1.8
#: A car let through a yellow by the gentle rule reaches the line at least this long [s] before
#: the yellow ends, at its speed when the yellow began.
YELLOW_SPARE = 0.5


def travel_time(distance: float, speed: float, accel: float, top: float) -> float:
    """Time [s] to cover ``distance`` [m] from ``speed`` [m/s], speeding up at ``accel`` [m/s^2]
    to at most ``top`` [m/s] (keeping ``speed`` when it is above ``top``)."""
    if distance <= 0.0:
        return 0.0
    speed = max(speed, 0.0)
    if speed >= top:
        return distance / max(speed, 1e-9)
    t_up = (top - speed) / accel
    d_up = 0.5 * (speed + top) * t_up
    if distance <= d_up:
        return (-speed + math.sqrt(speed * speed + 2.0 * accel * distance)) / accel
    return t_up + (distance - d_up) / top


def arrival_time(distance: float, speed: float, rate: float, top: float) -> float:
    """Time [s] for a car at ``speed`` [m/s] to reach a line ``distance`` [m] ahead where its path's
    speed is ``top`` [m/s]: speeding up to it at ``rate`` [m/s^2] (:func:`travel_time`), or, faster,
    keeping its speed until it slows to it at ``rate`` by the line (evenly, where it is already
    nearer than that)."""
    if speed <= top:
        return travel_time(distance, speed, rate, top)
    slowing = (speed * speed - top * top) / (2.0 * rate)
    if distance <= slowing:
        return 2.0 * max(distance, 0.0) / (speed + top)
    return (distance - slowing) / speed + (speed - top) / rate


def green_left(phases, phase: int, to_switch: float) -> list[float] | None:
    """Per link of a traffic light whose program runs ``phases`` (``(duration [s], state)``, SUMO's
    state strings) in a cycle, now in phase ``phase``, which ends in ``to_switch`` [s]: the time
    [s] until the link leaves green (:data:`GO`); 0 where it is not green now, inf where it is
    green round the whole cycle. None for a phase the program does not have."""
    if not 0 <= phase < len(phases):
        return None
    out = []
    for link, now in enumerate(phases[phase][1]):
        if now not in GO:
            out.append(0.0)
            continue
        t, k = max(float(to_switch), 0.0), (phase + 1) % len(phases)
        while k != phase and phases[k][1][link] in GO:
            t, k = t + float(phases[k][0]), (k + 1) % len(phases)
        out.append(math.inf if k == phase else t)
    return out


@dataclass(frozen=True)
class YellowRule:
    """Who goes on through a yellow besides those that cannot stop at their comfort deceleration:
    a car that would need more than ``decel`` [m/s^2] to stop with ``slack`` [m] and one period
    ``dt`` [s] of travel to spare before the line, and whose front reaches the line at its speed
    ``YELLOW_SPARE`` before the shortest yellow of the line's light ends (``yellow``: traffic
    light id -> that duration [s]; a light without one lets no one through so). With ``preview``
    > 0 [s] a line holds that long before its yellow begins: a car goes on if it reaches the line
    ``YELLOW_SPARE`` before the yellow ends (:func:`arrival_time` at ``accel`` [m/s^2] to its path's
    speed at the line)."""

    decel: float
    slack: float
    dt: float
    yellow: dict[str, float]
    preview: float = 0.0
    accel: float = 1.5

    def goes_on(self, tls: str, speed: float, d: float, before: float = 0.0, top: float = math.inf) -> bool:
        """Whether a car at ``speed`` [m/s] whose front is ``d`` [m] before a line of light
        ``tls`` that has just turned yellow goes on; or, ``before`` [s] > 0 before the yellow
        begins, a car whose path's speed at the line is ``top`` [m/s] (inf: it keeps its speed)."""
        ends = before + self.yellow.get(tls, 0.0) - YELLOW_SPARE
        if before > 0.0:
            return arrival_time(d, speed, self.accel, top if math.isfinite(top) else speed) < ends
        spare = d - speed * self.dt - self.slack
        return self.decel > 0.0 and speed * speed > 2.0 * self.decel * spare and d < speed * ends


@dataclass(frozen=True)
class Line:
    """One stop line: traffic light ``tls``, its link index ``link``, the incoming ``lane`` id,
    the line's centre ``point`` (2,) [m] and the lane's ``heading`` [rad] there."""

    tls: str
    link: int
    lane: str
    point: np.ndarray
    heading: float

    @property
    def key(self) -> tuple[str, int, str]:
        return self.tls, self.link, self.lane

    def box(self) -> Obstacle:
        """The standing box just beyond the line (its back edge on it)."""
        direction = np.array([np.cos(self.heading), np.sin(self.heading)])
        return Obstacle(f"signal {self.tls} {self.link} {self.lane}", "signal", self.point + 0.5 * BOX_LENGTH * direction, np.zeros(2),
                        self.heading, BOX_LENGTH, BOX_WIDTH)


class Holds:
    """Boxes for stop lines that hold traffic, with the yellow rule: when a line starts to hold, the
    cars that can no longer stop before it at their comfort deceleration go on (``through``), and
    its box appears once the last of them has passed it. The links of one lane share its line: a
    box appears only once no car of any of them stands over it or has yet to pass it (the box of a
    straight link that turned yellow came down on a right-turning car of the same lane that had
    just crossed the line, which then braked at 5 m/s^2: the city's seed 3, aac.1)."""

    def __init__(self, yellow: YellowRule | None = None):
        self.yellow = yellow  # who else goes on at yellow (None: the comfort rule alone)
        self.lines: dict[tuple[str, int, str], Line] = {}
        self.through: dict[tuple[str, int, str], set[int]] = {}  # per line that holds: the cars let through

    def boxes(self, holding: dict[tuple[str, int, str], bool], seen: dict[tuple[str, int, str], list[tuple[int, float]]],
              speeds: np.ndarray, comfort: np.ndarray, lengths: np.ndarray, amber: frozenset = frozenset(),
              early: dict[tuple[str, int, str], float] | None = None, tops: np.ndarray | None = None) -> list[Obstacle]:
        """The boxes of the lines (keys of :attr:`lines`) that are ``holding``; ``seen``: per line,
        the cars near it and their fronts' distances to it [m] (negative: beyond it); ``speeds``
        [m/s], ``comfort`` decelerations [m/s^2] and ``lengths`` [m] per car; ``amber``: the
        lines that show yellow, to which :attr:`yellow` applies; ``early``: the lines that hold
        before their yellow, with the time [s] until it begins (who goes on is chosen afresh each
        period, by :attr:`yellow` with each car's path speed at the line, ``tops`` [m/s])."""
        early = {} if early is None else early
        covered = set()  # lanes whose line a car stands over or a car let through has yet to pass, whichever link it takes
        for key, cars in seen.items():
            if any(-(lengths[k] + BOX_LENGTH) < d < 0.0 for k, d in cars):  # a box there would overlap it
                covered.add(key[2])
            if not holding[key]:
                self.through.pop(key, None)
                continue
            if key not in self.through or key in early:  # it has just started to hold: who can no longer stop comfortably goes on
                gentle, before = (self.yellow if key in amber or key in early else None), early.get(key, 0.0)
                passed = {k for k, d in cars if d < 0.0 and k in self.through.get(key, ())}
                self.through[key] = passed | {k for k, d in cars if d >= 0.0 and (speeds[k] ** 2 > 2.0 * comfort[k] * d or (
                    gentle is not None and gentle.goes_on(key[0], float(speeds[k]), d, before, math.inf if tops is None else float(tops[k]))))}
            if any(k in self.through[key] and d > -(lengths[k] + BOX_LENGTH) for k, d in cars):
                covered.add(key[2])
        return [self.lines[key].box() for key in seen if holding[key] and key[2] not in covered]


class Signals:
    """The stop lines of the controlled cars and what each shows; ``violations`` counts red-light
    violations (see the module)."""

    def __init__(self, yellow: YellowRule | None = None):
        self.holds = Holds(yellow)
        self.before: dict[tuple[int, tuple[str, int, str]], tuple[float, str]] = {}  # (car, line) -> (its front's distance to it [m], state) last period
        self.violations = 0

    def boxes(self, states: dict[str, str], approach: dict[int, list[tuple[Line, float]]], speeds: np.ndarray,
              comfort: np.ndarray, lengths: np.ndarray, leaving: dict[str, list[float] | None] | None = None,
              tops: np.ndarray | None = None) -> list[Obstacle]:
        """The boxes of this period's stop lines that hold traffic. ``states``: each traffic
        light's link states (SUMO's string); ``approach``: per car on the road, its stop lines
        with the distance [m] from its front to each (negative: beyond it); ``speeds`` [m/s],
        ``comfort`` decelerations [m/s^2] and ``lengths`` [m] per car. With the yellow rule's
        ``preview``: ``leaving``, per light, the time [s] until each link leaves green
        (:func:`green_left`), and ``tops``, each car's path speed at its next line [m/s]. Counts
        the violations since the last period."""
        seen: dict[tuple[str, int, str], list[tuple[int, float]]] = {}
        for k, lines in approach.items():
            for line, d in lines:
                self.holds.lines.setdefault(line.key, line)
                seen.setdefault(line.key, []).append((k, d))
                last = self.before.get((k, line.key))
                if last is not None and last[0] >= 0.0 > d and (last[1] in RED or (last[1] not in GO and k not in self.holds.through.get(line.key, ()))):
                    self.violations += 1
                self.before[(k, line.key)] = (d, states[line.tls][line.link])
        holding = {key: states[key[0]][key[1]] not in GO for key in seen}
        amber = frozenset(key for key in seen if states[key[0]][key[1]] in "yY")
        early = {}
        rule = self.holds.yellow
        if rule is not None and rule.preview > 0.0 and leaving:
            for key in seen:
                left = leaving.get(key[0])
                if not holding[key] and left is not None and key[1] < len(left) and left[key[1]] <= rule.preview:
                    early[key], holding[key] = left[key[1]], True
        return self.holds.boxes(holding, seen, speeds, comfort, lengths, amber, early, tops)
