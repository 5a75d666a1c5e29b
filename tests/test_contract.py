"""Every registered coordinator on a short case of every bundled kind: it either runs and reports
the contract's metrics, or it is refused at build time with one clear scenario error naming
``controller.coordinator`` (the kinds it does not drive). New coordinators join through the
registry and are held to the same contract."""

from __future__ import annotations

import importlib

import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.registry import COORDINATORS
from aac_sumo.metrics import METRIC_KEYS

SCENARIOS = ("swarm_rescue", "circle_swap", "random_crossing", "braking", "lane_change")
SHORT = {"lane_change": ["lane_change.vehicles=3"], "circle_swap": ["circle_swap.n_robots=4"],
         "random_crossing": ["random_crossing.n_robots=4"]}
#: Which coordinators drive which scenarios (the rest must be refused).
DRIVES = {"aac": set(SCENARIOS), "lfc": set(SCENARIOS), "independent": set(SCENARIOS),
          "orca": {"swarm_rescue", "circle_swap", "random_crossing"},
          "cbf_qp": {"swarm_rescue", "circle_swap", "random_crossing", "braking", "lane_change"},
          "sumo": {"lane_change"}}


def test_every_registered_coordinator_is_in_the_contract():
    importlib.import_module("aac_sumo.experiments")  # registers the bundled coordinators
    assert set(COORDINATORS) == set(DRIVES)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("name", sorted(DRIVES))
def test_a_coordinator_runs_a_short_case_or_refuses_the_kind(name, scenario):
    sets = [f"controller.coordinator={name}", "scenario.duration=0.5"] + SHORT.get(scenario, [])
    loaded = config.load(scenario, sets)
    if scenario not in DRIVES[name]:
        with pytest.raises(config.ScenarioError, match="controller.coordinator"):
            runner.run(loaded)
        return
    metrics = runner.run(loaded).metrics
    assert "error" not in metrics, metrics.get("error")
    assert metrics["coordinator"] == name
    assert set(METRIC_KEYS) <= set(metrics)
    assert metrics["collisions"] == 0
