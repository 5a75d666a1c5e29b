"""The ``sumo`` baseline: SUMO's own driver (its car-following model and LC2013, or SL2015 with
``sumo.lateral_resolution`` > 0) moves the controlled cars, and our runner measures it.

The seam: this coordinator plans nothing. It is registered with ``simulator_drives`` (see
:func:`aac_sumo.experiments.common.simulator_drives`); the experiment's builder then starts its
simulator in the mode where the simulator moves the robots itself (for SUMO:
``SumoOptions.sumo_drives``, :mod:`aac_sumo.sim.sumo`) and hands it the scenario's target lanes.
Each period this coordinator returns zero inputs, which that simulator ignores; the simulator
reports the inputs that match what its driver did (``ContactReport.applied``), and the runner
records those. Like every coordinator it never sees a simulator, only the world.
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.base import Coordinator, Decision, RobotDecision
from aac_sumo.registry import register_coordinator
from aac_sumo.world import WorldState


class SumoDriver(Coordinator):
    """No decision of ours: every robot is marked ``mode = "sumo"`` (no authority, no solve)."""

    name = "sumo"

    def _decide(self, world: WorldState) -> Decision:
        n = len(world.robots)
        return Decision(np.zeros((n, 2)), [RobotDecision(False, reason="sumo", mode="sumo") for _ in range(n)])


register_coordinator("sumo", SumoDriver, kinds=("lane_change", "city"), simulator_drives=True, baseline=True, label="SUMO's own driver",
                     doc="SUMO's own driver moves the cars, kinds lane_change and city: docs/baselines_sumo.md")
