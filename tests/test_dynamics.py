"""Specification tests for aac_sumo.dynamics (the paper's discrete kinematic bicycle model).

State ``[x, y, heading, v]`` at the rear axle, input ``[accel, steer]``; one forward-Euler step is

    x+ = x + v cos(heading) dt,  y+ = y + v sin(heading) dt,
    heading+ = heading + v tan(steer) / L dt,  v+ = v + accel dt.

The tests check the closed-form motions this implies (straight line, regular polygon on a circle,
constant acceleration), numpy/casadi agreement, and the limits applied by the simulator model.
"""

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from aac_sumo.dynamics import NU, NX, BicycleModel, FleetModel, VehicleLimits, bicycle_step

coord = st.floats(-100.0, 100.0)
heading_st = st.floats(-np.pi, np.pi)
speed_st = st.floats(0.1, 20.0)
dt_st = st.sampled_from([0.01, 0.05, 0.1, 0.2])
wheelbase_st = st.floats(0.3, 4.0)


def rollout(state, control, dt, wheelbase, steps):
    """States (steps + 1, 4) from holding ``control`` constant."""
    out = [np.asarray(state, dtype=float)]
    for _ in range(steps):
        out.append(bicycle_step(out[-1], np.asarray(control, dtype=float), dt, wheelbase))
    return np.array(out)


# --------------------------------------------------------------------------------------------
# Closed-form motions
# --------------------------------------------------------------------------------------------


@given(x0=coord, y0=coord, v=speed_st, dt=dt_st, wheelbase=wheelbase_st)
@settings(max_examples=50)
def test_straight_line_heading_zero(x0, y0, v, dt, wheelbase):
    """Zero steer, zero accel, heading 0: x_k = x0 + v k dt, y, heading and v never change."""
    states = rollout([x0, y0, 0.0, v], [0.0, 0.0], dt, wheelbase, 40)
    k = np.arange(41)
    np.testing.assert_allclose(states[:, 0], x0 + v * k * dt, rtol=1e-12, atol=1e-10)
    assert np.all(states[:, 1] == y0)
    assert np.all(states[:, 2] == 0.0)
    assert np.all(states[:, 3] == v)


