"""Specification tests for aac_sumo.barriers (F-CBF / CBF safety ellipses, paper eqs. 6-7).

F-CBF semi-axes: a = L/2 + mu1 sigma(|v_par| - v0) |v_par|, b = W/2 + mu2 sigma(|v_perp| - v0) |v_perp|,
with sigma(x) = 1 / (1 + exp(-k x)) and the major axis along the obstacle's velocity. The MPC keeps
each ego disc centre outside an ellipse (A, B) containing safety ellipse + disc(d); the decisive
property checked here is that every point the algebraic barrier accepts has exact signed distance
>= d from the true safety ellipse.
"""

import casadi as ca
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings, example
from hypothesis import strategies as st

from aac_sumo.barriers import (
    N_STAGE_FIELDS,
    STAGE_FIELDS,
    FcbfParams,
    ObstaclePrediction,
    barrier_value,
    cbf_axes,
    fcbf_axes,
    inactive_slot,
    inflate_for_disc,
    predict_constant_velocity,
    safety_ellipses,
    sigmoid,
    stack_predictions,
    stage_parameters,
)
from aac_sumo.geometry import ellipse_signed_distance

length_st = st.floats(0.2, 6.0)
width_st = st.floats(0.2, 3.0)
heading_st = st.floats(-np.pi, np.pi)
moving_st = st.just(0.0) | st.floats(2e-3, 30.0)  # at rest, or above fcbf_axes' v_eps = 1e-3
params_st = st.builds(FcbfParams, mu1=st.floats(0.0, 1.0), mu2=st.floats(0.0, 1.0), k=st.floats(0.1, 10.0), v0=st.floats(0.0, 5.0))


def expected_sigmoid(x, k):
    return 1.0 / (1.0 + np.exp(-k * x))


# --------------------------------------------------------------------------------------------
# sigmoid
# --------------------------------------------------------------------------------------------


@given(x=st.floats(-50.0, 50.0), k=st.floats(0.01, 10.0))
def test_sigmoid_is_logistic(x, k):
    assert float(sigmoid(x, k)) == pytest.approx(expected_sigmoid(x, k), rel=1e-12, abs=1e-15)


def test_sigmoid_limits_are_finite():
    with np.errstate(all="raise"):
        values = sigmoid(np.array([-1e6, -50.0, 0.0, 50.0, 1e6]), 10.0)
    np.testing.assert_allclose(values, [0.0, 0.0, 0.5, 1.0, 1.0], atol=1e-200)
    assert np.all(np.diff(values) >= 0.0)


# --------------------------------------------------------------------------------------------
# F-CBF and CBF axes
# --------------------------------------------------------------------------------------------


@given(length=length_st, width=width_st, heading=heading_st, params=params_st)
def test_fcbf_axes_at_rest_are_the_footprint(length, width, heading, params):
    """A standing obstacle's F-CBF ellipse is its footprint ellipse (L/2, W/2) along its heading."""
    a, b, phi = fcbf_axes(length, width, np.zeros(2), heading, params)
    assert a == 0.5 * length
    assert b == 0.5 * width
    assert phi == heading


def paper_axes(length, width, v_par, v_perp, p: FcbfParams):
    """Eqs. 6-7 written out with the textbook sigmoid."""
    a = length / 2 + p.mu1 * expected_sigmoid(abs(v_par) - p.v0, p.k) * abs(v_par)
    b = width / 2 + p.mu2 * expected_sigmoid(abs(v_perp) - p.v0, p.k) * abs(v_perp)
    return a, b


