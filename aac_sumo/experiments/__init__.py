"""Experiments turn a validated scenario into a world, tasks and a coordinator."""

from __future__ import annotations

from aac_sumo.config import Scenario
from aac_sumo.experiments.common import Setup


def build(scenario: Scenario) -> Setup:
    """The simulator, coordinator and termination rule of ``scenario``."""
    if scenario.kind == "braking":
        from aac_sumo.experiments.braking import build_braking

        return build_braking(scenario)
    raise ValueError(f"no builder for scenario kind {scenario.kind!r}")
