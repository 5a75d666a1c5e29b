"""Pieces every experiment builds the same way from its scenario."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from aac_sumo.barriers import FcbfParams
from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.coordination.aac import AacCoordinator, AacParams, Authorities
from aac_sumo.coordination.anticipation import Anticipation
from aac_sumo.coordination.base import Coordinator, Finished
from aac_sumo.coordination.cbf_qp import CbfQpCoordinator, CbfQpParams
from aac_sumo.coordination.independent import IndependentCoordinator
from aac_sumo.coordination.lfc import LfcCoordinator, LfcParams
from aac_sumo.coordination.orca import OrcaCoordinator, OrcaParams
from aac_sumo.coordination.prioritized import PrioritizedLfc
from aac_sumo.coordination.proximity import ProximityParams
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
    c = scenario.data["controller"]
    return MpcConfig(
        horizon=c["horizon"], dt=scenario["scenario.dt"], solver=c["solver"], barrier=c["barrier"],
        gamma=c["gamma"], d_safe=c["d_safe"], fcbf=FcbfParams(c["mu1"], c["mu2"], c["sigmoid_k"], c["v0"]),
        slots=c["obstacle_slots"], discs=c["ego_discs"], q_pos=c["q_pos"], q_heading=c["q_heading"],
        q_speed=c["q_speed"], r_accel=c["r_accel"], r_steer=c["r_steer"], s_accel=c["s_accel"],
        s_steer=c["s_steer"], terminal_scale=c["terminal_scale"], max_iter=c["max_iter"],
        max_cpu_time=c["max_cpu_time"], retry_with_ipopt=c["retry_with_ipopt"], codegen=c["codegen"],
        warm_start=c["warm_start"],
        pedestrian_reach=c["pedestrian_reach"], pedestrian_margin=c["pedestrian_margin"], walkway_time=c["walkway_time"],
        prediction=c["prediction"], prediction_window=c["prediction_window"],
        terminal_stop=c["terminal_stop"], obstacle_decel=c["obstacle_decel"],
        comfort_accel=c["comfort_accel"], comfort_lat=c["comfort_lat"],
    )


def aac_params(scenario: Scenario) -> AacParams:
    """The AAC settings of ``[aac]``; the sampling trees are seeded by the scenario seed."""
    a = scenario.data["aac"]
    return AacParams(
        close_distance=a["close_distance"],
        proximity=ProximityParams(a["proximity_iterations"], a["alpha"], a["beta"], a["tree_step"], a["sample_radius"], a["collision_radius"]),
        safety_stop=a["safety_stop"], safety_margin=a["safety_margin"], lookahead=a["lookahead"], speed_gain=a["speed_gain"],
        fallback=a["fallback"], ignore_followers=a["ignore_followers"], seed=scenario["scenario.seed"],
        commit=a["commit"], authorities=Authorities.parse(a["authorities"]), tail_brake=a["tail_brake"], commit_margin=a["commit_margin"],
        keep_right=a["keep_right"], keep_right_range=a["keep_right_range"], keep_right_max=a["keep_right_max"], make_room=a["make_room"],
        stall_time=a["stall_time"], lead_time=a["lead_time"], detour=a["detour"], detour_clearance=a["detour_clearance"],
        cruise=a["cruise"],
    )


def lfc_params(scenario: Scenario) -> LfcParams:
    """The LFC settings of ``[lfc]``."""
    f = scenario.data["lfc"]
    return LfcParams(f["safety_stop"], f["safety_margin"], f["fallback"], f["lookahead"], f["speed_gain"], f["ignore_followers"])


def _check_safety_options(scenario: Scenario, section: str) -> None:
    """Exit-2 error when an option of ``section`` that relies on its safety stop is on without it."""
    if section == "aac" and scenario["aac.detour"] and not scenario["aac.commit"]:
        raise ScenarioError(scenario.source, "aac.detour", "false unless aac.commit is true", True)
    if scenario[f"{section}.safety_stop"]:
        return
    if scenario[f"{section}.fallback"] == "tracking":
        raise ScenarioError(scenario.source, f"{section}.fallback", f"brake unless {section}.safety_stop is true", "tracking")
    if scenario[f"{section}.ignore_followers"]:
        raise ScenarioError(scenario.source, f"{section}.ignore_followers", f"false unless {section}.safety_stop is true", True)


@register_coordinator("aac")
def aac_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> AacCoordinator:
    _check_safety_options(scenario, "aac")
    return AacCoordinator(planner, tasks, corridors, finished, params=aac_params(scenario))


@register_coordinator("lfc")
def lfc_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> LfcCoordinator | PrioritizedLfc:
    """The paper's LFC, or with ``lfc.commit`` prioritized planning on committed plans (its
    committed-plan settings from ``[aac]``, its safety options from ``[lfc]``)."""
    _check_safety_options(scenario, "lfc")
    if scenario["lfc.commit"]:
        f = scenario.data["lfc"]
        params = dataclasses.replace(aac_params(scenario), commit=True, safety_stop=f["safety_stop"], safety_margin=f["safety_margin"],
                                     fallback=f["fallback"], lookahead=f["lookahead"], speed_gain=f["speed_gain"],
                                     ignore_followers=f["ignore_followers"],
                                     detour=scenario["aac.detour"] and scenario["aac.commit"])
        return PrioritizedLfc(planner, tasks, corridors, finished, params=params)
    return LfcCoordinator(planner, tasks, corridors, finished, params=lfc_params(scenario))


@register_coordinator("independent")
def independent_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> IndependentCoordinator:
    return IndependentCoordinator(planner, tasks, corridors, finished)


#: The scenario kinds the ORCA baseline runs on (internal simulator, robots with goals).
ORCA_KINDS = ("swarm_rescue", "circle_swap", "random_crossing")


def orca_params(scenario: Scenario) -> OrcaParams:
    """The ORCA settings of ``[orca]``; its preferred-velocity noise is seeded by the scenario seed."""
    o = scenario.data["orca"]
    return OrcaParams(o["neighbor_dist"], o["max_neighbors"], o["time_horizon"], o["time_horizon_obst"], o["radius_margin"],
                      o["max_speed"], o["lookahead"], o["pref_noise"], o["turn_time"], o["reverse"], scenario["scenario.seed"],
                      o["tracking"])


@register_coordinator("orca")
def orca_coordinator(scenario: Scenario, planner: MpcPlanner, tasks, corridors, finished) -> OrcaCoordinator:
    if scenario.kind not in ORCA_KINDS:
        raise ScenarioError(scenario.source, "controller.coordinator", f"orca only with scenario.kind {', '.join(ORCA_KINDS)}", "orca")
    return OrcaCoordinator(planner, tasks, corridors, finished, params=orca_params(scenario))


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
    q = scenario.data["cbf_qp"]
    return CbfQpCoordinator(planner, tasks, corridors, finished, params=CbfQpParams(q["radius"], q["lookahead"], q["speed_gain"]))


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
    c = scenario.data["controller"]
    if not c["anticipate"]:
        return None
    return Anticipation(decel=c["anticipate_decel"], accel=c["anticipate_accel"], brake=c["anticipate_brake"], gap=c["anticipate_gap"],
                        time_gap=c["anticipate_time_gap"],
                        pedestrian_margin=c["pedestrian_margin"], pedestrian_reach=c["pedestrian_reach"],
                        walkway_time=c["walkway_time"], yield_distance=c["yield_distance"],
                        yield_band=c["yield_band"])


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