@given(length=length_st, width=width_st, heading=heading_st, speed=st.floats(0.01, 30.0), direction=heading_st, params=params_st)
def test_fcbf_axes_follow_eqs_6_7_and_velocity_direction(length, width, heading, speed, direction, params):
    """Moving obstacle: major axis along the velocity (phi = atan2(vy, vx)), so the whole speed is
    the parallel component, the perpendicular one is zero and b = W/2."""
    velocity = speed * np.array([np.cos(direction), np.sin(direction)])
    a, b, phi = fcbf_axes(length, width, velocity, heading, params)
    assert float(phi) == pytest.approx(np.arctan2(velocity[1], velocity[0]), abs=1e-12)
    exp_a, exp_b = paper_axes(length, width, speed, 0.0, params)
    assert float(a) == pytest.approx(exp_a, rel=1e-12)
    assert float(b) == pytest.approx(exp_b, rel=1e-12, abs=1e-12)


@given(
    length=length_st,
    width=width_st,
    heading=heading_st,
    speeds=st.tuples(moving_st, moving_st),
    direction=heading_st,
    params=params_st,
)
@settings(max_examples=150)
def test_fcbf_axes_grow_monotonically_with_speed(length, width, heading, speeds, direction, params):
    """For the same direction of motion, a faster obstacle never has a smaller ellipse; with
    mu1 > 0 its major axis is strictly longer. (Speeds in (0, v_eps] are excluded: there the
    ellipse keeps the obstacle's heading and the velocity may have a tiny perpendicular part.)"""
    slow, fast = sorted(speeds)
    unit = np.array([np.cos(direction), np.sin(direction)])
    a_slow, b_slow, _ = fcbf_axes(length, width, slow * unit, heading, params)
    a_fast, b_fast, _ = fcbf_axes(length, width, fast * unit, heading, params)
    assert a_fast >= a_slow - 1e-12
    assert b_fast >= b_slow - 1e-12
    assert a_slow >= 0.5 * length and b_slow >= 0.5 * width - 1e-12
    if params.mu1 > 0.01 and fast - slow > 0.1:
        assert a_fast > a_slow


def test_fcbf_axes_known_values():
    """Hand-computed: L=4, W=2, moving at 3 m/s along +y, mu=0.5, k=2, v0=1:
    a = 2 + 0.5 * 3 / (1 + e^-4), b = 1, phi = pi/2."""
    params = FcbfParams(mu1=0.5, mu2=0.5, k=2.0, v0=1.0)
    a, b, phi = fcbf_axes(4.0, 2.0, np.array([0.0, 3.0]), 0.0, params)
    assert float(a) == pytest.approx(2.0 + 1.5 / (1.0 + np.exp(-4.0)), rel=1e-12)
    assert float(b) == pytest.approx(1.0, abs=1e-12)
    assert float(phi) == pytest.approx(np.pi / 2, abs=1e-12)


@given(length=length_st, width=width_st, heading=heading_st, vx=st.floats(-30, 30), vy=st.floats(-30, 30))
def test_fcbf_with_zero_gains_is_the_footprint(length, width, heading, vx, vy):
    """mu1 = mu2 = 0: the F-CBF ellipse keeps the footprint semi-axes (L/2, W/2) at any speed."""
    a, b, _ = fcbf_axes(length, width, np.array([vx, vy]), heading, FcbfParams(mu1=0.0, mu2=0.0))
    assert a == 0.5 * length
    assert b == 0.5 * width


def test_fcbf_axes_vectorised():
    """Shapes (n,) lengths / widths / headings and (n, 2) velocities give (n,) axes matching the
    one-obstacle call."""
    rng = np.random.default_rng(0)
    n = 7
    length, width = rng.uniform(0.5, 5, n), rng.uniform(0.3, 2, n)
    heading, vel = rng.uniform(-3, 3, n), rng.uniform(-10, 10, (n, 2))
    vel[2] = 0.0
    params = FcbfParams()
    a, b, phi = fcbf_axes(length, width, vel, heading, params)
    assert a.shape == b.shape == phi.shape == (n,)
    for i in range(n):
        ai, bi, pi = fcbf_axes(length[i], width[i], vel[i], heading[i], params)
        assert (a[i], b[i], phi[i]) == pytest.approx((float(ai), float(bi), float(pi)), rel=1e-14, abs=1e-14)
    assert phi[2] == heading[2]


