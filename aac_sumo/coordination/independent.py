"""Every robot plans for itself each period, seeing the other robots as constant-velocity
obstacles. With one controlled robot (the braking experiment) this is plain MPC-(F)CBF."""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.base import Coordinator, Decision
from aac_sumo.world import WorldState


class IndependentCoordinator(Coordinator):
    name = "independent"

    def _decide(self, world: WorldState) -> Decision:
        n = len(world.robots)
        others = [world.robot_as_obstacle(j) for j in range(n)]
        records = [self.solve(world, i, world.obstacles + others[:i] + others[i + 1 :], "independent") for i in range(n)]
        inputs = np.array([self.plans[i].inputs[0] for i in range(n)])
        return Decision(inputs, records)
