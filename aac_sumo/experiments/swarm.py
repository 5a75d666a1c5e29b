"""Goal-reaching swarms on the internal simulator.

* **S1 swarm rescue** (paper Table I): robots start on one side of an area and drive to goals
  near the trapped individuals along straight reference paths that cross, among static debris.
* **Circle swap**: ``n_robots`` evenly spaced on a circle drive to the antipodal points, the
  symmetric head-on case known to deadlock decentralised CBF methods.

Each robot's reference is the straight segment from its start to its goal at ``cruise_speed``,
slowing to stop at the goal; it has arrived when its rear axle is within ``goal_tolerance`` of
the goal. The seed shifts every start position uniformly within ``start_jitter``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.config.keys import MAX_ROBOTS, NN, P, rows
from aac_sumo.config.schema import from_section, param
from aac_sumo.experiments.common import Setup, check_start, coordinator, robot_spec
from aac_sumo.geometry import point_rect_signed_distance, OrientedRect
from aac_sumo.references import PathReference
from aac_sumo.registry import register_experiment
from aac_sumo.sim.internal import InternalSimulator
from aac_sumo.world import Obstacle, WorldState

def turn_radius(robot) -> float:
    """Tightest turning radius [m] of the rear axle of a robot that can reverse (0 if it cannot:
    backing off is then no option)."""
    lim = robot.model.limits
    return robot.model.wheelbase / np.tan(lim.steer_max) if lim.v_min < 0.0 else 0.0


#: Within this many goal tolerances of its goal a robot's reference runs straight at the goal
#: (:class:`~aac_sumo.references.PathReference` ``approach``).
GOAL_APPROACH = 3.0


def cruise_speed_param():
    """The ``cruise_speed`` field of a goal-reaching kind: the reference speed [m/s]."""
    return param(1.0, "reference speed along the straight path to the goal [m/s]", **P)


def goal_tolerance_param():
    """The ``goal_tolerance`` field of a goal-reaching kind: the arrival radius of the rear axle [m]."""
    return param(0.3, "a robot has arrived when its rear axle is this close to its goal [m]", **P)


def _rows(value) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(row) for row in value)


@dataclass(frozen=True)
class SwarmRescueParams:
    """Section ``[swarm_rescue]``: rear-axle start poses ``[x, y, heading]`` [m, m, rad] and goals
    ``[x, y]`` [m] (world frame), debris rectangles ``[cx, cy, length, width, heading]``
    [m, m, m, m, rad], and the goal-reaching settings (see the module)."""

    starts: tuple = param(((0.0, 0.0, 0.0), (0.0, 2.0, 0.0)), "start poses of the robots' rear axles [m, m, rad]",
                          parse=_rows, raw_default=[[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]], **rows("x", "y", "heading"))
    goals: tuple = param(((10.0, 2.0), (10.0, 0.0)), "goal of each robot's rear axle, one per start [m]",
                         parse=_rows, raw_default=[[10.0, 2.0], [10.0, 0.0]], **rows("x", "y"))
    debris: tuple = param((), "static obstacles as footprint rectangles [m, m, m, m, rad]", parse=_rows, raw_default=[],
                          **rows("cx", "cy", "length", "width", "heading"))
    cruise_speed: float = cruise_speed_param()
    goal_tolerance: float = goal_tolerance_param()
    start_jitter: float = param(0.1, "the seed shifts every start position uniformly within +- this [m]", **NN)


@dataclass(frozen=True)
class CircleSwapParams:
    """Section ``[circle_swap]``: ``n_robots`` on a circle of ``radius`` [m] about the origin,
    each driving to the antipodal point, and the goal-reaching settings (see the module)."""

    n_robots: int = param(8, "robots evenly spaced on the circle", check=lambda n: 2 <= n <= MAX_ROBOTS, expect=f"in 2..{MAX_ROBOTS}")
    radius: float = param(4.0, "circle radius; each robot drives to the antipodal point [m]", **P)
    cruise_speed: float = cruise_speed_param()
    goal_tolerance: float = goal_tolerance_param()
    start_jitter: float = param(0.05, "the seed shifts every start position uniformly within +- this [m]", **NN)


@register_experiment("swarm_rescue", params=SwarmRescueParams)
def build_swarm_rescue(scenario: Scenario) -> Setup:
    s = from_section(SwarmRescueParams, scenario, "swarm_rescue")
    starts, goals = np.array(s.starts, dtype=float).reshape(-1, 3), np.array(s.goals, dtype=float).reshape(-1, 2)
    if len(starts) == 0:
        raise ScenarioError(scenario.source, "swarm_rescue.starts", "at least one [x, y, heading] row")
    if len(goals) != len(starts):
        raise ScenarioError(scenario.source, "swarm_rescue.goals", f"one [x, y] row per start ({len(starts)})", len(goals))
    debris = [Obstacle(f"debris{k}", "static", np.array(row[:2], dtype=float), np.zeros(2), float(row[4]), float(row[2]), float(row[3]))
              for k, row in enumerate(s.debris)]
    return _goal_setup(scenario, "swarm_rescue", s, starts, goals, debris)


@register_experiment("circle_swap", params=CircleSwapParams)
def build_circle_swap(scenario: Scenario) -> Setup:
    c = from_section(CircleSwapParams, scenario, "circle_swap")
    angle = 2.0 * np.pi * np.arange(c.n_robots) / c.n_robots
    ring = c.radius * np.column_stack([np.cos(angle), np.sin(angle)])
    starts = np.column_stack([ring, angle + np.pi])
    return _goal_setup(scenario, "circle_swap", c, starts, -ring, [])


def _goal_setup(scenario: Scenario, section: str, p: SwarmRescueParams | CircleSwapParams, starts: np.ndarray, goals: np.ndarray,
                statics: list[Obstacle]) -> Setup:
    """Robots at ``starts`` (n, 3) rear-axle poses, each with a straight path to its goal (n, 2);
    ``p`` the kind's section ``[section]`` (its ``start_jitter``, ``goal_tolerance``, ``cruise_speed``)."""
    rng = np.random.default_rng(scenario["scenario.seed"])
    starts = starts.copy()
    starts[:, :2] += rng.uniform(-p.start_jitter, p.start_jitter, size=(len(starts), 2))
    for i, (start, goal) in enumerate(zip(starts, goals)):
        if np.hypot(*(goal - start[:2])) <= p.goal_tolerance:
            raise ScenarioError(scenario.source, f"{section}.goals", f"goal {i} farther than goal_tolerance from its start", goal.tolist())
        for o in statics:
            if point_rect_signed_distance(goal[None, :], OrientedRect(*o.footprint()))[0] <= 0:
                raise ScenarioError(scenario.source, f"{section}.goals", f"goal {i} outside every debris footprint (it lies in {o.name})", goal.tolist())
    robots = [robot_spec(scenario, f"robot{i}") for i in range(len(starts))]
    state = np.column_stack([starts, np.zeros(len(starts))])
    sim = InternalSimulator(robots, state, scenario["scenario.dt"], statics=statics)
    check_start(scenario, sim.observe(), f"{section}.starts")
    speed, tol = p.cruise_speed, p.goal_tolerance
    if speed > robots[0].model.limits.v_max:
        raise ScenarioError(scenario.source, f"{section}.cruise_speed", f"at most robot.v_max ({robots[0].model.limits.v_max})", speed)
    tasks = [PathReference([start[:2], goal], speed, decel=0.5 * robots[0].model.limits.a_max, approach=GOAL_APPROACH * tol,
                           turn_radius=turn_radius(robots[0]), arrive=tol)
             for start, goal in zip(starts, goals)]

    def finished(world: WorldState) -> np.ndarray:
        return np.hypot(*(world.states[:, :2] - goals).T) <= tol

    free_flow = np.array([t.length / speed for t in tasks])
    return Setup(scenario, sim, coordinator(scenario, tasks, finished=finished), tasks, finished, free_flow)
