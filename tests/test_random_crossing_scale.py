"""Random crossing at scale: the KD-tree robot check gives the all-pairs rule's verdicts, the
draws of up to 200 robots are those published before it, and (slow) 300 robots cross without a
collision."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.config import ScenarioError
from aac_sumo.experiments.random_crossing import Placed, draw
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.runs import runner

#: Starts, goals and debris drawn by the all-pairs implementation (before the KD-tree), keys
#: ``n{robots}_s{seed}_{field}``.
REFERENCE = Path(__file__).resolve().parent / "data" / "random_crossing_draws.npz"


def clash_all_pairs(rows: np.ndarray, g_xy: np.ndarray, footprints: np.ndarray, goals: np.ndarray,
                    foot_gap: float, goal_gap: float) -> np.ndarray:
    """:meth:`Placed.clash` by testing every placed robot (the draw's rule before the KD-tree)."""
    bad = pairwise_rect_clearance(rows, footprints).min(axis=1) < foot_gap
    return bad | (np.hypot(g_xy[:, None, 0] - goals[None, :, 0], g_xy[:, None, 1] - goals[None, :, 1]).min(axis=1) < goal_gap)


def test_draws_up_to_200_robots_are_unchanged():
    ref = np.load(REFERENCE)
    cases = sorted({tuple(k.split("_")[:2]) for k in ref.files})
    assert len(cases) == 8
    for n, s in cases:
        d = draw(config.load("random_crossing", [f"scenario.seed={s[1:]}", f"random_crossing.n_robots={n[1:]}"]))
        for field in ("starts", "goals", "debris"):
            # the same draw; a heading may differ in its last bit between machines (numpy's CPU-dispatched kernels)
            np.testing.assert_allclose(getattr(d, field), ref[f"{n}_{s}_{field}"], rtol=0.0, atol=1e-12, err_msg=f"{n} {s} {field}")


def _robots(rng: np.random.Generator, k: int, half: float, length=0.6, width=0.4) -> tuple[np.ndarray, np.ndarray]:
    rows = np.column_stack([rng.uniform(-half, half, (k, 2)), np.full(k, length), np.full(k, width),
                            rng.uniform(-np.pi, np.pi, k)])
    return rows, rng.uniform(-half, half, (k, 2))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), placed=st.integers(1, 300), half=st.floats(1.0, 30.0),
       gap=st.floats(0.0, 1.0), goal_gap=st.floats(0.0, 3.0))
def test_kd_tree_check_gives_the_all_pairs_verdicts(seed, placed, half, gap, goal_gap):
    rng = np.random.default_rng(seed)
    foot, goals = _robots(rng, placed, half)
    rows, g_xy = _robots(rng, 64, half)
    near = min(8, placed)
    rows[:near, :2] = foot[:near, :2] + rng.normal(0.0, 0.5, (near, 2))  # some near misses and touches
    g_xy[:near] = goals[:near] + rng.normal(0.0, goal_gap + 0.1, (near, 2))
    fast = Placed(foot, goals, gap, goal_gap).clash(rows, g_xy)
    np.testing.assert_array_equal(fast, clash_all_pairs(rows, g_xy, foot, goals, gap, goal_gap))


def test_boundary_pairs_are_tested_exactly():
    """Goals exactly goal_gap apart pass (the rule is strictly closer), a hair closer fail."""
    goals = np.array([[0.0, 0.0]])
    foot = np.array([[50.0, 50.0, 0.6, 0.4, 0.0]])
    g_xy = np.array([[1.5, 0.0], [np.nextafter(1.5, 0.0), 0.0], [0.0, 1.5 + 1e-9]])
    rows = np.tile([[-50.0, -50.0, 0.6, 0.4, 0.0]], (3, 1))
    fast = Placed(foot, goals, 0.5, 1.5).clash(rows, g_xy)
    assert fast.tolist() == [False, True, False]
    np.testing.assert_array_equal(fast, clash_all_pairs(rows, g_xy, foot, goals, 0.5, 1.5))


def test_n_robots_up_to_1000():
    assert config.load("random_crossing", ["random_crossing.n_robots=1000"])["random_crossing.n_robots"] == 1000
    with pytest.raises(ScenarioError) as err:
        config.load("random_crossing", ["random_crossing.n_robots=1001"])
    assert err.value.key == "random_crossing.n_robots" and "2..1000" in str(err.value)



@pytest.mark.slow
def test_300_robots_cross_without_a_collision():
    """300 robots at the 1,000-robot row's 8 m^2 a robot (a 49 m square, 48 debris): every robot
    arrives (in 205 s of simulated time, about 3 minutes here) and none collides."""
    result = runner.run(config.load("random_crossing", [
        "random_crossing.n_robots=300", "random_crossing.area_per_robot=8", "scenario.duration=300"]))
    m = result.metrics
    assert m["n_robots"] == 300 and m.get("error") is None
    assert m["collisions"] == 0
    assert m["completed"], m.get("incomplete_reason")
