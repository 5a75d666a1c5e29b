"""The controlled vehicles of a SUMO user's route files (``sumo.controlled_types`` /
``sumo.controlled_ids``): which they are, their routes' edges and their robot specs, for the lane
change's cars of SUMO's routes (:mod:`~aac_sumo.experiments.routed_cars`) and the city's
(:mod:`~aac_sumo.experiments.city`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.experiments.common import Setup, coordinator, robot_spec
from aac_sumo.sim.sumo import sumo_simulator
from aac_sumo.sim.sumo_options import SumoOptions, sumo_params
from aac_sumo.sim.sumo_routes import RoutedVehicle, RoutesError, controlled, read_routes
from aac_sumo.world import WorldState, parking_spot

#: The key the errors about the controlled vehicles name.
KEYS = "sumo.controlled_types"


def routed_vehicles(scenario: Scenario, routes: list) -> list[RoutedVehicle]:
    """The controlled vehicles of the route files ``routes`` departing within the run; exit-2
    errors naming the key when none is, or a file cannot be read."""
    su = sumo_params(scenario)
    try:
        everyone = read_routes(routes, scenario["scenario.duration"])
    except RoutesError as exc:
        raise ScenarioError(scenario.source, KEYS, "route files whose controlled vehicles can be known before the run", str(exc)) from None
    chosen = controlled(everyone, su.controlled_types, su.controlled_ids)
    if not chosen:
        types = sorted({v.vtype for v in everyone})
        raise ScenarioError(scenario.source, KEYS, "vTypes (or ids in sumo.controlled_ids) of vehicles in the route files that depart "
                            f"within scenario.duration (vTypes there: {', '.join(types) or 'none'})",
                            ", ".join(su.controlled_types + su.controlled_ids))
    return chosen


def route_edges(scenario: Scenario, net, v: RoutedVehicle) -> tuple[str, ...]:
    """Vehicle ``v``'s edges (a trip routed on the network's shortest path through its ``via``);
    exit-2 errors naming ``sumo.controlled_types`` for an edge or a trip the network lacks."""
    if not v.trip:
        return v.edges
    edges: list = []
    for a, b in zip(v.edges, v.edges[1:]):
        try:
            path, _ = net.getShortestPath(net.getEdge(a), net.getEdge(b))
        except KeyError as exc:
            raise ScenarioError(scenario.source, KEYS, f"routes over edges of the network ({v.id})", str(exc)) from None
        if path is None:
            raise ScenarioError(scenario.source, KEYS, f"a trip the network connects ({v.id}: no way from {a} to {b})")
        edges += [e for e in path if not edges or e is not edges[-1]]
    return tuple(e.getID() for e in edges)


def routed_robots(scenario: Scenario, vehicles: list[RoutedVehicle], speed: float, speed_key: str) -> list:
    """The controlled robots of ``vehicles``, each its vType's footprint with ``[robot]``'s limits;
    exit-2 errors for a vType shorter than the wheelbase, and for a cruise ``speed`` [m/s] (key
    ``speed_key``) above ``robot.v_max``."""
    robots = []
    for v in vehicles:
        try:
            robots.append(robot_spec(scenario, v.id, v.length, v.width))
        except ScenarioError:
            raise ScenarioError(scenario.source, KEYS, f"vTypes at least robot.wheelbase long ({v.vtype} is {v.length:g} m)") from None
    v_max = robots[0].model.limits.v_max
    if speed > v_max:
        raise ScenarioError(scenario.source, speed_key, f"at most robot.v_max ({v_max})", speed)
    return robots


def routed_setup(scenario: Scenario, cars, robots: list, vehicles: list[RoutedVehicle], options: SumoOptions, **extra) -> Setup:
    """The Setup of the routed ``cars`` (an experiment's cars of SUMO's routes: their ``tasks``,
    ``bands``, ``free_flow``, ``prepare`` and ``finished``; its ``sim`` and ``coordinator`` are set
    here): SUMO started with ``vehicles`` routed and ``robots`` parked until it departs them, the
    scenario's coordinator on lateral bands; ``extra`` goes to the Setup. SUMO is closed again when
    anything fails."""
    states = np.array([parking_spot(k) for k in range(len(robots))])
    if sumo_params(scenario).declared_at_insertion:
        options = replace(options, declared_types=tuple(sorted({v.vtype for v in vehicles})))
    sim = sumo_simulator(robots, states, scenario["scenario.dt"], [], options, scenario["sumo.isolate"], frozenset(v.id for v in vehicles))
    try:
        cars.sim = sim

        def finished(world: WorldState) -> np.ndarray:  # a function: a coordinator's copy (warm-up) shares it
            return cars.finished(world)

        cars.coordinator = coordinator(scenario, cars.tasks, cars.bands, finished, band=True)
        return Setup(scenario, sim, cars.coordinator, cars.tasks, finished, cars.free_flow, prepare=cars.prepare,
                     **extra)
    except BaseException:
        sim.close()
        raise