@given(x0=coord, y0=coord, heading=heading_st, v=speed_st, dt=dt_st, wheelbase=wheelbase_st)
@settings(max_examples=50)
def test_straight_line_arbitrary_heading(x0, y0, heading, v, dt, wheelbase):
    """Zero steer, zero accel: the rear axle moves along its heading by v dt per step."""
    states = rollout([x0, y0, heading, v], [0.0, 0.0], dt, wheelbase, 40)
    k = np.arange(41)
    np.testing.assert_allclose(states[:, 0], x0 + v * k * dt * np.cos(heading), rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(states[:, 1], y0 + v * k * dt * np.sin(heading), rtol=1e-12, atol=1e-10)
    assert np.all(states[:, 2] == heading)
    assert np.all(states[:, 3] == v)


def polygon_circle(p0, heading0, v, steer, dt, wheelbase):
    """Centre and circumradius of the regular polygon traced by constant (v, steer) Euler steps.

    Each step is a chord of length s = v dt followed by a turn of beta = v tan(steer) dt / L, so
    the vertices lie on a circle of radius R = s / (2 |sin(beta / 2)|) whose centre is the chord
    midpoint shifted by s / (2 tan(beta / 2)) along the left normal.
    """
    s = v * dt
    beta = v * np.tan(steer) * dt / wheelbase
    t = np.array([np.cos(heading0), np.sin(heading0)])
    n = np.array([-t[1], t[0]])
    centre = np.asarray(p0) + 0.5 * s * t + s / (2.0 * np.tan(0.5 * beta)) * n
    return centre, s / (2.0 * abs(np.sin(0.5 * beta)))


@given(
    x0=coord,
    y0=coord,
    heading=heading_st,
    v=speed_st,
    steer=st.floats(0.05, 0.6) | st.floats(-0.6, -0.05),
    dt=dt_st,
    wheelbase=wheelbase_st,
)
@settings(max_examples=60)
def test_constant_steer_points_lie_on_circle(x0, y0, heading, v, steer, dt, wheelbase):
    """Constant steer, zero accel: the discrete points are the vertices of a regular polygon
    with circumradius R_dt = v dt / (2 sin(v tan(steer) dt / (2 L))), and the heading grows by
    v tan(steer) / L dt per step."""
    beta = v * np.tan(steer) * dt / wheelbase
    assume(abs(beta) < np.pi / 2)  # one step turns less than a quarter circle: a proper polygon
    steps = 30
    states = rollout([x0, y0, heading, v], [0.0, steer], dt, wheelbase, steps)
    centre, radius = polygon_circle([x0, y0], heading, v, steer, dt, wheelbase)
    dist = np.hypot(states[:, 0] - centre[0], states[:, 1] - centre[1])
    scale = max(radius, abs(x0), abs(y0), 1.0)
    np.testing.assert_allclose(dist, radius, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(np.diff(states[:, 2]), beta, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(states[:, 2], heading + beta * np.arange(steps + 1), rtol=1e-12, atol=1e-12)
    # turning left (steer > 0) puts the centre on the left of the initial heading
    left = -np.sin(heading) * (centre[0] - x0) + np.cos(heading) * (centre[1] - y0)
    assert np.sign(left) == np.sign(steer)


@given(v=speed_st, steer=st.floats(0.05, 0.6), wheelbase=wheelbase_st)
def test_polygon_radius_tends_to_continuous_turn_radius(v, steer, wheelbase):
    """As dt -> 0 the polygon circumradius tends to the bicycle's turn radius L / tan(steer);
    at dt = 1e-3 the difference is second order (R_dt ~ R (1 + beta^2 / 24))."""
    turn_radius = wheelbase / np.tan(steer)
    radii = []
    for dt in (1e-1, 1e-2, 1e-3):
        _, r_dt = polygon_circle([0.0, 0.0], 0.0, v, steer, dt, wheelbase)
        radii.append(r_dt)
    beta = v * np.tan(steer) * 1e-3 / wheelbase
    assert abs(radii[-1] - turn_radius) <= (1.01 * beta**2 / 24.0 + 1e-12) * turn_radius
    assert abs(radii[-1] - turn_radius) <= 1e-4 * turn_radius
    errors = np.abs(np.array(radii) - turn_radius)
    assert np.all(np.diff(errors) <= 0.0)


def test_simulated_turn_at_small_dt_follows_continuous_circle():
    """Integrating a quarter turn at dt = 1e-3 stays within 1e-3 R of the continuous circle of
    radius L / tan(steer) centred on the left of the start."""
    v, steer, wheelbase, dt = 5.0, 0.3, 2.0, 1e-3
    turn_radius = wheelbase / np.tan(steer)
    steps = int(round(0.5 * np.pi / (v * np.tan(steer) / wheelbase) / dt))
    states = rollout([0.0, 0.0, 0.0, v], [0.0, steer], dt, wheelbase, steps)
    dist = np.hypot(states[:, 0], states[:, 1] - turn_radius)
    assert np.max(np.abs(dist - turn_radius)) < 1e-3 * turn_radius
    assert states[-1, 2] == pytest.approx(0.5 * np.pi, abs=v * np.tan(steer) / wheelbase * dt)


@given(
    x0=coord,
    v0=st.floats(0.0, 20.0),
    accel=st.floats(-6.0, 3.0),
    dt=dt_st,
    wheelbase=wheelbase_st,
)
@settings(max_examples=50)
def test_constant_acceleration(x0, v0, accel, dt, wheelbase):
    """Heading 0, zero steer, constant accel: v_k = v0 + a k dt and
    x_k = x0 + v0 k dt + a dt^2 k (k - 1) / 2 (Euler uses the speed at the start of each step)."""
    steps = 30
    states = rollout([x0, 0.0, 0.0, v0], [accel, 0.0], dt, wheelbase, steps)
    k = np.arange(steps + 1)
    np.testing.assert_allclose(states[:, 3], v0 + accel * k * dt, rtol=1e-12, atol=1e-11)
    expected_x = x0 + v0 * k * dt + accel * dt**2 * k * (k - 1) / 2.0
    np.testing.assert_allclose(states[:, 0], expected_x, rtol=1e-12, atol=1e-10)
    assert np.all(states[:, 1] == 0.0)
    assert np.all(states[:, 2] == 0.0)


# --------------------------------------------------------------------------------------------
# numpy / casadi agreement and batching
# --------------------------------------------------------------------------------------------

_SX_STATE = ca.SX.sym("x", NX)
_SX_INPUT = ca.SX.sym("u", NU)
_SX_L = ca.SX.sym("L")
_SX_DT = 0.1
_CASADI_STEP = ca.Function("step", [_SX_STATE, _SX_INPUT, _SX_L], [bicycle_step(_SX_STATE, _SX_INPUT, _SX_DT, _SX_L, xp=ca)])

state_st = st.tuples(coord, coord, st.floats(-2 * np.pi, 2 * np.pi), st.floats(-5.0, 25.0))
input_st = st.tuples(st.floats(-10.0, 10.0), st.floats(-1.2, 1.2))


@given(state=state_st, control=input_st, wheelbase=wheelbase_st)
@settings(max_examples=100)
def test_numpy_and_casadi_agree(state, control, wheelbase):
    """The same definition evaluated with numpy, with casadi DM and through a symbolic casadi
    Function gives the same next state."""
    state, control = np.array(state), np.array(control)
    expected = bicycle_step(state, control, _SX_DT, wheelbase)
    dm = np.asarray(bicycle_step(ca.DM(state), ca.DM(control), _SX_DT, wheelbase, xp=ca)).ravel()
    sym = np.asarray(_CASADI_STEP(state, control, wheelbase)).ravel()
    assert expected.shape == (NX,)
    np.testing.assert_allclose(dm, expected, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(sym, expected, rtol=1e-13, atol=1e-12)


@given(
    states=st.lists(state_st, min_size=1, max_size=6),
    controls=st.lists(input_st, min_size=6, max_size=6),
    wheelbase=wheelbase_st,
)
@settings(max_examples=30)
def test_numpy_batch_equals_rowwise(states, controls, wheelbase):
    """Arrays of shape (n, 4) / (n, 2) step row by row."""
    states = np.array(states)
    controls = np.array(controls)[: len(states)]
    batch = bicycle_step(states, controls, 0.1, wheelbase)
    assert batch.shape == states.shape
    for i in range(len(states)):
        np.testing.assert_array_equal(batch[i], bicycle_step(states[i], controls[i], 0.1, wheelbase))


# --------------------------------------------------------------------------------------------
# Limits: BicycleModel.step and VehicleLimits
# --------------------------------------------------------------------------------------------

LIMITS = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.6, v_min=0.0, v_max=12.0)
MODEL = BicycleModel(wheelbase=0.8, limits=LIMITS)


@given(
    state=st.tuples(coord, coord, heading_st, st.floats(LIMITS.v_min, LIMITS.v_max)),
    control=st.tuples(st.floats(-50.0, 50.0), st.floats(-3.0, 3.0)),
    dt=dt_st,
)
@settings(max_examples=100)
def test_model_step_clips_inputs_and_speed(state, control, dt):
    """BicycleModel.step applies the Euler step with the input clipped to the limits and keeps
    the speed inside [v_min, v_max]."""
    state, control = np.array(state), np.array(control)
    nxt = MODEL.step(state, control, dt)
    accel = min(max(control[0], LIMITS.a_min), LIMITS.a_max)
    steer = min(max(control[1], -LIMITS.steer_max), LIMITS.steer_max)
    x, y, heading, v = state
    np.testing.assert_allclose(nxt[0], x + v * np.cos(heading) * dt, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(nxt[1], y + v * np.sin(heading) * dt, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(nxt[2], heading + v * np.tan(steer) / MODEL.wheelbase * dt, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(nxt[3], min(max(v + accel * dt, LIMITS.v_min), LIMITS.v_max), rtol=1e-14, atol=1e-12)
    assert LIMITS.v_min <= nxt[3] <= LIMITS.v_max
    # never reverses: the displacement is along the heading, never against it
    assert (nxt[0] - x) * np.cos(heading) + (nxt[1] - y) * np.sin(heading) >= -1e-12


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), dt=dt_st)
@settings(max_examples=50)
def test_fleet_step_is_each_robots_own_model_step(seed, n, dt):
    """FleetModel steps robots with different wheelbases and limits exactly as each robot's
    BicycleModel.step would, inputs far outside the limits included."""
    rng = np.random.default_rng(seed)
    models = [BicycleModel(rng.uniform(0.3, 4.0), VehicleLimits(-rng.uniform(1, 9), rng.uniform(1, 5), rng.uniform(0.1, 0.8),
                                                                rng.uniform(-2, 1), rng.uniform(2, 30))) for _ in range(n)]
    states = np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-np.pi, np.pi, n), rng.uniform(0, 20, n)])
    inputs = rng.uniform(-20, 20, (n, 2))
    expected = np.array([m.step(s, u, dt) for m, s, u in zip(models, states, inputs)])
    np.testing.assert_array_equal(FleetModel(models).step(states, inputs, dt), expected)


def test_model_step_does_not_mutate_its_arguments():
    state = np.array([1.0, 2.0, 0.3, 4.0])
    control = np.array([100.0, -5.0])
    MODEL.step(state, control, 0.1)
    np.testing.assert_array_equal(state, [1.0, 2.0, 0.3, 4.0])
    np.testing.assert_array_equal(control, [100.0, -5.0])


def test_hard_braking_stops_and_stays_stopped():
    """Full braking from 5 m/s at a_min = -6 m/s^2 stops after ceil(5 / 0.6) steps and never
    goes backwards."""
    state = np.array([0.0, 0.0, 0.0, 5.0])
    speeds, xs = [state[3]], [state[0]]
    for _ in range(20):
        state = MODEL.step(state, np.array([-100.0, 0.0]), 0.1)
        speeds.append(state[3])
        xs.append(state[0])
    assert speeds[9] == 0.0 and speeds[8] > 0.0
    assert np.all(np.diff(speeds) <= 0.0) and min(speeds) == 0.0
    assert np.all(np.diff(xs) >= 0.0)
    assert xs[-1] == xs[10]


def test_clip_input_batches():
    controls = np.array([[10.0, 1.0], [-10.0, -1.0], [1.0, 0.1]])
    np.testing.assert_array_equal(LIMITS.clip_input(controls), [[3.0, 0.6], [-6.0, -0.6], [1.0, 0.1]])


@given(
    v_min=st.floats(0.0, 3.0),
    extra=st.floats(0.0, 15.0),
    a_min=st.floats(-10.0, -0.5),
    dt=dt_st,
)
@settings(max_examples=100)
def test_braking_input_never_below_v_min(v_min, extra, a_min, dt):
    """braking_input is admissible (a_min <= accel <= 0, zero steer), never brings the speed below
    v_min within dt, and is the hardest such braking: it either uses a_min or lands on v_min."""
    limits = VehicleLimits(a_min=a_min, a_max=3.0, steer_max=0.6, v_min=v_min, v_max=v_min + 20.0)
    speed = v_min + extra
    accel, steer = limits.braking_input(speed, dt)
    assert steer == 0.0
    assert a_min <= accel <= 0.0
    nxt = speed + accel * dt
    assert nxt >= v_min - 1e-12
    assert accel == a_min or nxt == pytest.approx(v_min, abs=1e-12)
    # through the raw (unclipped) dynamics as well
    state = bicycle_step(np.array([0.0, 0.0, 0.0, speed]), np.array([accel, steer]), dt, 1.0)
    assert state[3] >= v_min - 1e-12


@given(speed=st.floats(-5.0, 5.0), a_min=st.floats(-10.0, -0.5), a_max=st.floats(0.5, 5.0), dt=dt_st)
@settings(max_examples=100)
def test_braking_with_reverse_allowed_stops_at_zero(speed, a_min, a_max, dt):
    """With reversing allowed (v_min < 0) braking heads for standstill from either direction and
    never crosses it; stopping_inputs reaches standstill and stays there."""
    limits = VehicleLimits(a_min=a_min, a_max=a_max, steer_max=0.6, v_min=-5.0, v_max=5.0)
    accel, _ = limits.braking_input(speed, dt)
    nxt = speed + accel * dt
    assert nxt * speed >= -1e-12  # same sign as before, or zero
    assert abs(nxt) <= abs(speed) + 1e-12
    steps = int(np.ceil(abs(speed) / min(-a_min, a_max) / dt)) + 2
    speeds = speed + np.cumsum(limits.stopping_inputs(speed, dt, steps)[:, 0]) * dt
    assert speeds[-1] == pytest.approx(0.0, abs=1e-9)
    assert np.all(speeds * speed >= -1e-9)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 100_000), use_first=st.booleans(), steps=st.integers(1, 40), dt=dt_st)
