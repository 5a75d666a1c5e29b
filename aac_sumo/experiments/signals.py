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
ends; the box appears once the last of them has passed it. A car whose
front crosses a line while its signal shows red, or yellow when it was not let through (the line
held it), counts as a red-light violation.

Arc lengths [m] are along each car's own path (its rear axle's projection plus its front
overhang gives its front); a car's stop lines are those on its path ahead of it.
"""

from __future__ import annotations

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


@dataclass(frozen=True)
class YellowRule:
    """Who goes on through a yellow besides those that cannot stop at their comfort deceleration:
    a car that would need more than ``decel`` [m/s^2] to stop with ``slack`` [m] and one period
    ``dt`` [s] of travel to spare before the line, and whose front reaches the line at its speed
    ``YELLOW_SPARE`` before the shortest yellow of the line's light ends (``yellow``: traffic
    light id -> that duration [s]; a light without one lets no one through so)."""

    decel: float
    slack: float
    dt: float
    yellow: dict[str, float]

    def goes_on(self, tls: str, speed: float, d: float) -> bool:
        """Whether a car at ``speed`` [m/s] whose front is ``d`` [m] before a line of light
        ``tls`` that has just turned yellow goes on."""
        spare = d - speed * self.dt - self.slack
        return (self.decel > 0.0 and speed * speed > 2.0 * self.decel * spare
                and d < speed * (self.yellow.get(tls, 0.0) - YELLOW_SPARE))


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
              speeds: np.ndarray, comfort: np.ndarray, lengths: np.ndarray, amber: frozenset = frozenset()) -> list[Obstacle]:
        """The boxes of the lines (keys of :attr:`lines`) that are ``holding``; ``seen``: per line,
        the cars near it and their fronts' distances to it [m] (negative: beyond it); ``speeds``
        [m/s], ``comfort`` decelerations [m/s^2] and ``lengths`` [m] per car; ``amber``: the
        lines that show yellow, to which :attr:`yellow` applies."""
        covered = set()  # lanes whose line a car stands over or a car let through has yet to pass, whichever link it takes
        for key, cars in seen.items():
            if any(-(lengths[k] + BOX_LENGTH) < d < 0.0 for k, d in cars):  # a box there would overlap it
                covered.add(key[2])
            if not holding[key]:
                self.through.pop(key, None)
                continue
            if key not in self.through:  # it has just started to hold: who can no longer stop comfortably goes on
                gentle = self.yellow if key in amber else None
                self.through[key] = {k for k, d in cars if d >= 0.0 and (speeds[k] ** 2 > 2.0 * comfort[k] * d or (
                    gentle is not None and gentle.goes_on(key[0], float(speeds[k]), d)))}
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
              comfort: np.ndarray, lengths: np.ndarray) -> list[Obstacle]:
        """The boxes of this period's stop lines that hold traffic. ``states``: each traffic
        light's link states (SUMO's string); ``approach``: per car on the road, its stop lines
        with the distance [m] from its front to each (negative: beyond it); ``speeds`` [m/s],
        ``comfort`` decelerations [m/s^2] and ``lengths`` [m] per car. Counts the violations
        since the last period."""
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
        return self.holds.boxes(holding, seen, speeds, comfort, lengths, amber)
