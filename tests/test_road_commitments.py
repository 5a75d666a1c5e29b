"""Committed plans on a road (``aac.cruise``): a commitment goes on along the car's lane at the
speeds its anticipated reference has before its stopping tail, where the exact check passes."""

from __future__ import annotations

import numpy as np
import pytest

from aac_sumo import config
from aac_sumo.runs import runner
from aac_sumo.coordination.aac import AacCoordinator, AacParams
from aac_sumo.coordination.anticipation import Anticipation
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.kernels.motion import footprint_rows
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import PathReference
from aac_sumo.world import Obstacle, RobotSpec, WorldState

DT = 0.1
LIMITS = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_min=0.0, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
CARS = [RobotSpec(f"car{i}", 4.0, 1.8, BicycleModel(2.6, LIMITS)) for i in range(2)]
COMMITTED = ["aac.commit=true", "aac.safety_stop=false", "aac.fallback=brake", "aac.ignore_followers=false", "aac.make_room=false"]


def two_cars(cruise: float, obstacles=(), reach: float = 0.0):
    """Two cars in one lane along y = 0 at 10 m/s, 30 m apart, their first decision under
    committed AAC with anticipation, ``cruise`` [s] and walkers' ``reach`` [m/s]."""
    tasks = [PathReference([[-50.0, 0.0], [800.0, 0.0]], 10.0, stop_at_end=False) for _ in CARS]
    config_ = MpcConfig(dt=DT, horizon=10, comfort_accel=2.0, comfort_lat=2.0, pedestrian_margin=1.0, pedestrian_reach=reach)
    aac = AacCoordinator(MpcPlanner(config_), tasks, params=AacParams(commit=True, safety_stop=False, make_room=False, cruise=cruise,
                                                                      lookahead=10.0))
    aac.anticipation = Anticipation(pedestrian_margin=1.0)
    world = WorldState(0.0, np.array([[0.0, 0.0, 0.0, 10.0], [30.0, 0.0, 0.0, 10.0]]), CARS, list(obstacles))
    aac.decide(world)
    return aac


def test_without_cruise_a_car_without_authority_brakes_from_the_start_and_with_it_drives_on():
    """The first period: without ``cruise`` both commitments are stopping tails (one of them is
    the authority's plan, then its tail); with 4 s each car drives on at 10 m/s for 4 s before
    any tail, and the two commitments keep the margin (the exact check)."""
    plain = two_cars(0.0)
    assert min(c.planned for c in plain.book.items) <= 10
    assert all(c.inputs[-1, 0] < 0.0 for c in plain.book.items)
    cruising = two_cars(4.0)
    for c in cruising.book.items:
        assert c.planned >= 40 and np.all(c.states[: c.planned + 1, 3] > 9.0)  # 4 s on at its speed
        assert np.all(np.abs(c.states[: c.planned + 1, 1]) < 0.05)  # in its lane
    rear, front = cruising.book.items
    assert np.all(front.states[: rear.planned + 1, 0] - rear.states[: rear.planned + 1, 0] > 4.0 + 0.05)


def test_a_continuation_yields_to_a_walker_on_the_lane_as_the_anticipation_does():
    """A walker standing on the lane 60 m ahead of the front car: its continuation slows to stand
    before her with the margin, at no more than the comfort envelope (2 m/s^2), rather than
    drive through her at 10 m/s."""
    walker = Obstacle("p", "pedestrian", np.array([90.0, 0.0]), np.zeros(2), np.pi / 2, 0.3, 0.5)
    aac = two_cars(8.0, [walker])
    front = aac.book.items[1]
    course = front.states[: front.planned + 1]
    nose = course[:, 0] + 1.3 + 2.0
    assert np.all(nose < 90.0 - 0.25 - 1.0)
    assert np.all(np.diff(course[:, 3]) >= -2.0 * DT - 1e-9)