@example(seed=67937, use_first=False, steps=8, dt=0.2)  # a car backing up at 0.8 m/s with a_max 0.5: rest takes longer than braking
def test_compiled_braking_courses_step_the_bicycle_model_under_the_braking_law(seed, use_first, steps, dt):
    """The compiled braking course is, step by step, :func:`bicycle_step` (speed clipped into its
    bounds) under its first input and then the braking law: acceleration ``clip(-v / dt)``,
    steering from :func:`heading_hold_steer` within :meth:`BicycleModel.limit_steer` (rate from
    the steering before, lateral acceleration); it reaches standstill and stays there."""
    from aac_sumo.dynamics import heading_hold_steer
    from aac_sumo.kernels.safety import braking_courses

    rng = np.random.default_rng(seed)
    m = 6
    states = np.column_stack([rng.uniform(-50, 50, (m, 2)), rng.uniform(-np.pi, np.pi, m), rng.uniform(-2.0, 15.0, m)])
    states[0, 3] = 0.0
    first = np.column_stack([rng.uniform(-6, 3, m), rng.uniform(-0.5, 0.5, m)])
    headings = rng.uniform(-4.0, 4.0, m)
    wheelbase, steer_max = rng.uniform(0.4, 3.0, m), rng.uniform(0.2, 0.7, m)
    a_min, a_max = rng.uniform(-8.0, -1.0, m), rng.uniform(0.5, 4.0, m)
    v_min, v_max = np.where(rng.random(m) < 0.5, 0.0, -3.0), np.full(m, 20.0)
    a_lat, rate = np.where(rng.random(m) < 0.3, np.inf, rng.uniform(0.5, 5.0, m)), np.where(rng.random(m) < 0.3, np.inf, rng.uniform(0.1, 3.0, m))
    previous = rng.uniform(-0.5, 0.5, m)
    models = [BicycleModel(wheelbase[i], VehicleLimits(a_min[i], a_max[i], steer_max[i], v_min[i], v_max[i], a_lat[i], rate[i])) for i in range(m)]
    got = braking_courses(states, first, use_first, previous, headings[:, None], 1.0, wheelbase, a_min, a_max, v_min, v_max,
                          np.column_stack([steer_max, a_lat, rate]), dt, 0.5, steps)

    x = states.copy()
    steer = previous.copy()
    for k in range(steps):
        if k == 0 and use_first:
            u = first
        else:
            accel = np.clip(-x[:, 3] / dt, a_min, a_max)
            wanted = heading_hold_steer(x, headings, dt, wheelbase, steer_max, 0.5)
            u = np.column_stack([accel, [models[i].limit_steer(wanted[i], x[i, 3], steer[i], dt, accel[i]) for i in range(m)]])
        steer = u[:, 1].copy()
        x = bicycle_step(x, u, dt, wheelbase)
        x[:, 3] = np.clip(x[:, 3], v_min, v_max)
        np.testing.assert_allclose(got[:, k + 1], x, rtol=1e-12, atol=1e-9)
    rate = np.minimum(-a_min, a_max)  # a car backing up comes to rest speeding up (at most a_max), one going forward braking
    if steps >= 2 + int(np.ceil(np.max((np.abs(states[:, 3]) + 6.0 * dt) / rate) / dt)):
        np.testing.assert_allclose(got[:, -1, 3], 0.0, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 100_000), steps=st.integers(0, 20), dt=dt_st)
