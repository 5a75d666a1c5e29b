"""Experiments turn a validated scenario into a world, tasks and a coordinator."""

from __future__ import annotations

from aac_sumo.config import Scenario
from aac_sumo.experiments.common import Setup


def build(scenario: Scenario) -> Setup:
    """The simulator, coordinator and termination rule of ``scenario``."""
    if scenario.kind == "braking":
        from aac_sumo.experiments.braking import build_braking

        return build_braking(scenario)
    if scenario.kind in ("swarm_rescue", "circle_swap"):
        from aac_sumo.experiments import swarm

        return getattr(swarm, f"build_{scenario.kind}")(scenario)
    if scenario.kind == "random_crossing":
        from aac_sumo.experiments.random_crossing import build_random_crossing

        return build_random_crossing(scenario)
    if scenario.kind == "lane_change":
        from aac_sumo.experiments.lane_change import build_lane_change

        return build_lane_change(scenario)
    raise ValueError(f"no builder for scenario kind {scenario.kind!r}")
