"""City networks (scenario kind ``city``): controlled cars on their SUMO routes through junctions,
turns and traffic lights.

The controlled cars are the vehicles of SUMO's route files whose vType is in
``sumo.controlled_types`` (or whose id matches ``sumo.controlled_ids``); SUMO inserts each at its
departure (its departLane, speed and gaps) and drives everything else, walkers included, which
reach the coordinators as obstacles. From its departure on a car is ours:

- its way is its route's lanes through the network's connections and the junctions' internal
  lanes (:mod:`aac_sumo.experiments.junction_routes`), with the fewest lane changes, each on the edge
  before the turn that needs it (beginning ``city.change_start`` into the edge, over
  ``city.change_length`` per lane);
- its reference drives that way at ``city.speed``, at most each lane's speed limit, slower in
  curves (``city.curve_lat_accel``); its lateral band is the lane it is in (both lanes during a
  change);
- a red or yellow signal ahead is a stop line it does not cross (:mod:`aac_sumo.experiments.signals`);
  ``red_light_violations`` counts the cars that crossed one at red;
- where its link must yield, its line holds it while a foe with priority could reach the
  junction before it has left it (:mod:`aac_sumo.experiments.right_of_way`);
  ``right_of_way_violations`` counts the entries against one.

It has finished when its rear axle is within ``city.finish_margin`` of its route's end; SUMO then
takes it as arrived and it leaves the network. A lane change for a turn is driven where the
committed plans' exact check passes against the cars in the target lane (``aac.traffic_beside``),
else the car waits in its lane. Positions in SUMO's network frame [m].
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass

import numpy as np

from aac_sumo import network
from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import from_section, param
from aac_sumo.experiments.common import Setup, simulator_drives
from aac_sumo.experiments.lane_change import network_files, sumo_options, with_resolved_paths
from aac_sumo.experiments.lane_geometry import ROAD_MARGIN, SAMPLE_STEP
from aac_sumo.experiments.routed_vehicles import KEYS, route_edges, routed_robots, routed_setup, routed_vehicles
from aac_sumo.experiments.right_of_way import RightOfWay, YieldLine, may_hold, yield_lines
from aac_sumo.experiments.signals import BOX_LENGTH, GO, Line, Signals, YellowRule, green_left
from aac_sumo.experiments.junction_routes import route_legs, route_path
from aac_sumo.references import LateralBand, PathReference
from aac_sumo.registry import register_experiment
from aac_sumo.sim.sumo_frames import bumper_to_axle
from aac_sumo.sim.sumo_options import SumoParams, sumo_params
from aac_sumo.world import WorldState, parking_spot

SECTION = "city"
#: A car's stop lines are shown to it from this far [m] before its front reaches them (beyond
#: what it needs to stop from the fastest city speed) until its rear has left them.
SIGNAL_RANGE = 150.0
#: Room [m] a car keeps before a stop line it stops for at yellow, beyond one period's travel.
YELLOW_SLACK = 1.0
#: SUMO's default ``departPos`` puts a car's front this far [m] beyond its length into its first edge ...
DEPART_FRONT = 0.1
#: ... and a car inserted there is to stop this far [m] before that edge's end: the check's margin and a metre.
INSERTION_ROOM = 1.5


@dataclass(frozen=True)
class CityParams:
    """The city's references, lane changes and finish rule (each field's doc: meaning and unit)."""

    speed: float = param(13.89, "cruise speed of the references, at most each lane's speed limit [m/s]", **P)
    curve_lat_accel: float = param(2.0, "the references slow down in turns and curves to keep their lateral acceleration within this "
                                   "(and within robot.a_lat_max) [m/s^2]", **P)
    change_start: float = param(10.0, "a lane change for the next turn begins this far into its edge [m]", **NN)
    change_length: float = param(30.0, "arc length a lane change takes per lane crossed [m]", **P)
    finish_margin: float = param(15.0, "a car has finished when its rear axle is within this of its route's end [m]", **NN)
    yield_gap: float = param(1.0, "a car whose link must yield enters the junction only if it leaves it this long before any "
                             "foe with priority could reach the junction (SUMO's jmTimegapMinor) [s]", **NN)
    yellow_decel: float = param(2.0, "at a yellow a car goes on where stopping before the line (with one period's travel and 1 m "
                                "to spare) would need more than this, if it reaches the line before the light's shortest yellow "
                                "ends; 0: only cars that cannot stop at robot.a_comfort go on [m/s^2]", **NN)
    yellow_preview: float = param(3.0, "a stop line holds already this long before its light turns yellow (the program says when): a "
                                  "car that would not reach the line before the yellow ends stops gently, where at the yellow it "
                                  "might neither stop at yellow_decel nor pass before red; 0: only at the yellow [s]", **NN)
    centre_turns: bool = param(True, "a car's path keeps inside each turn and curve by as much as centres the band its body "
                               "sweeps on its lane (lane_geometry.centring_shift: 0.4 m on a 7 m turn), so that its front corner "
                               "does not swing into the next lane; false: its rear axle follows the lanes' centre lines")
    curb_clearance: float = param(0.0, "on the last curb_length before a junction a car keeps this between its right side and its "
                                  "lane's right edge where a sidewalk runs there (it keeps left of the lane's centre if it must), "
                                  "so that walkers passing it on the sidewalk as it stands in a queue keep clear; 0: the lane's "
                                  "centre [m]", **NN)
    curb_length: float = param(40.0, "the stretch before a junction where curb_clearance holds: about the queue a red light "
                               "stands [m]", **NN)


class CityCars:
    """The controlled cars' ways, references and bands, made as SUMO departs them; their stop
    lines; ``prepare`` is the run's :attr:`Setup.prepare`."""

    def __init__(self, scenario: Scenario, net, vehicles, robots):
        self.scenario, self.net, self.robots = scenario, net, robots
        self.p = from_section(CityParams, scenario, SECTION)
        self.edges = [route_edges(scenario, net, v) for v in vehicles]
        n = len(vehicles)
        self.tasks = [PathReference([parking_spot(k)[:2], parking_spot(k)[:2] + [1.0, 0.0]], self.p.speed, stop_at_end=False)
                      for k in range(n)]
        self.bands: list = [None] * n
        self.lines: list[list[tuple[Line, float]]] = [[] for _ in range(n)]  # per car: its stop lines and their arc lengths [m]
        self.free_flow = np.full(n, np.nan)
        self.done = np.zeros(n, dtype=bool)
        self.admitted = np.zeros(n, dtype=bool)
        self.signals = Signals(YellowRule(self.p.yellow_decel, YELLOW_SLACK, scenario["scenario.dt"], shortest_yellows(net), self.p.yellow_preview,
                                          scenario["controller.anticipate_accel"]))
        self.programs = programs(net)
        self.right_of_way = RightOfWay(self.p.yield_gap, scenario["controller.anticipate_accel"])
        self.yields: list[list[tuple[YieldLine, float]]] = [[] for _ in range(n)]  # per car: the links that may have to yield
        self.names = [r.name for r in robots]
        self.held: set[tuple[float, str]] = set()  # (t, car) of the periods whose next stop line showed red or yellow
        self.sim = None
        self.coordinator = None
        self.sumo_drives = False  # SUMO's own driver moves the cars (the baseline): it keeps to its signals and leaves at its route's end

    def prepare(self, world: WorldState) -> WorldState:
        """Admit the cars SUMO departed since the last period, take the finished ones off the
        road, and show the coordinators the stop lines that hold traffic (SUMO's driver keeps to
        its signals itself: its cars' red-light violations and waits are counted all the same)."""
        for k in np.flatnonzero(world.on_road & ~self.admitted):
            self.admit(world, int(k))
        if self.sumo_drives:
            self.stop_boxes(world)
            return world
        leaving = np.flatnonzero(self.done & world.on_road)
        for k in leaving:
            self.sim.retire(int(k), arrived=True)
        if leaving.size:
            world = self.sim.observe()
        boxes = self.stop_boxes(world)
        return dataclasses.replace(world, obstacles=world.obstacles + boxes) if boxes else world

    def admit(self, world: WorldState, k: int) -> None:
        """Car ``k``'s way from the lane SUMO put it on, its reference and band."""
        state, robot = world.states[k], self.robots[k]
        first = self.net.getEdge(self.edges[k][0])
        lanes = network.car_lanes(first)
        shapes = [PathReference(np.asarray(lane.getShape(), dtype=float), 1.0, stop_at_end=False) for lane in lanes]
        start = int(np.argmin([shape.project(state[:2])[1] for shape in shapes]))
        s0 = shapes[start].project(state[:2])[0]
        try:
            path = city_path(self.net, self.edges[k], start, s0, self.p, self.scenario["robot.a_lat_max"], robot.length, robot.model.wheelbase,
                             robot.width)
        except ValueError as exc:
            raise ScenarioError(self.scenario.source, KEYS, f"routes a controlled car can drive ({robot.name}: {exc})") from None
        self.tasks[k] = PathReference(path.points, self.p.speed, stop_at_end=False, limits=path.limits)
        self.bands[k] = LateralBand(path.band_right, path.band_left, 0.5 * robot.width + ROAD_MARGIN)
        self.yields[k] = yield_lines(self.net, path)
        self.lines[k] = [(Line(stop.tls, stop.link, stop.lane, stop.point, stop.heading), stop.s) for stop in path.stops]
        self.free_flow[k] = world.t + self.tasks[k].length / self.p.speed
        self.admitted[k] = True
        self.coordinator.admit(world, k)

    def stop_boxes(self, world: WorldState) -> list:
        """The boxes of the stop lines that hold traffic now: the signals' (:class:`~aac_sumo.experiments.signals.Signals`)
        and those of the links that must yield (:class:`~aac_sumo.experiments.right_of_way.RightOfWay`)."""
        approach, yields = {}, {}
        for k in np.flatnonzero(self.admitted & world.on_road & ~self.done):
            robot = self.robots[k]
            front = self.tasks[k].project(world.states[k, :2])[0] + robot.centre_offset + 0.5 * robot.length
            near = [(line, s - front) for line, s in self.lines[k] if -(robot.length + BOX_LENGTH) < s - front < SIGNAL_RANGE]
            if near:
                approach[int(k)] = near
            near = [(y, s - front) for y, s in self.yields[k] if -(y.s_out - y.s_in + robot.length + 1.0) < s - front < SIGNAL_RANGE]
            if near:
                yields[int(k)] = near
        if not approach and not yields:
            return []
        ids = {line.tls for lines in approach.values() for line, _ in lines}
        ids |= {tls for lines in yields.values() for y, _ in lines for tls in (y.tls, *(foe.tls for foe in y.foes)) if tls}
        states = self.sim.signal_states(tuple(sorted(ids)))
        speeds = np.maximum(world.states[:, 3], 0.0)
        comfort = np.array([r.model.limits.comfort_decel for r in self.robots])
        lengths = np.array([r.length for r in self.robots])
        hardest = np.array([-r.model.limits.a_min for r in self.robots])
        boxes = self.right_of_way.boxes(world.t, yields, states, self.sim.lane_vehicles(RightOfWay.lanes(yields)), self.names, speeds,
                                        comfort, lengths, hardest) if yields else []
        return boxes + self.signal_boxes(world, approach, states, speeds, comfort, lengths)

    def signal_boxes(self, world: WorldState, approach: dict, states: dict[str, str], speeds: np.ndarray, comfort: np.ndarray,
                     lengths: np.ndarray) -> list:
        """The signals' boxes, and the periods in which a car's next signal holds it (``held``)."""
        for k, near in approach.items():
            ahead = [(d, line) for line, d in near if d >= 0.0]
            if ahead:
                _, line = min(ahead, key=lambda a: a[0])
                if states[line.tls][line.link] not in GO:
                    self.held.add((round(world.t, 9), self.robots[k].name))
        leaving = None
        if self.signals.holds.yellow.preview > 0.0:
            phases = self.sim.signal_phases(tuple(sorted(states)))
            leaving = {tls: green_left(self.programs.get(tls, {}).get(program, ()), phase, to_switch)
                       for tls, (program, phase, to_switch) in phases.items()}
        return self.signals.boxes(states, approach, speeds, comfort, lengths, leaving, self.line_speeds(approach))

    def line_speeds(self, approach: dict) -> np.ndarray:
        """Per car, its path's speed [m/s] at the first of its stop lines ahead in ``approach`` (inf without one)."""
        tops = np.full(len(self.robots), np.inf)
        for k, near in approach.items():
            arcs = [s for line, s in self.lines[k] if any(line is ln and d >= 0.0 for ln, d in near)]
            if arcs:
                tops[k] = float(self.tasks[k].speed_at(min(arcs)))
        return tops

    def finished(self, world: WorldState) -> np.ndarray:
        """Cars within ``finish_margin`` of their route's end, or that SUMO took off."""
        for k in np.flatnonzero(~self.done & world.on_road & self.admitted):
            self.done[k] = self.tasks[k].project(world.states[k, :2])[0] >= self.tasks[k].length - self.p.finish_margin
        for k in np.flatnonzero(~self.done & ~world.on_road):
            self.done[k] = self.robots[k].name in self.sim.removed
        return self.done.copy()