def test_compiled_rollouts_step_the_bicycle_model(seed, steps, dt):
    """The compiled rollout is :func:`bicycle_step` under the given inputs, step by step, with
    the speed clipped into each robot's bounds."""
    from aac_sumo.kernels.motion import rollouts

    rng = np.random.default_rng(seed)
    m = 5
    states = np.column_stack([rng.uniform(-50, 50, (m, 2)), rng.uniform(-np.pi, np.pi, m), rng.uniform(-2.0, 15.0, m)])
    inputs = np.stack([rng.uniform(-6, 3, (m, steps)), rng.uniform(-0.5, 0.5, (m, steps))], axis=-1)
    wheelbase, v_min, v_max = rng.uniform(0.4, 3.0, m), np.where(rng.random(m) < 0.5, 0.0, -3.0), rng.uniform(5.0, 20.0, m)
    got = rollouts(states, inputs, dt, wheelbase, v_min, v_max)
    x = states.copy()
    np.testing.assert_array_equal(got[:, 0], states)
    for k in range(steps):
        x = bicycle_step(x, inputs[:, k], dt, wheelbase)
        x[:, 3] = np.clip(x[:, 3], v_min, v_max)
        np.testing.assert_allclose(got[:, k + 1], x, rtol=1e-12, atol=1e-9)


