"""Experiments turn a validated scenario into a world, tasks and a coordinator. Each kind's
builder is registered with :func:`aac_sumo.registry.register_experiment`, the bundled ones in the
modules of this package."""

from __future__ import annotations

import importlib

from aac_sumo.config import Scenario
from aac_sumo.experiments.common import Setup
from aac_sumo.registry import EXPERIMENTS

BUNDLED = ("braking", "swarm", "random_crossing", "lane_change")


def build(scenario: Scenario) -> Setup:
    """The simulator, coordinator and termination rule of ``scenario``, from its kind's builder."""
    for module in BUNDLED:
        importlib.import_module(f"aac_sumo.experiments.{module}")
    if scenario.kind not in EXPERIMENTS:
        raise ValueError(f"no builder for scenario kind {scenario.kind!r}")
    return EXPERIMENTS[scenario.kind](scenario)
