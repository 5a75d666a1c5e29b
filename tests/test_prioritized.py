"""LFC with committed plans (``lfc.commit = true``): prioritized planning, every active robot
plans every period in index order, and no footprints meet (the exact check, as AAC's)."""

from __future__ import annotations

import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.coordination.prioritized import PrioritizedLfc
from aac_sumo.experiments import build


def test_lfc_commit_builds_prioritized_planning_with_the_lfc_safety_options():
    scenario = config.load("circle_swap", ["controller.coordinator=lfc", "lfc.commit=true", "circle_swap.n_robots=4"])
    coordinator = build(scenario).coordinator
    assert isinstance(coordinator, PrioritizedLfc)
    assert coordinator.params.commit and coordinator.params.safety_stop is False  # [lfc]'s, not [aac]'s
    paper = config.load("circle_swap", ["controller.coordinator=lfc", "circle_swap.n_robots=4"])
    assert not isinstance(build(paper).coordinator, PrioritizedLfc)


@pytest.mark.slow
def test_every_active_robot_plans_every_period_in_index_order_and_none_collide():
    scenario = config.load("circle_swap", ["controller.coordinator=lfc", "lfc.commit=true", "circle_swap.n_robots=4",
                                           "circle_swap.radius=3", "scenario.duration=25"])
    result = runner.run(scenario)
    assert result.metrics["completed"] and result.metrics["collisions"] == 0
    steps = result.steps
    active = steps[~steps["arrived"].astype(bool)]
    assert active["authority"].astype(bool).all()
    assert set(active["reason"]) == {"priority"}
