"""Section ``[lane_change]``, the lane-change kind's parameters (:mod:`aac_sumo.experiments.lane_change`
for the cars it places, :mod:`aac_sumo.experiments.routed_cars` for the cars of SUMO's routes).

Distances are arc lengths along the road's lanes [m], speeds [m/s]; lane indices count the
road's car lanes from the rightmost (0)."""

from __future__ import annotations

from dataclasses import dataclass

from aac_sumo.config import Scenario
from aac_sumo.config.keys import MAX_ROBOTS, NN, P
from aac_sumo.config.schema import from_section, param

SECTION = "lane_change"


def _lane_indices(v) -> bool:
    return all(isinstance(x, int) and not isinstance(x, bool) and 0 <= x < 16 for x in v)


@dataclass(frozen=True)
class LaneChangeParams:
    """The lane change's cars, references, finish rule, and the lane plans and gap acceptance of
    the cars from SUMO's routes (each field's doc gives its meaning and unit)."""

    vehicles: int = param(15, "controlled vehicles, dealt to the lanes in turn (vehicle k starts in lane k mod lanes)",
                          check=lambda n: 1 <= n <= MAX_ROBOTS, expect=f"in 1..{MAX_ROBOTS}")
    speed: float = param(10.0, "cruise speed of every reference [m/s]", **P)
    spacing: float = param(24.0, "distance between consecutive vehicles of one lane; lane i is shifted by i*spacing/lanes [m]", **P)
    start_s: float = param(10.0, "arc length of the rearmost start (rear axle) along its lane [m]", **NN)
    start_jitter: float = param(1.0, "the seed shifts every start along its lane uniformly within +- this [m]", **NN)
    change_start: float = param(5.0, "a vehicle's lane change begins this far beyond its start [m]", **NN)
    change_length: float = param(40.0, "arc length over which the reference moves from start lane to target lane [m]", **P)
    curve_lat_accel: float = param(2.0, "the references slow down on curves to keep their lateral acceleration within this "
                                   "(and within robot.a_lat_max) [m/s^2]", **P)
    finish_margin: float = param(20.0, "a vehicle has passed the cone zone when its rear axle is this far beyond the last cone [m]", **NN)
    lane_tolerance: float = param(0.5, "lateral distance to the target lane's centre line that counts as arrived in it [m]", **P)
    closure_lead: float = param(30.0, "cars from SUMO's routes (sumo.controlled_types) leave a lane that cones close ahead this far "
                                "before its first cone [m]", **NN)
    exit_lanes: tuple[int, ...] = param((), "cars from SUMO's routes: beyond the last cones each changes to one of these road lanes "
                                        "(0 = rightmost car lane), drawn by the seed per car; empty: it keeps its lane",
                                        parse=tuple, raw_default=[], check=_lane_indices, expect="a list of lane indices 0..15")
    exit_spread: float = param(0.0, "cars from SUMO's routes begin the change to their exit lane at a point drawn by the seed "
                               "within this far beyond finish_margin past the last cone, so that they do not all weave at once [m]", **NN)
    closure_window: float = param(100.0, "cars from SUMO's routes begin to leave a lane that cones close this far before their "
                                  "latest begin (the one that ends closure_lead before the first cone), so that a car without a "
                                  "gap can slow down and wait for one before it [m]", **NN)
    gap_acceptance: bool = param(True, "cars from SUMO's routes begin (and go on with) a lane change only into a safe gap "
                                 "(gap_time, gap_decel, gap_min; docs/highway_work_zone.md); otherwise they keep their lane, "
                                 "slow down (gap_speed) and try again further on")
    gap_time: float = param(1.0, "gap acceptance: the time gap a lane change keeps to the leader in the target lane (at its own "
                            "speed) and leaves the follower there (at the follower's speed) [s]", **NN)
    gap_decel: float = param(3.0, "gap acceptance: the safe deceleration: the car must be able to come down to its new leader's "
                             "speed, and its new follower to its speed, braking at most this hard [m/s^2]", **P)
    gap_min: float = param(2.0, "gap acceptance: the standstill gap, bumper to bumper, on top [m]", **NN)
    gap_speed: float = param(0.75, "gap acceptance: a car whose lane change waits for a gap slows to this share of "
                             "lane_change.speed until it has changed, so that the traffic beside it moves on",
                             check=lambda f: 0 < f <= 1, expect="in (0, 1]")


def lane_change_params(scenario: Scenario) -> LaneChangeParams:
    """Section ``[lane_change]`` of ``scenario``."""
    return from_section(LaneChangeParams, scenario, SECTION)