@given(
    length=length_st,
    width=width_st,
    heading=heading_st,
    v1=st.tuples(st.floats(-30, 30), st.floats(-30, 30)),
    v2=st.tuples(st.floats(-30, 30), st.floats(-30, 30)),
)
def test_cbf_ellipse_never_depends_on_velocity(length, width, heading, v1, v2):
    """Plain CBF: the footprint ellipse (L/2, W/2) along the heading, whatever the velocity."""
    a, b, phi = cbf_axes(length, width, heading)
    assert (a, b, phi) == (0.5 * length, 0.5 * width, heading)
    horizon, dt = 4, 0.1
    rows = []
    for v in (v1, v2):
        pred = predict_constant_velocity([1.0, 2.0], v, heading, length, width, horizon, dt)
        rows.append(safety_ellipses(pred, "cbf", FcbfParams())[:, 2:])
    np.testing.assert_array_equal(rows[0], rows[1])
    np.testing.assert_array_equal(rows[0], np.tile([0.5 * length, 0.5 * width, heading], (horizon + 1, 1)))


def test_safety_ellipses_fcbf_rows_use_stage_velocity():
    """Rows are [cx, cy, a, b, phi] per stage, with the F-CBF shape of that stage's velocity."""
    params = FcbfParams()
    velocities = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [-3.0, -3.0]])
    centres = np.array([[0.0, 0.0], [0.1, 0.0], [0.1, 0.2], [-0.2, -0.1]])
    pred = ObstaclePrediction(centres, velocities, np.full(4, 0.4), 2.0, 1.0)
    rows = safety_ellipses(pred, "fcbf", params)
    assert rows.shape == (4, 5)
    np.testing.assert_array_equal(rows[:, :2], centres)
    for k in range(4):
        a, b, phi = fcbf_axes(2.0, 1.0, velocities[k], 0.4, params)
        np.testing.assert_allclose(rows[k, 2:], [a, b, phi], rtol=1e-14, atol=1e-14)
    assert rows[0, 4] == 0.4  # standing still: its heading
    with pytest.raises(ValueError):
        safety_ellipses(pred, "hjb", params)


# --------------------------------------------------------------------------------------------
# Algebraic barrier and the disc inflation
# --------------------------------------------------------------------------------------------

semi_st = st.floats(0.05, 8.0)
# physical clearances (disc radius + d_safe): zero or at least a micrometre
clearance_st = st.just(0.0) | st.floats(1e-6, 4.0)
# optional point (ellipse-local frame) the inflation is tightened towards
toward_st = st.none() | st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0))


@given(
    a=semi_st,
    b=semi_st,
    theta=heading_st,
    cx=st.floats(-20, 20),
    cy=st.floats(-20, 20),
    px=st.floats(-30, 30),
    py=st.floats(-30, 30),
)
def test_barrier_sign_matches_exact_signed_distance(a, b, theta, cx, cy, px, py):
    """(x'/a)^2 + (y'/b)^2 - 1 is negative exactly inside the ellipse (away from the boundary)."""
    h = barrier_value(px, py, cx, cy, np.cos(theta), np.sin(theta), a**-2, b**-2)
    sd = float(ellipse_signed_distance(np.array([px, py]), cx, cy, a, b, theta))
    assume(abs(sd) > 1e-9 * max(1.0, a, b))
    assert (h < 0) == (sd < 0)


def test_barrier_value_numpy_and_casadi_agree():
    rng = np.random.default_rng(1)
    sym = ca.SX.sym("z", 8)
    fun = ca.Function("h", [sym], [barrier_value(*(sym[i] for i in range(8)))])
    for _ in range(20):
        z = rng.uniform(-5, 5, 8)
        z[6:] = np.abs(z[6:]) + 0.1
        assert float(fun(z)) == pytest.approx(barrier_value(*z), rel=1e-13, abs=1e-13)