def _pure_pursuit(robot, state, task, lookahead, speed_gain, previous_steer, dt, offset, target_speed):
    """The tracking law as numpy statements, from the path's own methods: the definition the
    compiled rollout is held to."""
    from aac_sumo.coordination.tracking import pursuit

    aim = pursuit(lookahead)  # a fixed distance, or at low speed the distance covered in aim.time, at least aim.least
    look = aim.distance if aim.time <= 0.0 else min(aim.distance, max(aim.least, aim.time * abs(float(state[3]))))
    s0, _ = task.project(state[:2])
    pose = task.pose_at(min(s0 + look, task.length) if task.stop_at_end else s0 + look)[0]
    target = pose[:2] + offset * np.array([np.sin(pose[2]), -np.cos(pose[2])])
    near_goal = task.stop_at_end and float(np.hypot(*(task.points[-1] - state[:2]))) <= task.approach
    if near_goal:
        target = task.points[-1]
    rel = target - state[:2]
    dist = float(np.hypot(*rel))
    steer = 0.0 if dist < 1e-6 else float(np.arctan2(2.0 * robot.model.wheelbase * np.sin(np.arctan2(rel[1], rel[0]) - state[2]), dist))
    speed = min(task.speed, float(np.sqrt(2.0 * task.decel * dist))) if near_goal else float(task.speed_at(s0))
    if target_speed is not None and not near_goal:
        speed = target_speed
    lim = robot.model.limits
    accel = speed_gain * (speed - state[3])
    if task.stop_at_end and state[3] > max(speed, 0.0):  # above the stopping profile: at least what stops it at the goal
        rest = dist if near_goal else max(task.length - s0, 0.0)
        accel = min(accel, -state[3] ** 2 / (2.0 * max(rest, 1e-6)))
    accel = min(max(accel, -lim.comfort_decel), lim.a_max)
    return np.array([accel, float(robot.model.limit_steer(steer, state[3], previous_steer, dt, accel))])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), steps=st.integers(1, 12))
