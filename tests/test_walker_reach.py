"""The walkers' regions in the exact check of committed plans: closed-form distances from a car's
footprint to where a walker may be, and the bound never passes what the exact region refuses."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo.coordination.walker_reach import FAR, SEGMENT_STEP, WalkerReach
from aac_sumo.world import Obstacle, WorldState

DT = 0.1


def box_distance(points: np.ndarray, row: np.ndarray) -> np.ndarray:
    """Signed distance [m] from ``points`` (P, 2) to the footprint ``row`` [cx, cy, length,
    width, heading]: outside, the clamped excess over the half sizes in the box's frame; inside,
    minus the depth to the nearest side."""
    c, s = np.cos(row[4]), np.sin(row[4])
    d = np.atleast_2d(points) - row[:2]
    x = np.abs(d[:, 0] * c + d[:, 1] * s) - 0.5 * row[2]
    y = np.abs(-d[:, 0] * s + d[:, 1] * c) - 0.5 * row[3]
    return np.where((x <= 0.0) & (y <= 0.0), np.maximum(x, y), np.hypot(np.maximum(x, 0.0), np.maximum(y, 0.0)))


def walker(centre, velocity, walkway=None, size=0.5) -> Obstacle:
    return Obstacle("p", "pedestrian", np.array(centre, float), np.array(velocity, float), 0.0, size, size, walkway=walkway)


def reach_of(*walkers, margin=1.0, reach=1.5, walkway_time=10.0, to_end=False) -> WalkerReach:
    world = WorldState(0.0, np.zeros((0, 4)), [], list(walkers))
    return WalkerReach.of(world, margin, reach, walkway_time, DT, to_end)


def standing_course(centre, length=4.0, width=1.8, heading=0.0, periods=20) -> np.ndarray:
    return np.tile([centre[0], centre[1], length, width, heading], (periods + 1, 1))


def test_a_standing_walker_may_walk_off_in_any_direction_at_the_reach_speed():
    """She stands 8 m from the car's front (closest point): after 2 s she may be 3 m nearer, so
    the slack is 8 - (half diagonal + margin) - 1.5 m/s x 2 s, taken at the course's last row."""
    car = standing_course([10.0, 0.0])  # front bumper at x = 8
    slack = reach_of(walker([0.0, 0.0], [0.0, 0.0])).slack(car)
    radius = 0.5 * np.hypot(0.5, 0.5) + 1.0
    assert np.isclose(slack, 8.0 - radius - 1.5 * 2.0)


def test_a_walker_who_stays_on_her_walkway_never_reaches_a_car_beside_it():
    """Far from both ends of her footpath (SUMO's walkers leave it only there) she walks on
    along it: a car 3 m beside her way keeps its slack for as long as she needs to pass it."""
    on_path = walker([0.0, 0.0], [1.2, 0.0], walkway=(100.0, 100.0))
    car = standing_course([10.0, 3.0], periods=200)  # 20 s: she walks 30 m at the reach speed
    radius = 0.5 * np.hypot(0.5, 0.5) + 1.0
    slack = reach_of(on_path).slack(car)
    assert slack <= 3.0 - 0.9 - radius + 1e-9  # beside the car she is 2.1 m from its side
    assert slack >= 3.0 - 0.9 - radius - 0.5 * SEGMENT_STEP - 1e-9
    near_end = walker([0.0, 0.0], [1.2, 0.0], walkway=(2.0, 5.0))  # she can turn at her walkway's end: any direction
    assert reach_of(near_end).slack(car) < -10.0