@given(a=semi_st, d=clearance_st, toward=toward_st)
@example(a=1.0, d=1.0, toward=(5e-324, 5e-324))  # denormal components: their norm underflows
def test_inflation_of_circle_is_exact(a, d, toward):
    """For a circle the Minkowski sum is the circle of radius a + d, and the inflation returns it."""
    big_a, big_b = inflate_for_disc(a, a, d, None if toward is None else np.array(toward))
    assert float(big_a) == pytest.approx(a + d, rel=1e-14)
    assert float(big_b) == pytest.approx(a + d, rel=1e-14)


def test_inflation_is_finite_for_subnormal_clearance():
    big_a, big_b = inflate_for_disc(1.0, 2.0, 1e-310)
    assert np.isfinite(big_a) and np.isfinite(big_b)
    assert (float(big_a), float(big_b)) == pytest.approx((1.0, 2.0))


@given(a=semi_st, b=semi_st)
def test_inflation_by_zero_is_identity(a, b):
    big_a, big_b = inflate_for_disc(a, b, 0.0)
    assert (float(big_a), float(big_b)) == pytest.approx((a, b), rel=1e-15)


@given(a=semi_st, b=semi_st, d=clearance_st, direction=st.floats(0.0, 2 * np.pi), toward=toward_st)
@settings(max_examples=300)
def test_inflated_support_function_dominates_minkowski_sum(a, b, d, direction, toward):
    """Containment via support functions: for every unit direction u,
    sqrt(A^2 ux^2 + B^2 uy^2) >= sqrt(a^2 ux^2 + b^2 uy^2) + d."""
    big_a, big_b = inflate_for_disc(a, b, d, None if toward is None else np.array(toward))
    ux, uy = np.cos(direction), np.sin(direction)
    outer = np.sqrt(big_a**2 * ux**2 + big_b**2 * uy**2)
    inner = np.sqrt(a**2 * ux**2 + b**2 * uy**2) + d
    assert outer >= inner - 1e-12 * max(1.0, inner)


@given(
    a=semi_st,
    b=semi_st,
    d=clearance_st,
    theta=heading_st,
    cx=st.floats(-10, 10),
    cy=st.floats(-10, 10),
    angle=st.floats(0.0, 2 * np.pi),
    stretch=st.one_of(st.floats(1.0, 1.0 + 1e-6), st.floats(1.0, 1.05), st.floats(1.0, 4.0)),
    toward=toward_st,
)
@settings(max_examples=500)
def test_barrier_accepted_points_are_at_least_d_from_true_ellipse(a, b, d, theta, cx, cy, angle, stretch, toward):
    """Conservativeness the MPC relies on: no point the inflated barrier accepts (h >= 0) lies
    within exact distance d of the true safety ellipse, whichever side the inflation is tightened
    towards. Points are sampled on rays through the inflated boundary, from just outside it
    (stretch ~ 1) to well away."""
    big_a, big_b = inflate_for_disc(a, b, d, None if toward is None else np.array(toward))
    c, s = np.cos(theta), np.sin(theta)
    lx, ly = stretch * big_a * np.cos(angle), stretch * big_b * np.sin(angle)
    px, py = cx + c * lx - s * ly, cy + s * lx + c * ly
    h = barrier_value(px, py, cx, cy, c, s, big_a**-2, big_b**-2)
    assume(h >= 0.0)
    sd = float(ellipse_signed_distance(np.array([px, py]), cx, cy, a, b, theta))
    assert sd >= d - 1e-9


