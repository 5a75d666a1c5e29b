"""Manoeuvres (beyond the paper): a last resort for a robot that its MPC cannot move, planned on
exact footprints.

The MPC keeps robots apart through ellipses that contain their footprints, grown by ``d_safe``.
In a crowd packed at the commitments' margin those ellipses overlap where the rectangles leave
room, and a robot that stands between parked neighbours finds no plan that moves it (24 robots
on r = 4 m, seed 3: the last robot stood 1.2 m short of its goal, 0.18 m from the nearest
footprint, its solves infeasible for 8 s). A **manoeuvre** searches the robot's way to its goal
on the exact rectangles instead (hybrid A*): from standstill to standstill, each primitive turns
the wheels where the robot stands (within its steering rate), drives one arc forwards or, where
the robot may reverse, backwards at ``SPEED``, and stops. Every state of every primitive keeps
``margin`` from the obstacles' footprints, so the found inputs, rolled out with the simulator's
own Euler model, are a course that the commitments' exact check can pass.

The search is resolution complete on its lattice of primitives for standing obstacles: it finds
a way whenever the primitives (``STEERS`` x directions x ``LENGTHS``) join start and goal
within ``MAX_EXPANSIONS`` expansions and the box round them. World frame [m], headings [rad],
speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

import math

import numpy as np

from aac_sumo.kernels.geometry import pairwise_clearance
from aac_sumo.kernels.manoeuvres import lattice_search

#: Driving speed [m/s] of a primitive and the acceleration [m/s^2] it sets off and stops with
#: (each within the robot's limits).
SPEED = 0.4
ACCEL = 1.0
#: Steering of the primitives as shares of the robot's steering limit, and the arc lengths [m].
STEERS = (-1.0, -0.5, 0.0, 0.5, 1.0)
LENGTHS = (0.3, 0.9)
#: Lattice of the search's closed set: cell [m] and heading bins.
CELL = 0.1
HEADINGS = 36
#: Expansions before the search gives up, and the box round start and goal it keeps to [m].
MAX_EXPANSIONS = 1500
BORDER = 1.5
#: Weight of the heuristic (time at SPEED to the goal): above 1 the search is greedier.
WEIGHT = 1.5
#: A backward primitive costs this many times its time (a robot turns round rather than back far).
BACKWARD_COST = 1.5
#: Every state of a primitive keeps this much more than the margin [m] (or, where the robot stands
#: closer now, as much as it keeps now).
SPARE = 0.02


def speed_profile(length: float, speed: float, accel: float, decel: float, dt: float) -> np.ndarray:
    """Accelerations (K,) [m/s^2] that take a robot from standstill to standstill over about
    ``length`` [m]: up to ``speed`` at ``accel``, on, and down at ``decel`` (all positive),
    each period's speed change exact so that it ends at rest."""
    up = [min(speed, accel * dt * (k + 1)) for k in range(int(math.ceil(speed / (accel * dt))))]
    down = [max(0.0, speed - decel * dt * (k + 1)) for k in range(int(math.ceil(speed / (decel * dt))))]
    ramps = dt * (sum(up[:-1]) + speed + sum(down))  # Euler: each period moves at the speed it starts with
    cruise = max(int(round((length - ramps) / (speed * dt))), 0)
    speeds = np.array([0.0, *up, *([speed] * cruise), *down])
    return np.diff(speeds) / dt


