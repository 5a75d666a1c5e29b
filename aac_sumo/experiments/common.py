"""Pieces every experiment builds the same way from its scenario."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.config.keys import P
from aac_sumo.config.schema import from_section, param, section
from aac_sumo.coordination.aac import AacParams
from aac_sumo.coordination.anticipation import Anticipation
from aac_sumo.coordination.base import Coordinator, Finished
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import LateralBand, PathReference
from aac_sumo.registry import coordinators
from aac_sumo.sim.base import Simulator
from aac_sumo.world import RobotSpec, WorldState



@dataclass
class PlannerSettings:
    """The planner's settings without its solvers, for a coordinator that solves nothing (the
    simulator drives): building an MPC problem would only cost set-up time."""

    config: MpcConfig


@dataclass
class Setup:
    """A ready-to-run experiment. ``finished(world)`` tells, per controlled robot, whether it
    has finished its task; the run completes when all have. ``free_flow_s`` is each robot's
    arrival time without interaction [s] (its start time plus its path length at cruise
    speed), for the delay metrics. ``prepare(world)``, when given, runs on every observed world
    before anything else and returns the world to use: an experiment whose robots enter and
    leave during the run (:attr:`WorldState.present`) gives the newcomers their tasks there.
    ``figures()``, when given, returns the experiment's own metrics at the end of the run;
    ``held()`` the ``(t, robot name)`` of the periods in which a robot was held by a traffic
    signal, which ``pedestrian_wait_s`` does not count as waiting at a crossing."""

    scenario: Scenario
    sim: Simulator
    coordinator: Coordinator
    tasks: list[PathReference]
    finished: Callable[[WorldState], np.ndarray]
    free_flow_s: np.ndarray | None = None
    prepare: Callable[[WorldState], WorldState] | None = None
    figures: Callable[[], dict] | None = None
    held: Callable[[], set[tuple[float, str]]] | None = None


@section("robot")
@dataclass(frozen=True)
class RobotParams:
    """Section ``[robot]``: every controlled robot's footprint [m] (a rectangle centred half the
    wheelbase ahead of the rear axle) and its kinematic bicycle's limits
    (:class:`~aac_sumo.dynamics.VehicleLimits`)."""

    length: float = param(1.0, "footprint length [m]", **P)
    width: float = param(0.6, "footprint width [m]", **P)
    wheelbase: float = param(0.8, "wheelbase L [m]", **P)
    a_min: float = param(-6.0, "strongest braking [m/s^2]", check=lambda a: a < 0, expect="< 0")
    a_max: float = param(3.0, "strongest acceleration [m/s^2]", **P)
    steer_max: float = param(0.6, "steering limit [rad]", check=lambda s: 0 < s < 1.5, expect="in (0, 1.5)")
    v_max: float = param(30.0, "speed limit [m/s]", **P)
    allow_reverse: bool = param(False, "allow negative speed down to -v_max")
    a_lat_max: float = param(3.0, "friction/comfort limit on the lateral acceleration v^2 |tan(steer)| / wheelbase [m/s^2]", **P)
    steer_rate_max: float = param(0.5, "how fast the steering angle may change [rad/s]", **P)
    a_comfort: float = param(3.0, "deceleration used unless an emergency needs more (capped at |a_min|) [m/s^2]", **P)


def robot_params(scenario: Scenario) -> RobotParams:
    """Section ``[robot]`` of ``scenario``."""
    return from_section(RobotParams, scenario, "robot")


def robot_spec(scenario: Scenario, name: str, length: float | None = None, width: float | None = None) -> RobotSpec:
    """A controlled robot with the scenario's ``[robot]`` limits and footprint (``length`` and
    ``width`` [m] instead, when given: a SUMO vType's)."""
    r = robot_params(scenario)
    length = r.length if length is None else length
    if r.wheelbase > length:
        raise ScenarioError(scenario.source, "robot.wheelbase", f"at most robot.length ({length})", r.wheelbase)
    limits = VehicleLimits(r.a_min, r.a_max, r.steer_max, -r.v_max if r.allow_reverse else 0.0, r.v_max,
                           r.a_lat_max, r.steer_rate_max, r.a_comfort)
    return RobotSpec(name, length, r.width if width is None else width, BicycleModel(r.wheelbase, limits))


def mpc_config(scenario: Scenario) -> MpcConfig:
    """The planner settings of ``[controller]``."""
    return from_section(MpcConfig, scenario, "controller")


def aac_params(scenario: Scenario) -> AacParams:
    """The AAC settings of ``[aac]``; the sampling trees are seeded by the scenario seed."""
    return from_section(AacParams, scenario, "aac")


def simulator_drives(scenario: Scenario) -> bool:
    """Whether ``controller.coordinator`` leaves driving to the simulator (it is registered with
    ``simulator_drives``): the builder then starts the simulator in that mode."""
    return coordinators()[scenario["controller.coordinator"]].simulator_drives


def coordinator(scenario: Scenario, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                band: bool | None = None) -> Coordinator:
    """The registered ``controller.coordinator`` with its own MPC planner; ``finished`` tells it
    which robots have finished their task (they no longer take authority). Its planner keeps
    robots within lateral bands when ``band`` is true (None: when ``corridors`` holds one)."""
    band = any(isinstance(c, LateralBand) for c in corridors or []) if band is None else band
    config = dataclasses.replace(mpc_config(scenario), band=band)
    planner = PlannerSettings(config) if simulator_drives(scenario) else MpcPlanner(config)
    coord = coordinators()[scenario["controller.coordinator"]].build(scenario, planner, tasks, corridors, finished)
    coord.anticipation = None if simulator_drives(scenario) else anticipation(scenario)
    return coord


def anticipation(scenario: Scenario) -> Anticipation | None:
    """The ``controller.anticipate*`` and ``yield_*`` settings, None when ``controller.anticipate`` is off."""
    if not scenario["controller.anticipate"]:
        return None
    return from_section(Anticipation, scenario, "controller")


def check_start(scenario: Scenario, world: WorldState, key: str) -> None:
    """Exit-2 error naming ``key`` when any two start footprints overlap."""
    robots = world.robot_footprints()
    rows = np.vstack([robots] + [o.footprint()[None, :] for o in world.obstacles])
    gaps = pairwise_rect_clearance(robots, rows)
    gaps[np.arange(len(robots)), np.arange(len(robots))] = np.inf
    if np.any(gaps < 0):
        i, j = np.unravel_index(np.argmin(gaps), gaps.shape)
        names = [r.name for r in world.robots] + [o.name for o in world.obstacles]
        raise ScenarioError(scenario.source, key, f"start footprints that do not overlap ({names[i]} overlaps {names[j]} by {-gaps[i, j]:.2f} m)")