def test_every_commitment_keeps_clear_of_where_a_walker_beside_the_lane_may_walk_meanwhile():
    """A walker stands on a crossing 3.2 m beside the lane, 40 m ahead of the front car: she may
    set off at any moment at the reach speed (1.5 m/s). Every commitment keeps its footprint,
    period after period, outside the disc she may reach by then (her half diagonal, the 1 m
    margin and 1.5 m/s x the time); without her the front car commits to drive past her spot."""
    centre = np.array([70.0, -3.2])
    walker = Obstacle("p", "pedestrian", centre, np.zeros(2), np.pi / 2, 0.3, 0.5)
    aac = two_cars(4.0, [walker], reach=1.5)
    radius = 0.5 * np.hypot(0.3, 0.5) + 1.0
    for c in aac.book.items:
        rows = footprint_rows(c.states[None], np.array([1.3]), np.array([4.0]), np.array([1.8]))[0]
        for k, row in enumerate(rows):
            co, si = np.cos(row[4]), np.sin(row[4])
            d = centre - row[:2]
            x, y = abs(d[0] * co + d[1] * si) - 2.0, abs(-d[0] * si + d[1] * co) - 0.9
            assert np.hypot(max(x, 0.0), max(y, 0.0)) >= radius + 1.5 * k * DT - 1e-9, f"period {k}"
    front = aac.book.items[1]
    assert front.states[-1, 0] + 3.3 < centre[0]  # it stands before her spot
    assert two_cars(4.0, reach=1.5).book.items[1].states[-1, 0] > centre[0] + 10.0


@pytest.mark.slow
def test_the_bundled_lane_change_completes_with_committed_plans_and_no_emergency_layer():
    """S2, seed 0, committed plans with one authority per cluster and a 4 s continuation, no
    safety stop: every car finishes, 0 collisions by our check and by SUMO's, no car within
    pedestrian_margin of a walker."""
    scenario = config.load("lane_change", COMMITTED + ["aac.cruise=4", 'aac.authorities="clusters"'])
    m = runner.run(scenario).metrics
    assert "error" not in m
    assert m["completed"] is True and m["collisions"] == 0 and m["sim_collisions"] == 0
    assert m["safety_stops"] == 0 and m["min_pedestrian_clearance_m"] >= 1.0


@pytest.mark.parametrize("reaction_brake", [0.0, 1.0])
def test_a_car_held_reactively_brakes_for_a_vehicle_ahead_though_the_car_behind_committed_against_its_gentler_course(reaction_brake):
    """Held reactively (``aac.traffic_reaction``), a car's commitment may run into a vehicle's
    braking course as long as its reaction (one period, then 3 m/s^2) stops short of it. Here a
    car at 10 m/s has a SUMO car standing 20 m ahead (its 2 m/s^2 tail needs 25 m, its reaction
    18 m) and a car 18 m behind it at 12.4 m/s, committed against its gentler course. When its
    reaction comes within the 1 m margin it must take it up, although that stop meets the
    follower's commitment; the follower then takes up its own reaction in the same period. Before
    that (seed 12 of ``highway_work_zone``, aac.50 into bg.17 at t = 216.6 s) the firmer stop was
    refused for the follower's commitment and the car drove its gentle tail into the vehicle.
    Every commitment keeps the margin from the others, the car stops at least the margin short
    of the vehicle, and nothing touches; so too when the reaction is the strongest braking
    (``aac.reaction_brake`` = 1), where the cars brake later and the follower may stop on a
    gentler course than its reaction."""
    cars = [RobotSpec(f"car{i}", 4.0, 1.8, BicycleModel(2.6, LIMITS)) for i in range(2)]
    tasks = [PathReference([[-50.0, 0.0], [800.0, 0.0]], 16.0, stop_at_end=False) for _ in cars]
    config_ = MpcConfig(dt=DT, horizon=10, comfort_accel=2.0, comfort_lat=2.0, pedestrian_margin=1.0)
    params = AacParams(commit=True, safety_stop=False, make_room=False, cruise=4.0, lookahead=10.0, tail_brake=0.3333, firm_tail=0.5,
                       traffic_reaction=True, commit_margin=1.0, fallback="brake", ignore_followers=False, reaction_brake=reaction_brake)
    aac = AacCoordinator(MpcPlanner(config_), tasks, params=params)
    aac.anticipation = Anticipation(pedestrian_margin=1.0)
    states = np.array([[8.0, 0.0, 0.0, 12.4], [30.0, 0.0, 0.0, 10.0]])  # the follower, the car
    lead = Obstacle("bg.0", "scripted", np.array([30.0 + 3.3 + 20.0 + 2.25, 0.0]), np.zeros(2), 0.0, 4.5, 1.8)
    braked = 0
    for k in range(70):
        world = WorldState(k * DT, states, cars, [lead])
        decision = aac.decide(world)
        book, period = aac.book, aac.period - 1
        braked += decision.notes["traffic_brakes"]
        gaps = book.pairwise_clearance(period)
        assert gaps.min() >= book.margin - 1e-9, f"period {period}: commitments {gaps.min():.3f} m apart"
        centres = world.robot_centres()[:, 0]
        assert lead.centre[0] - 2.25 - (centres[1] + 2.0) >= book.margin - 1e-6, f"period {period}: the car within the margin of the vehicle"
        assert centres[1] - centres[0] - 4.0 > 0.0
        states = aac.fleet.rollout(np.arange(2), states, decision.inputs[:, None, :], DT)[:, -1]
    assert braked > 0 and states[1, 3] < 0.05