def test_compiled_tracking_course_is_the_pure_pursuit_law_applied_period_after_period(seed, steps):
    """:func:`~aac_sumo.coordination.tracking.track_course` on random paths (stopping or not,
    with speed limits or not, an approach zone or not), robots, offsets, target speeds and
    lookaheads (fixed, or shrinking with speed) gives the inputs of the tracking law evaluated
    from the path's methods and the model's steering limits, stepping the robot's model between
    periods."""
    from aac_sumo.coordination.tracking import Pursuit, track_course
    from aac_sumo.references import PathReference
    from aac_sumo.world import RobotSpec

    rng = np.random.default_rng(seed)
    limits = VehicleLimits(a_min=-rng.uniform(2, 6), a_max=rng.uniform(1, 3), steer_max=rng.uniform(0.3, 0.6), v_max=rng.uniform(1.5, 20),
                           a_lat_max=rng.choice([np.inf, 3.0]), steer_rate_max=rng.choice([np.inf, 0.5, 2.0]), a_comfort=rng.choice([np.inf, 2.0]))
    robot = RobotSpec("r", 4.0, 1.8, BicycleModel(rng.uniform(0.4, 2.6), limits))
    points = np.cumsum(rng.uniform(-5, 5, (int(rng.integers(2, 40)), 2)), axis=0)
    task = PathReference(points, rng.uniform(0.5, 10), rng.uniform(0.5, 3), stop_at_end=bool(rng.integers(2)), approach=rng.choice([0.0, 2.0]),
                         limits=rng.uniform(0.5, 10, len(points)) if rng.integers(2) else None)
    state = np.r_[points[0] + rng.uniform(-2, 2, 2), rng.uniform(-3, 3), rng.uniform(0, limits.v_max)]
    lookahead, offset, previous, dt = rng.uniform(0.5, 3), rng.choice([0.0, 1.0]), rng.uniform(-0.3, 0.3), 0.1
    if rng.integers(2):  # aiming nearer at low speed
        lookahead = Pursuit(lookahead, rng.uniform(0.2, 1.5), rng.uniform(0.1, 1.0))
    target = float(rng.uniform(0, 5)) if rng.integers(2) else None
    got = track_course(robot, state, task, lookahead, 1.0, previous, dt, steps, offset, target)
    for k in range(steps):
        want = _pure_pursuit(robot, state, task, lookahead, 1.0, previous, dt, offset, target)
        np.testing.assert_allclose(got[k], want, rtol=1e-9, atol=1e-9)
        previous, state = want[1], robot.model.step(state, want, dt)


