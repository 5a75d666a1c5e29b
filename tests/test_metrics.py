"""Per-step measurements and run metrics: time to collision in closed form and against a brute
force, and what the metrics count."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.runs.files import write_run
from aac_sumo.runs import runner
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.kernels.metrics import sweep_gap, times_to_collision
from aac_sumo.metrics import METRIC_KEYS, compute_metrics, time_to_collision
from aac_sumo.world import Obstacle, RobotSpec, WorldState


def car(name: str) -> RobotSpec:
    return RobotSpec(name, 4.0, 1.8, BicycleModel(2.6, VehicleLimits()))


def test_time_to_collision_is_the_bumper_gap_over_the_closing_speed():
    """Cars 4 m x 1.8 m. Car a (10 m/s) has car b (4 m/s) 12 m ahead bumper to bumper: 12 / 6 =
    2 s, sooner than a walker (0.5 m square, standing 1 m beside the path, within the half-widths
    0.9 + 0.25) whose centre is 25.75 m ahead: (25.75 - 2.25) / 10 = 2.35 s. For b the walker is
    9.75 m ahead: 7.5 / 4 = 1.875 s. Car c drives away from all of them, with a cone behind it
    and nothing ahead: NaN. A cone 3 m beside the road counts for nobody."""
    offset = car("a").centre_offset
    states = np.array([[0.0, 0.0, 0.0, 10.0], [16.0, 0.0, 0.0, 4.0], [0.0, 10.0, np.pi / 2, 5.0]])
    world = WorldState(0.0, states, [car("a"), car("b"), car("c")], [
        Obstacle("walker", "pedestrian", np.array([offset + 25.75, 1.0]), np.zeros(2), 0.0, 0.5, 0.5),
        Obstacle("beside", "cone", np.array([offset + 30.0, 3.0]), np.zeros(2), 0.0, 0.4, 0.4),
        Obstacle("behind", "cone", np.array([0.0, 10.0 + offset - 6.0]), np.zeros(2), 0.0, 0.4, 0.4),
    ])
    np.testing.assert_allclose(time_to_collision(world), [2.0, 1.875, np.nan])


def test_time_to_collision_counts_only_closing_traffic():
    """A car ahead that drives away faster gives none; nor does a walker crossing in front of a
    car that stands (no velocity along its heading, so nothing closes in)."""
    offset = car("a").centre_offset
    states = np.array([[0.0, 0.0, 0.0, 5.0], [10.0, 0.0, 0.0, 6.0], [0.0, 20.0, 0.0, 0.0]])
    world = WorldState(0.0, states, [car("a"), car("b"), car("c")],
                       [Obstacle("walker", "pedestrian", np.array([offset + 5.0, 20.0]), np.array([0.0, 1.2]), 0.0, 0.5, 0.5)])
    np.testing.assert_allclose(time_to_collision(world), [np.nan, np.nan, np.nan])


# --- TTC: the true footprint gap along the closing direction, for any orientation ---------------


def ego_world(ego_speed: float, obstacles, heading: float = 0.0) -> WorldState:
    """One car (4 m x 1.8 m) whose footprint centre is at the origin, driving at ``ego_speed``
    along ``heading``."""
    ego = car("ego")
    rear = -ego.centre_offset * np.array([np.cos(heading), np.sin(heading)])
    return WorldState(0.0, np.array([[rear[0], rear[1], heading, ego_speed]]), [ego], obstacles)


def test_ttc_sees_a_rotated_obstacle_by_its_nearest_corner():
    """A 1 m square cone turned by 45 degrees, centred 10 m ahead, shows the car its corner at
    10 - sqrt(2)/2 m; the car's bumper is 2 m ahead of its centre: at 10 m/s the TTC is
    (10 - 0.7071 - 2) / 10 s, not the (10 - 0.5 - 2) / 10 of a cone taken as unrotated."""
    cone = Obstacle("cone", "cone", np.array([10.0, 0.0]), np.zeros(2), np.pi / 4, 1.0, 1.0)
    np.testing.assert_allclose(time_to_collision(ego_world(10.0, [cone])), [(10.0 - np.sqrt(0.5) - 2.0) / 10.0])


def test_ttc_sees_a_perpendicular_vehicle_by_its_width_even_when_its_centre_is_off_the_lane():
    """A standing car (4 m x 1.8 m) across the road, centred 10 m ahead: its near side is
    10 - 0.9 m away, so TTC = (10 - 0.9 - 2) / 10. The same car centred 2.5 m to the side
    still reaches 0.5 m into the ego's lane (its half-length is 2 m), so it still counts."""
    for lateral in (0.0, 2.5, -2.5):
        across = Obstacle("across", "scripted", np.array([10.0, lateral]), np.zeros(2), np.pi / 2, 4.0, 1.8)
        np.testing.assert_allclose(time_to_collision(ego_world(10.0, [across])), [0.71])
    clear = Obstacle("across", "scripted", np.array([10.0, 2.95]), np.zeros(2), np.pi / 2, 4.0, 1.8)
    np.testing.assert_allclose(time_to_collision(ego_world(10.0, [clear])), [np.nan])


