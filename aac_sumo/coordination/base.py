"""What every coordinator shares: the MPC planner component, per-robot memory, and the record
of a decision. Coordinators see a :class:`~aac_sumo.world.WorldState` and never a simulator."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from aac_sumo.mpc.planner import MpcPlanner, Plan
from aac_sumo.references import PathReference
from aac_sumo.world import Obstacle, WorldState


@dataclass
class RobotDecision:
    """One robot's part of a decision. ``status`` is None when the robot did not solve."""

    authority: bool
    status: str | None = None
    solve_ms: float = 0.0
    solver: str = ""
    reference: np.ndarray | None = None


@dataclass
class Decision:
    """Inputs (n, 2) ``[accel, steer]`` for every controlled robot, per-robot records, the
    coordinator's wall time for the period [ms] and free-form notes (e.g. authority reasons)."""

    inputs: np.ndarray
    robots: list[RobotDecision]
    compute_ms: float = 0.0
    notes: dict = field(default_factory=dict)


class Coordinator(ABC):
    """Holds the planner, each robot's task (reference path), optional position box
    (``[x_min, x_max, y_min, y_max]``, see :meth:`MpcPlanner.plan`), last plan and last input."""

    name = "base"

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors: list[np.ndarray | None] | None = None):
        self.planner = planner
        self.tasks = tasks
        self.corridors = corridors or [None] * len(tasks)
        self.plans: list[Plan | None] = [None] * len(tasks)
        self.last_inputs = np.zeros((len(tasks), 2))

    def decide(self, world: WorldState) -> Decision:
        """Inputs for this period; ``compute_ms`` is the wall time of the whole decision."""
        start = time.perf_counter()
        decision = self._decide(world)
        decision.compute_ms = (time.perf_counter() - start) * 1e3
        self.last_inputs = decision.inputs.copy()
        return decision

    @abstractmethod
    def _decide(self, world: WorldState) -> Decision: ...

    def reference(self, world: WorldState, i: int) -> np.ndarray:
        """Robot ``i``'s reference over the horizon (N+1, 4)."""
        cfg = self.planner.config
        return self.tasks[i].horizon(world.states[i], cfg.horizon, cfg.dt)

    def solve(self, world: WorldState, i: int, obstacles: list[Obstacle]) -> RobotDecision:
        """Plan robot ``i`` around ``obstacles``, remember the plan, and report it."""
        ref = self.reference(world, i)
        plan = self.planner.plan(world.robots[i], world.states[i], ref, self.last_inputs[i], obstacles, self.plans[i], self.corridors[i])
        self.plans[i] = plan
        return RobotDecision(True, plan.status, plan.solve_ms, plan.solver, ref)
