"""Where the walkers may be while a commitment is driven: the walker-aware part of the exact check.

A walker seen now at centre ``c`` [m] with velocity ``v`` [m/s] walks at most at ``V`` =
max(``|v|``, ``pedestrian_reach``) [m/s]. ``t`` [s] later she is taken to be
* within ``V t`` of ``c`` in any direction: she may start, stop or turn at any moment; or,
* on the segment from ``c`` to ``c + V t v/|v|`` along her way (she may stop or slow down, she
  does not turn back) when she walks on a walkway of her own whose ends she cannot reach within
  ``walkway_time`` (:meth:`~aac_sumo.world.Obstacle.step_out_speed` is 0: SUMO's walkers leave a
  footpath only at its end), or walks across a crossing's strip at ``CROSSING_WALK`` or faster
  (SUMO's walkers cross to the far side; a car goes once she has cleared its lane and margin);
* with ``to_end`` (``aac.walkway_to_end``), on a walkway whose nearer end ``e`` [m] away she can
  reach within ``walkway_time``: on that segment until ``t = e / V``, the soonest she can leave
  the walkway, and within ``V t`` of ``c`` from then on, as without it (the end she may step out
  at lies within that; which way it lies is not known).
Every car keeps ``radius`` from that region: her footprint's half diagonal plus
``pedestrian_margin``. Unlike the planner's regions over its short horizon (constant velocity,
grown by the reach on every side), this is a bound on her speed, so it stays true over a
commitment's whole course.

A course passes when, at every period from now until it stands, its footprint keeps outside
every walker's region of that moment, and where it stands keeps ``pedestrian_margin`` from
every crossing's strip (a car never waits on a crossing: the walkers to come walk there).
Frames and units: world frame [m], periods of ``dt`` [s].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from aac_sumo.geometry import OrientedRect, point_rect_signed_distance
from aac_sumo.kernels.walkers import strip_slack, walker_slack
from aac_sumo.world import WorldState

#: Spacing [m] of the points that stand for a walker's segment; the gap is taken half a spacing
#: smaller, so the check never passes what the exact segment would refuse.
SEGMENT_STEP = 0.25
#: A walker on a crossing's strip who walks at least this fast [m/s] keeps to her way across it.
CROSSING_WALK = 0.3
#: Walkers whose region stays this far [m] from a course's footprints by the centres alone are
#: not measured exactly: the slack is exact below it.
FAR = 5.0


@dataclass(frozen=True)
class WalkerReach:
    """The walkers of one period: each one's region at ``t`` [s] is the segment from its centre
    (m, 2) [m] to ``centre + velocities * t`` ((m, 2) [m/s]) while ``t < delay`` ((m,) [s]: inf for a
    walker who keeps to her way, 0 for one who may turn now), else the disc of ``growth * t``
    ((m,) [m/s]) round her centre, either grown by ``radius`` (m,) [m]; ``dt`` [s] is the period. ``strips``
    (c, 2, 2) are the segments of the crossings' centre lines, ``strip_radius`` (c,) [m] half
    their width plus the margin."""

    centres: np.ndarray
    velocities: np.ndarray
    radius: np.ndarray
    growth: np.ndarray
    dt: float
    strips: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    strip_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    delay: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def of(cls, world: WorldState, margin: float, reach: float, walkway_time: float, dt: float, to_end: bool = False) -> "WalkerReach":
        """The pedestrians of ``world``, each kept ``margin`` [m] from, walking at most at
        ``reach`` [m/s] or their speed now (``walkway_time`` [s]: see the module; ``to_end``:
        one who can reach her walkway's end keeps to her way until then, else her reach grows
        in every direction from now)."""
        walkers = [o for o in world.obstacles if o.kind == "pedestrian"]
        velocity = np.array([o.velocity for o in walkers], dtype=float).reshape(-1, 2)
        speed = np.hypot(*velocity.T)
        top = np.maximum(speed, reach)
        segments = [(c.shape[k:k + 2], 0.5 * c.width) for c in world.crossings for k in range(len(c.shape) - 1)]
        strips = np.array([seg for seg, _ in segments], dtype=float).reshape(-1, 2, 2)
        half = np.array([h for _, h in segments], dtype=float)  # half the strip's width [m]
        centres = np.array([o.centre for o in walkers], dtype=float).reshape(-1, 2)
        crossing = (speed >= CROSSING_WALK) & np.any(segment_distance(centres, strips) <= half[None, :], axis=1)
        bound = crossing | np.array([o.step_out_speed(reach, walkway_time) == 0.0 for o in walkers], dtype=bool)  # keeps to her way
        end = np.array([min(o.walkway) if o.walkway is not None else 0.0 for o in walkers], dtype=float)  # [m]
        delay = np.where(bound, np.inf, end / np.maximum(top, 1e-9) if to_end else 0.0)  # until she may leave her way [s]
        way = velocity / np.maximum(speed, 1e-9)[:, None] * top[:, None]
        return cls(centres, np.where((bound | (delay > 0.0))[:, None], way, 0.0),
                   np.array([0.5 * np.hypot(o.length, o.width) + margin for o in walkers], dtype=float),
                   np.where(bound, 0.0, top), float(dt),
                   strips, half + margin, delay)

    def slack(self, rows: np.ndarray) -> float:
        """Least gap [m] between the footprints ``rows`` (K, 5) ``[cx, cy, length, width,
        heading]`` of a course (row k at k periods from now; the course stands after its last
        row, which is checked too) and the walkers' regions at the same moments; negative where
        a footprint enters one, inf without walkers; a lower bound above ``FAR``."""
        if len(self.centres) == 0 or len(rows) == 0:
            return np.inf
        rows = np.ascontiguousarray(rows, dtype=float)
        return float(walker_slack(rows, np.cos(rows[:, 4]), np.sin(rows[:, 4]), self.centres, self.velocities, self.radius, self.growth, self.delay,
                                  self.dt, FAR, SEGMENT_STEP))

    def stand_slack(self, row: np.ndarray) -> float:
        """Least gap [m] between the footprint ``row`` (5,) where a course stands and the
        crossings' strips grown by the margin; inf without crossings."""
        if len(self.strips) == 0:
            return np.inf
        points, half_spacing = self._strip_points
        heading = np.asarray(row[4:5], dtype=float)
        return float(strip_slack(np.ascontiguousarray(row, dtype=float), float(np.cos(heading)[0]), float(np.sin(heading)[0]), points,
                                 half_spacing, self.strip_radius))

    @cached_property
    def _strip_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Points (c, S, 2) [m] every at most ``SEGMENT_STEP`` along each crossing's strip, and half
        their spacing (c,) [m] (the distance to a strip is taken that much nearer)."""
        length = np.hypot(*(self.strips[:, 1] - self.strips[:, 0]).T)  # (c,)
        count = int(np.ceil(float(length.max()) / SEGMENT_STEP)) + 1
        u = np.linspace(0.0, 1.0, count)[None, :, None]
        points = self.strips[:, :1] + u * (self.strips[:, 1:] - self.strips[:, :1])  # (c, S, 2)
        return np.ascontiguousarray(points), 0.5 * length / max(count - 1, 1)


def box_distance(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Signed distance [m] (K, m, S) from points (K, m, S, 2) to the footprints ``rows`` (K, 5)
    ``[cx, cy, length, width, heading]``, negative inside: :func:`~aac_sumo.geometry.point_rect_signed_distance`
    with each footprint broadcast over its points."""
    return point_rect_signed_distance(points, OrientedRect(*(rows[:, j, None, None] for j in range(5))))


def segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance [m] (p, s) from points (p, 2) to segments (s, 2, 2)."""
    a, d = segments[None, :, 0], segments[None, :, 1] - segments[None, :, 0]
    u = np.clip(np.sum((points[:, None] - a) * d, axis=2) / np.maximum(np.sum(d * d, axis=2), 1e-12), 0.0, 1.0)
    return np.hypot(*(points[:, None] - a - u[..., None] * d).transpose(2, 0, 1))