def test_ttc_head_on_uses_both_speeds():
    """Two cars head-on, centres 20 m apart at 5 m/s each: the bumpers are 16 m apart and close
    at 10 m/s, so each sees 1.6 s."""
    a, b = car("a"), car("b")
    off = a.centre_offset
    states = np.array([[-off, 0.0, 0.0, 5.0], [20.0 + off, 0.0, np.pi, 5.0]])
    np.testing.assert_allclose(time_to_collision(WorldState(0.0, states, [a, b])), [1.6, 1.6])


def test_ttc_of_a_perpendicular_crossing():
    """The car (centre at the origin, heading +x, 5 m/s) and a 1 m box centred at (10, -10)
    moving +y at 5 m/s. Relative to the box the car moves along (5, -5): the x extents meet
    for |5 t - 10| <= 2.5, t in [1.5, 2.5], the y extents for |10 - 5 t| <= 1.4, t in [1.72, 2.28],
    so they touch at t = 1.72 s. Started at (10, -20) the box passes behind the car (y window
    [3.72, 4.28] s, x window still [1.5, 2.5] s): no collision."""
    box = Obstacle("box", "static", np.array([10.0, -10.0]), np.array([0.0, 5.0]), 0.0, 1.0, 1.0)
    np.testing.assert_allclose(time_to_collision(ego_world(5.0, [box])), [1.72])
    late = Obstacle("box", "static", np.array([10.0, -20.0]), np.array([0.0, 5.0]), 0.0, 1.0, 1.0)
    np.testing.assert_allclose(time_to_collision(ego_world(5.0, [late])), [np.nan])


def test_ttc_belongs_to_the_robot_that_drives_into_the_other():
    """A car standing 12 m (bumper to bumper) ahead of one that comes at 6 m/s: the follower
    sees 2 s, the standing car, closed in on from behind, sees nothing ahead. Turned round so
    that it faces the follower, the standing car sees the oncoming car: 2 s as well."""
    a, b = car("a"), car("b")
    off = a.centre_offset
    behind = np.array([[-off, 0.0, 0.0, 6.0], [16.0 - off, 0.0, 0.0, 0.0]])
    np.testing.assert_allclose(time_to_collision(WorldState(0.0, behind, [a, b])), [2.0, np.nan])
    facing = np.array([[-off, 0.0, 0.0, 6.0], [16.0 + off, 0.0, np.pi, 0.0]])
    np.testing.assert_allclose(time_to_collision(WorldState(0.0, facing, [a, b])), [2.0, 2.0])


def brute_force_gap(a: np.ndarray, b: np.ndarray, direction: np.ndarray) -> tuple[float, float]:
    """The least s >= 0 at which rectangle row ``a`` shifted by ``s * direction`` touches row
    ``b`` (inf if never), found with the footprint clearance alone, and the least clearance
    along the way. The clearance along the ray is convex in s (a signed distance to the convex
    set b - a), so a golden-section search finds its least value, and bisection the first root
    before it."""
    def clearance(s):
        moved = a.copy()
        moved[:2] += s * direction
        return float(pairwise_rect_clearance(moved[None], b[None])[0, 0])

    if clearance(0.0) <= 0.0:
        return 0.0, clearance(0.0)
    lo, hi = 0.0, float(np.hypot(*(b[:2] - a[:2])) + np.hypot(*a[2:4]) + np.hypot(*b[2:4]))
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    for _ in range(200):
        m1, m2 = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
        if clearance(m1) <= clearance(m2):
            hi = m2
        else:
            lo = m1
    s_min = 0.5 * (lo + hi)
    least = clearance(s_min)
    if least > 0.0:
        return np.inf, least
    lo, hi = 0.0, s_min
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if clearance(mid) > 0.0 else (lo, mid)
    return hi, least