def city_path(net, edges, start: int, s0: float, p: CityParams, a_lat_max: float, length: float, wheelbase: float, width: float):
    """The way (:func:`~aac_sumo.experiments.junction_routes.route_path`) of a car ``length`` by
    ``width`` [m] with ``wheelbase`` [m] (equal overhangs) on the route ``edges`` from lane ``start``
    of the first, ``s0`` [m] into it, as ``p`` asks; ValueError where there is none."""
    front = bumper_to_axle(length, wheelbase) if p.centre_turns else 0.0
    return route_path(net, route_legs(net, list(edges), start), s0, min(p.curve_lat_accel, a_lat_max), p.change_start, p.change_length,
                      front, 0.5 * width, (p.curb_clearance, p.curb_length))


def drivable(scenario: Scenario, net, vehicles: list) -> list:
    """The ``vehicles`` whose routes a controlled car can drive from some lane of its first edge:
    every lane change on an edge long enough for it, no turn tighter than the car's smallest
    (``robot.wheelbase`` / tan ``robot.steer_max``) over two car lengths (the path's curvature
    averaged over them: a corner of the spline through a junction's coarse internal lane is
    tighter, and the car rounds it). Each other one is left to SUMO's own driver,
    said in one line on stderr (a route file made for any network, say an OpenStreetMap one by
    ``aac-sumo net trips``, may hold a turn too close behind the last, or a corner drawn sharper
    than a car can turn); an exit-2 error when none is left."""
    p, out, refused = from_section(CityParams, scenario, SECTION), [], []
    tightest = float(np.tan(scenario["robot.steer_max"]) / scenario["robot.wheelbase"])  # [1/m]
    span = max(1, int(round(2.0 * scenario["robot.length"] / SAMPLE_STEP)))  # points over two car lengths
    for v in vehicles:
        edges = list(route_edges(scenario, net, v))
        reasons = []
        for start in range(len(network.car_lanes(net.getEdge(edges[0])))):
            try:
                path = city_path(net, edges, start, 0.0, p, scenario["robot.a_lat_max"], scenario["robot.length"], scenario["robot.wheelbase"],
                                 scenario["robot.width"])
            except ValueError as exc:
                reasons.append(str(exc))
                continue
            bend = np.convolve(np.abs(path.curvature), np.full(span, 1.0 / span), mode="same")
            k = int(np.argmax(bend))
            if bend[k] <= tightest:
                break
            reasons.append(f"a turn of radius {1.0 / bend[k]:.1f} m at ({path.points[k, 0]:.1f}, {path.points[k, 1]:.1f}), "
                           f"tighter than the car's {1.0 / tightest:.1f} m")
        else:
            refused.append(f"{v.id} is left to SUMO's driver: no way a controlled car can drive its route "
                           f"({reasons[0] if reasons else 'no car lane'})")
            continue
        out.append(v)
    if not out:
        raise ScenarioError(scenario.source, KEYS, f"routes a controlled car can drive (none of {len(refused)} is: {refused[0]})")
    for line in refused:
        print(f"aac-sumo: {line}", file=sys.stderr)
    return out


