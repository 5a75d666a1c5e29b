"""Reference paths: projection, horizon windows, and what happens at and beyond the path's end."""

import numpy as np

from aac_sumo.references import PathReference


def test_projection_of_a_point_beside_the_path():
    path = PathReference([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]], 1.0)
    s, d = path.project([4.0, -2.0])
    assert (s, d) == (4.0, 2.0)


def test_a_stopping_path_clamps_the_projection_to_its_end():
    path = PathReference([[0.0, 0.0], [10.0, 0.0]], 2.0)
    s, d = path.project([15.0, 1.0])
    assert s == 10.0 and np.isclose(d, np.hypot(5.0, 1.0))


def test_a_path_that_goes_on_projects_beyond_its_end_and_leads_forwards():
    """A car that drove past the end of its (non-stopping) path still has its reference ahead of
    it along the last segment's direction, never behind it (it would turn round)."""
    path = PathReference([[0.0, 0.0], [10.0, 0.0]], 2.0, stop_at_end=False)
    s, d = path.project([25.0, 1.0])
    assert s == 25.0 and d == 1.0
    ref = path.horizon(np.array([25.0, 1.0, 0.0, 2.0]), 5, 0.5)
    np.testing.assert_allclose(ref[:, 0], 25.0 + np.arange(6))
    np.testing.assert_allclose(ref[:, 1], 0.0)
    np.testing.assert_allclose(ref[:, 3], 2.0)