def test_a_walker_near_her_walkways_end_keeps_to_it_until_she_can_reach_the_end():
    """With ``to_end``: 12 m from her sidewalk's end at 1.0 m/s (reach 1.5 m/s) she cannot leave it for 8 s: a
    car passing 3 m beside her way within those 8 s keeps its slack; for one standing there until
    10 s she may be anywhere within 1.5 m/s x 10 s of where she is now by then, as without
    ``to_end`` (the end may lie either way)."""
    near_end = walker([0.0, 0.0], [1.0, 0.0], walkway=(12.0, 40.0))
    radius = 0.5 * np.hypot(0.5, 0.5) + 1.0
    t = np.arange(0, 71) * DT  # 7 s
    passing = np.column_stack([-10.0 + 4.0 * t, np.full_like(t, 3.0), np.full_like(t, 4.0), np.full_like(t, 1.8), np.zeros_like(t)])
    slack = reach_of(near_end, to_end=True).slack(passing)
    assert 3.0 - 0.9 - radius - 0.5 * SEGMENT_STEP - 1e-9 <= slack <= 3.0 - 0.9 - radius + 1e-9
    standing = standing_course([10.0, 3.0], periods=100)
    nearest = np.hypot(8.0, 3.0 - 0.9)  # the car's corner nearest to where she is now
    assert np.isclose(reach_of(near_end, to_end=True).slack(standing), nearest - radius - 1.5 * 10.0)
    assert reach_of(near_end).slack(passing) < slack - 1.0  # without to_end her reach grows in every direction from now


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), periods=st.integers(0, 120))
def test_keeping_a_walker_to_her_way_until_its_end_never_makes_the_check_stricter(seed, periods):
    """Her region with ``to_end`` lies inside the one without at every moment: a course the
    check passes without it passes with it."""
    rng = np.random.default_rng(seed)
    who = walker(rng.uniform(-10, 10, 2), rng.uniform(-1.5, 1.5, 2), walkway=(float(rng.uniform(0, 20)), float(rng.uniform(0, 40))))
    heading = rng.uniform(-np.pi, np.pi)
    t = np.arange(periods + 1) * DT
    rows = np.column_stack([rng.uniform(-10, 10) + 5.0 * t * np.cos(heading), rng.uniform(-10, 10) + 5.0 * t * np.sin(heading),
                            np.full_like(t, 4.0), np.full_like(t, 1.8), np.full_like(t, heading)])
    assert reach_of(who, to_end=True).slack(rows) >= reach_of(who).slack(rows) - 0.5 * SEGMENT_STEP - 1e-9


def test_a_walker_on_her_walkway_reaches_a_car_standing_on_it_at_the_reach_speed():
    """Ahead on her way: the region is the segment she can cover at max(her speed, reach)."""
    on_path = walker([0.0, 0.0], [1.0, 0.0], walkway=(500.0, 500.0))
    car = standing_course([20.0, 0.0], periods=100)  # its rear at x = 18; after 10 s she may be at x = 15
    radius = 0.5 * np.hypot(0.5, 0.5) + 1.0
    slack = reach_of(on_path).slack(car)
    assert 3.0 - radius - 0.5 * SEGMENT_STEP - 1e-9 <= slack <= 3.0 - radius + 1e-9


@settings(max_examples=40, deadline=None)
@given(cx=st.floats(-15, 15), cy=st.floats(-15, 15), heading=st.floats(-np.pi, np.pi), vx=st.floats(-1.6, 1.6),
       vy=st.floats(-1.6, 1.6), way=st.sampled_from(["free", "bound", "end"]), end=st.floats(0.5, 14.0), periods=st.integers(0, 60))
def test_the_slack_is_never_above_the_exact_region_and_at_most_half_a_step_below(cx, cy, heading, vx, vy, way, end, periods):
    """Against a dense sampling of the exact region (a segment, or a disc; on a walkway whose end
    she can reach, the segment until the soonest she can get there, then the disc), for a car moving
    across it: never more slack than exact (the check never passes what it should refuse), and
    never more than half a SEGMENT_STEP less."""
    walkway = {"free": None, "bound": (1e4, 1e4), "end": (end, 30.0)}[way]
    who = walker([0.0, 0.0], [vx, vy], walkway=walkway)
    reach = reach_of(who, to_end=True)
    bound = way == "bound"
    t = np.arange(periods + 1) * DT
    rows = np.column_stack([cx + 3.0 * t * np.cos(heading), cy + 3.0 * t * np.sin(heading), np.full_like(t, 4.0), np.full_like(t, 1.8),
                            np.full_like(t, heading)])
    speed = np.hypot(vx, vy)
    top = max(speed, 1.5)
    along = np.array([vx, vy]) / max(speed, 1e-9) * top if way != "free" else np.zeros(2)
    growth, delay = (0.0, np.inf) if bound else (top, end / top if way == "end" else 0.0)
    radius = 0.5 * np.hypot(0.5, 0.5) + 1.0
    u = np.linspace(0.0, 1.0, 801)[:, None]
    exact = min(box_distance(along * tk * u, row).min() - radius if tk < delay else box_distance(np.zeros((1, 2)), row).min() - radius - growth * tk
                for tk, row in zip(t, rows))
    slack = reach.slack(rows)
    assert slack <= exact + 1e-9
    assert slack >= min(exact - 0.5 * SEGMENT_STEP - top * t[-1] / 800, FAR) - 1e-9  # exact below FAR