@given(a=semi_st, b=semi_st, d=st.floats(1e-3, 4.0), toward=st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0)))
@settings(max_examples=200)
def test_inflation_is_tight_towards_the_ego(a, b, d, toward):
    """With ``toward`` the inflated ellipse touches ellipse + disc(d) in the direction u of the
    ellipse normal where the ray to ``toward`` leaves the ellipse: its support there equals
    sqrt(a^2 ux^2 + b^2 uy^2) + d, so the zero level of the barrier is at exact distance d on
    the ego's side (no wasted clearance)."""
    tx, ty = toward
    scale = np.hypot(tx / a, ty / b)
    assume(scale > 1e-6)
    nx, ny = tx / scale / a**2, ty / scale / b**2
    ux, uy = nx / np.hypot(nx, ny), ny / np.hypot(nx, ny)
    big_a, big_b = inflate_for_disc(a, b, d, np.array(toward))
    outer = np.sqrt(big_a**2 * ux**2 + big_b**2 * uy**2)
    inner = np.sqrt(a**2 * ux**2 + b**2 * uy**2) + d
    assert float(outer) == pytest.approx(inner, rel=1e-9)
    # the touching point: ellipse point with normal u, pushed out by d along u
    px, py = tx / scale + d * ux, ty / scale + d * uy
    assert float(barrier_value(px, py, 0.0, 0.0, 1.0, 0.0, big_a**-2, big_b**-2)) == pytest.approx(0.0, abs=1e-8)
    assert float(ellipse_signed_distance(np.array([px, py]), 0.0, 0.0, a, b, 0.0)) == pytest.approx(d, rel=1e-9, abs=1e-12)


def test_barrier_accepted_points_dense_grid():
    """Same property on a dense grid around an elongated, rotated ellipse (an F-CBF shape of a fast
    obstacle): every grid point with h >= 0 is at least d away; and the inflation is not
    absurdly loose, i.e. some accepted points come within 0.1 d of the bound."""
    a, b, theta, d = 3.5, 0.4, 0.7, 0.9
    big_a, big_b = inflate_for_disc(a, b, d)
    xs, ys = np.meshgrid(np.linspace(-7, 7, 401), np.linspace(-7, 7, 401))
    pts = np.stack([xs.ravel(), ys.ravel()], axis=-1)
    h = barrier_value(pts[:, 0], pts[:, 1], 0.0, 0.0, np.cos(theta), np.sin(theta), big_a**-2, big_b**-2)
    sd = ellipse_signed_distance(pts[h >= 0], 0.0, 0.0, a, b, theta)
    assert sd.min() >= d - 1e-9
    assert sd.min() <= 1.1 * d


# --------------------------------------------------------------------------------------------
# MPC stage parameters
# --------------------------------------------------------------------------------------------


def constraint_value(p_now, p_next, row_now, row_next, gamma):
    """The MPC's per-stage barrier constraint written out: active * (h_next - (1 - gamma) h_now) + (1 - active)."""
    h_now = barrier_value(p_now[0], p_now[1], *row_now[:6])
    h_next = barrier_value(p_next[0], p_next[1], *row_next[:6])
    active = row_next[6]
    return active * (h_next - (1 - gamma) * h_now) + (1 - active)


@pytest.fixture(scope="module")
def one_stage_problem():
    """The compiled MPC problem of one stage, one obstacle slot and one ego disc (ipopt: built in
    well under a second)."""
    from aac_sumo.mpc.problem import MpcProblem, ProblemShape

    return MpcProblem(ProblemShape(horizon=1, slots=1, discs=1, solver="ipopt", dt=0.1))


def stage_zero_barrier(problem, state, rows, gamma, wheelbase=0.5, offset=0.3) -> float:
    """The problem's own stage-0 barrier row (after the NZ dynamics rows), evaluated by casadi
    with ``rows`` (2, N_STAGE_FIELDS) as the slot's parameters at stages 0 and 1, the ego at
    rear-axle ``state`` driving straight on (zero inputs)."""
    from aac_sumo.mpc.problem import NZ

    p = problem.parameters(wheelbase=wheelbase, gamma=gamma, disc_offsets=offset, weights=np.zeros(12), x_ref=np.zeros(8),
                           obstacles=rows, band=np.empty(0), limits=[3.0, 0.1], terminal=np.empty(0), stop_decel=np.empty(0))
    w = problem.pack(np.array([state, state]), np.zeros((1, 2)), np.zeros(2))
    return float(problem.solver.oracle()(w, p)[1][NZ])