def test_a_car_behind_a_queue_setting_off_plans_at_the_speeds_the_queue_has_committed_to():
    """Two cars at 2 m/s, 8 m apart (4 m between bumpers, inside the 1 s time gap): the front
    car's commitment speeds up along the free lane. The rear car's reference, seeing the front
    car at the speed its commitment has 1 s on, speeds up where the same reference with the
    speeds of now slows down to open the gap first, as the paper's LFC reference does."""
    tasks = [PathReference([[-50.0, 0.0], [800.0, 0.0]], 10.0, stop_at_end=False) for _ in CARS]
    config_ = MpcConfig(dt=DT, horizon=10, comfort_accel=2.0, comfort_lat=2.0, pedestrian_margin=1.0)
    aac = AacCoordinator(MpcPlanner(config_), tasks, params=AacParams(commit=True, safety_stop=False, make_room=False, cruise=4.0,
                                                                      lookahead=10.0))
    aac.anticipation = Anticipation(pedestrian_margin=1.0)
    world = WorldState(0.0, np.array([[0.0, 0.0, 0.0, 2.0], [8.0, 0.0, 0.0, 2.0]]), CARS, [])
    aac.decide(world)
    period = aac.period
    front = aac.book.items[1].course(period, 10)
    assert front[-1, 3] > 2.5  # the front car has committed to set off
    seen = aac.lead_speeds(world, 0, period)
    assert seen[0] == 2.0 and seen[1] == pytest.approx(front[-1, 3])
    now = aac.reference(world, 0)[:, 3]
    committed = aac.reference(world, 0, seen)[:, 3]
    assert now[-1] < 2.0 < committed[-1]
    assert np.all(committed >= now - 1e-9)


def cut_in(gap: float, lead_speed: float, **params) -> tuple[list[float], list[float]]:
    """A car held reactively (``params`` on top) cruises at 16 m/s on a free lane; then a SUMO
    car cuts in ``gap`` [m] ahead (between bumpers) at ``lead_speed`` [m/s] and drives on. The
    car's accelerations [m/s^2] and its bumper gaps [m] to that car, period by period."""
    car = [CARS[0]]
    tasks = [PathReference([[-50.0, 0.0], [2000.0, 0.0]], 16.0, stop_at_end=False)]
    config_ = MpcConfig(dt=DT, horizon=10, comfort_accel=2.0, comfort_lat=2.0, pedestrian_margin=1.0)
    params = AacParams(**{**dict(commit=True, safety_stop=False, make_room=False, cruise=4.0, lookahead=10.0, tail_brake=0.3333,
                                 firm_tail=0.3333, traffic_reaction=True, commit_margin=1.0, fallback="brake", ignore_followers=False), **params})
    aac = AacCoordinator(MpcPlanner(config_), tasks, params=params)
    aac.anticipation = Anticipation(pedestrian_margin=1.0)
    states = np.array([[0.0, 0.0, 0.0, 16.0]])
    accels, gaps = [], []
    for k in range(40):
        lead_x = states[0, 0] + 1.3 + 2.0 + gap + 2.25 if k == 5 else lead_x + lead_speed * DT if k > 5 else None
        obstacles = [Obstacle("bg.0", "scripted", np.array([lead_x, 0.0]), np.array([lead_speed, 0.0]), 0.0, 4.5, 1.8)] if k >= 5 else []
        decision = aac.decide(WorldState(k * DT, states, car, obstacles))
        accels.append(float(decision.inputs[0, 0]))
        if k >= 5:
            gaps.append(lead_x - 2.25 - (states[0, 0] + 1.3 + 2.0))
        states = aac.fleet.rollout(np.arange(1), states, decision.inputs[:, None, :], DT)[:, -1]
    return accels, gaps


