"""Pieces every experiment builds the same way from its scenario."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.config.schema import from_section
from aac_sumo.coordination.aac import AacCoordinator, AacParams
from aac_sumo.coordination.anticipation import Anticipation
from aac_sumo.coordination.base import Coordinator, Finished
from aac_sumo.coordination.cbf_qp import CbfQpCoordinator, CbfQpParams
from aac_sumo.coordination.independent import IndependentCoordinator
from aac_sumo.coordination.lfc import LfcCoordinator, LfcParams
from aac_sumo.coordination.orca import OrcaCoordinator, OrcaParams
from aac_sumo.coordination.prioritized import PrioritizedLfc
from aac_sumo.coordination.sumo_driver import SumoDriver
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import LateralBand, PathReference
from aac_sumo.registry import COORDINATORS, register_coordinator
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
    ``figures()``, when given, returns the experiment's own metrics at the end of the run."""

    scenario: Scenario
    sim: Simulator
    coordinator: Coordinator
    tasks: list[PathReference]
    finished: Callable[[WorldState], np.ndarray]
    free_flow_s: np.ndarray | None = None
    prepare: Callable[[WorldState], WorldState] | None = None
    figures: Callable[[], dict] | None = None


def robot_spec(scenario: Scenario, name: str, length: float | None = None, width: float | None = None) -> RobotSpec:
    """A controlled robot with the scenario's ``[robot]`` limits and footprint (``length`` and
    ``width`` [m] instead, when given: a SUMO vType's)."""
    r = scenario.data["robot"]
    length = r["length"] if length is None else length
    if r["wheelbase"] > length:
        raise ScenarioError(scenario.source, "robot.wheelbase", f"at most robot.length ({length})", r["wheelbase"])
    limits = VehicleLimits(r["a_min"], r["a_max"], r["steer_max"], -r["v_max"] if r["allow_reverse"] else 0.0, r["v_max"],
                           r["a_lat_max"], r["steer_rate_max"], r["a_comfort"])
    return RobotSpec(name, length, r["width"] if width is None else width, BicycleModel(r["wheelbase"], limits))


def mpc_config(scenario: Scenario) -> MpcConfig:
    """The planner settings of ``[controller]``."""
    return from_section(MpcConfig, scenario, "controller")


def aac_params(scenario: Scenario) -> AacParams:
    """The AAC settings of ``[aac]``; the sampling trees are seeded by the scenario seed."""
    return from_section(AacParams, scenario, "aac")


@register_coordinator("aac")
def aac_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> AacCoordinator:
    return AacCoordinator(planner, tasks, corridors, finished, params=aac_params(scenario))


@register_coordinator("lfc")
def lfc_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> LfcCoordinator | PrioritizedLfc:
    """The paper's LFC, or with ``lfc.commit`` prioritized planning on committed plans (its
    committed-plan settings from ``[aac]``, its safety options from ``[lfc]``)."""
    lfc = from_section(LfcParams, scenario, "lfc")
    if lfc.commit:
        params = from_section(AacParams, scenario, "aac", commit=True, safety_stop=lfc.safety_stop, safety_margin=lfc.safety_margin,
                              fallback=lfc.fallback, lookahead=lfc.lookahead, speed_gain=lfc.speed_gain,
                              ignore_followers=lfc.ignore_followers, detour=scenario["aac.detour"] and scenario["aac.commit"])
        return PrioritizedLfc(planner, tasks, corridors, finished, params=params)
    return LfcCoordinator(planner, tasks, corridors, finished, params=lfc)


@register_coordinator("independent")
def independent_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> IndependentCoordinator:
    return IndependentCoordinator(planner, tasks, corridors, finished)


#: The scenario kinds the ORCA baseline runs on (internal simulator, robots with goals).
ORCA_KINDS = ("swarm_rescue", "circle_swap", "random_crossing")


@register_coordinator("orca")
def orca_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> OrcaCoordinator:
    if scenario.kind not in ORCA_KINDS:
        raise ScenarioError(scenario.source, "controller.coordinator", f"orca only with scenario.kind {', '.join(ORCA_KINDS)}", "orca")
    return OrcaCoordinator(planner, tasks, corridors, finished, params=from_section(OrcaParams, scenario, "orca"))


@register_coordinator("sumo")
def sumo_coordinator(scenario: Scenario, planner, tasks, corridors, finished) -> SumoDriver:
    """SUMO's own driver moves the cars (:mod:`aac_sumo.coordination.sumo_driver`); road kinds only."""
    if scenario.kind != "lane_change":
        raise ScenarioError(scenario.source, "controller.coordinator", "a coordinator of ours on this kind (sumo: SUMO's own driver, "
                            "for kind lane_change, whose cars SUMO hosts)", "sumo")
    return SumoDriver(planner, tasks, corridors, finished)


sumo_coordinator.simulator_drives = True  # the builder starts its simulator with SUMO driving (sumo_driver's module)


def simulator_drives(scenario: Scenario) -> bool:
    """Whether ``controller.coordinator`` leaves driving to the simulator (its factory declares
    ``simulator_drives``): the builder then starts the simulator in that mode."""
    return bool(getattr(COORDINATORS.get(scenario["controller.coordinator"]), "simulator_drives", False))


@register_coordinator("cbf_qp")
def cbf_qp_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> CbfQpCoordinator:
    return CbfQpCoordinator(planner, tasks, corridors, finished, params=from_section(CbfQpParams, scenario, "cbf_qp"))


def coordinator(scenario: Scenario, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                band: bool | None = None) -> Coordinator:
    """The registered ``controller.coordinator`` with its own MPC planner; ``finished`` tells it
    which robots have finished their task (they no longer take authority). Its planner keeps
    robots within lateral bands when ``band`` is true (None: when ``corridors`` holds one)."""
    band = any(isinstance(c, LateralBand) for c in corridors or []) if band is None else band
    config = dataclasses.replace(mpc_config(scenario), band=band)
    planner = PlannerSettings(config) if simulator_drives(scenario) else MpcPlanner(config)
    coord = COORDINATORS[scenario["controller.coordinator"]](scenario, planner, tasks, corridors, finished)
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
