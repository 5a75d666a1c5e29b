"""Experiments turn a validated scenario into a world, tasks and a coordinator. Each kind's
builder is registered with :func:`aac_sumo.registry.register_experiment`, the bundled ones in the
modules of this package (loaded with the schema: :func:`aac_sumo.config.common`)."""

from __future__ import annotations

from aac_sumo import config
from aac_sumo.config import Scenario
from aac_sumo.experiments.common import Setup
from aac_sumo.registry import EXPERIMENTS


def build(scenario: Scenario) -> Setup:
    """The simulator, coordinator and termination rule of ``scenario``, from its kind's builder."""
    config.common()
    if scenario.kind not in EXPERIMENTS:
        raise ValueError(f"no builder for scenario kind {scenario.kind!r}")
    return EXPERIMENTS[scenario.kind](scenario)