@pytest.mark.parametrize("gap", [18.0, 10.0])
def test_a_car_held_reactively_answers_a_cut_in_with_the_gentlest_stop_that_leaves_the_margin(gap):
    """Held reactively with a 2 m/s^2 reaction, a car at 16 m/s meets a SUMO car cutting in
    ``gap`` [m] ahead at its own speed. Its reaction no longer stops it short of where that car
    could stop braking at 4.5 m/s^2, so it must brake harder, but only as hard as leaves the
    margin: 3 m/s^2 for 18 m, 4 m/s^2 for 10 m (it braked at its strongest, 6 m/s^2, before). The
    car keeps the margin from the vehicle."""
    accels, gaps = cut_in(gap, 16.0)
    assert min(gaps) >= 1.0 - 1e-6
    assert -min(accels) == pytest.approx(3.0 if gap == 18.0 else 4.0, abs=0.05)


def test_a_strong_reaction_lets_a_faster_car_cut_in_without_braking_beyond_comfort():
    """A SUMO car at 20 m/s cuts in 8 m ahead of a car at 16 m/s. Held to a 2 m/s^2 reaction,
    the car cannot stop behind where that car could stop at 4.5 m/s^2 and brakes beyond the
    comfort bound; held to its strongest braking (``aac.reaction_brake`` = 1: it could still stop
    at 6 m/s^2), it rides the cut-in out within comfort while the faster car pulls away, and both
    keep the margin."""
    gentle, gentle_gaps = cut_in(8.0, 20.0)
    strong, strong_gaps = cut_in(8.0, 20.0, reaction_brake=1.0)
    assert -min(gentle) > 2.0 + 1e-6
    assert -min(strong) <= 2.0 + 1e-6
    assert min(strong_gaps) >= 1.0 - 1e-6 and min(gentle_gaps) >= 1.0 - 1e-6


@pytest.mark.parametrize("gap", [15.0, 20.0])
def test_a_slow_car_cutting_in_where_no_stop_keeps_the_margin_is_met_with_the_strongest_braking(gap):
    """A SUMO car at 3.5 m/s cuts in ``gap`` [m] ahead of a car at 16 m/s (12.5 m/s slower:
    SUMO's driver forcing its way out of a queue). No stop keeps the margin from where the check
    has that car stand, so the car takes the stop that would meet it slowest: its strongest,
    6 m/s^2, from the first period (it took its gentle 2 m/s^2 before, as every stop left the
    same room beside it, and ran into the car at 9 m/s). It stops short of the car: 12.5 m/s
    closing at 6 m/s^2 takes 13 m."""
    accels, gaps = cut_in(gap, 3.5, reaction_brake=1.0)
    assert accels[5] == pytest.approx(-6.0)
    assert min(gaps) > 0.0



def test_a_nudge_away_from_a_car_standing_beside_sets_off_within_the_comfort_envelope():
    """Two cars stand side by side 0.2 m apart (the highway's and the city's lock): the nudge
    that moves the right one away from the left one sets off and steers within the planner's
    comfort envelope (2 m/s^2, as every course a car drives when not braking for its life; it set
    off at the car's 3 m/s^2 in the city), and it moves the car away from its neighbour."""
    tasks = [PathReference([[-50.0, y], [800.0, y]], 10.0, stop_at_end=False) for y in (0.0, 2.0)]
    config_ = MpcConfig(dt=DT, horizon=10, comfort_accel=2.0, comfort_lat=2.0)
    aac = AacCoordinator(MpcPlanner(config_), tasks, params=AacParams(commit=True, safety_stop=False, make_room=False, cruise=4.0,
                                                                      lookahead=10.0, tail_brake=1 / 3))  # tails at 2 m/s^2
    world = WorldState(0.0, np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0]]), CARS, [])
    aac.decide(world)
    aac.nearest = (0.2, 1)
    nudge = aac.nudged(world, 0, 1, np.zeros((0, 5)), None)
    assert nudge is not None
    assert np.all(np.abs(nudge.inputs[:, 0]) <= 2.0 + 1e-9)
    lat = nudge.states[:-1, 3] ** 2 * np.abs(np.tan(nudge.inputs[:, 1])) / 2.6
    assert np.all(lat <= 2.0 + 1e-9)
    assert nudge.states[-1, 1] < 0.0 and nudge.states[-1, 0] > 0.0
