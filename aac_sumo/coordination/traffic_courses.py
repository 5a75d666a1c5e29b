"""SUMO's own cars as the exact check of committed plans sees them (beyond the paper).

A vehicle no coordinator drives (kind ``scripted``) is a **braking course**: it goes on along its
velocity braking at ``aac.traffic_decel`` (or harder where it already is) until it stands. Only
the vehicles ahead of a robot count for it, and a continuation stays where it can stop behind
where each of them could stand. Used by :class:`~aac_sumo.coordination.commitments.CommitmentBook`
and :class:`~aac_sumo.coordination.aac.committed.CommittedAac`.

Frames and units: world frame [m], headings [rad], speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

import numpy as np

from aac_sumo.references import PathReference


def braking_courses(obstacles, decel: float, dt: float) -> list[np.ndarray]:
    """Footprint rows ``[cx, cy, length, width, heading]`` (K+1, 5) of each vehicle among
    ``obstacles`` that no coordinator drives (kind ``scripted``: SUMO's own cars) from now until
    it stands, braking from its speed along its velocity at ``decel`` [m/s^2], or harder when
    its estimated :attr:`~aac_sumo.world.Obstacle.accel` already is, with the heading it has;
    K periods of ``dt`` [s] until it stands (0 for a standing vehicle)."""
    out = []
    for o in obstacles:
        if o.kind != "scripted":
            continue
        speed = float(np.hypot(*o.velocity))
        brake = max(float(decel), -float(o.accel))
        steps = int(np.ceil(speed / (brake * dt) - 1e-9)) if speed > 0.0 else 0  # an exact count is not lost to rounding
        t = np.minimum(np.arange(steps + 1) * dt, speed / brake)
        travel = speed * t - 0.5 * brake * t**2
        direction = np.asarray(o.velocity, dtype=float) / speed if speed > 0.0 else np.zeros(2)
        rows = np.empty((steps + 1, 5))
        rows[:, :2] = np.asarray(o.centre, dtype=float) + travel[:, None] * direction
        rows[:, 2:] = (o.length, o.width, o.heading)
        out.append(rows)
    return out


def ahead_of(points: np.ndarray, here: np.ndarray, heading: float) -> np.ndarray:
    """Whether each of ``points`` (K, 2) [m] lies ahead of ``here`` (2,) [m] along ``heading``
    [rad]: the uncontrolled vehicles a robot's check counts."""
    return (points[:, 0] - here[0]) * np.cos(heading) + (points[:, 1] - here[1]) * np.sin(heading) > 0.0


def standing_points(path: PathReference, traffic: list[np.ndarray], here: np.ndarray, heading: float, reach: float,
                    gap: float) -> np.ndarray:
    """Arc lengths [m] along ``path`` (K,) where a robot's rear axle must stand to keep ``gap``
    [m] (its rear axle to its front, and room to spare) behind where each vehicle of
    ``traffic`` (braking courses, :func:`braking_courses`) stands at the end of its course: the
    vehicles whose centres are ahead of ``here`` (the robot's footprint centre [m]) along
    ``heading`` [rad], as the check counts them, and whose standing footprints come within
    ``reach`` [m] of the path (on top of half their width)."""
    if not traffic:
        return np.empty(0)
    first = np.array([c[0] for c in traffic])
    ends = np.array([c[-1] for c in traffic])
    ends = ends[ahead_of(first[:, :2], here, heading)]
    if len(ends) == 0:
        return np.empty(0)
    s, off = path.project_many(ends[:, :2])
    on = off <= 0.5 * ends[:, 3] + reach
    return np.ascontiguousarray(s[on] - 0.5 * ends[on, 2] - gap)
