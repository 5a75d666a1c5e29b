"""Close pairs and the proximity decision of AAC (paper Algorithm 1, as DESIGN.md reads it).

Positions are world-frame [m]. The decision grows one sampling tree per candidate robot, all
trees in one compiled loop (:func:`~aac_sumo.kernels.grow_trees`): each iteration draws a
seeded random sample within ``sample_radius`` of every robot, finds each tree's nearest node
and steps ``tree_step`` toward the sample. Every new node is scored ``alpha * progress - beta * collision_cost``, where progress is the reduction
of the distance to the goal from the robot's position (the paper's ``alpha * d(s, g)`` rewards
moving away from the goal, a sign slip) and the collision cost sums ``(1 - d / r)^2`` over the
other robots and obstacles closer than ``r``, along the node's path from the root. Each robot's
best-scoring node ends its best path; the robot whose best path makes the most progress gets
authority.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param
from aac_sumo.kernels.proximity import grow_trees


def close_pairs(centres: np.ndarray, distance: float) -> np.ndarray:
    """Index pairs ``(i, j)``, i < j, of points (n, 2) closer than ``distance`` [m], sorted (P, 2)."""
    if len(centres) < 2:
        return np.empty((0, 2), dtype=int)
    pairs = cKDTree(centres).query_pairs(distance, output_type="ndarray")
    if len(pairs):
        gaps = np.hypot(*(centres[pairs[:, 0]] - centres[pairs[:, 1]]).T)
        pairs = pairs[gaps < distance]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if len(pairs) else np.empty((0, 2), dtype=int)


@dataclass(frozen=True)
class ProximityParams:
    """Sampling-tree settings: iterations per robot, score weights alpha [1/m] and beta, step
    length [m], sampling radius [m], collision-cost radius [m] and the share of samples drawn
    at the goal (the usual RRT goal bias)."""

    iterations: int = param(40, "sampling-tree iterations per robot in the proximity decision", key="proximity_iterations",
                            check=lambda n: 1 <= n <= 10_000, expect="in 1..10000")
    alpha: float = param(1.0, "proximity score weight on progress toward the goal [1/m]", **NN)
    beta: float = param(2.0, "proximity score weight on the collision cost with other robots", **NN)
    step: float = param(0.3, "sampling-tree step length [m]", key="tree_step", **P)
    sample_radius: float = param(3.0, "sampling-tree samples are drawn within this radius of the robot [m]", **P)
    collision_radius: float = param(1.0, "a tree node closer than this to another robot costs (1 - d/r)^2 [m]", **P)
    goal_bias: float = param(0.1, "share of the samples drawn at the goal (the usual RRT goal bias)", internal=True)


@dataclass
class ProximityResult:
    """The chosen candidate's position in the candidate list, and per candidate its best
    node's score, its best path's progress [m] and the best node (R, 2)."""

    winner: int
    scores: np.ndarray
    progress: np.ndarray
    best_nodes: np.ndarray


def proximity_decision(starts: np.ndarray, goals: np.ndarray, blockers: np.ndarray, blocker_radius: np.ndarray,
                       owner: np.ndarray, params: ProximityParams, rng: np.random.Generator) -> ProximityResult:
    """Decide among candidates at ``starts`` (R, 2) heading to ``goals`` (R, 2).

    ``blockers`` (M, 2) are the points that cost a collision (other robots, obstacles) with
    cost radii ``blocker_radius`` (M,); ``owner`` (M,) gives the candidate index a blocker
    belongs to (it costs nothing to that candidate) or -1. A node's collision cost is summed
    along its path from the root, so a path cannot slip through a blocker between two nodes
    without paying for it. A share ``goal_bias`` of the samples is the goal itself.
    """
    r_count, k = len(starts), params.iterations
    rows = np.arange(r_count)
    radius = params.sample_radius * np.sqrt(rng.random((r_count, k)))
    angle = 2.0 * np.pi * rng.random((r_count, k))
    samples = starts[:, None, :] + radius[..., None] * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    to_goal = rng.random((r_count, k)) < params.goal_bias
    samples[to_goal] = np.broadcast_to(goals[:, None, :], samples.shape)[to_goal]
    foreign = owner[None, :] != rows[:, None]  # (R, M): blockers that cost candidate r
    nodes, path_cost = grow_trees(np.asarray(starts, dtype=float), samples, np.asarray(blockers, dtype=float),
                                  np.asarray(blocker_radius, dtype=float), foreign, float(params.step))

    new = nodes[:, 1:]
    progress = np.hypot(*(starts - goals).T)[:, None] - np.hypot(*(new - goals[:, None, :]).transpose(2, 0, 1))
    score = params.alpha * progress - params.beta * path_cost[:, 1:]
    best = np.argmax(score, axis=1)
    best_progress = progress[rows, best]
    return ProximityResult(int(np.argmax(best_progress)), score[rows, best], best_progress, new[rows, best])
