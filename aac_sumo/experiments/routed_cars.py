"""Controlled cars chosen from SUMO's own routes: the lane change's second way of making cars.

With ``sumo.controlled_types`` (vType ids) or ``sumo.controlled_ids`` (id globs), every matching
vehicle of the route files (those of ``sumo.config`` and ``sumo.routes``) that departs within
``scenario.duration`` is a controlled robot, ``lane_change.vehicles`` is not used, and SUMO
drives everything else (background traffic reaches the MPC as moving obstacles). A car is off
the road until SUMO departs it (insertion as SUMO does it: its departLane, departSpeed, gaps),
ours from then on, and off the road again once it has finished.

Its reference is made when it departs, from its own route (a chain of edges, lanes followed
through the network's connections) and the lane SUMO put it on:

- a lane that cones close ahead (a lane most of a cone cluster stands on) is left for the
  nearest lane open along the closure (the left one on a tie), the change ending
  ``lane_change.closure_lead`` metres before the first cone;
- beyond the last cones (``lane_change.finish_margin`` past them, plus a distance drawn per car
  by the seed within ``lane_change.exit_spread``; without cones, right after its start) it
  changes to its exit lane, drawn per car by the seed from ``lane_change.exit_lanes`` (empty:
  it keeps its lane);
- each change takes ``lane_change.change_length`` metres per lane crossed.

Its lateral band spans the lanes it uses until its last change has ended, then its exit lane.
It has finished when it is within ``lane_tolerance`` of its exit lane's centre line, less
than ``END_MARGIN`` before the end of its route; it is then taken off SUMO's road.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aac_sumo import network
from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.experiments.common import Setup, coordinator, robot_spec
from aac_sumo.experiments.lane_geometry import (
    BAND_SETTLE, MIN_LANES, ROAD_MARGIN, SAMPLE_STEP, along, blend, lane_edges, smooth_reference, smoothstep,
)
from aac_sumo.references import LateralBand, PathReference
from aac_sumo.sim.sumo import SumoOptions, sumo_simulator
from aac_sumo.sim.base import Simulator
from aac_sumo.sim.sumo_routes import RoutedVehicle, RoutesError, controlled, read_routes
from aac_sumo.world import WorldState, parking_spot

END_MARGIN = 15.0  # a car has finished this far before the end of its route [m]
CLUSTER_GAP = 60.0  # cones of one lane closer than this along it close one stretch [m]
KEYS = "sumo.controlled_types"


def closures(rd: network.Road, centres: list[np.ndarray]) -> dict[int, list[tuple[float, float]]]:
    """Per road lane, the stretches ``(first, last)`` [m of arc length along the lane] that cones
    standing on it (within half its width of its centre line) close."""
    lines = [PathReference(line, 1.0, stop_at_end=False) for line in rd.lanes]
    at: dict[int, list[float]] = {}
    for c in centres:
        fits = [line.project(c) for line in lines]
        lane = int(np.argmin([lateral for _, lateral in fits]))
        s, lateral = fits[lane]
        if lateral <= 0.5 * rd.widths[lane] and 0.0 < s < rd.length(lane):
            at.setdefault(lane, []).append(s)
    out: dict[int, list[tuple[float, float]]] = {}
    for lane, ss in at.items():
        ss = sorted(ss)
        runs = [[ss[0], ss[0]]]
        for s in ss[1:]:
            if s - runs[-1][1] < CLUSTER_GAP:
                runs[-1][1] = s
            else:
                runs.append([s, s])
        out[lane] = [(a, b) for a, b in runs]
    return out


def lane_plan(rd: network.Road, start: int, s0: float, closed: dict[int, list[tuple[float, float]]], exit_lane: int | None,
              change_start: float, change_length: float, lead: float, margin: float) -> list[tuple[int, float, float]]:
    """The lane changes ``(lane, begin, length)`` [m of arc length along lane ``start``] of a car
    at arc length ``s0`` of lane ``start`` (see the module's rules)."""
    def scale(lane: int) -> float:  # arc length on lane ``start`` per metre of ``lane``
        return rd.length(start) / rd.length(lane)

    changes: list[tuple[int, float, float]] = []
    lane, free_from = start, s0 + change_start
    ahead = [(a * scale(start), b * scale(start)) for a, b in closed.get(start, []) if b * scale(start) > s0]
    if ahead:
        first, last = ahead[0]
        def is_open(j):
            return all(b * scale(j) < first or a * scale(j) > last for a, b in closed.get(j, []))
        options = sorted((j for j in range(rd.n_lanes) if j != start and is_open(j)), key=lambda j: (abs(j - start), -j))
        if options:
            lane = options[0]
            length = change_length * abs(lane - start)
            begin = max(free_from, first - lead - length)
            changes.append((lane, begin, length))
            free_from = begin + length
    ends = [b * scale(j) for j, stretches in closed.items() for a, b in stretches if b * scale(j) > s0]
    if exit_lane is not None and exit_lane != lane:
        length = change_length * abs(exit_lane - lane)
        changes.append((exit_lane, max(free_from, max(ends, default=-np.inf) + margin), length))
    return changes


def planned_path(rd: network.Road, start: int, s0: float, changes: list[tuple[int, float, float]]) -> np.ndarray:
    """Rear-axle waypoints (M, 2) [m] from arc length ``s0`` of lane ``start`` to the road's end,
    moving onto each change's lane with a quintic smoothstep (lane positions matched by their
    share of the lane's length, so curved roads work)."""
    la = rd.length(start)
    s = np.r_[np.arange(s0, la, SAMPLE_STEP), la]
    points = along(rd.lanes[start], s)[0]
    for lane, begin, length in changes:
        there = along(rd.lanes[lane], s * rd.length(lane) / la)[0]
        w = smoothstep((s - begin) / length)[:, None]
        points = (1.0 - w) * points + w * there
    return points


def planned_band(rd: network.Road, lanes: list[int], final: int, settle_at: float, margin: float) -> LateralBand:
    """The band across lanes ``lanes`` until arc length ``settle_at``, then over ``BAND_SETTLE``
    metres onto lane ``final`` alone; ``margin`` [m] inside the edges."""
    right, left = lane_edges(rd, min(lanes), max(lanes))
    final_right, final_left = lane_edges(rd, final, final)
    if final > min(lanes):
        right = blend(right, final_right, 0.0, settle_at, BAND_SETTLE)
    if final < max(lanes):
        left = blend(left, final_left, 0.0, settle_at, BAND_SETTLE)
    return LateralBand(right, left, margin)


def routed_vehicles(scenario: Scenario, routes: list) -> list[RoutedVehicle]:
    """The controlled vehicles of the route files ``routes`` departing within the run; exit-2
    errors naming the key when none is, or a file cannot be read."""
    su = scenario.data["sumo"]
    try:
        everyone = read_routes(routes, scenario["scenario.duration"])
    except RoutesError as exc:
        raise ScenarioError(scenario.source, KEYS, "route files whose controlled vehicles can be known before the run", str(exc)) from None
    chosen = controlled(everyone, su["controlled_types"], su["controlled_ids"])
    if not chosen:
        types = sorted({v.vtype for v in everyone})
        raise ScenarioError(scenario.source, KEYS, "vTypes (or ids in sumo.controlled_ids) of vehicles in the route files that depart "
                            f"within scenario.duration (vTypes there: {', '.join(types) or 'none'})",
                            ", ".join(su["controlled_types"] + su["controlled_ids"]))
    return chosen


class RoutedCars:
    """The roads, references and bands of the controlled cars from SUMO's routes, made as they
    depart; ``prepare`` is the run's :attr:`Setup.prepare`."""

    def __init__(self, scenario: Scenario, net, vehicles: list[RoutedVehicle], robots, sim: Simulator | None):
        self.scenario, self.net, self.vehicles, self.robots, self.sim = scenario, net, vehicles, robots, sim
        lc = scenario.data["lane_change"]
        self.lc = lc
        self.roads: dict[tuple[str, ...], network.Road] = {}
        self.edges = [self.route(v) for v in vehicles]
        rng = np.random.default_rng(scenario["scenario.seed"])
        exits = lc["exit_lanes"]
        self.exit = [int(rng.choice(exits)) if exits else None for _ in vehicles]
        self.exit_at = lc["finish_margin"] + rng.uniform(0.0, lc["exit_spread"], len(vehicles))
        for k, v in enumerate(vehicles):
            lanes = self.road(self.edges[k], v).n_lanes
            if self.exit[k] is not None and self.exit[k] >= lanes:
                raise ScenarioError(scenario.source, "lane_change.exit_lanes", f"lanes of every controlled car's road "
                                    f"({v.id}'s route has {lanes} car lanes, 0..{lanes - 1})", self.exit[k])
        n = len(vehicles)
        self.tasks = [PathReference([parking_spot(k)[:2], parking_spot(k)[:2] + [1.0, 0.0]], lc["speed"], stop_at_end=False)
                      for k in range(n)]
        self.bands: list = [None] * n
        self.finish: list[tuple[PathReference, float] | None] = [None] * n
        self.free_flow = np.full(n, np.nan)
        self.done = np.zeros(n, dtype=bool)
        self.admitted = np.zeros(n, dtype=bool)
        self.cone_centres: list[np.ndarray] | None = None
        self.coordinator = None

    def route(self, v: RoutedVehicle) -> tuple[str, ...]:
        """Vehicle ``v``'s edges (a trip routed on the network's shortest path through its ``via``)."""
        if not v.trip:
            return v.edges
        edges: list = []
        for a, b in zip(v.edges, v.edges[1:]):
            try:
                path, _ = self.net.getShortestPath(self.net.getEdge(a), self.net.getEdge(b))
            except KeyError as exc:
                raise ScenarioError(self.scenario.source, KEYS, f"routes over edges of the network ({v.id})", str(exc)) from None
            if path is None:
                raise ScenarioError(self.scenario.source, KEYS, f"a trip the network connects ({v.id}: no way from {a} to {b})")
            edges += [e for e in path if not edges or e is not edges[-1]]
        return tuple(e.getID() for e in edges)

    def road(self, edges: tuple[str, ...], v: RoutedVehicle) -> network.Road:
        if edges not in self.roads:
            unknown = next((e for e in edges if not self.net.hasEdge(e)), None)
            if unknown is not None or not edges:
                raise ScenarioError(self.scenario.source, KEYS, f"routes over edges of the network ({v.id})", unknown or "an empty route")
            try:
                chain = network.chain_of(self.net, list(edges))
            except ValueError as exc:
                raise ScenarioError(self.scenario.source, KEYS, f"routes along connected edges ({v.id}: {exc})") from None
            if chain.n_lanes < MIN_LANES:
                raise ScenarioError(self.scenario.source, KEYS, f"routes with {MIN_LANES} car lanes through every edge, room for a lane "
                                    f"change ({v.id}: {chain.describe()})")
            self.roads[edges] = network.chain_road(chain)
        return self.roads[edges]

    def prepare(self, world: WorldState) -> WorldState:
        """Give the cars SUMO departed since the last period their references (and the
        coordinator a fresh start for them); take the finished ones off the road."""
        for k in np.flatnonzero(world.on_road & ~self.admitted):
            self.admit(world, int(k))
        leaving = np.flatnonzero(self.done & world.on_road)
        for k in leaving:
            self.sim.retire(int(k))
        return self.sim.observe() if leaving.size else world

    def admit(self, world: WorldState, k: int) -> None:
        lc, v = self.lc, self.vehicles[k]
        rd = self.road(self.edges[k], v)
        if self.cone_centres is None:
            self.cone_centres = [o.centre for o in world.obstacles if o.kind == "cone"]
        closed = closures(rd, self.cone_centres)
        state = world.states[k]
        start = int(np.argmin([PathReference(line, 1.0, stop_at_end=False).project(state[:2])[1] for line in rd.lanes]))
        s0 = PathReference(rd.lanes[start], 1.0, stop_at_end=False).project(state[:2])[0]
        changes = lane_plan(rd, start, s0, closed, self.exit[k], lc["change_start"], lc["change_length"], lc["closure_lead"],
                            self.exit_at[k])
        final = changes[-1][0] if changes else start
        a_lat = min(lc["curve_lat_accel"], self.scenario["robot.a_lat_max"])
        task = smooth_reference(planned_path(rd, start, s0, changes), lc["speed"], a_lat)
        settle = max((b + length for _, b, length in changes), default=s0)
        band = planned_band(rd, [start] + [lane for lane, _, _ in changes], final, settle, 0.5 * self.robots[k].width + ROAD_MARGIN)
        line = PathReference(rd.lanes[final], 1.0, stop_at_end=False)
        end_s = max(line.length - END_MARGIN, line.project(state[:2])[0])
        self.tasks[k], self.bands[k], self.finish[k] = task, band, (line, end_s)
        self.admitted[k] = True
        self.free_flow[k] = world.t + task.project(along(rd.lanes[final], end_s)[0][0])[0] / lc["speed"]
        self.coordinator.admit(world, k)

    def finished(self, world: WorldState) -> np.ndarray:
        """Cars that reached their exit lane near their route's end, or that SUMO took off."""
        for k in np.flatnonzero(~self.done & world.on_road):
            line, end_s = self.finish[k]
            s, lateral = line.project(world.states[k, :2])
            self.done[k] = s >= end_s and lateral <= self.lc["lane_tolerance"]
        for k in np.flatnonzero(~self.done & ~world.on_road):
            self.done[k] = self.robots[k].name in self.sim.removed
        return self.done.copy()


def build_routed(scenario: Scenario, net_path: Path, routes: list[Path], options: SumoOptions) -> Setup:
    """The lane change's Setup with the controlled cars of SUMO's routes (see the module)."""
    vehicles = routed_vehicles(scenario, routes)
    net = network.read(net_path, "sumo.net", scenario.source)
    robots = []
    for v in vehicles:
        try:
            robots.append(robot_spec(scenario, v.id, v.length, v.width))
        except ScenarioError:
            raise ScenarioError(scenario.source, KEYS, f"vTypes at least robot.wheelbase long ({v.vtype} is {v.length:g} m)") from None
    v_max = robots[0].model.limits.v_max
    if scenario["lane_change.speed"] > v_max:
        raise ScenarioError(scenario.source, "lane_change.speed", f"at most robot.v_max ({v_max})", scenario["lane_change.speed"])
    states = np.array([parking_spot(k) for k in range(len(robots))])
    cars = RoutedCars(scenario, net, vehicles, robots, None)
    sim = sumo_simulator(robots, states, scenario["scenario.dt"], [], options, scenario["sumo.isolate"], frozenset(v.id for v in vehicles))
    try:
        cars.sim = sim
        def finished(world: WorldState) -> np.ndarray:  # a function: a coordinator's copy (warm-up) shares it
            return cars.finished(world)

        coord = coordinator(scenario, cars.tasks, cars.bands, finished, band=True)
        cars.coordinator = coord
        return Setup(scenario, sim, coord, cars.tasks, finished, cars.free_flow, prepare=cars.prepare)
    except BaseException:
        sim.close()
        raise