@settings(max_examples=400, deadline=None)
@given(size=st.tuples(st.floats(0.2, 5.0), st.floats(0.2, 3.0), st.floats(0.2, 5.0), st.floats(0.2, 3.0)),
       headings=st.tuples(st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi)),
       course=st.floats(-2.2, 2.2), closing=st.floats(0.05, 12.0), along=st.floats(-3.0, 15.0), beside=st.floats(-5.0, 5.0),
       other_velocity=st.tuples(st.floats(-6.0, 6.0), st.floats(-6.0, 6.0)))
def test_ttc_kernel_equals_the_brute_force_gap_along_the_closing_direction(size, headings, course, closing, along, beside,
                                                                          other_velocity):
    """For any two rectangles and velocities: when the closing velocity w = v_a - v_b points
    ahead of a (along its heading), TTC = the translation a can make along w before touching
    b, over |w|; otherwise none. Drawn: w at angle ``course`` from a's heading, b's centre
    ``along`` w and ``beside`` it from a's."""
    (la, wa, lb, wb), (ha, hb) = size, headings
    direction = np.array([np.cos(ha + course), np.sin(ha + course)])
    a = np.array([0.0, 0.0, la, wa, ha])
    b = np.array([*(along * direction + beside * np.array([-direction[1], direction[0]])), lb, wb, hb])
    velocity = np.array([np.add(other_velocity, closing * direction), other_velocity])
    ahead = closing * np.cos(course)
    assume(abs(ahead) > 1e-3)
    got = times_to_collision(np.vstack([a, b]), velocity, 1)[0]
    if ahead < 0:
        event("closing from behind")
        assert got == np.inf
        return
    gap, least = brute_force_gap(a, b, direction)
    assume(gap == 0.0 or abs(least) > 1e-6)  # a grazing touch or miss is decided by round-off
    event("touching now" if gap == 0.0 else "touches later" if np.isfinite(gap) else "misses")
    if np.isfinite(gap):
        np.testing.assert_allclose(got * closing, gap, atol=1e-6)
    else:
        assert got == np.inf


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), robots=st.integers(1, 60), side=st.floats(2.0, 40.0))
def test_ttc_kernel_is_each_robots_least_sweep_over_every_pair(seed, robots, side):
    """The compiled loop (its cheap tests that rule a pair out, its threads over the robots) gives
    each robot exactly the least ``sweep_gap / |w|`` over every other footprint that it closes on
    (``w`` ahead of its heading), in crowds of any density with standing robots and obstacles."""
    rng = np.random.default_rng(seed)
    m = robots + int(rng.integers(0, 10))
    rows = np.column_stack([rng.uniform(0, side, (m, 2)), rng.uniform(0.2, 5.0, m), rng.uniform(0.2, 3.0, m), rng.uniform(-4, 4, m)])
    velocity = rng.normal(0, 2, (m, 2)) * (rng.random(m) < 0.7)[:, None]
    expected = np.full(robots, np.inf)
    for i in range(robots):
        hx, hy = np.cos(rows[i, 4]), np.sin(rows[i, 4])
        for j in range(m):
            w = velocity[i] - velocity[j]
            closing = np.hypot(*w)
            if j != i and w @ [hx, hy] > 1e-6 and closing > 1e-6:
                expected[i] = min(expected[i], sweep_gap(rows[i], rows[j], *(w / closing)) / closing)
    np.testing.assert_array_equal(times_to_collision(rows, velocity, robots), expected)


# --- what the run metrics count -------------------------------------------------------------------


def steps_table(**columns) -> pd.DataFrame:
    """Two robots over two periods, all quiet, with ``columns`` overriding."""
    base = dict(t=[0.0, 0.0, 0.1, 0.1], robot=["a", "b", "a", "b"], x=[0.0, 5.0, 0.1, 5.0], y=[0.0, 0.0, 0.0, 0.0],
                v=[1.0] * 4, accel=[0.0] * 4, steer=[0.0] * 4, ref_x=[0.0, 5.0, 0.1, 5.0], ref_y=[0.0, 0.0, 0.0, 0.0],
                status=["solved", None, None, "solved"], iterations=[7, -1, -1, 9], capped=[False] * 4,
                authority=[True, False, False, True], arrived=[False] * 4, clearance_m=[3.0] * 4, nearest_robot_m=[5.0] * 4,
                ttc_s=[np.nan] * 4, pedestrian_clearance_m=[np.inf] * 4)
    return pd.DataFrame(base | columns)


def metrics_of(steps: pd.DataFrame, **info) -> dict:
    periods = pd.DataFrame(dict(t=[0.0, 0.1], compute_ms=[2.0, 4.0]))
    return compute_metrics(steps, periods, dict(completed=True, collisions=0, dt=0.1, wall_s=1.0, accel_threshold=3.0,
                                                lat_accel_threshold=3.0, wheelbase={"a": 1.0, "b": 1.0}) | info)


