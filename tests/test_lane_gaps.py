"""Gap acceptance for lane changes (aac_sumo/experiments/lane_gaps.py): the closed-form safe gaps,
who counts as in the target lane, and a seeded comparison with the rule evaluated by hand."""

from __future__ import annotations

import numpy as np
import pytest

from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.experiments.lane_gaps import LOOK, GapRule, judge_gap
from aac_sumo.references import PathReference
from aac_sumo.world import Obstacle, RobotSpec, WorldState

CAR = RobotSpec("ego", 4.0, 1.8, BicycleModel(2.6, VehicleLimits(-6.0, 3.0, 0.5, 0.0, 20.0, 3.0, 0.5, 3.0)))
RULE = GapRule(time_gap=1.0, decel=3.0, min_gap=2.0)
LANE_Y = 3.5  # the target lane's centre line; the ego drives along y = 0
TARGET = PathReference([[-500.0, LANE_Y], [1000.0, LANE_Y]], 1.0, stop_at_end=False)


def test_the_safe_gaps_in_closed_form():
    assert RULE.ahead(16.0, 12.0) == pytest.approx(2.0 + 16.0 + (16.0**2 - 12.0**2) / 6.0)  # 36.67 m behind a slower leader
    assert RULE.ahead(12.0, 16.0) == pytest.approx(2.0 + 12.0)  # a faster leader: the time gap only
    assert RULE.behind(20.0, 16.0) == pytest.approx(2.0 + 20.0 + (20.0**2 - 16.0**2) / 6.0)  # 46 m ahead of a faster follower
    assert RULE.behind(20.0, 0.0) == pytest.approx(2.0 + 20.0 + 400.0 / 6.0)  # ahead of it from a standstill: 88.7 m
    assert RULE.behind(20.0, 16.0, headway=False) == pytest.approx(2.0 + 144.0 / 6.0)  # a change under way: no time gap
    assert RULE.ahead(-1.0, 3.0) == RULE.ahead(0.0, 3.0) == pytest.approx(2.0)  # negative speeds count as standing


def world(others: list[tuple[float, float, float]], ego_speed: float = 16.0, robots: int = 0) -> WorldState:
    """The ego's rear axle at x = 100 m on y = 0 at ``ego_speed``; ``others`` ``(x, y, v)``
    [m, m/s] are 4.5 m x 1.8 m cars going +x (centres), the first ``robots`` of them controlled."""
    states = [[100.0 - CAR.centre_offset, 0.0, 0.0, ego_speed]]
    specs = [CAR]
    obstacles = []
    for k, (x, y, v) in enumerate(others):
        if k < robots:
            spec = RobotSpec(f"r{k}", 4.5, 1.8, CAR.model)
            specs.append(spec)
            states.append([x - spec.centre_offset, y, 0.0, v])
        else:
            obstacles.append(Obstacle(f"bg{k}", "scripted", np.array([x, y]), np.array([v, 0.0]), 0.0, 4.5, 1.8))
    return WorldState(0.0, np.array(states), specs, obstacles)


def test_a_follower_needs_its_secure_gap_and_a_leader_the_egos():
    behind = RULE.behind(20.0, 16.0)  # bumper to bumper; centres 0.5 (4 + 4.5) m further apart
    at = 100.0 - behind - 4.25
    assert judge_gap(world([(at, LANE_Y, 20.0)]), 0, TARGET, 1.75, RULE).safe
    verdict = judge_gap(world([(at + 0.1, LANE_Y, 20.0)]), 0, TARGET, 1.75, RULE)
    assert not verdict.safe and verdict.blocker == "bg0" and verdict.margin == pytest.approx(-0.1)
    assert verdict.robot == -1 and verdict.along == pytest.approx(at + 0.1 - 100.0)
    ahead = RULE.ahead(16.0, 12.0)
    assert judge_gap(world([(100.0 + ahead + 4.25, LANE_Y, 12.0)]), 0, TARGET, 1.75, RULE).safe
    assert not judge_gap(world([(100.0 + ahead + 4.15, LANE_Y, 12.0)]), 0, TARGET, 1.75, RULE).safe
    # the change under way keeps neither time gap
    assert judge_gap(world([(at + 10.0, LANE_Y, 20.0)]), 0, TARGET, 1.75, RULE, headway=False).safe


def test_beside_is_never_safe_and_only_what_reaches_into_the_lane_counts():
    beside = judge_gap(world([(101.0, LANE_Y, 16.0)]), 0, TARGET, 1.75, RULE)
    assert not beside.safe and beside.margin == -np.inf
    assert judge_gap(world([(101.0, 2 * LANE_Y, 16.0)]), 0, TARGET, 1.75, RULE).safe  # the lane beyond
    assert judge_gap(world([(101.0, LANE_Y + 2.7, 16.0)]), 0, TARGET, 1.75, RULE).safe  # its side 0.05 m beyond the lane's edge
    assert not judge_gap(world([(101.0, LANE_Y + 2.6, 16.0)]), 0, TARGET, 1.75, RULE).safe  # its side 0.05 m into the lane
    # a controlled car moving into the lane counts wherever it is
    assert not judge_gap(world([(101.0, 2 * LANE_Y, 16.0)], robots=1), 0, TARGET, 1.75, RULE, also=(1,)).safe
    verdict = judge_gap(world([(95.0, LANE_Y, 16.0)], robots=1), 0, TARGET, 1.75, RULE)
    assert verdict.robot == 1 and verdict.blocker == "r0" and verdict.along < 0.0


def test_judging_matches_the_rule_by_hand_on_random_lanes():
    """Seeded: 300 target lanes, each with 0-6 cars at random places and speeds within 250 m;
    the verdict is safe exactly when every car within LOOK has at least the rule's gap, its
    margin is the smallest gap minus the rule's gap."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        n = int(rng.integers(0, 7))
        xs, vs = rng.uniform(-150.0, 350.0, n), rng.uniform(0.0, 25.0, n)
        ego_v = float(rng.uniform(0.0, 20.0))
        verdict = judge_gap(world([(x, LANE_Y, v) for x, v in zip(xs, vs)], ego_v), 0, TARGET, 1.75, RULE)
        margins = []
        for x, v in zip(xs, vs):
            if abs(x - 100.0) > LOOK:
                continue
            gap = abs(x - 100.0) - 4.25
            need = RULE.ahead(ego_v, v) if x >= 100.0 else RULE.behind(v, ego_v)
            margins.append(-np.inf if gap < 0.0 else gap - need)
        assert verdict.safe == all(m >= 0.0 for m in margins)
        assert verdict.margin == pytest.approx(min(margins, default=np.inf))
