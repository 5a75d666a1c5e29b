"""Obstacle prediction: the constant-acceleration predictor in closed form, the speed history it
is fed from, and the same prediction for both barriers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.barriers import predict_constant_velocity
from aac_sumo.cli.app import main
from aac_sumo.experiments import build
from aac_sumo.prediction import PREDICTIONS, SpeedHistory, predict_constant_acceleration, predict_obstacle, speed_slope
from aac_sumo.sim.internal import ScriptedAgent
from aac_sumo.world import Obstacle, WorldState


@settings(max_examples=200, deadline=None)
@given(speed=st.floats(0.0, 30.0), decel=st.floats(0.5, 10.0), heading=st.floats(-np.pi, np.pi),
       horizon=st.integers(1, 40), dt=st.sampled_from([0.05, 0.1, 0.2]))
def test_constant_deceleration_is_predicted_exactly(speed, decel, heading, horizon, dt):
    """A lead braking at a constant rate (the braking scenario's script) is predicted stage by
    stage where it will be, and it stops and stands: no stage speed below zero, no step back."""
    lead = ScriptedAgent("lead", np.array([3.0, -2.0]), heading, speed, 1.0, 0.6, schedule=((0.0, -decel),))
    now = lead.as_obstacle()
    pred = predict_constant_acceleration(now.centre, now.velocity, -decel, heading, 1.0, 0.6, horizon, dt)
    truth = [lead.centre.copy()]
    for k in range(horizon):
        lead.advance(k * dt, dt)
        truth.append(lead.centre.copy())
    np.testing.assert_allclose(pred.centres, truth, atol=1e-9)
    speeds = np.hypot(pred.velocities[:, 0], pred.velocities[:, 1])
    np.testing.assert_allclose(speeds, np.maximum(speed - decel * dt * np.arange(horizon + 1), 0.0), atol=1e-9)
    direction = np.array([np.cos(heading), np.sin(heading)])
    assert np.all(np.diff(pred.centres @ direction) >= -1e-12)
    assert np.all(pred.velocities @ direction >= -1e-12)
    if speed / decel <= horizon * dt:  # stopped within the horizon: at the stopping distance
        assert pred.centres[-1] @ direction - now.centre @ direction == pytest.approx(speed**2 / (2 * decel), abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(vx=st.floats(-20, 20), vy=st.floats(-20, 20), accel=st.floats(0.0, 5.0), horizon=st.integers(1, 20))
def test_constant_acceleration_in_closed_form(vx, vy, accel, horizon):
    """Speeding up along the direction of motion: s(t) = s0 + a t, travelled s0 t + a t^2 / 2;
    with a = 0 it is the constant-velocity prediction."""
    v = np.array([vx, vy])
    pred = predict_constant_acceleration([1.0, 2.0], v, accel, 0.3, 4.0, 1.8, horizon, 0.1)
    t = np.arange(horizon + 1) * 0.1
    speed = np.hypot(vx, vy)
    direction = v / speed if speed > 0.0 else np.array([np.cos(0.3), np.sin(0.3)])
    np.testing.assert_allclose(pred.centres, [1.0, 2.0] + (speed * t + 0.5 * accel * t**2)[:, None] * direction, atol=1e-9)
    np.testing.assert_allclose(pred.velocities, (speed + accel * t)[:, None] * direction, atol=1e-9)
    cv = predict_constant_velocity([1.0, 2.0], v, 0.3, 4.0, 1.8, horizon, 0.1)
    zero = predict_constant_acceleration([1.0, 2.0], v, 0.0, 0.3, 4.0, 1.8, horizon, 0.1)
    np.testing.assert_allclose(zero.centres, cv.centres, atol=1e-9)
    np.testing.assert_allclose(zero.velocities, cv.velocities, atol=1e-9)


def test_standing_obstacle_does_not_move_backwards():
    pred = predict_constant_acceleration([5.0, 0.0], [0.0, 0.0], -6.0, 0.0, 1.0, 0.6, 10, 0.1)
    np.testing.assert_array_equal(pred.centres, np.tile([5.0, 0.0], (11, 1)))
    np.testing.assert_array_equal(pred.velocities, np.zeros((11, 2)))


@settings(max_examples=100, deadline=None)
@given(s0=st.floats(-30, 30), slope=st.floats(-10, 10), n=st.integers(2, 10))
def test_speed_slope_of_a_line_is_exact(s0, slope, n):
    t = 3.0 + 0.1 * np.arange(n)
    assert speed_slope(t, s0 + slope * t) == pytest.approx(slope, abs=1e-6)
    assert speed_slope(t[:1], [s0]) == 0.0


def _lead_world(t: float, agent: ScriptedAgent) -> WorldState:
    return WorldState(t, np.zeros((0, 4)), [], [agent.as_obstacle(), Obstacle("cone", "cone", np.zeros(2), np.zeros(2), 0.0, 0.3, 0.3)])


@pytest.mark.parametrize("window", [2, 3, 5])
def test_speed_history_estimates_the_observed_deceleration(window):
    """Fed the lead's observed speeds, the estimate is 0 before braking, the lead's deceleration
    once the window lies within braking, 0 again when it stands; a cone gets none; a gap in the
    observations restarts the history."""
    dt = 0.1
    lead = ScriptedAgent("lead", np.zeros(2), 0.0, 10.0, 1.0, 0.6, schedule=((0.5, -4.0),))
    history = SpeedHistory(window, dt)
    estimates = {}
    for k in range(60):
        world = history.annotate(_lead_world(k * dt, lead))
        assert world.obstacles[1].accel == 0.0
        estimates[k] = world.obstacles[0].accel
        lead.advance(k * dt, dt)
    assert estimates[0] == 0.0 and estimates[5] == 0.0  # the first braking period shows at k = 6
    assert estimates[5 + window - 1] == pytest.approx(-4.0)
    assert estimates[20] == pytest.approx(-4.0)  # still braking (stops at t = 3.0 s)
    assert estimates[59] == pytest.approx(0.0)
    later = history.annotate(_lead_world(9.0, ScriptedAgent("lead", np.zeros(2), 0.0, 3.0, 1.0, 0.6)))
    assert later.obstacles[0].accel == 0.0  # last seen at t = 5.9 s: a new history


def test_speed_history_copies_the_world():
    lead = ScriptedAgent("lead", np.zeros(2), 0.0, 10.0, 1.0, 0.6)
    world = _lead_world(0.0, lead)
    assert SpeedHistory(2, 0.1).annotate(world) is not world and world.obstacles[0].accel == 0.0
    with pytest.raises(ValueError):
        SpeedHistory(1, 0.1)


def test_predict_obstacle_models():
    ob = Obstacle("lead", "scripted", np.array([7.0, 0.0]), np.array([10.0, 0.0]), 0.0, 1.0, 0.6, accel=-6.0)
    cv = predict_obstacle(ob, 10, 0.1)
    ca = predict_obstacle(ob, 10, 0.1, "constant_acceleration")
    assert cv.centres[-1, 0] == pytest.approx(17.0) and ca.centres[-1, 0] == pytest.approx(14.0)
    assert set(PREDICTIONS) == set(config.common()["controller"]["prediction"].type)
    with pytest.raises(ValueError, match="prediction"):
        predict_obstacle(ob, 10, 0.1, "constant_jerk")


def test_given_predicted_centres_win_over_the_model():
    centres = np.column_stack([np.arange(12.0), np.zeros(12)])
    ob = Obstacle("r", "robot", centres[0], np.array([10.0, 0.0]), 0.0, 1.0, 0.6, predicted=centres, accel=-6.0)
    np.testing.assert_array_equal(predict_obstacle(ob, 10, 0.1, "constant_acceleration").centres, centres[:11])


def _worlds_seen(setup, periods: int) -> list[WorldState]:
    """The worlds the coordinator's own decision step was handed over ``periods`` closed-loop periods."""
    coord, sim, seen = setup.coordinator, setup.sim, []
    decide = coord._decide
    coord._decide = lambda world: (seen.append(world), decide(world))[1]
    for _ in range(periods):
        sim.step(coord.decide(sim.observe()).inputs)
    return seen


@pytest.mark.parametrize("prediction", PREDICTIONS)
def test_cbf_and_fcbf_get_the_same_predicted_centres(prediction):
    """In closed loop, both barriers' coordinators estimate the same lead acceleration from what
    they observe (never from the script), and their planners put its regions at the same centres
    at every stage; only the shapes differ."""
    regions, accels = {}, {}
    for barrier in ("cbf", "fcbf"):
        setup = build(config.load("braking", [f"controller.barrier={barrier}", f"controller.prediction={prediction}"]))
        worlds = _worlds_seen(setup, 16)  # the lead brakes from about t = 1 s
        accels[barrier] = [w.obstacles[0].accel for w in worlds]
        regions[barrier], _, _ = setup.coordinator.planner.nearest_regions(worlds[-1].states[0], worlds[-1].obstacles)
    assert accels["cbf"] == accels["fcbf"]
    assert accels["fcbf"][0] == 0.0
    assert accels["fcbf"][-1] == pytest.approx(-6.0 if prediction == "constant_acceleration" else 0.0)
    np.testing.assert_array_equal(regions["cbf"][..., :2], regions["fcbf"][..., :2])
    assert np.any(regions["cbf"][..., 2] != regions["fcbf"][..., 2])


@pytest.mark.parametrize("value, expected", [("constant_jerk", "one of constant_velocity, constant_acceleration"),
                                              ("1", "in 2..50")])
def test_bad_prediction_settings_exit_2_on_one_line(capsys, value, expected):
    key = "controller.prediction" if value == "constant_jerk" else "controller.prediction_window"
    assert main(["run", "braking", "--set", f"{key}={value}"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "braking.toml" in err and key in err and expected in err