@pytest.mark.parametrize("speed_gain", [0.5, 1.0, 3.0])
def test_the_tracking_law_stops_at_the_goal_of_a_path_that_stops(speed_gain):
    """On a straight 10 m path that stops (braking profile 0.5 m/s^2), a robot starting at the
    cruise speed of 1 m/s comes to rest at the goal, not beyond it: the proportional speed loop
    alone lags the profile by decel / gain and overshot by up to 0.9 m (swarm rescue, seed 2)
    before it brakes at least as hard as stops it at the goal."""
    from aac_sumo.coordination.tracking import track_course
    from aac_sumo.references import PathReference
    from aac_sumo.world import RobotSpec

    limits = VehicleLimits(a_min=-2.0, a_max=1.0, steer_max=0.6, v_max=1.5, a_comfort=2.0)
    robot = RobotSpec("r", 0.6, 0.4, BicycleModel(0.45, limits))
    task = PathReference(np.array([[0.0, 0.0], [10.0, 0.0]]), 1.0, 0.5, approach=0.15, arrive=0.3)
    state = np.array([0.0, 0.0, 0.0, 1.0])
    inputs = track_course(robot, state, task, 0.8, speed_gain, 0.0, 0.1, 200)
    for u in inputs:
        state = robot.model.step(state, u, 0.1)
        if state[3] <= 0.0:
            break
    assert state[3] == 0.0 and 10.0 - 0.3 <= state[0] <= 10.0 + 0.05


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), steps=st.integers(1, 40), t0=st.integers(0, 10), n_stops=st.integers(0, 4))
def test_compiled_continuation_is_the_loop_of_the_anticipated_speed_law(seed, steps, t0, n_stops):
    """:func:`~aac_sumo.kernels.motion.continuation_inputs` on random roads (with curve speed
    limits or not), robots, stop rows and keep-right shifts gives the loop it
    replaced in ``CommittedAac.continued_commitment``: each period the target speed is the lower
    of the path's speed where the car will be ``lag`` on and the anticipation's
    :func:`~aac_sumo.coordination.anticipation.speed_cap` of the stops (each moved on at its
    speed), the acceleration reaches it in ``lag`` within the comfort envelope and the
    anticipation's ``accel``, the steering is :func:`~aac_sumo.coordination.tracking.track`'s
    with that target, and the robot's model steps (equal up to the last bit of libm's rounding)."""
    from aac_sumo.coordination.anticipation import speed_cap
    from aac_sumo.coordination.tracking import Pursuit, track
    from aac_sumo.kernels.motion import continuation_inputs
    from aac_sumo.references import PathReference
    from aac_sumo.world import RobotSpec

    rng = np.random.default_rng(seed)
    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
    robot = RobotSpec("r", 4.0, 1.8, BicycleModel(2.6, limits))
    points = np.column_stack([np.linspace(0.0, 300.0, 31), np.cumsum(rng.uniform(-1.0, 1.0, 31))])
    task = PathReference(points, 10.0, stop_at_end=False, limits=rng.uniform(4.0, 12.0, 31) if rng.integers(2) else None)
    state = np.r_[points[0] + rng.uniform(-1.0, 1.0, 2), rng.uniform(-0.2, 0.2), rng.uniform(0.0, 12.0)]
    stops = np.column_stack([rng.uniform(-5.0, 120.0, n_stops), rng.uniform(0.0, 10.0, n_stops), rng.uniform(0.0, 1.5, n_stops)])
    dt, lag, decel, accel_up, calm = 0.1, 0.3, 1.5, 1.5, 2.0
    pursuit = Pursuit(10.0, *((1.0, 3.0) if rng.integers(2) else (0.0, 0.0)))
    gain, shift, lat, steer0 = 1.0, float(rng.choice([0.0, 0.5])), 2.0, float(rng.uniform(-0.05, 0.05))
    accel0, jerk = float(rng.uniform(-3.0, 3.0)), float(rng.choice([0.0, 5.0]))
    lim = robot.model.limits
    got = continuation_inputs(*(float(c) for c in state), steps, t0, dt, stops, decel, accel_up, calm, lag, robot.model.wheelbase,
                              lim.a_min, lim.a_max, lim.steer_max, lim.v_min, lim.v_max, lim.a_lat_max, min(lim.a_lat_max, lat),
                              lim.steer_rate_max, lim.comfort_decel, steer0, *task.arrays(), task.speed, task.decel, *pursuit.args(), gain, shift,
                              np.empty(0), 1.0, accel0, jerk)
    steer, before = steer0, accel0
    for k in range(steps):
        t = (t0 + k) * dt
        moved = stops + np.column_stack([stops[:, 1] * t, np.zeros((len(stops), 2))])
        ahead = task.project(state[:2])[0] + max(float(state[3]), 0.0) * lag
        target = min(float(speed_cap(moved, [ahead], decel)[0]), float(task.speed_at(ahead)))
        want = track(robot, state, task, pursuit, gain, steer, dt, shift, target_speed=target, a_lat=lat)
        want[0] = min(max((target - float(state[3])) / lag, -calm), accel_up)
        if jerk > 0.0:  # no faster than easing off at jerk reaches the target, within jerk * dt of the acceleration before,
            gap = target - float(state[3])  # then within the envelope, which wins
            want[0] = np.sign(gap) * min(abs(want[0]), np.sqrt(2.0 * jerk * abs(gap)))
            want[0] = min(max(min(max(want[0], before - jerk * dt), before + jerk * dt), -calm), accel_up)
        np.testing.assert_allclose(got[k], want, rtol=1e-9, atol=1e-12)  # libm may round the last bit differently
        state, steer, before = robot.model.step(state, got[k], dt), float(got[k][1]), float(got[k][0])