def test_a_car_may_not_come_to_stand_within_the_margin_of_a_crossing_strip():
    """A crossing along x = 239 m, 4 m wide: a car standing across the lane with its front at
    x = 236 m keeps 1 m from the strip's edge (237 m), the margin; two metres further on it
    stands 1 m inside it: the slack is the signed distance, within half a SEGMENT_STEP below."""
    from aac_sumo.world import Crossing
    world = WorldState(0.0, np.zeros((0, 4)), [], [], crossings=(Crossing("c", np.array([[239.0, 0.0], [239.0, -9.6]]), 4.0, 3.2),))
    reach = WalkerReach.of(world, 1.0, 1.5, 10.0, DT)
    before = np.array([234.0, -4.8, 4.0, 1.8, 0.0])  # front at 236
    for row, exact in ((before, 0.0), (before + [2.0, 0, 0, 0, 0], -2.0)):  # front at 238: 1 m into the 2 m half width
        assert exact - 0.5 * SEGMENT_STEP - 1e-9 <= reach.stand_slack(row) <= exact + 1e-9
    assert reach.slack(standing_course([234.0, -4.8])) == np.inf  # no walker: no region


def test_a_walker_crossing_the_road_keeps_to_her_way_and_a_standing_one_may_turn():
    """A crossing along x = 239 m from y = 0 to y = -9.6 m (4 m wide). A walker at y = -6 m walks
    south at 1.2 m/s: she has cleared the lane at y = -2 m, and a car standing there beside the
    crossing keeps its slack; the same walker standing still may turn back at the reach speed."""
    from aac_sumo.world import Crossing
    crossing = (Crossing("c", np.array([[239.0, 0.0], [239.0, -9.6]]), 4.0, 3.2),)
    car = standing_course([234.0, -2.0], periods=50)  # front at x = 236, 3 m from her way at x = 239
    radius = 0.5 * np.hypot(0.5, 0.5) + 1.0
    slacks = []
    for velocity in ([0.0, -1.2], [0.0, 0.0]):
        world = WorldState(0.0, np.zeros((0, 4)), [], [walker([239.0, -6.0], velocity)], crossings=crossing)
        slacks.append(WalkerReach.of(world, 1.0, 1.5, 10.0, DT).slack(car))
    walking, standing = slacks
    exact = np.hypot(3.0, 4.0 - 0.9) - radius  # her nearest point to the car is where she is now
    assert exact - 0.5 * SEGMENT_STEP - 1e-9 <= walking <= exact + 1e-9
    assert standing < walking - 1.5 * 5.0 + 1.0  # 5 s at 1.5 m/s in any direction


