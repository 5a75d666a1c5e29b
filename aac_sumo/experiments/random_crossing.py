"""Random crossing: ``n_robots`` seeded random starts and goals among random debris.

The square area is centred on the origin; its side ``sqrt(n_robots * area_per_robot)`` grows with
n so that the density stays constant. The draw, seeded by ``scenario.seed`` alone (same seed,
same scenario), goes in this order:

1. ``round(debris_density * side^2 / 100)`` debris rectangles, centres uniform in the area,
   length and width uniform in ``[debris_min_size, debris_max_size]``, heading uniform. Debris
   may overlap each other (a rubble heap).
2. Robot by robot, candidate start-goal pairs, both uniform in the area shrunk by the robot's
   reach (so every footprint lies inside it), until one passes every check:

   - the goal is at least ``min_travel_fraction * side`` (and twice ``goal_tolerance``) from the
     start, so paths cross the middle;
   - the start footprint, facing the goal, keeps ``clearance`` from every earlier start
     footprint and from every debris footprint (exact rectangle clearance);
   - the goal's reach disc (where the footprint can lie at the goal, whatever its heading:
     radius = rear axle to farthest corner) keeps ``clearance`` from every earlier goal's disc
     and from every debris footprint;
   - the straight path, the robot's reference, keeps ``path_clearance`` from every debris
     footprint.

   The robot checks test only the placed robots a KD-tree finds near a candidate (:class:`Placed`:
   the same verdicts as testing all of them, in O(log n) rather than O(n) a candidate).
   Candidates are drawn in batches of ``BATCH``. After ``MAX_TRIES`` rejected candidates for one
   robot the attempt is a dead end (the robots placed so far may leave no room) and the draw
   starts afresh, debris included, from the same random stream; after ``ATTEMPTS`` dead ends it
   gives up with a one-line :class:`ScenarioError` naming the key of the check
   that failed most often (``n_robots`` when robots crowd each other, ``debris_density`` when
   debris leaves no room, ``path_clearance``, ``min_travel_fraction``) and the share of
   candidates each check rejected (a candidate may fail several).

Robots start at rest facing their goal. As in :mod:`aac_sumo.experiments.swarm`, each robot's
reference is the straight segment from start to goal at ``cruise_speed`` (within
``GOAL_APPROACH`` goal tolerances it runs straight at the goal); it has arrived when its rear
axle is within ``goal_tolerance`` of its goal.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.config.keys import MAX_CROSSING_ROBOTS, NN, P
from aac_sumo.config.schema import from_section, param
from aac_sumo.experiments.common import Setup, check_start, coordinator, robot_params, robot_spec
from aac_sumo.experiments.swarm import GOAL_APPROACH, cruise_speed_param, goal_tolerance_param, turn_radius
from aac_sumo.geometry import pairwise_rect_clearance, rect_corners
from aac_sumo.kernels.geometry import paired_clearance
from aac_sumo.references import PathReference
from aac_sumo.registry import register_experiment
from aac_sumo.sim.internal import InternalSimulator
from aac_sumo.world import Obstacle, WorldState

SECTION = "random_crossing"
BATCH = 64         # candidate start-goal pairs drawn at once
MAX_TRIES = 5_000  # rejected candidates per robot before an attempt is a dead end
ATTEMPTS = 8       # fresh draws (debris and robots) before the scenario is rejected
MAX_DEBRIS = 2_000 # debris pieces at most (a bound on memory and time)
NEAR_SLACK = 1e-6  # [m] added to the KD-tree's search radius: pairs at the boundary are tested exactly

#: Rejection reasons, and the key to change when one of them keeps a robot from being placed.
REASONS = {
    "robots": "n_robots",            # start or goal too close to another robot's
    "debris": "debris_density",      # start or goal in or near debris
    "path": "path_clearance",        # straight path through debris
    "travel": "min_travel_fraction", # goal too close to its start
}


@dataclass(frozen=True)
class RandomCrossingParams:
    """Section ``[random_crossing]``: how many robots, the area per robot [m^2], the draw's
    checks (travel fraction of the side, clearances [m]), the debris (pieces per 100 m^2, sizes
    [m]) and the goal-reaching settings (see the module)."""

    n_robots: int = param(20, "robots, each with a seeded random start and a goal far across the area",
                          check=lambda n: 2 <= n <= MAX_CROSSING_ROBOTS,
                          expect=f"in 2..{MAX_CROSSING_ROBOTS}")
    area_per_robot: float = param(6.0, "the square area's side is sqrt(n_robots * area_per_robot): the density stays "
                                  "constant as n grows [m^2]", **P)
    density: float = param(0.0, "robots per 100 m^2 of area; above 0 it sets the area instead of area_per_robot "
                           "(100 / density m^2 a robot) [1/(100 m^2)]", **NN)
    min_travel_fraction: float = param(0.6, "each goal is at least this fraction of the area side from its start, so "
                                       "paths cross the middle", check=lambda f: 0 <= f <= 1.2, expect="in [0, 1.2]")
    clearance: float = param(0.5, "gap kept between start footprints, between goals' reach discs (the footprint at the goal "
                             "in any heading) and from every debris footprint [m]", **NN)
    path_clearance: float = param(0.5, "distance every straight start-goal path (rear-axle line) keeps from every debris "
                                  "footprint [m]", **NN)
    debris_density: float = param(2.0, "random debris rectangles per 100 m^2 of area (rounded)", **NN)
    debris_min_size: float = param(0.4, "smallest debris length or width [m]", **P)
    debris_max_size: float = param(1.2, "largest debris length or width [m]", **P)
    cruise_speed: float = cruise_speed_param()
    goal_tolerance: float = goal_tolerance_param()


def params(scenario: Scenario) -> RandomCrossingParams:
    """Section ``[random_crossing]`` of ``scenario``."""
    return from_section(RandomCrossingParams, scenario, SECTION)


@dataclass
class Draw:
    """One random-crossing instance: area side [m], rear-axle starts (n, 3) ``[x, y, heading]``,
    goals (n, 2) and debris rows (m, 5) ``[cx, cy, length, width, heading]``."""

    side: float
    starts: np.ndarray
    goals: np.ndarray
    debris: np.ndarray


def area_side(scenario: Scenario) -> float:
    """Side of the square area [m]: ``sqrt(n_robots * a)``, ``a`` the area a robot has
    (:func:`area_per_robot`)."""
    p = params(scenario)
    return float(np.sqrt(p.n_robots * area_per_robot(p)))


def area_per_robot(p: RandomCrossingParams) -> float:
    """The area [m^2] a robot has: ``100 / density`` when ``density`` is set, else ``area_per_robot``."""
    return 100.0 / p.density if p.density > 0.0 else p.area_per_robot


def _area_key(p: RandomCrossingParams) -> tuple[str, float]:
    """The key that sets the area, and its value (for error messages)."""
    return ("density", p.density) if p.density > 0.0 else ("area_per_robot", p.area_per_robot)


def debris_count(scenario: Scenario) -> int | float:
    """Debris pieces of the draw: ``round(debris_density * side^2 / 100)`` (inf when it overflows)."""
    side = area_side(scenario)
    count = params(scenario).debris_density * side * side / 100.0
    return round(count) if math.isfinite(count) else math.inf


def draw(scenario: Scenario) -> Draw:
    """The seeded random starts, goals and debris of ``scenario`` (see the module docstring)."""
    p, r = params(scenario), robot_params(scenario)
    if p.debris_max_size < p.debris_min_size:
        raise ScenarioError(scenario.source, f"{SECTION}.debris_max_size", f"at least debris_min_size ({p.debris_min_size})",
                            p.debris_max_size)
    rng = np.random.default_rng(scenario["scenario.seed"])
    side = area_side(scenario)
    reach = float(np.hypot(0.5 * r.length + 0.5 * r.wheelbase, 0.5 * r.width))  # rear axle to the farthest corner
    if 0.5 * side <= reach:
        key, value = _area_key(p)
        raise ScenarioError(scenario.source, f"{SECTION}.{key}",
                            f"an area whose side ({side:.2f} m) exceeds twice the robot's reach ({reach:.2f} m)", value)
    if debris_count(scenario) > MAX_DEBRIS:
        raise ScenarioError(scenario.source, f"{SECTION}.debris_density", f"at most {MAX_DEBRIS} debris pieces in the "
                            f"{side:.3g} m x {side:.3g} m area (debris_density * side^2 / 100)", p.debris_density)

    failures = []
    for _ in range(ATTEMPTS):
        result = _attempt(scenario, rng, side, reach)
        if isinstance(result, Draw):
            return result
        failures.append(result)
    i, tries, tally = max(failures, key=lambda f: f[0])  # the attempt that placed the most robots
    _give_up(scenario, i, side, tries, tally)


def _attempt(scenario: Scenario, rng: np.random.Generator, side: float, reach: float) -> Draw | tuple[int, int, dict]:
    """One fresh draw of debris and robots; on a dead end, (robot index, candidates, tally)."""
    p, r = params(scenario), robot_params(scenario)
    half, margin = 0.5 * side, 0.5 * side - reach
    length, width, offset = r.length, r.width, 0.5 * r.wheelbase
    n_debris = debris_count(scenario)
    debris = np.column_stack([
        rng.uniform(-half, half, size=(n_debris, 2)),
        rng.uniform(p.debris_min_size, p.debris_max_size, size=(n_debris, 2)),
        rng.uniform(0.0, np.pi, size=n_debris),
    ]) if n_debris else np.zeros((0, 5))
    debris_corners = rect_corners(debris)

    n, gap = p.n_robots, p.clearance
    min_travel = max(p.min_travel_fraction * side, 2.0 * p.goal_tolerance)
    starts, goals, footprints = np.zeros((n, 3)), np.zeros((n, 2)), np.zeros((n, 5))
    for i in range(n):
        placed = Placed(footprints[:i], goals[:i], foot_gap=gap, goal_gap=2 * reach + gap) if i else None
        tally = dict.fromkeys(REASONS, 0)
        tries = 0
        while True:
            s_xy = rng.uniform(-margin, margin, size=(BATCH, 2))
            g_xy = rng.uniform(-margin, margin, size=(BATCH, 2))
            delta = g_xy - s_xy
            travel = np.hypot(delta[:, 0], delta[:, 1])
            heading = np.arctan2(delta[:, 1], delta[:, 0])
            rows = np.column_stack([s_xy + offset * np.column_stack([np.cos(heading), np.sin(heading)]),
                                    np.full(BATCH, length), np.full(BATCH, width), heading])
            bad = {reason: np.zeros(BATCH, dtype=bool) for reason in REASONS}
            bad["travel"] = travel < min_travel
            if i:
                bad["robots"] = placed.clash(rows, g_xy)
            if len(debris):
                bad["debris"] |= pairwise_rect_clearance(rows, debris).min(axis=1) < gap
                bad["debris"] |= _point_rects(g_xy, debris).min(axis=1) < reach + gap
                bad["path"] |= _segment_rects(s_xy, g_xy, debris, debris_corners).min(axis=1) < p.path_clearance
            rejected = np.logical_or.reduce(list(bad.values()))
            ok = np.flatnonzero(~rejected)
            used = ok[0] if len(ok) else BATCH
            for reason in REASONS:  # a candidate counts under every check it fails
                tally[reason] += int(np.sum(bad[reason][:used]))
            tries += used
            if len(ok):
                starts[i], goals[i], footprints[i] = [*s_xy[used], heading[used]], g_xy[used], rows[used]
                break
            if tries >= MAX_TRIES:
                return i, tries, tally
    return Draw(side, starts, goals, debris)


def _give_up(scenario: Scenario, i: int, side: float, tries: int, tally: dict[str, int]) -> None:
    p = params(scenario)
    n = p.n_robots
    worst = max(tally, key=tally.get)  # ties: the first in REASONS
    shares = ", ".join(f"{100 * c / tries:.0f}% {what}" for what, c in sorted(tally.items(), key=lambda kv: -kv[1]) if c)
    key = REASONS[worst]
    raise ScenarioError(
        scenario.source, f"{SECTION}.{key}",
        f"robots that fit the {side:.1f} m x {side:.1f} m area ({area_per_robot(p):g} m^2 a robot, "
        f"clearance {p.clearance} m, debris_density {p.debris_density}): could not place robot {i} of {n} "
        f"in {tries} candidates (failed: {shares}; best of {ATTEMPTS} fresh draws)", getattr(p, key))


class Placed:
    """The robots placed so far, for the robot check of a batch of candidates: a candidate clashes
    when its start footprint comes within ``foot_gap`` of a placed start footprint (exact
    rectangle clearance) or its goal within ``goal_gap`` of a placed goal (centre distance).

    The same verdicts as testing every placed robot (the rule before, kept in the tests), pair by pair with
    the same arithmetic, but only for the pairs a KD-tree finds near enough to fail: footprints
    whose centres are farther apart than both circumradii plus ``foot_gap`` keep at least
    ``foot_gap`` between them (a margin of ``NEAR_SLACK`` covers round-off)."""

    def __init__(self, footprints: np.ndarray, goals: np.ndarray, foot_gap: float, goal_gap: float):
        self.footprints, self.goals, self.foot_gap, self.goal_gap = footprints, goals, foot_gap, goal_gap
        self.foot_tree, self.goal_tree = cKDTree(footprints[:, :2]), cKDTree(goals)
        self.circumradius = 0.5 * float(np.max(np.hypot(footprints[:, 2], footprints[:, 3])))

    def clash(self, rows: np.ndarray, g_xy: np.ndarray) -> np.ndarray:
        """Whether each candidate (start footprint ``rows`` (k, 5), goal ``g_xy`` (k, 2)) clashes."""
        reach = self.circumradius + 0.5 * float(np.max(np.hypot(rows[:, 2], rows[:, 3])))
        k, j = _near(self.foot_tree, rows[:, :2], reach + self.foot_gap)
        bad = np.zeros(len(rows), dtype=bool)
        bad[k[paired_clearance(rows[k], self.footprints[j]) < self.foot_gap]] = True
        k, j = _near(self.goal_tree, g_xy, self.goal_gap)
        a, b = g_xy[k], self.goals[j]
        bad[k[np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1]) < self.goal_gap]] = True
        return bad


def _near(tree: cKDTree, points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (k, j): the tree's point j within ``radius + NEAR_SLACK`` of ``points[k]``."""
    found = tree.query_ball_point(points, radius + NEAR_SLACK, return_sorted=False)
    counts = np.fromiter(map(len, found), dtype=np.intp, count=len(points))
    j = np.fromiter(itertools.chain.from_iterable(found), dtype=np.intp, count=int(counts.sum()))
    return np.repeat(np.arange(len(points)), counts), j


