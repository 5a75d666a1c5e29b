"""Detours for committed-plan AAC (beyond the paper): a global reference path round what stands.

A robot's MPC looks one horizon ahead (1 s in the swarm scenarios); pressed against debris, or
against robots parked at their goals or standing long, it finds no way round and stands. A
**detour** is a new reference path from where the robot is to its goal, planned on a grid over
the area:

- every standing footprint (debris, parked and standing robots) is a rectangle; a cell whose
  centre lies closer than ``hard`` [m] to one is blocked, and a cell closer than ``clearance``
  [m] costs more the closer it is (up to ``1 + PENALTY``), so that the path keeps
  ``clearance`` where there is room and squeezes through where there is not;
- the cheapest 8-connected path (:func:`~aac_sumo.kernels.grid_path`, A*) is then shortened
  to the corners it needs: from each kept point, the farthest later path point whose straight
  segment keeps at least the smallest distance the grid path kept over the same stretch.

The distance field, the costs and the shortcut are compiled (:mod:`aac_sumo.kernels`). A robot keeps
its detour as long as nothing new stands near what is left of it: the detour was planned round
what stood then, and a new plan from the same place round the same footprints differs at most by
changes farther off (see :class:`Detours`).

The path is for the robot's footprint centre, which the MPC tracks through the rear axle on
straight pieces; ``clearance`` covers the corners. The detour is only a reference: safety is
untouched, every course the robot drives still passes the commitments' exact check. Positions
in the world frame [m].
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.threads import thread_map
from aac_sumo.geometry import rect_distances
from aac_sumo.kernels.detours import band_costs, distance_field, grid_path, rects_within, shortcut
from aac_sumo.references import PathReference

#: Extra cost of a cell at distance ``hard`` from a standing footprint (none at ``clearance``).
PENALTY = 20.0
#: Grid margin round the start, the goal and the footprints [m].
BORDER = 3.0
#: Samples per cell side along a shortcut.
SAMPLES = 3
#: Speed [m/s] below which a robot counts as standing (as :data:`~aac_sumo.coordination.make_room.STILL_SPEED`).
STILL_SPEED = 0.05
#: Spacing [m] of the samples along a reference that is checked for standing footprints.
CHECK_SPACING = 0.1
#: Fewest reference checks in a period worth sharing out among threads (each is mostly Python).
NEAR_THREADS = 16
#: How far along what is left of its reference [m] a robot looks for standing footprints, and
#: plans its detours (20 s at the swarms' 1 m/s): what stands farther on is likely to have moved
#: by the time it gets there, and a crowd of 1,000 re-planned hundreds of whole detours a second
#: for it, each an A* search across the area.
LOOKAHEAD = 20.0
#: Within this distance [m] of its goal, a robot on a detour whose straight way to the goal is
#: free goes straight there: a detour's last corner near the goal is a hook a car cannot follow.
FINAL = 1.5


def plan_detour(start, goal, rects, hard: float, clearance: float, cell: float) -> np.ndarray | None:
    """Waypoints (K, 2) [m] from ``start`` to ``goal`` round the standing footprints ``rects``
    (m, 5) on a grid of ``cell`` [m] over the box round start and goal grown by ``BORDER``
    (see the module docstring), or None when no path exists (the goal itself blocked, or walled
    in). The start's own cell is never blocked (a robot pressed against a neighbour starts
    inside its band)."""
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    rects = np.asarray(rects, dtype=float).reshape(-1, 5)
    lo = np.minimum(start, goal) - BORDER
    hi = np.maximum(start, goal) + BORDER
    cols, rows = (np.ceil((hi - lo) / cell).astype(int) + 1)
    xs, ys = lo[0] + cell * np.arange(cols), lo[1] + cell * np.arange(rows)
    dist = distance_field(lo, cell, rows, cols, rects, clearance)  # each footprint only within clearance of it
    cost = band_costs(dist, hard, clearance, PENALTY)
    s_cell = np.round((start - lo) / cell).astype(int)[::-1]
    g_cell = np.round((goal - lo) / cell).astype(int)[::-1]
    if not np.isfinite(cost[g_cell[0], g_cell[1]]):
        return None
    cost[s_cell[0], s_cell[1]] = min(cost[s_cell[0], s_cell[1]], 1.0 + PENALTY)
    cells = grid_path(cost, s_cell, g_cell)
    if cells.size == 0:
        return None
    r, c = np.divmod(cells, cols)
    path = np.column_stack([xs[c], ys[r]])
    path[0], path[-1] = start, goal
    return path[shortcut(path, np.minimum(dist.ravel()[cells], clearance), rects, hard, cell, SAMPLES)]


class Detours:
    """The detour references of the robots of ``tasks`` (one per robot, None: its task's).

    Standing are the debris, the ``parked`` robots and those that have stood for
    ``stall_periods``. A robot plans a detour (:func:`plan_detour` round the standing footprints
    but its own, from its footprint centre to its goal, or to ``LOOKAHEAD`` on along its
    reference and then along the rest of it (:meth:`plan`), ``hard`` and ``clearance`` [m], grid
    ``cell`` [m]) when it has stood for ``stall_periods`` (and again after each further such
    stretch), and, every ``check_periods``, when what is left of its reference (from its
    projection on, for ``LOOKAHEAD``) comes within ``clearance`` of a standing footprint. A robot on a grid detour
    re-plans only when something stands near what is left of it that its plan did not go round
    (the same footprint row); after a stall, also when it has moved since the plan or a
    footprint it went round there no longer stands. Within ``FINAL`` of its
    goal, a robot on a detour whose straight segment (rear axle to goal) keeps ``hard`` from
    every standing footprint goes straight there instead. A robot that has finished drops its
    detour. A detour keeps its task's speed, braking, goal approach and
    turning radius. A period's detours are planned on up to ``workers`` threads (0: one per
    core), each round what stood at the period's start: the same detours on any count."""

    def __init__(self, tasks: list[PathReference], stall_periods: int, check_periods: int, hard: float, clearance: float,
                 cell: float, workers: int = 1):
        self.tasks = tasks
        self.workers = workers
        self.stall_periods, self.check_periods = stall_periods, check_periods
        self.hard, self.clearance, self.cell = hard, clearance, cell
        self.routes: list[PathReference | None] = [None] * len(tasks)
        self.still = np.zeros(len(tasks), dtype=int)
        self.next_check = np.zeros(len(tasks), dtype=int)
        self.final = np.zeros(len(tasks), dtype=bool)  # on the straight way to the goal (FINAL)
        self.basis: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(tasks)  # each detour's start and standing footprints
        self.planned = 0  # detours planned so far
        self.goals = np.array([t.points[-1] for t in tasks]).reshape(-1, 2)  # each task's goal [m]

    def path(self, i: int) -> PathReference:
        """Robot ``i``'s reference path: its detour, else its task."""
        route = self.routes[i]
        return self.tasks[i] if route is None else route

    def update(self, states: np.ndarray, footprints: np.ndarray, done: np.ndarray, parked: np.ndarray, statics: np.ndarray,
               period: int) -> None:
        """Count standing periods and (re)plan the detours due at ``period``: ``states`` (n, 4)
        rear axles, ``footprints`` (n, 5) rows ``[cx, cy, length, width, heading]``, ``done``
        and ``parked`` (n,) as the coordinator's, ``statics`` (m, 5) debris footprints."""
        self.still = np.where(~done & (np.abs(states[:, 3]) < STILL_SPEED), self.still + 1, 0)
        standing = parked | (self.still >= self.stall_periods)
        for i in np.flatnonzero(done):
            self.routes[i], self.final[i], self.basis[i] = None, False, None
        gap = np.hypot(*(states[:, :2] - self.goals).T)
        rows = np.vstack([statics.reshape(-1, 5), footprints])
        keep = np.concatenate([np.ones(len(rows) - len(footprints), dtype=bool), standing])

        def standing_but(i: int) -> np.ndarray:  # the standing footprints but robot i's own
            return rows[keep & (np.arange(len(rows)) != len(rows) - len(footprints) + i)]

        on_detour = np.array([route is not None for route in self.routes], dtype=bool) & ~self.final
        stalled_now = (self.still >= self.stall_periods) & (self.still % self.stall_periods == 0)
        due = (on_detour & (gap <= FINAL)) | stalled_now | (period >= self.next_check)  # the others have nothing to do
        checks = []  # (robot, its standing footprints, whether it stalled now) whose reference is checked
        for i in np.flatnonzero(~done & ~parked & due):
            if on_detour[i] and gap[i] <= FINAL:
                rects = standing_but(i)
                goal = self.goals[i]
                line = states[i, :2] + np.linspace(0.0, 1.0, int(np.ceil(gap[i] / CHECK_SPACING)) + 1)[:, None] * (goal - states[i, :2])
                if rect_distances(line, rects).min() >= self.hard:
                    self.routes[i] = self.route(i, np.array([states[i, :2], goal]))
                    self.final[i] = True
                    continue
            stalled = bool(stalled_now[i])
            if not stalled and period < self.next_check[i]:
                continue
            self.next_check[i] = period + self.check_periods
            checks.append((i, standing_but(i), stalled))
        nears = thread_map(lambda check: self.near(check[0], states[check[0]], check[1]), checks, self.workers, NEAR_THREADS)
        jobs = [(i, rects) for (i, rects, stalled), near in zip(checks, nears)  # to plan, each round what stood at the period's start
                if not self.keeps(i, states[i], footprints[i, :2], rects[near], stalled)]
        plans = thread_map(lambda job: self.plan(job[0], states[job[0]], footprints[job[0], :2], job[1]), jobs, self.workers)
        for (i, rects), waypoints in zip(jobs, plans):
            if waypoints is not None and len(waypoints) >= 2:
                self.routes[i], self.final[i] = self.route(i, waypoints), False
                self.basis[i] = (footprints[i, :2].copy(), rects)
                self.planned += 1

    def plan(self, i: int, state: np.ndarray, start: np.ndarray, rects: np.ndarray) -> np.ndarray | None:
        """Waypoints (K, 2) [m] of robot ``i``'s new detour from its footprint centre ``start`` round
        ``rects`` (:func:`plan_detour`): where more than ``LOOKAHEAD`` of its reference is left
        beyond the projection of its rear axle ``state``, to the reference's point ``LOOKAHEAD``
        on and then along the rest of the reference (what stands farther on is looked at again
        on the way); else, or when that point is blocked, to its goal. None: no way found."""
        path = self.path(i)
        s0 = path.project(state[:2])[0]
        if path.length - s0 > LOOKAHEAD:
            head = plan_detour(start, path.pose_at(s0 + LOOKAHEAD)[0, :2], rects, self.hard, self.clearance, self.cell)
            if head is not None and len(head) >= 2:
                return np.vstack([head, path.points[path.s > s0 + LOOKAHEAD]])
        return plan_detour(start, self.goals[i], rects, self.hard, self.clearance, self.cell)

    def route(self, i: int, waypoints: np.ndarray) -> PathReference:
        """A detour of robot ``i`` through ``waypoints`` (K, 2), with its task's speed, braking,
        goal approach and turning radius."""
        task = self.tasks[i]
        return PathReference(waypoints, task.speed, task.decel, approach=task.approach, turn_radius=task.turn_radius, arrive=task.arrive)

    def near(self, i: int, state: np.ndarray, rects: np.ndarray) -> np.ndarray:
        """Which of ``rects`` (m, 5) come within ``clearance`` of what is left of robot ``i``'s
        reference, from its projection on for ``LOOKAHEAD`` or to the goal (samples every
        ``CHECK_SPACING``), (m,)."""
        path = self.path(i)
        s0, _ = path.project(state[:2])
        end = min(path.length, s0 + LOOKAHEAD)
        s = np.append(np.arange(s0, end, CHECK_SPACING), end)
        return rects_within(path.pose_at(s)[:, :2], rects, self.clearance)

    def keeps(self, i: int, state: np.ndarray, start: np.ndarray, near: np.ndarray, stalled: bool) -> bool:
        """Whether robot ``i`` (rear axle ``state``, footprint centre ``start`` [m]) keeps its
        reference, with ``near`` (k, 5) the standing footprints within ``clearance`` of what is
        left of it: when none are and it has not stalled; or when it is on a grid detour that was
        planned round each of them and, if it has stalled, planned from ``start`` round exactly
        the footprints near the rest of it (a new plan would be the same but for changes
        farther off)."""
        if not stalled and len(near) == 0:
            return True
        if self.routes[i] is None or self.final[i] or self.basis[i] is None:
            return False
        planned_from, planned_round = self.basis[i]
        if not (near[:, None, :] == planned_round[None, :, :]).all(axis=2).any(axis=1).all():
            return False  # something new stands near it
        if not stalled:
            return True
        return bool(np.array_equal(start, planned_from) and self.near(i, state, planned_round).sum() == len(near))