@settings(max_examples=40, deadline=None)
@given(v0=st.floats(0.0, 16.0), spare=st.floats(0.5, 60.0), tail=st.floats(1.0, 2.0), accel0=st.floats(-2.0, 2.0),
       jerk=st.sampled_from([0.0, 6.0]), lag=st.sampled_from([0.1, 0.3]))
def test_a_continuation_behind_a_standing_point_can_always_stop_before_it(v0, spare, tail, accel0, jerk, lag):
    """With a standing point ``s_h`` ahead (where an uncontrolled vehicle ahead could stand),
    a continuation capped at ``HARD_SHARE`` of a stopping tail's deceleration ``tail`` (within
    the comfort envelope, 2 m/s^2) that starts able to stop before it stays able to within
    5 cm at every period (the tail from anywhere on it stops there), and never passes it by more,
    whether or not its acceleration changes at a limited jerk from the one before."""
    from aac_sumo.coordination.aac.committed import HARD_SHARE
    from aac_sumo.kernels.motion import continuation_inputs
    from aac_sumo.references import PathReference
    from aac_sumo.world import RobotSpec

    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
    robot = RobotSpec("r", 4.0, 1.8, BicycleModel(2.6, limits))
    task = PathReference(np.array([[0.0, 0.0], [500.0, 0.0]]), 16.0, stop_at_end=False)
    dt, calm = 0.1, 2.0
    s_h = v0 * lag + v0**2 / (2.0 * HARD_SHARE * tail) + spare
    lim = robot.model.limits
    inputs = continuation_inputs(0.0, 0.0, 0.0, v0, 200, 0, dt, np.zeros((0, 3)), 1.5, 1.5, calm, lag, robot.model.wheelbase,
                                 lim.a_min, lim.a_max, lim.steer_max, lim.v_min, lim.v_max, lim.a_lat_max, 2.0, lim.steer_rate_max,
                                 lim.comfort_decel, 0.0, *task.arrays(), task.speed, task.decel, 10.0, 0.0, 0.0, 1.0, 0.0,
                                 np.array([s_h]), HARD_SHARE * tail, accel0, jerk)
    state = np.array([0.0, 0.0, 0.0, v0])
    for u in inputs:
        state = robot.model.step(state, u, dt)
        assert state[0] + state[3] ** 2 / (2.0 * tail) <= s_h + 0.05
    assert state[0] <= s_h + 0.05
