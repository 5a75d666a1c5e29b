"""S3, emergency braking (paper Table III): an MPC-controlled ego follows an uncontrolled lead
in one lane at the same speed, the lead ``gap`` metres ahead (centre to centre). At ``t_brake``
the lead brakes at ``lead_decel`` to a stop; the seed shifts that instant uniformly within
``t_brake_jitter``. The ego's reference keeps cruising at the initial
speed along the lane, so only its barrier makes it stop. The ego may not leave its lane
(``lane_width``): its planned rear axle stays within the lane minus half its width. The run ends when both stand still."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import from_section, param
from aac_sumo.experiments.common import Setup, check_start, coordinator, robot_spec
from aac_sumo.references import PathReference
from aac_sumo.registry import register_experiment
from aac_sumo.sim.internal import InternalSimulator, ScriptedAgent
from aac_sumo.world import WorldState


@dataclass(frozen=True)
class BrakingParams:
    """Section ``[braking]``: the lead and the ego start at ``speed`` [m/s], the lead ``gap`` [m]
    ahead (centre to centre), in one lane of ``lane_width`` [m] centred on ``y = lane_y`` [m]
    (world frame, driving along +x); the lead brakes at ``lead_decel`` [m/s^2] from ``t_brake``
    [s], shifted by the seed within ``t_brake_jitter`` [s]."""

    speed: float = param(10.0, "initial speed of ego and lead [m/s]", **P)
    gap: float = param(7.0, "initial centre-to-centre distance, lead ahead of ego [m]", **P)
    t_brake: float = param(1.0, "time the lead starts braking [s]", **NN)
    t_brake_jitter: float = param(0.2, "the seed shifts t_brake uniformly within +- this [s]", **NN)
    lead_decel: float = param(6.0, "lead deceleration magnitude [m/s^2]", **P)
    lead_length: float = param(1.0, "lead footprint length [m]", **P)
    lead_width: float = param(0.6, "lead footprint width [m]", **P)
    lane_y: float = param(0.0, "y of the lane centre line [m]")
    lane_width: float = param(1.0, "lane width; the ego's rear axle keeps (lane_width - robot.width)/2 from the centre line [m]", **P)


@register_experiment("braking", params=BrakingParams)
def build_braking(scenario: Scenario) -> Setup:
    b = from_section(BrakingParams, scenario, "braking")
    ego = robot_spec(scenario, "ego")
    speed, y = b.speed, b.lane_y
    if speed > ego.model.limits.v_max:
        raise ScenarioError(scenario.source, "braking.speed", f"at most robot.v_max ({ego.model.limits.v_max})", speed)
    rear_axle_x = -ego.centre_offset
    state = np.array([[rear_axle_x, y, 0.0, speed]])
    rng = np.random.default_rng(scenario["scenario.seed"])
    t_brake = b.t_brake + rng.uniform(-b.t_brake_jitter, b.t_brake_jitter)
    lead = ScriptedAgent("lead", np.array([b.gap, y]), 0.0, speed, b.lead_length, b.lead_width,
                         schedule=((t_brake, -b.lead_decel),))
    sim = InternalSimulator([ego], state, scenario["scenario.dt"], scripted=[lead])
    check_start(scenario, sim.observe(), "braking.gap")
    lane_end = speed * scenario["scenario.duration"] + 10 * b.gap + 100.0
    tasks = [PathReference([[rear_axle_x, y], [lane_end, y]], speed, stop_at_end=False)]
    stop = scenario["metrics.stop_speed"]

    def finished(world: WorldState) -> np.ndarray:
        lead_stopped = all(o.velocity @ o.velocity <= stop**2 for o in world.obstacles)
        return (world.states[:, 3] <= stop) & lead_stopped

    room = 0.5 * (b.lane_width - ego.width)
    if room < 0:
        raise ScenarioError(scenario.source, "braking.lane_width", f"at least robot.width ({ego.width})", b.lane_width)
    corridor = np.array([-np.inf, np.inf, y - room, y + room])
    return Setup(scenario, sim, coordinator(scenario, tasks, [corridor]), tasks, finished)
