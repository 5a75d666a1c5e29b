"""The compiled stop rows (:func:`aac_sumo.kernels.anticipation.stop_rows`) give what the numpy definition of
:func:`aac_sumo.coordination.anticipation.stop_points` gave, on random roads and traffic: the
same rows and the same walkers held."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo.coordination.anticipation import Anticipation, agents, stop_points
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.kernels.anticipation import TIME_GAP_SPEED, WALK_AWAY
from aac_sumo.references import PathReference
from aac_sumo.world import Obstacle, RobotSpec, WorldState

LIMITS = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
CAR = RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, LIMITS))


def numpy_stop_points(world: WorldState, i: int, task: PathReference, params: Anticipation, held: dict | None) -> np.ndarray:
    """The definition, one numpy expression per rule (see the module docstring of anticipation)."""
    robot, state = world.robots[i], world.states[i]
    s0, off0 = task.project(state[:2])
    front = robot.centre_offset + 0.5 * robot.length
    index = agents(world)[0]
    others = np.flatnonzero(index != i)
    _, centres, headings, lengths, widths, velocity, walker, accel = (a[others] for a in agents(world))
    first = int(np.sum(index >= 0))
    step_out = np.array([world.obstacles[a - first].step_out_speed(params.pedestrian_reach, params.walkway_time) if w else 0.0
                         for a, w in zip(others, walker)])
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    arrive_max = (params.look + params.pedestrian_margin + robot.length + 1.0) / max(abs(state[3]), 1.0)
    reach_max = np.where(walker, speed * arrive_max + step_out * arrive_max, speed * params.cut_in)
    bound = (off0 + params.look + max(params.pedestrian_margin, params.lateral_margin) + 0.5 * np.hypot(lengths, widths)
             + 0.5 * robot.width + reach_max)
    candidate = np.flatnonzero(np.hypot(*(centres - state[:2]).T) <= bound + 1e-6)
    s, off = task.project_many(centres[candidate])
    ahead = s - s0
    near_c = (ahead > 0.0) & (ahead <= params.look)
    near = np.zeros(len(centres), dtype=bool)
    near[candidate[near_c]] = True
    if not near.any():
        return np.zeros((0, 3))
    s, off, ahead = s[near_c], off[near_c], ahead[near_c]
    c, vel, walker, step_out = centres[near], velocity[near], walker[near], step_out[near]
    poses = task.pose_at(s)
    rel = headings[near] - poses[:, 2]
    tangent = np.column_stack([np.cos(poses[:, 2]), np.sin(poses[:, 2])])
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    side = np.where(np.einsum("ij,ij->i", normal, c - poses[:, :2]) < 0.0, -1.0, 1.0)
    across_ext = 0.5 * np.abs(lengths[near] * np.sin(rel)) + 0.5 * np.abs(widths[near] * np.cos(rel))
    along = 0.5 * np.abs(lengths[near] * np.cos(rel)) + 0.5 * np.abs(widths[near] * np.sin(rel))
    gap_across = off - across_ext - 0.5 * robot.width
    across = -side * np.einsum("ij,ij->i", vel, normal)
    toward = np.maximum(0.0, across)
    # when its rear has passed her (and the margin) at its speed, at least 1 m/s
    passed = (ahead + along + params.pedestrian_margin + 0.5 * robot.length - robot.centre_offset) / max(abs(state[3]), 1.0)
    step_out = np.where(across < -WALK_AWAY, 0.0, step_out)  # walking away: not taken to turn back
    reach = np.where(walker, np.maximum(toward * passed, step_out * np.minimum(passed, abs(state[3]) / params.decel)),
                     toward * params.cut_in)
    counts = gap_across - reach <= np.where(walker, params.pedestrian_margin, params.lateral_margin)
    if held is not None and walker.any():
        names = [world.obstacles[a - first].name if w else "" for a, w in zip(others[near], walker)]
        for k, name in enumerate(names):
            if name and counts[k]:
                held[name] = world.t
            elif name and world.t - held.get(name, -np.inf) <= params.hold and across[k] >= 0.0:
                counts[k] = True
    lead = np.where(walker, 0.0, np.maximum(np.einsum("ij,ij->i", vel, tangent), 0.0))
    keep = np.where(walker, params.pedestrian_margin, 0.0)
    grow = np.where(walker, step_out / params.decel, params.time_gap * np.minimum(lead / TIME_GAP_SPEED, 1.0))
    behind_it = s - along - front - params.gap
    s_stop = behind_it - keep
    v = abs(state[3])
    late = walker & (gap_across > params.pedestrian_margin) & (v * v > 2.0 * robot.model.limits.comfort_decel * np.maximum(s_stop - s0, 0.0))
    clear = (ahead + along + 0.5 * robot.length - robot.centre_offset + params.pedestrian_margin) / max(v, 1.0)
    counts &= ~(late & (gap_across - toward * clear > params.pedestrian_margin))
    rows = np.column_stack([s_stop, lead, grow])[counts]
    braking = counts & ~walker & (accel[near] < 0.0) & (lead > 0.0)
    stopped_at = behind_it[braking] + lead[braking] ** 2 / (-2.0 * accel[near][braking])
    return np.vstack([rows, np.column_stack([stopped_at, np.zeros((len(stopped_at), 2))])])


agent = st.tuples(st.floats(-10.0, 120.0), st.floats(-12.0, 12.0), st.floats(-np.pi, np.pi), st.floats(0.0, 15.0),
                  st.floats(-np.pi, np.pi), st.sampled_from(["vehicle", "pedestrian", "cone"]), st.floats(-5.0, 1.0),
                  st.none() | st.tuples(st.floats(0.0, 100.0), st.floats(0.0, 100.0)))


@settings(max_examples=150, deadline=None)
@given(robots=st.lists(st.tuples(st.floats(-5.0, 100.0), st.floats(-4.0, 4.0), st.floats(-0.5, 0.5), st.floats(0.0, 15.0)),
                       min_size=1, max_size=4),
       obstacles=st.lists(agent, max_size=8), bend=st.floats(-0.02, 0.02), stops=st.booleans(), t=st.floats(0.0, 3.0),
       held_times=st.lists(st.floats(-3.0, 3.0), min_size=8, max_size=8), with_held=st.booleans(),
       present=st.lists(st.booleans(), min_size=4, max_size=4), walkway_time=st.sampled_from([0.0, 5.0]))
def test_the_compiled_rows_are_the_numpy_definitions(robots, obstacles, bend, stops, t, held_times, with_held, present, walkway_time):
    arc = np.linspace(0.0, 150.0, 40)
    path = np.column_stack([arc, bend * arc**2 / 2.0])  # a straight road or a gentle bend either way
    task = PathReference(path, 12.0, stop_at_end=stops)
    states = np.array(robots, dtype=float)
    kinds = {"vehicle": (4.5, 1.8), "pedestrian": (0.5, 0.5), "cone": (0.4, 0.4)}
    world = WorldState(t, states, [CAR] * len(robots),
                       [Obstacle(f"o{k}", kind, np.array([x, y]), speed * np.array([np.cos(course), np.sin(course)]), heading,
                                 *kinds[kind], accel=accel, walkway=walkway)
                        for k, (x, y, heading, speed, course, kind, accel, walkway) in enumerate(obstacles)],
                       present=np.array(present[: len(robots)]) | (np.arange(len(robots)) == 0))
    params = Anticipation(pedestrian_reach=1.5, pedestrian_margin=1.0, brake=3.0, walkway_time=walkway_time)
    held = {f"o{k}": h for k, h in enumerate(held_times)} if with_held else None
    expected_held = None if held is None else dict(held)
    expected = numpy_stop_points(world, 0, task, params, expected_held)
    got = stop_points(world, 0, task, params, held)
    np.testing.assert_allclose(got, expected.reshape(-1, 3), rtol=1e-12, atol=1e-9)
    assert held == expected_held