def closed_form(px, py, cx, cy, phi, inv_a2, inv_b2):
    """``(x'/A)^2 + (y'/B)^2 - 1`` of a point in the frame of an ellipse centred at (cx, cy), turned by phi."""
    dx, dy = px - cx, py - cy
    along, across = np.cos(phi) * dx + np.sin(phi) * dy, -np.sin(phi) * dx + np.cos(phi) * dy
    return along**2 * inv_a2 + across**2 * inv_b2 - 1.0


field = st.floats(-5.0, 5.0)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(x=field, y=field, heading=st.floats(-np.pi, np.pi), v=st.floats(0.0, 5.0), gamma=st.floats(0.05, 1.0),
       now=st.tuples(field, field, st.floats(-np.pi, np.pi), st.floats(0.05, 4.0), st.floats(0.05, 4.0)),
       nxt=st.tuples(field, field, st.floats(-np.pi, np.pi), st.floats(0.05, 4.0), st.floats(0.05, 4.0)),
       active=st.sampled_from([0.0, 1.0]))
def test_the_mpc_problem_reads_each_stage_field_where_stage_fields_names_it(one_stage_problem, x, y, heading, v, gamma, now, nxt, active):
    """A slot's parameters laid out by name as ``STAGE_FIELDS`` says (centre, cos and sin of the
    ellipse's turn, inverse squared semi-axes, active flag) give the compiled problem's barrier
    row its written-out value: active * (h_1 - (1 - gamma) h_0) + 1 - active, with h_k the ellipse
    of stage k at the ego disc, one Euler step on at stage 1 (driving straight on)."""
    offset, dt = 0.3, 0.1

    def row(cx, cy, phi, a, b, on):
        named = {"cx": cx, "cy": cy, "cos": np.cos(phi), "sin": np.sin(phi), "inv_a2": a**-2, "inv_b2": b**-2, "active": on}
        assert len(STAGE_FIELDS) == N_STAGE_FIELDS == len(named)
        return [named[name] for name in STAGE_FIELDS]

    rows = np.array([row(*now, 1.0), row(*nxt, active)])
    got = stage_zero_barrier(one_stage_problem, np.array([x, y, heading, v]), rows, gamma, offset=offset)
    disc = np.array([x, y]) + offset * np.array([np.cos(heading), np.sin(heading)])
    h0 = closed_form(*disc, now[0], now[1], now[2], now[3] ** -2, now[4] ** -2)
    h1 = closed_form(*(disc + v * dt * np.array([np.cos(heading), np.sin(heading)])), nxt[0], nxt[1], nxt[2], nxt[3] ** -2, nxt[4] ** -2)
    expected = active * (h1 - (1 - gamma) * h0) + 1 - active
    assert got == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_stage_parameters_feed_the_problem_the_ellipse_they_were_made_from(one_stage_problem):
    """Rows from :func:`stage_parameters` (clearance 0: the ellipse itself) put the problem's
    barrier at zero on the ellipse's rim, negative inside and positive outside, whatever its turn."""
    phi = 0.7
    ell = np.array([[2.0, -1.0, 1.5, 0.5, phi], [2.0, -1.0, 1.5, 0.5, phi]])
    rows = stage_parameters(ell, 0.0)
    rim = np.array([2.0, -1.0]) + 1.5 * np.array([np.cos(phi), np.sin(phi)])  # the end of the major axis
    for scale, sign in ((1.0, 0.0), (0.5, -1.0), (1.5, 1.0)):
        disc = np.array([2.0, -1.0]) + scale * (rim - np.array([2.0, -1.0]))
        state = np.array([*(disc - 0.3 * np.array([1.0, 0.0])), 0.0, 0.0])  # heading 0, standing: the disc 0.3 m ahead
        h = stage_zero_barrier(one_stage_problem, state, rows, gamma=1.0)  # gamma 1: the row is h at stage 1
        assert h == pytest.approx(scale**2 - 1.0, abs=1e-12) and np.sign(round(h, 12)) == sign