def _local(points: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """Points (k, 2) in each rectangle's frame: (k, m, 2)."""
    c, s = np.cos(rects[:, 4]), np.sin(rects[:, 4])
    dx, dy = points[:, None, 0] - rects[None, :, 0], points[:, None, 1] - rects[None, :, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


def _point_rects(points: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """Signed distance (k, m) from points (k, 2) to rectangles (m, 5), negative inside."""
    q = np.abs(_local(points, rects)) - 0.5 * rects[None, :, 2:4]
    outside = np.hypot(np.maximum(q[..., 0], 0.0), np.maximum(q[..., 1], 0.0))
    return outside + np.minimum(np.maximum(q[..., 0], q[..., 1]), 0.0)


def _segment_rects(p0: np.ndarray, p1: np.ndarray, rects: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Exact distance (k, m) from segments p0-p1 (k, 2) to rectangles (m, 5); 0 when they meet.

    Disjoint convex sets: the closest pair involves an endpoint of the segment or a corner of
    the rectangle. They meet when the segment, clipped to the rectangle's slab (Liang-Barsky in
    its frame), keeps a non-empty parameter interval."""
    a, b = _local(p0, rects), _local(p1, rects)
    ext = 0.5 * rects[None, :, 2:4]
    d = b - a
    lo, hi = np.zeros(a.shape[:2]), np.ones(a.shape[:2])
    meets = np.ones(a.shape[:2], dtype=bool)
    for ax in range(2):
        da, aa, e = d[..., ax], a[..., ax], ext[..., ax]
        still = np.abs(da) < 1e-12
        meets &= ~still | (np.abs(aa) <= e)
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (-e - aa) / da, (e - aa) / da
        t_lo, t_hi = np.where(still, 0.0, np.minimum(t0, t1)), np.where(still, 1.0, np.maximum(t0, t1))
        lo, hi = np.maximum(lo, t_lo), np.minimum(hi, t_hi)
    meets &= lo <= hi
    ends = np.minimum(_point_rects(p0, rects), _point_rects(p1, rects))
    # Corners (m, 4, 2) to segments (k): projection parameter clipped to [0, 1].
    seg = (p1 - p0)[:, None, None, :]
    rel = corners[None] - p0[:, None, None, :]
    t = np.clip((rel * seg).sum(-1) / np.maximum((seg * seg).sum(-1), 1e-12), 0.0, 1.0)
    corner = np.hypot(*(rel - t[..., None] * seg).transpose(3, 0, 1, 2)).min(axis=-1)
    return np.where(meets, 0.0, np.minimum(ends, corner))


@register_experiment("random_crossing", params=RandomCrossingParams)
def build_random_crossing(scenario: Scenario) -> Setup:
    """The drawn robots, each on a straight path to its goal, on the internal simulator."""
    p = params(scenario)
    limits = robot_spec(scenario, "robot").model.limits
    speed, tol = p.cruise_speed, p.goal_tolerance
    if speed > limits.v_max:
        raise ScenarioError(scenario.source, f"{SECTION}.cruise_speed", f"at most robot.v_max ({limits.v_max})", speed)
    d = draw(scenario)
    statics = [Obstacle(f"debris{k}", "static", row[:2].copy(), np.zeros(2), float(row[4]), float(row[2]), float(row[3]))
               for k, row in enumerate(d.debris)]
    robots = [robot_spec(scenario, f"robot{i}") for i in range(len(d.starts))]
    state = np.column_stack([d.starts, np.zeros(len(d.starts))])
    sim = InternalSimulator(robots, state, scenario["scenario.dt"], statics=statics)
    check_start(scenario, sim.observe(), f"{SECTION}.clearance")  # holds by construction
    goals = d.goals
    tasks = [PathReference([start[:2], goal], speed, decel=0.5 * limits.a_max, approach=GOAL_APPROACH * tol,
                           turn_radius=turn_radius(robots[0]), arrive=tol)
             for start, goal in zip(d.starts, goals)]

    def finished(world: WorldState) -> np.ndarray:
        return np.hypot(*(world.states[:, :2] - goals).T) <= tol

    free_flow = np.array([t.length / speed for t in tasks])
    return Setup(scenario, sim, coordinator(scenario, tasks, finished=finished), tasks, finished, free_flow)