def programs(net) -> dict[str, dict[str, list[tuple[float, str]]]]:
    """Per traffic light of the sumolib network ``net`` (read with its programs), per program id,
    its phases ``(duration [s], state)``."""
    return {tls.getID(): {pid: [(float(ph.duration), ph.state) for ph in prog.getPhases()] for pid, prog in tls.getPrograms().items()}
            for tls in net.getTrafficLights()}


def shortest_yellows(net) -> dict[str, float]:
    """Per traffic light of the sumolib network ``net`` (read with its programs), the shortest of
    its phases [s] that show yellow on some link; lights without one are left out."""
    out = {}
    for tls in net.getTrafficLights():
        amber = [float(ph.duration) for program in tls.getPrograms().values() for ph in program.getPhases() if "y" in ph.state.lower()]
        if amber:
            out[tls.getID()] = min(amber)
    return out


@register_experiment("city", params=CityParams, sections={"sumo": SumoParams})
def build_city(scenario: Scenario) -> Setup:
    """The city's Setup: the controlled cars of SUMO's routes (see the module)."""
    net_path, routes = network_files(scenario)
    scenario = with_resolved_paths(scenario)
    su = sumo_params(scenario)
    if not (su.controlled_types or su.controlled_ids):
        raise ScenarioError(scenario.source, KEYS, "the vTypes of the controlled cars (a city's cars come from SUMO's routes)", "")
    net = network.read(net_path, "sumo.net", scenario.source, withInternal=True, withPrograms=True)
    vehicles = drivable(scenario, net, routed_vehicles(scenario, routes))
    robots = routed_robots(scenario, vehicles, from_section(CityParams, scenario, SECTION).speed, "city.speed")
    cars = CityCars(scenario, net, vehicles, robots)
    cars.sumo_drives = simulator_drives(scenario)
    options = sumo_options(scenario, net_path, routes)
    if su.declared_at_insertion and su.declared_decel > 0.0:
        caps = insertion_speeds(net, cars.edges, vehicles, su.declared_decel, scenario["scenario.dt"])
        options = dataclasses.replace(options, insertion_speeds=caps)
    return routed_setup(scenario, cars, robots, vehicles, options,
                        figures=lambda: dict(red_light_violations=cars.signals.violations,
                                                     right_of_way_violations=cars.right_of_way.violations), held=lambda: cars.held)


def insertion_speeds(net, edges: list, vehicles: list, decel: float, dt: float) -> tuple[tuple[str, float], ...]:
    """``(id, speed [m/s])`` of each of ``vehicles`` (routes ``edges``) whose first junction may
    make it wait (:func:`~aac_sumo.experiments.right_of_way.may_hold`): the most it can be
    inserted at, at SUMO's default position, to stop ``INSERTION_ROOM`` before its first edge's
    end at ``decel`` [m/s^2] after one period ``dt`` [s] of travel. A fringe edge of randomTrips'
    routes is often a few tens of metres long: ``departSpeed="max"`` inserted grid6's cars at
    14-15 m/s 36-50 m before an unregulated junction where a foe was coming, and they had to
    brake at 2.3-2.6 m/s^2 from their first period."""
    out = []
    for v, route in zip(vehicles, edges):
        if len(route) < 2 or not may_hold(net, route[0], route[1]):
            continue
        room = max(net.getEdge(route[0]).getLength() - v.length - DEPART_FRONT - INSERTION_ROOM, 0.0)
        out.append((v.id, decel * (np.sqrt(dt * dt + 2.0 * room / decel) - dt)))
    return tuple(out)
