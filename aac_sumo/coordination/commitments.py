"""Committed plans: what makes AAC collision-free by construction (beyond the paper).

A robot's **commitment** is the course it drives until it next holds authority: the inputs of
its last MPC plan (possibly cut short), then a **stopping tail** that brakes it to standstill at
``tail_decel`` [m/s^2] while turning towards its reference's heading; after the tail it stands.
The states of a commitment are the exact rollout of its inputs with the simulator's Euler model,
so a robot that executes its commitment is where the commitment says, period after period.

A commitment replaces the old one only after an exact check: its footprint keeps at least
``margin`` [m] from every other robot's current commitment (each standing still after its end)
and from every standing obstacle, at every period, until both stand. Initially every robot is
committed to braking to a stop where it is. Hence, by induction, no two commitments ever come
closer than the margin, and the old commitment, shifted by the periods since it was made, is
always a safe fallback: a solve that fails, or a plan whose tail fails the check, changes
nothing. See ``docs/coordination.md`` for the argument and its limits.

Vehicles the coordinator does not drive (SUMO's own cars) ride in the check as **braking
courses** (:func:`~aac_sumo.coordination.traffic_courses.braking_courses`): each goes on along its velocity braking at ``traffic_decel``
until it stands. A vehicle that never brakes harder than that and keeps its direction is, at
every moment, at or beyond that course, so a commitment clear of the course stays clear of the
vehicle: a car following it keeps the room to stop behind where it can stop. Only the vehicles
ahead of the robot checked count (their centres ahead of its footprint centre along its
heading): one behind it keeps its own distance, as its driver does, within the lane-change gap
rule. With :attr:`CommitmentBook.reaction` set, a commitment is held against them reactively:
its first period, then braking (:meth:`CommitmentBook.traffic_rows`). A robot then relies on
braking at that reaction once a vehicle ahead brakes, so with :attr:`CommitmentBook.reaction` the
robots' reactions also keep the margin from each other (:meth:`CommitmentBook.check`), and
any robot may at the next period take up its reaction of now as its commitment
(:attr:`CommitmentBook.fallbacks`): a robot that must brake for a vehicle does, and every robot
whose commitment that braking meets takes up its own reaction in the same period.

Frames and units: world frame [m], headings [rad], speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from aac_sumo.coordination.regions import Fleet
from aac_sumo.coordination.traffic_courses import ahead_of, binding
from aac_sumo.coordination.walker_reach import WalkerReach
from aac_sumo.kernels.commitments import course_boxes, course_clearance, pair_components, ragged_nearest, stopping_course
from aac_sumo.kernels.motion import footprint_rows
from aac_sumo.references import PathReference

#: Time constant [s] with which a stopping tail turns the heading towards the reference's.
TAIL_TURN_TIME = 0.5


@dataclass
class Commitment:
    """Inputs (T, 2) from period ``start`` on, and the rear-axle states (T+1, 4) they give
    (``states[0]`` at ``start``); ``planned`` of the inputs come from an MPC plan, the rest
    are the stopping tail. After period ``start + T`` the robot stands still."""

    start: int
    states: np.ndarray
    inputs: np.ndarray
    planned: int
    rows: np.ndarray | None = field(default=None, repr=False, compare=False)  # footprint rows (T+1, 5) of ``states``, once asked for
    reacted: bool = False  # a reaction's stop taken up as the commitment (CommitmentBook.fallbacks): its own reaction from then on
    react: tuple | None = field(default=None, repr=False, compare=False)  # (period, its reaction then, that reaction's footprint rows), once asked for

    def input_at(self, period: int) -> np.ndarray:
        """The input [accel, steer] of ``period``; once ended (standing), none and the wheels where its last input left them."""
        k = period - self.start
        return self.inputs[k] if k < len(self.inputs) else np.array([0.0, self.inputs[-1, 1] if len(self.inputs) else 0.0])

    def stage(self, period: int) -> str:
        """``plan`` in the planned part, ``tail`` while braking, ``hold`` once standing."""
        k = period - self.start
        return "plan" if k < self.planned else "tail" if k < len(self.inputs) else "hold"

    def remaining(self, period: int) -> int:
        """Periods of the commitment left from ``period``."""
        return max(len(self.inputs) - (period - self.start), 0)

    def course(self, period: int, steps: int) -> np.ndarray:
        """States (steps+1, 4) from ``period`` on, the last state repeated once it has ended."""
        k = period - self.start
        idx = np.minimum(np.arange(k, k + steps + 1), len(self.states) - 1)
        return self.states[idx]

    def inputs_ahead(self, period: int, steps: int) -> np.ndarray:
        """Inputs (steps, 2) from ``period`` on, zero once it has ended."""
        out = np.zeros((steps, 2))
        rest = self.inputs[period - self.start:][:steps]
        out[: len(rest)] = rest
        return out


def stopping_commitment(fleet: Fleet, i: int, start: int, state: np.ndarray, head: np.ndarray, heading: float | PathReference,
                        tail_decel: float, previous_steer: float, dt: float) -> Commitment:
    """Robot ``i``'s commitment from ``state`` at period ``start``: the inputs ``head`` (m, 2),
    then a stopping tail at ``tail_decel`` turning towards ``heading`` [rad], or, for a path,
    towards the path's heading where the head ends (a path that goes on, a lane: where the robot
    will be, period after period, so that it brakes along a curve), within the robot's steering limits from
    the head's last steering (``previous_steer`` [rad], the steering applied before ``start``,
    when the head is empty). One compiled call (:func:`~aac_sumo.kernels.stopping_course`)."""
    head = np.ascontiguousarray(np.asarray(head, dtype=float).reshape(-1, 2))
    along = isinstance(heading, PathReference) and not heading.stop_at_end
    if isinstance(heading, PathReference):
        points, seg_len, cum, _, seg_heading, t_max, centres, radii, chunk, _ = heading.arrays()
        heading = np.nan
    else:
        points, seg_len, cum, seg_heading, t_max, centres, radii, chunk = _NO_PATH
    states, inputs = stopping_course(np.asarray(state, dtype=float), head, float(previous_steer), float(heading), float(tail_decel),
                                     fleet.wheelbase[i], fleet.v_min[i], fleet.v_max[i], fleet.steer_limits[i], dt, TAIL_TURN_TIME,
                                     points, seg_len, cum, seg_heading, t_max, centres, radii, chunk, along)
    return Commitment(start, states, inputs, len(head))


#: The path arguments of :func:`~aac_sumo.kernels.stopping_course` when the tail's heading is given.
_NO_PATH = (np.empty((0, 2)), np.empty(0), np.empty(1), np.empty(0), np.empty(0), np.empty((0, 2)), np.empty(0), 1)


class CommitmentBook:
    """Every robot's commitment, the fleet's footprints along them, and the exact check.

    The footprints of every commitment from the current period to its end are kept in one
    array, computed once per period (a replaced commitment's rows are appended), so that a
    check costs one compiled pass (:func:`~aac_sumo.kernels.ragged_nearest`, which visits only
    the courses whose boxes come near the candidate's)."""

    def __init__(self, fleet: Fleet, commitments: list[Commitment], margin: float):
        self.fleet, self.items, self.margin = fleet, list(commitments), float(margin)
        self._period: int | None = None
        self._flat: tuple | None = None  # (rows, starts, lengths, the statics they hold, the courses' boxes)
        self._refused: dict[int, tuple | None] = {}  # per robot, its last refusal by something standing (see refuse)
        self.walkers: WalkerReach | None = None  # the walkers of the current period, set by the coordinator (see check)
        self.traffic: list[np.ndarray] = []  # footprint rows of the uncontrolled vehicles' braking courses this period (see check)
        self.lines = np.zeros(0, dtype=bool)  # which of them are stop lines (traffic_courses.stop_lines)
        self._traffic: tuple | None = None  # (period, the list above, its flat rows, starts, lengths, boxes)
        self.reaction: tuple[np.ndarray, float] | None = None  # (per robot deceleration [m/s^2], dt [s]): see traffic_rows
        self.beside = False  # whether traffic_gap also holds the vehicles beside and behind in another lane
        self.fallbacks: list[Commitment] | None = None  # with reaction: each robot's reaction of the period before (see hold_fallbacks)
        self.paths: list | None = None  # each robot's path this period, set by the coordinator (see reaction_course)
        self._reactions: tuple | None = None  # (period, flat reaction rows, starts, lengths, boxes): see reaction_gap
        # every commitment's states, each padded with its last state to one length (n, L, 4), for courses
        self._states = np.zeros((len(self.items), 1, 4))
        self._start = np.zeros(len(self.items), dtype=int)  # each commitment's first period
        for j, c in enumerate(self.items):
            self._pad(j, c)

    def inputs(self, period: int) -> np.ndarray:
        """Every robot's committed input (n, 2) of ``period``."""
        return np.array([c.input_at(period) for c in self.items]).reshape(-1, 2)

    def courses(self, period: int, idx: np.ndarray, steps: int) -> np.ndarray:
        """States (m, steps+1, 4) of robots ``idx`` along their commitments from ``period`` (by
        which each has begun), the last state repeated once one has ended."""
        idx = np.asarray(idx, dtype=int)
        stage = np.minimum((period - self._start[idx])[:, None] + np.arange(steps + 1), self._states.shape[1] - 1)
        return self._states[idx[:, None], stage]

    def _pad(self, j: int, commitment: Commitment) -> None:
        """Store robot ``j``'s commitment states in the padded array (longer if need be)."""
        self._start[j] = commitment.start
        count = len(commitment.states)
        if count > self._states.shape[1]:
            grown = np.empty((len(self._states), count, 4))
            grown[:, : self._states.shape[1]] = self._states
            grown[:, self._states.shape[1]:] = self._states[:, -1:]
            self._states = grown
        self._states[j, :count] = commitment.states
        self._states[j, count:] = commitment.states[-1]

    def replace(self, i: int, commitment: Commitment, period: int) -> None:
        """Commit robot ``i`` to ``commitment`` (checked by the caller) from ``period`` on."""
        self.items[i] = commitment
        self._pad(i, commitment)
        if self._period == period and self._flat is not None:  # its new rows go at the end; the old ones are left unread
            flat, starts, lengths, statics, boxes = self._flat
            self._flat = (_appended(flat, starts, lengths, boxes, i, self.footprints(i, commitment, period)), starts, lengths, statics, boxes)
        if self._reactions is not None and self._reactions[0] == period:  # its new reaction likewise
            _, flat, starts, lengths, boxes = self._reactions
            self._reactions = (period, _appended(flat, starts, lengths, boxes, i, self.traffic_rows(i, commitment, period)), starts, lengths,
                               boxes)

    def park(self, off_road: np.ndarray, states: np.ndarray, period: int) -> None:
        """Robots ``off_road`` (n,) bool, taken off the road, stand at their ``states`` (n, 4)
        (their parking spots) from ``period`` on: a finished car's commitment goes with it."""
        for i in np.flatnonzero(off_road):
            if np.any(self.items[i].course(period, 0)[0, :2] != states[i, :2]):
                self.replace(int(i), Commitment(period, np.array(states[i:i + 1], dtype=float), np.zeros((0, 2)), 0), period)

    def footprints(self, i: int, commitment: Commitment, period: int) -> np.ndarray:
        """Footprint rows (remaining + 1, 5) of robot ``i`` along ``commitment`` from ``period``
        to the stage where it stands (rows of the whole commitment, computed once, then sliced)."""
        if commitment.rows is None:
            commitment.rows = footprint_rows(commitment.states[None], self.fleet.offset[[i]], self.fleet.length[[i]], self.fleet.width[[i]])[0]
        return commitment.rows[min(max(period - commitment.start, 0), len(commitment.inputs)):]

    def clearance(self, i: int, candidate: Commitment, period: int, statics: np.ndarray, walkers: bool = True,
                  traffic: bool = True) -> float:
        """Least footprint clearance [m] of robot ``i`` along ``candidate`` to every other
        robot along its commitment and to the standing obstacles ``statics`` (S, 5), from
        ``period`` until all stand still (exact below ``margin``), and to the braking courses of
        the uncontrolled vehicles ahead of it (:attr:`traffic`, set each period); with
        ``walkers`` and :attr:`walkers` set, also ``margin`` plus the course's slack to the
        walkers' regions (:class:`~aac_sumo.coordination.walker_reach.WalkerReach`), so that it
        passes (``>= margin``) only clear of them; without ``traffic``, not to the vehicles."""
        return self.check(i, candidate, period, statics, walkers, traffic)[0]

    def check(self, i: int, candidate: Commitment, period: int, statics: np.ndarray, walkers: bool = True,
              traffic: bool = True) -> tuple[float, int]:
        """:meth:`clearance` and what gives it: a robot's index, ``n`` + the row of ``statics``
        for a standing obstacle, -3 for an uncontrolled vehicle, -2 for a walker, -1 for
        nothing. The standing obstacles ride in the same flat array as the commitments (courses
        of one row), so a check is one compiled pass, and one more for the vehicles ahead."""
        if self._period != period or self._flat is None or self._flat[3] is not statics:
            self._period = period
            fixed = np.asarray(statics, dtype=float).reshape(-1, 5)
            flat, starts, lengths, boxes = _ragged([self.footprints(j, c, period) for j, c in enumerate(self.items)] + list(fixed[:, None]))
            self._flat = (flat, starts, lengths, statics, boxes)
        flat, starts, lengths, _, boxes = self._flat
        rows = self.footprints(i, candidate, period)
        gap, nearest = ragged_nearest(rows, flat, starts, lengths, boxes, i, self.margin)
        if self.reaction is not None and gap >= self.margin:  # the robots' reactions keep apart too
            apart, other = self.reaction_gap(i, candidate, period)
            if apart < gap:
                gap, nearest = apart, other
        if traffic and self.traffic and gap >= self.margin:
            ahead = self.traffic_gap(self.traffic_rows(i, candidate, period), period)
            if ahead < gap:
                gap, nearest = ahead, -3
        if walkers and self.walkers is not None and gap >= self.margin:
            slack = min(self.walkers.slack(rows), self.walkers.stand_slack(rows[-1]))
            if self.margin + slack < gap:
                return self.margin + slack, -2
        return float(gap), int(nearest)

    def traffic_rows(self, i: int, commitment: Commitment, period: int) -> np.ndarray:
        """The footprint rows robot ``i`` along ``commitment`` holds against the uncontrolled
        vehicles from ``period`` on: the commitment's own, or with :attr:`reaction` set, its
        first period and then braking to a stop (:meth:`reaction_course`: the check is reactive)."""
        if self.reaction is None or commitment.reacted:
            return self.footprints(i, commitment, period)
        if commitment.react is None or commitment.react[0] != period:
            react = self.reaction_course(i, commitment, period)
            commitment.react = (period, react, footprint_rows(react.states[None], self.fleet.offset[[i]], self.fleet.length[[i]], self.fleet.width[[i]])[0])
        return commitment.react[2]

    def reaction_course(self, i: int, commitment: Commitment, period: int) -> Commitment:
        """Robot ``i``'s reaction along ``commitment`` from ``period`` (:attr:`reaction` set):
        its input of ``period``, then braking to a stop along its path in :attr:`paths` (a car
        changing lanes finishes the change as its tails do; straight on, it ran into the next
        lane), else straight on (a reaction taken up, :attr:`Commitment.reacted`, is its own)."""
        if commitment.reacted:
            return commitment
        decel, dt = self.reaction
        k = min(max(period - commitment.start, 0), len(commitment.inputs))
        state, head = commitment.states[k], commitment.inputs[k:k + 1]
        steer = float(head[0, 1]) if len(head) else 0.0
        along = self.paths[i] if self.paths is not None else float(state[2])
        react = stopping_commitment(self.fleet, i, period, state, head, along, float(decel[i]), steer, dt)
        react.reacted = True
        return react

    def hold_fallbacks(self, period: int) -> None:
        """With :attr:`reaction`, at the start of ``period`` (before any commitment changes):
        each robot's reaction along its commitment of the period before (:attr:`fallbacks`).
        The robot has driven that reaction's first input, so from ``period`` on it is a
        commitment the robot can take up, checked against every other robot's reaction when
        made (:meth:`check`), and against the vehicles ahead (:meth:`traffic_gap`, by
        ``brake_for_traffic``). A commitment made this period is its own fallback."""
        if self.reaction is None:
            self.fallbacks = None
            return
        self.fallbacks = [c if c.start >= period else c.react[1] if c.react is not None and c.react[0] == period - 1
                          else self.reaction_course(j, c, period - 1) for j, c in enumerate(self.items)]  # the reaction held then

    def reaction_gap(self, i: int, candidate: Commitment, period: int) -> tuple[float, int]:
        """Least clearance [m] of robot ``i``'s reaction along ``candidate`` to every other
        robot's reaction along its commitment, from ``period`` on, and the robot that gives it
        (exact below ``margin``; -1 for none)."""
        if self._reactions is None or self._reactions[0] != period:
            self._reactions = (period, *_ragged([self.traffic_rows(j, c, period) for j, c in enumerate(self.items)]))
        _, flat, starts, lengths, boxes = self._reactions
        gap, nearest = ragged_nearest(self.traffic_rows(i, candidate, period), flat, starts, lengths, boxes, i, self.margin)
        return float(gap), int(nearest)

    def traffic_gap(self, rows: np.ndarray, period: int) -> float:
        """Least clearance [m] of the footprint rows ``rows`` (a course from ``period`` on) to
        the braking courses of the uncontrolled vehicles whose centres are ahead of ``rows[0]``
        along its heading, and with ``beside`` also of those that are not straight behind it
        (their centre further across its heading than half the two widths: in another lane); of
        the stop lines among them (:attr:`lines`) only those that bind it;
        inf without any."""
        if self._traffic is None or self._traffic[0] != period or self._traffic[1] is not self.traffic:
            self._traffic = (period, self.traffic, *_ragged(self.traffic))
        _, _, flat, starts, lengths, boxes = self._traffic
        counted = ahead_of(flat[starts, :2], rows[0, :2], float(rows[0, 4]))
        if self.beside:
            normal = np.array([-np.sin(rows[0, 4]), np.cos(rows[0, 4])])
            counted |= np.abs((flat[starts, :2] - rows[0, :2]) @ normal) > 0.5 * (rows[0, 3] + flat[starts, 3])
        counted &= binding(flat[starts], self.lines, float(rows[0, 4]))
        ahead = np.flatnonzero(counted)
        if ahead.size == 0:
            return np.inf
        return float(ragged_nearest(rows, flat, starts[ahead], lengths[ahead], boxes[ahead], -1, self.margin)[0])

    def refuse(self, i: int, state: np.ndarray, key: tuple, blocker: int, period: int, statics: np.ndarray) -> None:
        """Remember that robot ``i``, standing at ``state`` (4,), had a candidate (made from
        ``state`` and ``key``, compared with ``is`` or ``==``) refused by ``blocker`` (from
        :meth:`check`), when that blocker stands for good: a robot holding at the end of its
        commitment, or a standing obstacle. Anything else forgets what was remembered."""
        n = len(self.items)
        what = None
        if state[3] == 0.0 and 0 <= blocker < n and self.items[blocker].stage(period) == "hold":
            what = self.items[blocker]
        elif state[3] == 0.0 and n <= blocker < n + len(np.asarray(statics).reshape(-1, 5)):
            what = np.array(statics[blocker - n], dtype=float)
        self._refused[i] = None if what is None else (np.array(state, dtype=float), key, blocker, what)

    def refused_again(self, i: int, state: np.ndarray, key: tuple, statics: np.ndarray) -> bool:
        """Whether :meth:`check` would refuse robot ``i``'s candidate again, known without
        computing it: ``i`` stands at the same ``state`` with the same ``key`` as when it was
        refused (so the candidate is the same course), and the blocker is still the same
        holding commitment or standing obstacle (the same footprint at every stage). The pair's
        clearance is then the same number below the margin."""
        memo = self._refused.get(i)
        if memo is None:
            return False
        before, known, blocker, what = memo
        if not (np.array_equal(before, state) and len(known) == len(key) and all(a is b or a == b for a, b in zip(known, key))):
            return False
        n, fixed = len(self.items), np.asarray(statics, dtype=float).reshape(-1, 5)
        if blocker < n:
            return self.items[blocker] is what
        return blocker - n < len(fixed) and np.array_equal(fixed[blocker - n], what)

    def pairwise_clearance(self, period: int, statics: np.ndarray | None = None) -> np.ndarray:
        """Least clearance [m] (n, n) between every two commitments from ``period`` on (inf on
        the diagonal), and to ``statics`` in an extra last column when given."""
        n = len(self.items)
        steps = max(c.remaining(period) for c in self.items) + 1
        rows = self.fleet.footprints(np.arange(n), self.courses(period, np.arange(n), steps))
        out = np.full((n, n + (statics is not None)), np.inf)
        for i in range(n):
            for j in range(i + 1, n):
                out[i, j] = out[j, i] = course_clearance(rows[i], rows[j][None], np.inf)
            if statics is not None and len(statics):
                fixed = np.repeat(np.asarray(statics, dtype=float).reshape(-1, 1, 5), steps + 1, axis=1)
                out[i, n] = course_clearance(rows[i], fixed, np.inf)
        return out


def _ragged(courses: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Footprint-row courses (each (K_j, 5)) as one flat array, each course's first row and
    length in it, and their bounding boxes (:func:`~aac_sumo.kernels.course_boxes`)."""
    lengths = np.array([len(c) for c in courses], dtype=np.int64)
    starts = np.r_[0, np.cumsum(lengths)[:-1]].astype(np.int64) if len(lengths) else lengths
    flat = np.concatenate(courses) if courses else np.zeros((0, 5))
    return flat, starts, lengths, course_boxes(flat, starts, lengths)


def _appended(flat: np.ndarray, starts: np.ndarray, lengths: np.ndarray, boxes: np.ndarray, i: int, rows: np.ndarray) -> np.ndarray:
    """Course ``i`` of a :func:`_ragged` array replaced by ``rows``: they go at the end of the flat
    array (returned), ``starts``, ``lengths`` and ``boxes`` are changed in place; the old rows stay unread."""
    starts[i], lengths[i] = len(flat), len(rows)
    boxes[i] = course_boxes(rows, np.zeros(1, dtype=np.int64), lengths[i: i + 1])[0]
    return np.concatenate([flat, rows])


def reach_radii(fleet: Fleet, states: np.ndarray, horizon: int, dt: float, tail_decel=None) -> np.ndarray:
    """Per robot, a radius [m] around its footprint centre that contains its footprint along any
    course it can commit to from ``states`` (n, 4), and along the rest of its current
    commitment: ``horizon`` periods accelerating as hard as it can, then a stopping tail at
    ``tail_decel`` [m/s^2] (the farthest any such course goes), plus twice the rear-axle-to-centre
    offset (turning) and the footprint's half diagonal. Without ``tail_decel``: over the
    ``horizon`` periods only."""
    speed = np.abs(states[:, 3])
    accel = np.maximum(fleet.a_max, -fleet.a_min)
    top = np.maximum(fleet.v_max, -fleet.v_min)
    k = np.arange(horizon)
    speeds = np.minimum(top[:, None], speed[:, None] + accel[:, None] * dt * k[None, :])  # speed at the start of each period
    end = np.minimum(top, speed + accel * dt * horizon)
    travel = speeds.sum(axis=1) * dt + (0.0 if tail_decel is None else end**2 / (2.0 * tail_decel) + end * dt)
    return travel + 2.0 * np.abs(fleet.offset) + 0.5 * np.hypot(fleet.length, fleet.width)


def clusters(centres: np.ndarray, radii: np.ndarray, margin: float) -> list[np.ndarray]:
    """Connected components (each sorted robot indices, ordered by their first index) of the
    graph whose edges join robots whose reach discs (``centres`` (n, 2), ``radii`` (n,)) come
    within ``margin`` of each other: robots in different components cannot interact over the
    courses they can commit to now."""
    n = len(centres)
    if n == 0:
        return []
    pairs = cKDTree(centres).query_pairs(2.0 * float(radii.max()) + margin, output_type="ndarray")
    if len(pairs):
        gap = np.hypot(*(centres[pairs[:, 0]] - centres[pairs[:, 1]]).T) - radii[pairs[:, 0]] - radii[pairs[:, 1]]
        pairs = pairs[gap < margin]
    label = pair_components(n, pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)) if len(pairs) else np.arange(n)
    order = np.argsort(label, kind="stable")  # each component's robots in index order; labels follow their lowest robots
    return np.split(order, np.cumsum(np.bincount(label))[:-1])