def numpy_slack(reach: WalkerReach, rows: np.ndarray) -> float:
    """The numpy form that :func:`aac_sumo.kernels.walkers.walker_slack` replaced in
    ``WalkerReach.slack`` (operation for operation)."""
    from aac_sumo.coordination.walker_reach import box_distance as boxes

    if len(reach.centres) == 0 or len(rows) == 0:
        return np.inf
    t = np.arange(len(rows)) * reach.dt
    walking = t[:, None] < reach.delay[None, :]  # (K, m): on her segment, else anywhere within growth * t
    walked = np.where(walking, t[:, None], 0.0)
    grown = np.where(walking, 0.0, reach.growth[None, :] * t[:, None])
    extent = np.where(walking, np.hypot(*reach.velocities.T)[None, :] * t[:, None], grown) + reach.radius[None, :]
    apart = np.hypot(rows[:, None, 0] - reach.centres[None, :, 0], rows[:, None, 1] - reach.centres[None, :, 1])
    bound = (apart - 0.5 * np.hypot(rows[:, 2], rows[:, 3])[:, None] - extent).min(axis=0)
    near = bound < FAR
    if not near.any():
        return float(bound.min())
    c, v, r = reach.centres[near], reach.velocities[near], reach.radius[near]
    count = int(np.ceil(float((np.hypot(*v.T) * t[-1]).max()) / SEGMENT_STEP)) + 1
    u = np.linspace(0.0, 1.0, count)
    points = c[None, :, None, :] + (walked[:, near, None, None] * u[None, None, :, None]) * v[None, :, None, :]
    spacing = np.hypot(*v.T)[None, :] * walked[:, near] / max(count - 1, 1)
    gap = boxes(points, rows).min(axis=2) - 0.5 * spacing - r[None, :] - grown[:, near]
    return float(min(gap.min(), bound[~near].min(initial=np.inf)))


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 100_000), walkers=st.integers(1, 6), periods=st.integers(0, 60), spread=st.floats(2.0, 40.0))
def test_the_compiled_slack_is_the_numpy_form_to_the_last_bit(seed, walkers, periods, spread):
    """``WalkerReach.slack`` (compiled) gives exactly the numbers of its numpy form, for walkers
    near and far, still, walking and kept to their way, along curving courses."""
    rng = np.random.default_rng(seed)
    people = [walker(rng.uniform(-spread, spread, 2), rng.uniform(-1.5, 1.5, 2) * rng.integers(0, 2),
                     walkway=(float(rng.uniform(0, 50)), float(rng.uniform(0, 50))) if rng.integers(0, 2) else None)
              for _ in range(walkers)]
    reach = reach_of(*people, to_end=bool(rng.integers(0, 2)))
    heading = np.cumsum(rng.normal(0, 0.05, periods + 1)) + rng.uniform(-np.pi, np.pi)
    xy = np.cumsum(rng.uniform(0.0, 1.6, periods + 1)[:, None] * np.column_stack([np.cos(heading), np.sin(heading)]), axis=0)
    rows = np.column_stack([xy + rng.uniform(-10, 10, 2), np.full(periods + 1, 4.0), np.full(periods + 1, 1.8), heading])
    assert reach.slack(rows) == numpy_slack(reach, rows)


def numpy_stand_slack(reach: WalkerReach, row: np.ndarray) -> float:
    """The numpy form that :func:`aac_sumo.kernels.walkers.strip_slack` replaced in
    ``WalkerReach.stand_slack``."""
    from aac_sumo.coordination.walker_reach import box_distance as boxes

    length = np.hypot(*(reach.strips[:, 1] - reach.strips[:, 0]).T)
    count = int(np.ceil(float(length.max()) / SEGMENT_STEP)) + 1
    u = np.linspace(0.0, 1.0, count)[None, :, None]
    points = reach.strips[:, :1] + u * (reach.strips[:, 1:] - reach.strips[:, :1])
    gap = boxes(points[None], row[None]).min(axis=2)[0] - 0.5 * length / max(count - 1, 1) - reach.strip_radius
    return float(gap.min())


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 100_000), strips=st.integers(1, 5))
def test_the_compiled_stand_slack_is_the_numpy_form_to_the_last_bit(seed, strips):
    """``WalkerReach.stand_slack`` (compiled, the strips' points made once) gives exactly the
    numbers of its numpy form, for footprints on, beside and far from crossings of any length."""
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-20, 20, (strips, 2))
    segments = np.stack([starts, starts + rng.uniform(-12, 12, (strips, 2))], axis=1)
    reach = WalkerReach(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0), DT, segments, rng.uniform(1.0, 4.0, strips))
    for _ in range(5):
        row = np.array([*rng.uniform(-25, 25, 2), 4.0, 1.8, rng.uniform(-np.pi, np.pi)])
        assert reach.stand_slack(row) == numpy_stand_slack(reach, row)