def test_tracking_error_is_the_mean_over_every_robot_at_every_step():
    """Errors 0, 0.3, 0.4 and 0.5 m (the last two across and along): mean 0.3 m, whichever rows
    the coordinator solved on. A row without a reference makes it null: never a mean over a subset."""
    steps = steps_table(y=[0.0, 0.3, 0.4, 0.0], x=[0.0, 5.0, 0.1, 5.5])
    assert metrics_of(steps)["tracking_error_m"] == pytest.approx(0.3)
    assert metrics_of(steps.assign(ref_x=[0.0, np.nan, 0.1, 5.0]))["tracking_error_m"] is None


def test_an_input_at_the_threshold_is_not_aggressive_whatever_its_rounding():
    """The thresholds are 3 m/s^2 here: robot a accelerates at the threshold as a ramp summed stage
    by stage gives it (a few ulps above) or as a solver's plan at that bound gives it (within
    its tolerance, 5e-9 above), robot b at 3.001 m/s^2: only b drives aggressively."""
    at_bound = sum([0.2] * 15)  # 3.0000000000000004
    assert at_bound > 3.0
    for a in (at_bound, 3.000000005):
        steps = steps_table(accel=[a, 0.0, 0.0, 3.001], mode=["tracking", "mpc", "tracking", "mpc"])
        assert metrics_of(steps)["aggressive_driving_rate"] == pytest.approx(0.5)
        assert metrics_of(steps.assign(accel=[a, 0.0, 0.0, 0.0]))["aggressive_driving_rate"] == 0.0


def test_capped_solves_count_the_solves_stopped_at_their_iteration_cap_and_setup_is_reported_apart():
    """Two capped solves, one of them still solved (a feasible iterate), one failed: both count;
    they stay in solves and only the failed one is infeasible. setup_s is passed on, and the
    per-period compute times are the periods' own."""
    steps = steps_table(status=["solved", "solved", "failed", "solved"], capped=[True, False, True, False])
    m = metrics_of(steps, setup_s=1.25)
    assert (m["capped_solves"], m["solves"], m["infeasible_solves"]) == (2, 4, 1)
    assert m["setup_s"] == 1.25
    assert m["compute_ms_mean"] == pytest.approx(3.0)
    assert metrics_of(steps_table())["capped_solves"] == 0


def test_the_realtime_factor_leaves_the_setup_out():
    """Two periods (0.2 s simulated) in a run of 1.5 s wall time, 1.25 s of it set-up (a first
    run compiling its problems): the real-time factor is 0.2 s over the 0.25 s after set-up;
    a run reporting no set-up is timed whole."""
    assert metrics_of(steps_table(), wall_s=1.5, setup_s=1.25)["realtime_factor"] == pytest.approx(0.8)
    assert metrics_of(steps_table(), wall_s=1.5)["realtime_factor"] == pytest.approx(0.2 / 1.5)


def documented_metric_keys() -> list[str]:
    """The keys of the README's "Metric keys" table, in its order (each row's first cell may name several)."""
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    table = text.split("Metric keys (also the columns of `results.csv`", 1)[1].split("\n\n", 2)[1]
    rows = [line.split("|")[1] for line in table.splitlines() if line.startswith("| `")]
    return [key for cell in rows for key in re.findall(r"`([a-z0-9_]+)`", cell)]


def test_metrics_json_writes_the_documented_keys_in_the_documented_order(tmp_path):
    """A run's real metrics.json starts with METRIC_KEYS, in order; the README documents every
    one of them in that same order (keys are added at the end, so no script that reads columns
    by position breaks), and every other key written is documented too (or named in its prose:
    ``incomplete_reason``, ``error``)."""
    documented = documented_metric_keys()
    assert len(documented) == len(set(documented)) > len(METRIC_KEYS)
    assert [k for k in documented if k in METRIC_KEYS] == list(METRIC_KEYS)
    result = runner.run(config.load("swarm_rescue", ["scenario.duration=0.3", "controller.horizon=5"]))
    write_run(result, tmp_path)
    written = list(json.loads((tmp_path / "metrics.json").read_text()))
    assert written[: len(METRIC_KEYS)] == list(METRIC_KEYS)
    assert set(written[len(METRIC_KEYS):]) <= set(documented) | {"incomplete_reason", "error"}
    assert "incomplete_reason" in written  # 0.3 s: the time limit, not an error
    assert "error" not in written
