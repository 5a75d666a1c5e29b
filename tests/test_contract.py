"""Every registered coordinator on a short case of every registered kind (its bundled scenario):
on a kind it drives, the run goes on to its time limit or its end without an error, in periods
of ``scenario.dt``, with the contract's metrics and the collisions the footprints in
trajectories.csv show; on a kind it does not drive, it is refused at build time with one
scenario error naming ``controller.coordinator``. New coordinators and kinds join through the
registry and are held to the same contract (as highway-env's environment test does for its
environments). Kinds hosted by SUMO run two simulated seconds with three cars (about 2 s each here)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import shapely

from aac_sumo import config, experiments, registry
from aac_sumo.coordination.base import Coordinator, Decision, RobotDecision
from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.runs import runner

KINDS = registry.kinds()
COORDINATORS = registry.coordinators()
#: Short, small cases: the overrides of each kind's bundled scenario.
SHORT = {"lane_change": ["lane_change.vehicles=3", "scenario.duration=2.0"], "circle_swap": ["circle_swap.n_robots=4"],
         "random_crossing": ["random_crossing.n_robots=4"]}
QUICK = ["scenario.duration=1.0", "controller.horizon=5"]


CASES = [pytest.param(name, kind, id=f"{name}-{kind}") for name in COORDINATORS for kind in KINDS]


def collisions_seen(trajectories: pd.DataFrame) -> int:
    """The collisions in ``trajectories`` (trajectories.csv), counted independently of the
    simulator: at every time, the pairs of footprints (rectangles of centre, heading, length,
    width) that overlap with positive area, one of them controlled; a pair counts when it begins
    to overlap."""
    count, before = 0, set()
    for _, rows in trajectories.groupby("t", sort=True):
        shapes = [(r.name, r.kind == "controlled", shapely.affinity.rotate(
            shapely.box(r.x - r.length / 2, r.y - r.width / 2, r.x + r.length / 2, r.y + r.width / 2),
            r.heading, origin=(r.x, r.y), use_radians=True)) for r in rows.itertuples()]
        now = {tuple(sorted((a, b))) for k, (a, mine, p) in enumerate(shapes) for b, theirs, q in shapes[k + 1:]
               if (mine or theirs) and p.intersection(q).area > 1e-9}
        count += len(now - before)
        before = now
    return count


def check_contract(result, name: str) -> None:
    metrics, dt = result.metrics, result.scenario["scenario.dt"]
    assert "error" not in metrics, metrics.get("error")
    assert metrics["coordinator"] == name
    assert set(METRIC_KEYS) <= set(metrics)
    periods = result.periods["t"].to_numpy()
    assert periods[0] == 0.0 and np.allclose(np.diff(periods), dt)  # monotone, one period each dt
    end = metrics["task_duration_s"] if metrics["completed"] else result.scenario["scenario.duration"]
    assert result.trajectories["t"].max() == pytest.approx(end)  # it ran to its end, not stopped at t = 0
    assert len(periods) == round(end / dt)
    assert metrics["collisions"] == collisions_seen(result.trajectories)


@pytest.mark.parametrize("name, kind", CASES)
def test_a_coordinator_runs_a_short_case_or_refuses_the_kind(name, kind):
    loaded = config.load(kind, [f"controller.coordinator={name}"] + QUICK + SHORT.get(kind, []))
    if not COORDINATORS[name].drives(kind):
        with pytest.raises(config.ScenarioError, match="controller.coordinator"):
            runner.run(loaded)
        return
    check_contract(runner.run(loaded), name)


def test_every_bundled_coordinator_and_kind_is_in_the_contract():
    assert {"aac", "lfc", "independent", "orca", "cbf_qp", "sumo"} <= set(COORDINATORS)
    assert {"braking", "swarm_rescue", "circle_swap", "random_crossing", "lane_change"} <= set(KINDS)
    assert [name for name in COORDINATORS if not COORDINATORS[name].drives("braking")] == ["sumo", "orca"]


class Blind(Coordinator):
    """Every robot accelerates straight ahead, whatever is in its way."""

    name = "blind"

    def _decide(self, world):
        n = len(world.robots)
        return Decision(np.tile([2.0, 0.0], (n, 1)), [RobotDecision(False, mode="blind") for _ in range(n)])


def test_the_contract_counts_the_collisions_that_happen(monkeypatch):
    """Four robots of a circle swap drive blindly into its centre: the runner's count and the
    footprints' agree, and are not zero."""
    build = experiments.build

    def blind(scenario):
        setup = build(scenario)
        setup.coordinator = Blind(setup.coordinator.planner, setup.tasks)
        return setup

    monkeypatch.setattr(experiments, "build", blind)
    result = runner.run(config.load("circle_swap", ["circle_swap.n_robots=4", "scenario.duration=4.5", "controller.horizon=5"]))
    assert result.metrics["collisions"] == collisions_seen(result.trajectories) > 0
