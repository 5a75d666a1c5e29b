"""The one SUMO frame conversion: front bumper + navigational degrees <-> rear axle + radians CCW."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aac_sumo.sim.sumo_frames import state_from_sumo, sumo_from_state

coords = st.floats(-1e4, 1e4, allow_nan=False)
dims = st.tuples(st.floats(0.3, 20.0), st.floats(0.0, 1.0)).map(lambda t: (t[0], t[0] * t[1]))  # length, wheelbase <= length


@given(coords, coords, st.floats(-math.pi, math.pi), st.floats(-30, 30), dims)
def test_state_round_trips_through_sumo(x, y, heading, v, dim):
    length, wheelbase = dim
    back = state_from_sumo(*sumo_from_state([x, y, heading, v], length, wheelbase), v, length, wheelbase)
    assert back[:2] == pytest.approx([x, y], abs=1e-6)
    assert math.cos(back[2] - heading) == pytest.approx(1.0, abs=1e-9)
    assert back[3] == v


@given(coords, coords, st.floats(0.0, 359.999), dims)
def test_sumo_pose_round_trips_through_state(x, y, angle, dim):
    length, wheelbase = dim
    sx, sy, sangle = sumo_from_state(state_from_sumo(x, y, angle, 0.0, length, wheelbase), length, wheelbase)
    assert (sx, sy) == pytest.approx((x, y), abs=1e-6)
    assert math.cos(math.radians(sangle - angle)) == pytest.approx(1.0, abs=1e-9)
    assert 0.0 <= sangle < 360.0


@pytest.mark.parametrize("heading, angle, ahead", [
    (0.0, 90.0, (1, 0)),             # east
    (math.pi / 2, 0.0, (0, 1)),      # north
    (math.pi, 270.0, (-1, 0)),       # west
    (-math.pi / 2, 180.0, (0, -1)),  # south
])
def test_front_bumper_lies_half_length_plus_half_wheelbase_ahead(heading, angle, ahead):
    x, y, a = sumo_from_state([10.0, 20.0, heading, 5.0], 4.0, 2.6)
    assert (x, y) == pytest.approx(np.array([10.0, 20.0]) + 3.3 * np.array(ahead))
    assert a == pytest.approx(angle)