@given(horizon=st.integers(1, 20), d=clearance_st)
def test_stage_parameters_layout(horizon, d):
    pred = predict_constant_velocity([3.0, -1.0], [1.0, 2.0], 0.2, 4.0, 1.8, horizon, 0.1)
    ell = safety_ellipses(pred, "fcbf", FcbfParams())
    params = stage_parameters(ell, d)
    assert params.shape == (horizon + 1, N_STAGE_FIELDS)
    big_a, big_b = inflate_for_disc(ell[:, 2], ell[:, 3], d)
    np.testing.assert_array_equal(params[:, 0:2], ell[:, 0:2])
    np.testing.assert_allclose(params[:, 2], np.cos(ell[:, 4]), rtol=1e-15)
    np.testing.assert_allclose(params[:, 3], np.sin(ell[:, 4]), rtol=1e-15)
    np.testing.assert_allclose(params[:, 4], big_a**-2, rtol=1e-14)
    np.testing.assert_allclose(params[:, 5], big_b**-2, rtol=1e-14)
    assert np.all(params[:, 6] == 1.0)


@pytest.mark.parametrize("barrier", ["fcbf", "cbf"])
def test_batched_ellipses_and_parameters_equal_one_at_a_time(barrier):
    """A batch of predictions and of clearances gives exactly the per-obstacle, per-clearance rows."""
    rng = np.random.default_rng(0)
    preds = [predict_constant_velocity(rng.normal(0, 9, 2), rng.normal(0, 4, 2), rng.uniform(-3, 3), rng.uniform(1, 5), rng.uniform(0.5, 2), 6, 0.1)
             for _ in range(5)]
    ells = safety_ellipses(stack_predictions(preds), barrier, FcbfParams())
    assert ells.shape == (5, 7, 5)
    ds, ego = np.array([1.1, 0.8]), np.array([2.0, -1.0])
    params = stage_parameters(ells, ds[:, None, None], ego)
    assert params.shape == (2, 5, 7, N_STAGE_FIELDS)
    for m, pred in enumerate(preds):
        one = safety_ellipses(pred, barrier, FcbfParams())
        np.testing.assert_array_equal(ells[m], one)
        for j, d in enumerate(ds):
            np.testing.assert_array_equal(params[j, m], stage_parameters(one, d, ego))


def test_stage_parameters_with_ego_are_tight_on_the_ego_side():
    """Tightening towards the ego keeps the layout; for an elongated F-CBF ellipse seen from
    ahead the zero level of the barrier is exactly d in front of it, and never closer anywhere."""
    horizon, d = 3, 0.8
    pred = predict_constant_velocity([0.0, 0.0], [6.0, 0.0], 0.0, 4.0, 1.8, horizon, 0.1)
    ell = safety_ellipses(pred, "fcbf", FcbfParams())
    ego = np.array([30.0, 0.0])
    params = stage_parameters(ell, d, ego)
    assert params.shape == (horizon + 1, N_STAGE_FIELDS)
    assert np.all(params[:, 6] == 1.0)
    plain = stage_parameters(ell, d)
    np.testing.assert_array_equal(params[:, :4], plain[:, :4])
    for k in range(horizon + 1):
        big_a = params[k, 4] ** -0.5
        front = ell[k, 0] + big_a
        assert front == pytest.approx(ell[k, 0] + ell[k, 2] + d, rel=1e-12)  # tight straight ahead
        angles = np.linspace(0, 2 * np.pi, 721)
        pts = ell[k, :2] + np.column_stack([big_a * np.cos(angles), params[k, 5] ** -0.5 * np.sin(angles)])
        sd = ellipse_signed_distance(pts, *ell[k])
        assert sd.min() >= d - 1e-9


