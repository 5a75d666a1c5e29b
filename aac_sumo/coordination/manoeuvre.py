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
from aac_sumo.kernels.motion import _bicycle_step, limited_steer

#: Driving speed [m/s] of a primitive and the acceleration [m/s^2] it sets off and stops with
#: (each within the robot's limits).
SPEED = 0.4
ACCEL = 1.0
#: Steering of the primitives as shares of the robot's steering limit, and the arc lengths [m];
#: where those find no way, the search is tried again with INCHING's (a robot hemmed in a few
#: centimetres from its neighbours, that no 0.3 m arc leaves, can inch out).
STEERS = (-1.0, -0.5, 0.0, 0.5, 1.0)
LENGTHS = (0.3, 0.9)
INCHING = (0.1, 0.3, 0.9)
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
#: A smoothed manoeuvre turns its wheels towards the next leg's angle this long [s] before it begins.
LEAD = 0.15
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
                 length: float, width: float, offset: float, dt: float, lengths: tuple[float, ...] = LENGTHS):
        self.wheelbase, self.dt = float(wheelbase), float(dt)
        self.v_min, self.v_max = float(v_min), float(v_max)
        self.shape = (np.array([float(offset)]), np.array([float(length)]), np.array([float(width)]))
        self.reach = float(np.hypot(offset + 0.5 * length, 0.5 * width))  # rear axle to the footprint's farthest corner
        speed = self.speed = min(SPEED, v_max)
        limit = min(float(steer_limits[0]), math.atan(float(steer_limits[1]) * wheelbase / speed ** 2))
        self.rate, self.steer_limits = float(steer_limits[2]) * dt, np.asarray(steer_limits, dtype=float)
        self.accel, self.decel = min(ACCEL, a_max), min(ACCEL, -a_min)
        self.steers = np.array(STEERS) * limit
        self.drives = [(d, d * speed_profile(length_, speed, self.accel, self.decel, dt))
                       for d in ((1.0, -1.0) if v_min < 0.0 else (1.0,)) for length_ in lengths]
        self.distances = [abs(float(np.sum(np.cumsum(a)[:-1]))) * dt * dt for _, a in self.drives]  # Euler: the speed each period starts with

    def primitives(self, steer: float) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
        """Every primitive from standstill with the wheels at ``steer`` [rad]: its inputs (K_p, 2),
        their lengths (P,), and their costs [s] (P,): their time, ``BACKWARD_COST`` times it backwards."""
        rows, costs = [], []
        for target in self.steers:
            ramp = self._ramp(steer, target)
            for direction, accels in self.drives:
                head = np.column_stack([np.zeros(len(ramp)), ramp]).reshape(-1, 2)
                rows.append(np.vstack([head, np.column_stack([accels, np.full(len(accels), target)])]))
                costs.append(len(rows[-1]) * self.dt * (BACKWARD_COST if direction < 0.0 else 1.0))
        return rows, np.array([len(r) for r in rows]), np.array(costs)

    def plan(self, state: np.ndarray, steer: float, goal: np.ndarray, tolerance: float, obstacles: np.ndarray,
             margin: float) -> np.ndarray | None:
        """The inputs (K, 2) of :meth:`stop_and_go` along the legs :meth:`search` finds; None
        when it finds none."""
        legs = self.search(state, steer, goal, tolerance, obstacles, margin)
        return None if legs is None else self.stop_and_go(legs, steer)

    def search(self, state: np.ndarray, steer: float, goal: np.ndarray, tolerance: float, obstacles: np.ndarray,
               margin: float) -> list[tuple[int, float]] | None:
        """The legs ``(drive, steer)`` (an index into the drives, and the wheels' angle [rad]) from
        rear-axle ``state`` (4,) at rest with the wheels at ``steer`` to a standstill whose rear
        axle lies within ``tolerance`` [m] of ``goal`` (2,), every footprint on the way ``margin``
        [m] clear of ``obstacles`` (m, 5) rows ``[cx, cy, length, width, heading]`` (or, where it
        stands closer now, no closer than that); None when the search
        (:func:`~aac_sumo.kernels.manoeuvres.lattice_search`) finds no way."""
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
            return None if np.hypot(*(start[:2] - goal)) > tolerance else []
        return [(int(p) % len(self.drives), float(self.steers[int(p) // len(self.drives)])) for _, p in chain]

    def _ramp(self, steer: float, target: float) -> list[float]:
        """The wheels' angles [rad], period by period, from ``steer`` to ``target`` at the steering rate."""
        out = []
        while abs(target - steer) > 1e-12:
            steer = min(max(target, steer - self.rate), steer + self.rate)
            out.append(steer)
        return out

    def to_rest(self, state: np.ndarray, steer: float) -> tuple[np.ndarray, np.ndarray]:
        """Inputs (m, 2) that bring rear-axle ``state`` (4,) to rest at up to the primitives'
        deceleration, the wheels held at ``steer`` [rad], and the state (4,) at rest (the
        simulator's Euler step): where a manoeuvre of a robot still rocking begins."""
        x, y, h, v = (float(a) for a in state)
        rows = []
        while abs(v) > 1e-9:
            accel = -math.copysign(min(self.decel, abs(v) / self.dt), v)
            rows.append((accel, steer))
            x, y, h, v = _bicycle_step(x, y, h, v, accel, steer, self.dt, self.wheelbase, self.v_min, self.v_max)
        return np.array(rows, dtype=float).reshape(-1, 2), np.array([x, y, h, 0.0])

    def stop_and_go(self, legs: list[tuple[int, float]], steer: float) -> np.ndarray:
        """Inputs (K, 2) of ``legs`` as searched: before each, the wheels turn where the robot
        stands (from ``steer`` [rad] at first); each drives its arc and stops."""
        rows = [np.zeros((0, 2))]
        for drive, target in legs:
            ramp = self._ramp(steer, target)
            accels = self.drives[drive][1]
            rows += [np.column_stack([np.zeros(len(ramp)), ramp]).reshape(-1, 2), np.column_stack([accels, np.full(len(accels), target)])]
            steer = target
        return np.vstack(rows)

    def smooth(self, legs: list[tuple[int, float]], steer: float, speed: float) -> np.ndarray:
        """Inputs (K, 2) along ``legs`` without the stops between legs of one direction: each run
        of them is driven at up to ``speed`` [m/s], the wheels turning towards the next leg's angle
        at the steering rate ``LEAD`` [s] of driving before it begins. Its course leaves the
        searched one where the wheels turn, so it is a candidate only (the exact check decides)."""
        rows, k = [np.zeros((0, 2))], 0
        while k < len(legs):
            run = [legs[k]]
            while k + len(run) < len(legs) and self.drives[legs[k + len(run)][0]][0] == self.drives[legs[k][0]][0]:
                run.append(legs[k + len(run)])
            k += len(run)
            direction = self.drives[run[0][0]][0]
            ramp = self._ramp(steer, run[0][1])
            ends = np.cumsum([self.distances[d] for d, _ in run])
            accels = direction * speed_profile(float(ends[-1]), speed, self.accel, self.decel, self.dt)
            v, s, out = 0.0, 0.0, []
            steer = run[0][1]
            for a in accels:
                target = run[min(int(np.searchsorted(ends, s + abs(v) * LEAD, side="right")), len(run) - 1)][1]
                steer = limited_steer(target, v, a, steer, self.wheelbase, self.steer_limits, self.dt)
                out.append((a, steer))
                s, v = s + abs(v) * self.dt, v + a * self.dt
            rows += [np.column_stack([np.zeros(len(ramp)), ramp]).reshape(-1, 2), np.array(out).reshape(-1, 2)]
        return np.vstack(rows)
