"""S3, emergency braking (paper Table III): an MPC-controlled ego follows an uncontrolled lead
in one lane at the same speed, the lead ``gap`` metres ahead (centre to centre). At ``t_brake``
the lead brakes at ``lead_decel`` to a stop; the seed shifts that instant uniformly within
``t_brake_jitter``. The ego's reference keeps cruising at the initial
speed along the lane, so only its barrier makes it stop. The ego may not leave its lane
(``lane_width``): its planned rear axle stays within the lane minus half its width. The run ends when both stand still."""

from __future__ import annotations

import numpy as np

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.experiments.common import Setup, check_start, coordinator, robot_spec
from aac_sumo.references import PathReference
from aac_sumo.registry import register_experiment
from aac_sumo.sim.internal import InternalSimulator, ScriptedAgent
from aac_sumo.world import WorldState


@register_experiment("braking")
def build_braking(scenario: Scenario) -> Setup:
    b = scenario.data["braking"]
    ego = robot_spec(scenario, "ego")
    speed, y = b["speed"], b["lane_y"]
    if speed > ego.model.limits.v_max:
        raise ScenarioError(scenario.source, "braking.speed", f"at most robot.v_max ({ego.model.limits.v_max})", speed)
    rear_axle_x = -ego.centre_offset
    state = np.array([[rear_axle_x, y, 0.0, speed]])
    rng = np.random.default_rng(scenario["scenario.seed"])
    t_brake = b["t_brake"] + rng.uniform(-b["t_brake_jitter"], b["t_brake_jitter"])
    lead = ScriptedAgent("lead", np.array([b["gap"], y]), 0.0, speed, b["lead_length"], b["lead_width"],
                         schedule=((t_brake, -b["lead_decel"]),))
    sim = InternalSimulator([ego], state, scenario["scenario.dt"], scripted=[lead])
    check_start(scenario, sim.observe(), "braking.gap")
    lane_end = speed * scenario["scenario.duration"] + 10 * b["gap"] + 100.0
    tasks = [PathReference([[rear_axle_x, y], [lane_end, y]], speed, stop_at_end=False)]
    stop = scenario["metrics.stop_speed"]

    def finished(world: WorldState) -> np.ndarray:
        lead_stopped = all(o.velocity @ o.velocity <= stop**2 for o in world.obstacles)
        return (world.states[:, 3] <= stop) & lead_stopped

    room = 0.5 * (b["lane_width"] - ego.width)
    if room < 0:
        raise ScenarioError(scenario.source, "braking.lane_width", f"at least robot.width ({ego.width})", b["lane_width"])
    corridor = np.array([-np.inf, np.inf, y - room, y + room])
    return Setup(scenario, sim, coordinator(scenario, tasks, [corridor]), tasks, finished)