class ManoeuvrePlanner:
    """Hybrid A* over standstill-to-standstill primitives for one robot: ``wheelbase`` [m],
    ``steer_limits`` ``[steer_max, a_lat_max, steer_rate_max]``, ``v_min``/``v_max`` [m/s]
    (``v_min < 0``: it may reverse), ``a_min``/``a_max`` [m/s^2], and a footprint of
    ``length`` x ``width`` [m] centred ``offset`` [m] ahead of the rear axle."""

    def __init__(self, wheelbase: float, steer_limits: np.ndarray, v_min: float, v_max: float, a_min: float, a_max: float,
                 length: float, width: float, offset: float, dt: float):
        self.wheelbase, self.dt = float(wheelbase), float(dt)
        self.v_min, self.v_max = float(v_min), float(v_max)
        self.shape = (np.array([float(offset)]), np.array([float(length)]), np.array([float(width)]))
        self.reach = float(np.hypot(offset + 0.5 * length, 0.5 * width))  # rear axle to the footprint's farthest corner
        speed = self.speed = min(SPEED, v_max)
        limit = min(float(steer_limits[0]), math.atan(float(steer_limits[1]) * wheelbase / speed ** 2))
        self.rate = float(steer_limits[2]) * dt
        self.steers = np.array(STEERS) * limit
        self.drives = [(d, d * speed_profile(length_, speed, min(ACCEL, a_max), min(ACCEL, -a_min), dt))
                       for d in ((1.0, -1.0) if v_min < 0.0 else (1.0,)) for length_ in LENGTHS]

    def primitives(self, steer: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every primitive from standstill with the wheels at ``steer`` [rad]: inputs (P, K, 2)
        padded with standing periods, their lengths (P,), and their costs [s] (P,): their time,
        ``BACKWARD_COST`` times it backwards."""
        rows, costs = [], []
        for target in self.steers:
            ramp, s = [], steer
            while abs(target - s) > 1e-12:
                s = min(max(target, s - self.rate), s + self.rate)
                ramp.append(s)
            for direction, accels in self.drives:
                head = np.column_stack([np.zeros(len(ramp)), ramp]).reshape(-1, 2)
                rows.append(np.vstack([head, np.column_stack([accels, np.full(len(accels), target)])]))
                costs.append(len(rows[-1]) * self.dt * (BACKWARD_COST if direction < 0.0 else 1.0))
        return rows, np.array([len(r) for r in rows]), np.array(costs)

    def plan(self, state: np.ndarray, steer: float, goal: np.ndarray, tolerance: float, obstacles: np.ndarray,
             margin: float) -> np.ndarray | None:
        """Inputs (K, 2) ``[accel, steer]`` from rear-axle ``state`` (4,) at rest with the wheels at
        ``steer`` to a standstill whose rear axle lies within ``tolerance`` [m] of ``goal`` (2,),
        every footprint on the way ``margin`` [m] clear of ``obstacles`` (m, 5) rows
        ``[cx, cy, length, width, heading]`` (or, where it stands closer now, no closer than
        that); None when the search (:func:`~aac_sumo.kernels.manoeuvres.lattice_search`) finds no way."""
        start, goal = np.asarray(state, dtype=float).copy(), np.asarray(goal, dtype=float)
        start[3] = 0.0
        lo, hi = np.minimum(start[:2], goal) - BORDER, np.maximum(start[:2], goal) + BORDER
        obstacles = np.asarray(obstacles, dtype=float).reshape(-1, 5)
        radii = 0.5 * np.hypot(obstacles[:, 2], obstacles[:, 3])
        near = np.all((obstacles[:, :2] + radii[:, None] > lo - self.reach) & (obstacles[:, :2] - radii[:, None] < hi + self.reach), axis=1)
        obstacles, radii = np.ascontiguousarray(obstacles[near]), np.ascontiguousarray(radii[near])
        sets = [self.primitives(s) for s in (*self.steers, float(steer))]  # from each wheel set of the lattice, and from now
        width = max(int(lengths.max()) for _, lengths, _ in sets)
        prims = np.zeros((len(sets), len(sets[0][0]), width, 2))
        for w, (rows, _, _) in enumerate(sets):
            for p, r in enumerate(rows):
                prims[w, p, : len(r)] = r
        steps, costs = np.array([s[1] for s in sets]), np.array([s[2] for s in sets])
        after = np.repeat(np.arange(len(self.steers)), len(self.drives))
        offset, length, width_ = (float(a[0]) for a in self.shape)
        body = float(np.hypot(0.5 * length, 0.5 * width_))
        row = np.array([[start[0] + offset * np.cos(start[2]), start[1] + offset * np.sin(start[2]), length, width_, start[2]]])
        room = float(pairwise_clearance(row, obstacles).min()) if len(obstacles) else np.inf
        chain = lattice_search(start, room, goal, float(tolerance), prims, steps, costs, after, obstacles, radii, body, float(margin), SPARE,
                               lo, hi, CELL, HEADINGS, MAX_EXPANSIONS, WEIGHT, self.speed, self.dt, self.wheelbase, self.v_min, self.v_max,
                               offset, length, width_)
        if not len(chain):
            return None if np.hypot(*(start[:2] - goal)) > tolerance else np.zeros((0, 2))
        return np.vstack([sets[w][0][p] for w, p in chain])
