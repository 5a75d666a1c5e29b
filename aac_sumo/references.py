"""Reference trajectories: a polyline path followed at a cruise speed, slowing to stop at its end.

Positions in the world frame [m]; the reference is for the rear-axle point.
"""

from __future__ import annotations

import numpy as np

from aac_sumo.geometry import polyline_offset, wrap_angle
from aac_sumo.kernels.paths import closest_on_polyline, path_headings, path_poses, paths_at, polyline_chunks, project_points

#: Segments per bounding circle of a path's projection (:func:`~aac_sumo.kernels.paths.closest_on_polyline`):
#: at least PROJECTION_CHUNK, and the square root of the segment count on longer paths, so that a
#: projection scans about as many bounds as segments (a 2 km lane sampled every metre: 45 chunks of
#: 45, 1.1 us a query against 1.65 us with 126 chunks of 16; the same answer either way).
PROJECTION_CHUNK = 16


def projection_chunk(segments: int) -> int:
    """Segments per bounding circle of a path of ``segments`` segments (``PROJECTION_CHUNK``)."""
    return max(PROJECTION_CHUNK, int(np.sqrt(segments)))


#: A robot backing off from a goal inside its turning circle goes on until the goal lies this
#: many turning radii from both circles' centres.
BACK_OFF_HYSTERESIS = 1.5
#: A goal inside a turning circle but within ALIGNED * arrive of it is reached by the tightest
#: turn on or back (the approach), not by backing off: a robot that stopped just past its goal.
ALIGNED = 0.8


