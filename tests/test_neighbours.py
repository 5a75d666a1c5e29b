"""The KD-tree forms of the per-robot least clearance and nearest centre give exactly what the
all-pairs forms give, on random crowds where the candidates matter; the time to collision skips
only pairs its sweep never brings together."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import neighbours
from aac_sumo.kernels.geometry import pairwise_clearance
from aac_sumo.kernels.metrics import sweep_gap, times_to_collision


@pytest.fixture(scope="module", autouse=True)
def tree_path_always():
    """Every call of this module takes the KD-tree path, however small the crowd."""
    saved, neighbours.DENSE_PAIRS = neighbours.DENSE_PAIRS, 0
    yield
    neighbours.DENSE_PAIRS = saved


def crowd(seed: int, n: int, m: int, side: float):
    """n robots and m obstacles (rows, velocities) in a square of ``side`` [m]; some overlap,
    some stand, some obstacles are long."""
    rng = np.random.default_rng(seed)
    k = n + m
    rows = np.column_stack([rng.uniform(0, side, (k, 2)), rng.uniform(0.3, 1.5, k), rng.uniform(0.2, 0.8, k),
                            rng.uniform(-np.pi, np.pi, k)])
    rows[n::7, 2] *= 6.0  # a few long obstacles
    speed = np.where(rng.random(k) < 0.3, 0.0, rng.uniform(0.0, 2.0, k))
    angle = np.where(np.arange(k) < n, rows[:, 4], rng.uniform(-np.pi, np.pi, k))
    velocity = speed[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    return rows, velocity


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 60), m=st.integers(0, 30), side=st.floats(3.0, 40.0))
def test_least_clearances_are_the_all_pairs_minima_and_overlaps(seed, n, m, side):
    rows, _ = crowd(seed, n, m, side)
    gaps = pairwise_clearance(rows[:n], rows)
    gaps[np.arange(n), np.arange(n)] = np.inf
    least, pairs = neighbours.least_clearances(rows[:n], rows)
    np.testing.assert_array_equal(least, gaps.min(axis=1))
    assert sorted(pairs) == sorted((int(i), int(j)) for i, j in zip(*np.nonzero(gaps < 0)))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 60), m=st.integers(0, 30), side=st.floats(3.0, 40.0))
def test_nearest_distances_are_the_all_pairs_minima(seed, n, m, side):
    rows, _ = crowd(seed, n, m, side)
    d = np.hypot(*(rows[:n, None, :2] - rows[None, :, :2]).transpose(2, 0, 1))
    d[np.arange(n), np.arange(n)] = np.inf
    np.testing.assert_array_equal(neighbours.nearest_distances(rows[:n, :2], rows[:, :2]), d.min(axis=1))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 25), side=st.floats(2.0, 30.0))
def test_the_time_kernel_skips_only_pairs_the_sweep_never_brings_together(seed, n, side):
    """Pairs off the line of the sweep or behind it are inf without the sweep: the same values
    as the sweep of every pair."""
    rows, velocity = crowd(seed, n, n, side)
    expected = np.full(n, np.inf)
    for i in range(n):
        for j in range(len(rows)):
            w = velocity[i] - velocity[j]
            closing = float(np.hypot(*w))
            if j == i or closing <= 1e-6 or w @ [np.cos(rows[i, 4]), np.sin(rows[i, 4])] <= 1e-6:
                continue
            expected[i] = min(expected[i], sweep_gap(rows[i], rows[j], w[0] / closing, w[1] / closing) / closing)
    np.testing.assert_array_equal(times_to_collision(rows, velocity, n), expected)
