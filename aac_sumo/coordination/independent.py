"""Every robot plans for itself each period, seeing the other robots as constant-velocity
obstacles; robots that have finished a task that stops at its end, or are not on the road,
hold still. With one controlled robot (the braking experiment) this is plain MPC-(F)CBF."""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.base import Coordinator, Decision, RobotDecision
from aac_sumo.registry import register_coordinator
from aac_sumo.world import WorldState


class IndependentCoordinator(Coordinator):
    name = "independent"

    def _decide(self, world: WorldState) -> Decision:
        n = len(world.robots)
        parked = self.parked(world, self.finished(world))
        others = [world.robot_as_obstacle(j) for j in range(n)]
        inputs = np.zeros((n, 2))
        records = [RobotDecision(False, mode="hold") for _ in range(n)]
        for i in np.flatnonzero(~parked):
            records[i] = self.solve(world, i, world.obstacles + others[:i] + others[i + 1 :], "independent")
            inputs[i] = self.plans[i].inputs[0]
        for i in np.flatnonzero(parked):
            inputs[i] = self.hold_inputs(world, i, 1)[0]
        return Decision(inputs, records)


register_coordinator("independent", IndependentCoordinator, doc="every robot for itself")
