"""SUMO's own cars as the exact check of committed plans sees them (beyond the paper).

A vehicle no coordinator drives (kind ``scripted``) is a **braking course**: it goes on along its
course (SUMO's cars: their route's lanes through the junctions), else along its velocity, braking
at ``aac.traffic_decel`` (or harder where it already is) until it stands. Only
the vehicles ahead of a robot count for it, and a continuation stays where it can stop behind
where each of them could stand. Used by :class:`~aac_sumo.coordination.commitments.CommitmentBook`
and :class:`~aac_sumo.coordination.aac.committed.CommittedAac`.

Frames and units: world frame [m], headings [rad], speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from aac_sumo.geometry import along
from aac_sumo.kernels.geometry import paired_clearance
from aac_sumo.references import PathReference
from aac_sumo.world import line_binds


def braking_courses(obstacles, decel: float, dt: float) -> list[np.ndarray]:
    """Footprint rows ``[cx, cy, length, width, heading]`` (K+1, 5) of each vehicle among
    ``obstacles`` that no coordinator drives (kind ``scripted``: SUMO's own cars; and ``signal``, a red
    light's stop line, which stands) from now until
    it stands, braking from its speed at ``decel`` [m/s^2], or harder when its estimated
    :attr:`~aac_sumo.world.Obstacle.accel` already is: along its
    :attr:`~aac_sumo.world.Obstacle.course` where it has one (headed along it), else straight
    along its velocity with the heading it has; K periods of ``dt`` [s] until it stands (0 for
    a standing vehicle)."""
    out = []
    for o in obstacles:
        if o.kind not in ("scripted", "signal"):
            continue
        speed = float(np.hypot(*o.velocity))
        brake = max(float(decel), -float(o.accel))
        steps = int(np.ceil(speed / (brake * dt) - 1e-9)) if speed > 0.0 else 0  # an exact count is not lost to rounding
        t = np.minimum(np.arange(steps + 1) * dt, speed / brake)
        travel = speed * t - 0.5 * brake * t**2
        rows = np.empty((steps + 1, 5))
        rows[:, 2:] = (o.length, o.width, o.heading)
        if o.course is not None and steps > 0:
            rows[:, :2] = along(o.course, travel, extend=True)[0]
            rows[1:, :2], rows[1:, 4] = _on_course(o.course, travel[1:], o.length)
        else:
            direction = np.asarray(o.velocity, dtype=float) / speed if speed > 0.0 else np.zeros(2)
            rows[:, :2] = np.asarray(o.centre, dtype=float) + travel[:, None] * direction
        out.append(rows)
    return out


def _on_course(course: np.ndarray, travel: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Centres (K, 2) [m] and headings (K,) [rad] of a vehicle ``length`` [m] long whose centre
    has gone ``travel`` (K,) [m] along ``course`` (starting at its centre): where the course bends
    under its body, as SUMO places a car on its lane, its front on the course, headed along the
    chord from the course's point half a length behind its centre to its front (centred on the
    course and turned to its tangent, a turning car's rear swung 1.3 m out into the next lane);
    elsewhere the course's point and segment."""
    centre, tangent = along(course, travel, extend=True)
    front, ahead = along(course, travel + 0.5 * length, extend=True)
    back, behind = along(course, travel - 0.5 * length, extend=True)
    bent = (ahead != tangent) | (behind != tangent)
    chord = np.arctan2(front[:, 1] - back[:, 1], front[:, 0] - back[:, 0])
    placed = front - 0.5 * length * np.column_stack([np.cos(chord), np.sin(chord)])
    return np.where(bent[:, None], placed, centre), np.where(bent, chord, tangent)


def stop_lines(obstacles) -> np.ndarray:
    """Which of :func:`braking_courses` of ``obstacles`` (K,) are stop lines (kind ``signal``)."""
    return np.array([o.kind == "signal" for o in obstacles if o.kind in ("scripted", "signal")], dtype=bool)


def binding(first: np.ndarray, lines: np.ndarray, heading: float) -> np.ndarray:
    """Which courses (first rows ``first`` (K, 5); ``lines``: which of the first ones are stop lines,
    the rest are not) can hold a robot heading ``heading`` [rad]: every vehicle, and the stop lines
    it comes up to along their lanes (:func:`~aac_sumo.world.line_binds`)."""
    lines = np.r_[np.asarray(lines, dtype=bool), np.zeros(len(first) - len(lines), dtype=bool)]
    return ~lines | line_binds(first[:, 4], heading)


def signalled_courses(obstacles, decel: float, dt: float) -> list[np.ndarray]:
    """:func:`braking_courses` of the vehicles among ``obstacles`` whose blinker signals a lane
    change they wait to make, seen over their lane and the next on that side
    (:attr:`~aac_sumo.world.Obstacle.signalled`): a continuation keeps where it can stop behind
    them, so that a car approaching one lets it in (the exact check does not hold them)."""
    waiting = [o for o in obstacles if o.kind == "scripted" and o.signalled is not None]
    return braking_courses([replace(o, centre=o.signalled[:2], length=float(o.signalled[2]), width=float(o.signalled[3]),
                                    heading=float(o.signalled[4]), course=None) for o in waiting], decel, dt)


def ahead_of(points: np.ndarray, here: np.ndarray, heading: float) -> np.ndarray:
    """Whether each of ``points`` (K, 2) [m] lies ahead of ``here`` (2,) [m] along ``heading``
    [rad]: the uncontrolled vehicles a robot's check counts."""
    return (points[:, 0] - here[0]) * np.cos(heading) + (points[:, 1] - here[1]) * np.sin(heading) > 0.0


def standing_points(path: PathReference, traffic: list[np.ndarray], lines: np.ndarray, here: np.ndarray, heading: float,
                    reach: float, gap: float) -> np.ndarray:
    """Arc lengths [m] along ``path`` (K,) where a robot's rear axle must stand to keep ``gap``
    [m] (its rear axle to its front, and room to spare) behind where each vehicle of
    ``traffic`` (braking courses, :func:`braking_courses`; ``lines``: which of the first ones are stop lines)
    stands at the end of its course: the vehicles whose centres are ahead of ``here`` (the robot's
    footprint centre [m]) along ``heading`` [rad] and the stop lines that bind it (:func:`binding`),
    as the check counts them, and whose standing footprints come within
    ``reach`` [m] of the path (on top of half their width) ahead of the robot (a vehicle nearest
    to a stretch of its route it has driven already, say where the route came by earlier, is
    not a place it must stand behind: that held a car for good just past a junction)."""
    if not traffic:
        return np.empty(0)
    first = np.array([c[0] for c in traffic])
    ends = np.array([c[-1] for c in traffic])
    ends = ends[ahead_of(first[:, :2], here, heading) & binding(first, lines, heading)]
    if len(ends) == 0:
        return np.empty(0)
    s, off = path.project_many(ends[:, :2])
    on = (off <= 0.5 * ends[:, 3] + reach) & (s >= path.project(here)[0])
    return np.ascontiguousarray(s[on] - 0.5 * ends[on, 2] - gap)



def traffic_clearances(rows: np.ndarray, traffic: list[np.ndarray], lines: np.ndarray) -> np.ndarray:
    """Per stage, the least clearance [m] of the footprint rows ``rows`` (K, 5), a course from now
    that stands at its last row once it has ended, to the braking courses of the vehicles of
    ``traffic`` ahead of ``rows[0]`` (each also standing at its end; of the stop lines among them,
    ``lines`` (as :func:`binding`), those that bind it), over the stages until all
    have ended (inf where none is ahead)."""
    here = rows[0]
    first = np.array([c[0] for c in traffic]).reshape(-1, 5)
    held = ahead_of(first[:, :2], here[:2], float(here[4])) & binding(first, lines, float(here[4]))
    courses = [c for c, h in zip(traffic, held) if h]
    stages = max([len(rows)] + [len(c) for c in courses])
    own = rows[np.minimum(np.arange(stages), len(rows) - 1)]
    least = np.full(stages, np.inf)
    for c in courses:
        least = np.minimum(least, paired_clearance(own, c[np.minimum(np.arange(stages), len(c) - 1)]))
    return least