def smooth_path(points, spacing: float = 0.5, tolerance: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Points (K, 2) every ``spacing`` [m] along a curvature-continuous path through the polyline
    ``points`` (M, 2) [m], and the signed curvature (K,) [1/m] there (positive: turning left).

    The path is a quintic smoothing spline on arc length (scipy's ``make_splprep``), so its
    curvature has no jumps where the polyline has corners (lane shapes from SUMO, whose chords
    on a curve lie up to ``c^2 / 8R`` inside the arc: 7 cm for 9 m chords at R = 150 m); it keeps
    within about ``tolerance`` [m] of the polyline's points. Straight polylines stay straight."""
    from scipy.interpolate import make_splprep

    pts = np.asarray(points, dtype=float)
    keep = np.r_[True, np.hypot(*np.diff(pts, axis=0).T) > 1e-9]
    pts = pts[keep]
    u = np.r_[0.0, np.cumsum(np.hypot(*np.diff(pts, axis=0).T))]
    if len(pts) < 6:  # too few points for a quintic: a straight piece or one corner, sampled finer first
        u_fine = np.linspace(0.0, u[-1], max(6, int(np.ceil(u[-1] / spacing)) + 1))
        pts = np.column_stack([np.interp(u_fine, u, pts[:, 0]), np.interp(u_fine, u, pts[:, 1])])
        u = u_fine
    spline, _ = make_splprep(pts.T, u=u, k=5, s=len(pts) * tolerance**2)
    grid = np.r_[np.arange(0.0, u[-1], spacing), u[-1]]
    xy = spline(grid).T
    d1, d2 = spline.derivative(1)(grid).T, spline.derivative(2)(grid).T
    curvature = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(np.hypot(*d1.T), 1e-12) ** 3
    return xy, curvature


def curve_speeds(curvature, spacing: float, speed: float, a_lat: float, decel: float) -> np.ndarray:
    """Speeds [m/s] at path points ``spacing`` [m] apart with ``curvature`` (K,) [1/m]: at most
    ``speed``, and ``sqrt(a_lat / |curvature|)`` so that the lateral acceleration ``v^2 |k|``
    stays within ``a_lat`` [m/s^2]; lowered ahead of each curve so that slowing down for it
    takes at most ``decel`` [m/s^2]."""
    with np.errstate(divide="ignore"):
        v = np.minimum(speed, np.sqrt(a_lat / np.abs(np.asarray(curvature, dtype=float))))
    for k in range(len(v) - 2, -1, -1):
        v[k] = min(v[k], np.sqrt(v[k + 1] ** 2 + 2.0 * decel * spacing))
    return v


class PathReference:
    """Path ``waypoints`` (M, 2) [m] driven at ``speed`` [m/s]; decelerates at ``decel`` [m/s^2]
    to stop at the last waypoint when ``stop_at_end`` is set. Within ``approach`` [m] of that
    goal the reference runs straight from the robot to the goal instead (see :meth:`horizon`).
    ``limits`` (M,) [m/s], one per waypoint, lowers the speed there further (on curves, say)."""

    def __init__(self, waypoints, speed: float, decel: float = 1.5, stop_at_end: bool = True, approach: float = 0.0,
                 turn_radius: float = 0.0, arrive: float = 0.0, limits=None):
        pts = np.asarray(waypoints, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError("a path needs at least two (x, y) waypoints")
        seg = np.diff(pts, axis=0)
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.hypot(seg[:, 0], seg[:, 1]) > 1e-9
        self.points = pts[keep]
        if len(self.points) < 2:
            raise ValueError("a path needs at least two distinct (x, y) waypoints")
        self.limits = None if limits is None else np.asarray(limits, dtype=float)[keep]
        seg = np.diff(self.points, axis=0)
        self.seg_len = np.hypot(seg[:, 0], seg[:, 1])
        self.seg_heading = np.arctan2(seg[:, 1], seg[:, 0])
        self._seg_dir = np.empty((len(seg), 2))
        self._seg_dir[:, 0], self._seg_dir[:, 1] = np.cos(self.seg_heading), np.sin(self.seg_heading)
        self.s = np.zeros(len(self.points))
        np.cumsum(self.seg_len, out=self.s[1:])
        self.length = float(self.s[-1])
        self.speed = float(speed)
        self.decel = float(decel)
        self.stop_at_end = stop_at_end
        self.approach = float(approach)
        self.turn_radius = float(turn_radius)
        self.arrive = float(arrive)
        # upper bound of the fraction of each segment a projection may reach: past the end of a path that does not stop
        self._t_max = np.ones(len(self.seg_len))
        self._t_max[-1] = 1.0 if stop_at_end else np.inf
        self._chunk = projection_chunk(len(self.seg_len))
        self._chunks = polyline_chunks(self.points, self._chunk)

    def arrays(self) -> tuple:
        """The path as the compiled kernels take it: points (M, 2), segment lengths, cumulative
        arc lengths (M,), segment directions (M-1, 2) and headings, the projection's ``t`` bounds,
        the chunk bounds with the chunk size, and the speed limits (M,; empty without)."""
        limits = np.empty(0) if self.limits is None else self.limits
        return (self.points, self.seg_len, self.s, self._seg_dir, self.seg_heading, self._t_max, *self._chunks, self._chunk,
                limits)

    def project(self, point) -> tuple[float, float]:
        """Arc length [m] of the closest path point to ``point`` and the distance [m] to it. A
        path that does not stop goes on straight beyond its end, so a point past the end projects
        onto that extension (arc length above ``length``)."""
        i, t, dist = self._closest(point)
        return float(self.s[i] + t * self.seg_len[i]), float(dist)

    def project_many(self, points) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` of each of ``points`` (K, 2): arc lengths (K,) and distances (K,) [m]."""
        queries = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
        return project_points(self.points, self.seg_len, self.s, self._t_max, queries, *self._chunks, self._chunk)

    def _closest(self, point) -> tuple[int, float, float]:
        return closest_on_polyline(self.points, self.seg_len, self._t_max, float(point[0]), float(point[1]), *self._chunks, self._chunk)

    def distance(self, points) -> np.ndarray:
        """Distance [m] from each of ``points`` (K, 2) to the path."""
        return np.array([self.project(p)[1] for p in np.atleast_2d(points)])

    def speed_at(self, s) -> np.ndarray:
        """Reference speed [m/s] at arc length ``s``."""
        s = np.asarray(s, dtype=float)
        cap = self.speed if self.limits is None else np.interp(s, self.s, self.limits)
        if not self.stop_at_end:
            return np.minimum(np.full_like(s, self.speed), cap)
        return np.minimum(cap, np.sqrt(2.0 * self.decel * np.clip(self.length - s, 0.0, None)))

    def pose_at(self, s) -> np.ndarray:
        """Rows ``[x, y, heading]`` at arc lengths ``s`` (clamped to the path; extrapolated past
        the end along the last segment when the path does not stop)."""
        s = np.ascontiguousarray(np.atleast_1d(np.asarray(s, dtype=float)).ravel())
        return path_poses(self.points, self.s, self.seg_len, self._seg_dir, self.seg_heading, self.stop_at_end, s)

    def heading_at(self, point) -> float:
        """Heading [rad] of the path where ``point`` [m] projects (of the later segment at a vertex)."""
        i, t, _ = self._closest(point)
        if i + 1 < len(self.seg_len) and self.s[i] + t * self.seg_len[i] >= self.s[i + 1]:
            i += 1  # at the vertex that ends segment i (the projection never passes it)
        return float(self.seg_heading[i])

    def headings_ahead(self, point, count: int, spacing: float) -> np.ndarray:
        """Headings (count,) [rad, unwrapped] of the path every ``spacing`` [m] from where
        ``point`` [m] projects on: the first is :meth:`heading_at`'s."""
        return path_headings(self.s, self.seg_heading, self.project(point)[0], count, spacing)

    def horizon(self, state, steps: int, dt: float) -> np.ndarray:
        """Reference states (steps + 1, 4) starting from the projection of ``state``'s position.

        Headings are unwrapped to lie within pi of the robot's heading. Within ``approach`` of
        the goal of a path that stops, or (when ``approach`` is set) where less of the path is
        left than the robot lies off it (the goal is more beside it than ahead), the reference
        positions run straight from the robot to the goal at the path's stopping speed profile
        (negative when the goal lies behind), and the heading is NaN, free (the planner does not
        weigh it): a robot that
        reaches the goal's neighbourhood off its path (it avoided someone) manoeuvres onto the
        goal, forwards or backwards as its MPC finds best, instead of stopping beside it with
        its heading held along the path, where a short horizon cannot undo a sideways error of
        a car-like robot. A robot that can reverse (``turn_radius`` [m] > 0, its tightest turning
        radius) and whose goal lies inside one of its turning circles, where no arc gets it closer,
        farther than ``arrive`` [m] (where it has arrived) and more than ``ALIGNED * arrive``
        inside the circle (else the tightest turn on or back gets it there), first moves straight
        away from it (backwards from a goal in front, forwards from one behind) at half the cruise
        speed, until the goal lies
        ``BACK_OFF_HYSTERESIS`` turning radii from both circles' centres.
        """
        rel, dist, s0, mode = self._goal_mode(state)
        if mode == "back_off":  # a goal inside a turning circle cannot be reached by turning: back off first
            away = -1.0 if rel @ np.array([np.cos(state[2]), np.sin(state[2])]) >= 0.0 else 1.0
            back = away * np.arange(steps + 1) * dt * 0.5 * self.speed
            xy = np.asarray(state[:2], dtype=float) + back[:, None] * np.array([np.cos(state[2]), np.sin(state[2])])
            return np.column_stack([xy, np.full(steps + 1, state[2]), np.full(steps + 1, away * 0.5 * self.speed)])
        if mode == "approach":
            speed = min(self.speed, float(np.sqrt(2.0 * self.decel * dist)))
            ahead = np.minimum(np.arange(steps + 1) * dt * speed, dist)
            xy = np.asarray(state[:2], dtype=float) + ahead[:, None] * (rel / dist)
            sign = 1.0 if rel @ np.array([np.cos(state[2]), np.sin(state[2])]) >= 0.0 else -1.0  # forwards or backwards
            speeds = sign * np.sqrt(2.0 * self.decel * (dist - ahead)).clip(max=self.speed)
            return np.column_stack([xy, np.full(steps + 1, np.nan), speeds])
        s = np.empty(steps + 1)
        s[0] = s0
        for k in range(steps):
            s[k + 1] = s[k] + self.speed_at(s[k]) * dt
        poses = self.pose_at(s)
        heading = state[2] + wrap_angle(poses[:, 2] - state[2])
        return np.column_stack([poses[:, :2], heading, self.speed_at(s)])

    def heading_free(self, state) -> bool:
        """Whether :meth:`horizon` leaves the heading free at ``state``: the goal approach, not
        backing off (what ``np.isnan(horizon(state, 0, dt)[0, 2])`` says, without the rest)."""
        return self._goal_mode(state)[3] == "approach"

    def _goal_mode(self, state) -> tuple[np.ndarray, float, float, str]:
        """``state``'s way to the goal (vector [m] and its length), its projection's arc length
        [m], and which reference :meth:`horizon` gives: ``"path"``, ``"approach"`` (straight to
        the goal, heading free) or ``"back_off"`` (straight away from a goal inside a turning
        circle)."""
        goal = self.points[-1]
        rel = goal - np.asarray(state[:2], dtype=float)
        dist = float(np.hypot(rel[0], rel[1]))
        s0, off = self.project(state[:2])
        if not (self.stop_at_end and 1e-9 < dist and self.approach > 0.0 and (dist <= self.approach or self.length - s0 <= off)):
            return rel, dist, s0, "path"
        if self.turn_radius > 0.0 and dist > self.arrive:
            left = np.array([-np.sin(state[2]), np.cos(state[2])])
            gap = np.hypot(*(np.asarray(state[:2], dtype=float) + self.turn_radius * np.array([left, -left]) - goal).T).min()
            ahead_of = rel @ np.array([np.cos(state[2]), np.sin(state[2])]) >= 0.0  # the goal lies in front
            backing = state[3] < 0.0 if ahead_of else state[3] > 0.0
            if gap < (self.turn_radius * BACK_OFF_HYSTERESIS if backing else self.turn_radius - ALIGNED * self.arrive):
                return rel, dist, s0, "back_off"
        return rel, dist, s0, "approach"

    def finished(self, state, tolerance: float) -> bool:
        """True when the robot is within ``tolerance`` [m] of the path's end."""
        return bool(np.hypot(*(np.asarray(state[:2]) - self.points[-1])) <= tolerance)


class PathSet:
    """The arrays of many paths end to end, for compiled loops over robots (:func:`paths_at`):
    built for one list of tasks, and :meth:`holds` tells whether it is still that list."""

    def __init__(self, tasks: list[PathReference]):
        self.tasks = tuple(tasks)
        parts = [task.arrays() for task in tasks]
        rows = lambda k: np.r_[0, np.cumsum([len(p[k]) for p in parts])].astype(np.int64)
        self.path_rows, self.seg_rows, self.chunk_rows = rows(0), rows(1), rows(6)
        join = lambda k, width: np.ascontiguousarray(np.concatenate([p[k] for p in parts]).reshape(-1, *width))
        self.arrays = (join(0, (2,)), join(1, ()), join(2, ()), join(3, (2,)), join(4, ()), join(5, ()), join(6, (2,)), join(7, ()),
                       self.path_rows, self.seg_rows, self.chunk_rows, np.array([p[8] for p in parts], dtype=np.int64),
                       np.array([t.stop_at_end for t in tasks], dtype=bool), np.array([t.approach for t in tasks]),
                       np.array([t.length for t in tasks]))
        self.stop_at_end, self.length = self.arrays[12], self.arrays[14]
        self.speed, self.decel = np.array([t.speed for t in tasks]), np.array([t.decel for t in tasks])
        self.limited = np.array([t.limits is not None for t in tasks], dtype=bool)

    def holds(self, tasks: list[PathReference]) -> bool:
        """Whether ``tasks`` are the very objects this set was built for."""
        return len(tasks) == len(self.tasks) and all(a is b for a, b in zip(tasks, self.tasks))


def reference_points(tasks: list[PathReference], states: np.ndarray, dt: float, paths: PathSet | None = None) -> np.ndarray:
    """Each robot's reference ``[x, y, heading, v]`` where it is (n, 4): row i is
    ``tasks[i].horizon(states[i], 0, dt)[0]`` to the bit. Robots surely on their paths (no goal
    approach, no speed limits) are projected in one compiled loop (``paths``: the tasks' arrays
    end to end, built here if not given) and their speeds and unwrapped headings computed for all
    at once (the same operations, so the same numbers); the others one at a time by ``horizon``."""
    states = np.ascontiguousarray(states, dtype=float)
    if not len(tasks):
        return np.empty((0, 4))
    paths = paths if paths is not None and paths.holds(tasks) else PathSet(tasks)
    s0, pose, on_path = paths_at(states, *paths.arrays)
    on_path &= ~paths.limited
    out = np.empty((len(tasks), 4))
    for i in np.flatnonzero(~on_path):
        out[i] = tasks[i].horizon(states[i], 0, dt)[0]
    rows = np.flatnonzero(on_path)
    if rows.size:
        speed = paths.speed[rows]
        braking = np.sqrt(2.0 * paths.decel[rows] * np.clip(paths.length[rows] - s0[rows], 0.0, None))
        out[rows, :3] = pose[rows]
        out[rows, 3] = np.where(paths.stop_at_end[rows], np.minimum(speed, braking), speed)
        out[rows, 2] = states[rows, 2] + wrap_angle(pose[rows, 2] - states[rows, 2])
    return out


class LateralBand:
    """Where a robot's rear axle may be across its reference: between the ``right`` and ``left``
    boundary polylines (M, 2) of its road [m], at least ``margin`` [m] inside each, and at most
    ``hug`` [m] from the reference."""

    def __init__(self, right, left, margin: float, hug: float = np.inf):
        self.right = np.asarray(right, dtype=float)
        self.left = np.asarray(left, dtype=float)
        self.margin = float(margin)
        self.hug = float(hug)

    def hugging(self, width: float) -> "LateralBand":
        """The same band, narrowed to at most ``width`` [m] on either side of the reference."""
        return LateralBand(self.right, self.left, self.margin, width)

    def limits(self, reference: np.ndarray) -> np.ndarray:
        """Rows ``[nx, ny, lo, hi]`` (N, 4) for stages 1..N of ``reference`` (N+1, 4): the
        reference's left normal and the bounds on ``nx * x + ny * y`` of the rear axle."""
        pts, heading = reference[1:, :2], reference[1:, 2]
        normal = np.column_stack([-np.sin(heading), np.cos(heading)])
        across = np.einsum("ij,ij->i", normal, pts)
        lo = np.maximum(across - polyline_offset(pts, self.right) + self.margin, across - self.hug)  # offsets: positive to the left
        hi = np.minimum(across - polyline_offset(pts, self.left) - self.margin, across + self.hug)
        return np.column_stack([normal, lo, np.maximum(lo, hi)])