@given(horizon=st.integers(1, 20))
def test_inactive_slot_layout(horizon):
    slot = inactive_slot(horizon)
    assert slot.shape == (horizon + 1, N_STAGE_FIELDS)
    assert np.all(slot[:, 6] == 0.0)
    assert np.all(np.isfinite(slot))


@given(
    p_now=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    p_next=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    gamma=st.floats(0.0, 1.0),
)
def test_inactive_slot_constraint_reads_one_everywhere(p_now, p_next, gamma):
    """An unused slot can never bind: its constraint value is exactly 1 wherever the ego is."""
    slot = inactive_slot(3)
    for k in range(3):
        assert constraint_value(p_now, p_next, slot[k], slot[k + 1], gamma) == 1.0


def test_barrier_value_known_values():
    """(x'/A)^2 + (y'/B)^2 - 1 in the ellipse's frame: centre (1, 2), A = 2 along 90 deg, B = 1."""
    args = (1.0, 2.0, 0.0, 1.0, 0.25, 1.0)
    assert barrier_value(1.0, 4.0, *args) == pytest.approx(0.0, abs=1e-15)  # major vertex
    assert barrier_value(2.0, 2.0, *args) == pytest.approx(0.0, abs=1e-15)  # minor vertex
    assert barrier_value(1.0, 2.0, *args) == -1.0  # centre
    assert barrier_value(4.0, 2.0, *args) == pytest.approx(8.0)  # 3 B across the major axis


def test_active_slot_constraint_is_the_discrete_cbf_condition():
    """For an active slot the value is h(k+1) - (1 - gamma) h(k): negative when the ego closes in
    faster than the decay rate allows, positive for a slow approach."""
    pred = predict_constant_velocity([5.0, 0.0], [0.0, 0.0], 0.0, 1.0, 1.0, 2, 0.1)
    row = stage_parameters(safety_ellipses(pred, "cbf", FcbfParams()), 0.5)  # circle of radius 1
    np.testing.assert_allclose(row[:, 4:6], 1.0, rtol=1e-14)
    gamma = 0.5

    def h(x):
        return barrier_value(x, 0.0, *row[0, :6])

    fast = constraint_value((2.0, 0.0), (3.5, 0.0), row[0], row[1], gamma)
    slow = constraint_value((2.0, 0.0), (2.1, 0.0), row[0], row[1], gamma)
    assert fast == pytest.approx(h(3.5) - 0.5 * h(2.0))
    assert slow == pytest.approx(h(2.1) - 0.5 * h(2.0))
    assert fast < 0.0 < slow


# --------------------------------------------------------------------------------------------
# Prediction
# --------------------------------------------------------------------------------------------


@given(
    centre=st.tuples(st.floats(-100, 100), st.floats(-100, 100)),
    velocity=st.tuples(st.floats(-20, 20), st.floats(-20, 20)),
    heading=heading_st,
    horizon=st.integers(0, 25),
    dt=st.sampled_from([0.05, 0.1, 0.2]),
)
def test_predict_constant_velocity(centre, velocity, heading, horizon, dt):
    """Centres advance by v dt per stage; velocity, heading and footprint stay constant."""
    pred = predict_constant_velocity(centre, velocity, heading, 4.0, 2.0, horizon, dt)
    assert pred.centres.shape == (horizon + 1, 2)
    assert pred.velocities.shape == (horizon + 1, 2)
    assert pred.headings.shape == (horizon + 1,)
    np.testing.assert_array_equal(pred.centres[0], centre)
    k = np.arange(horizon + 1)[:, None]
    np.testing.assert_allclose(pred.centres, np.asarray(centre) + k * dt * np.asarray(velocity), rtol=1e-13, atol=1e-11)
    if horizon:
        np.testing.assert_allclose(np.diff(pred.centres, axis=0), np.tile(np.asarray(velocity) * dt, (horizon, 1)), rtol=1e-9, atol=1e-11)
    assert np.all(pred.velocities == np.asarray(velocity))
    assert np.all(pred.headings == heading)
    assert (pred.length, pred.width) == (4.0, 2.0)
