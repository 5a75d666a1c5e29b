"""Controlled cars chosen from SUMO's own routes: the lane change's second way of making cars.

With ``sumo.controlled_types`` (vType ids) or ``sumo.controlled_ids`` (id globs), every matching
vehicle of the route files (those of ``sumo.config`` and ``sumo.routes``) that departs within
``scenario.duration`` is a controlled robot, ``lane_change.vehicles`` is not used, and SUMO
drives everything else (background traffic reaches the MPC as moving obstacles). A car is off
the road until SUMO departs it (insertion as SUMO does it: its departLane, departSpeed, gaps),
ours from then on, and off the road again once it has finished.

Its lane plan is made when it departs, from its own route (a chain of edges, lanes followed
through the network's connections) and the lane SUMO put it on:

- a lane that cones close ahead (a lane most of a cone cluster stands on) is left for the
  nearest lane open along the closure (the left one on a tie); the change begins
  ``lane_change.closure_window`` metres before its latest begin, the point from which it ends
  ``lane_change.closure_lead`` metres before the first cone;
- beyond the last cones (``lane_change.finish_margin`` past them, plus a distance drawn per car
  by the seed within ``lane_change.exit_spread``; without cones, right after its start) it
  changes to its exit lane, drawn per car by the seed from ``lane_change.exit_lanes`` (empty:
  it keeps its lane), one lane at a time, the last change ending ``END_MARGIN`` before the end
  of its route at the latest;
- each change takes ``lane_change.change_length`` metres per lane crossed.

With ``lane_change.gap_acceptance`` a change begins only into a safe gap
(:mod:`~aac_sumo.experiments.lane_gaps`, judged from ``preview`` metres before it on, where no
plan or tracking law of the car has used it yet). Without one the car keeps its lane: the change
moves ahead (``POSTPONE_STEP`` beyond the preview), and the car slows to
``lane_change.gap_speed`` of its cruise speed until it has changed, so that the traffic beside it
moves on. What holds it up may be a controlled car behind it (or beside it, a little behind) in
the target lane: that one lets the car in, as at a zipper merge (it slows at ``CURVE_DECEL`` to
the car's speed, at most ``gap_speed`` of the cruise speed, where the rule's gap behind the car
begins, until the car has begun its change), and the car keeps its speed (two controlled cars
that wait for each other's place do not ride side by side for good). Only a car that waits
standing (slower than ``STANDING``) is not let in by one that can no longer stop before its gap
at its comfort deceleration: that one passes (rather than stop beside it), and the next one lets
it in. Out of a closed lane a car
without a gap also slows to stand the tracking law's look-ahead before its latest begin
(braking at ``CURVE_DECEL``) and waits there for one. A change under way turns back
to the lane it left when its gap is no longer safe without the time gaps, while it has not
reached its new lane and there is room to try again before its latest begin. An exit change that
reaches its latest begin without a safe gap is given up, the last resort: the car finishes in
the lane it is in (counted as ``exits_missed``).

Its reference is its path: each change a quintic smoothstep from one smoothed lane line onto the
next. Its lateral band is the lane it is in, opening onto the next lane ``BAND_SETTLE`` metres
before a change begins and closing onto it as far beyond its end: a car waiting for a gap does
not swerve into the next lane. It has finished when it is within ``lane_tolerance`` of its last
lane's centre line, less than ``END_MARGIN`` before the end of its route; it is then taken off
SUMO's road.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aac_sumo import network
from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.experiments.common import Setup, simulator_drives
from aac_sumo.experiments.sumo_driver import lane_indices
from aac_sumo.experiments.lane_change_params import lane_change_params
from aac_sumo.experiments.lane_gaps import GapRule, GapVerdict, judge_gap
from aac_sumo.experiments.lane_plans import END_MARGIN, Change, LanePlan, closures, crossed_lanes, lane_plan, planned_band, planned_path
from aac_sumo.experiments.lane_geometry import CURVE_DECEL, MIN_LANES, ROAD_MARGIN, lane_reference, smooth_road
from aac_sumo.references import PathReference
from aac_sumo.sim.sumo_options import LaneOrder, SumoOptions
from aac_sumo.sim.base import Simulator
from aac_sumo.sim.sumo_routes import RoutedVehicle
from aac_sumo.experiments.routed_vehicles import KEYS, route_edges, routed_robots, routed_setup, routed_vehicles
from aac_sumo.world import WorldState, parking_spot

POSTPONE_STEP = 10.0  # a change without a safe gap moves this far beyond the preview [m]
MERGE_MOVE = 10.0  # a car letting another one in follows where that one's gap begins once it has moved this far [m]
STANDING = 1.0  # a car slower than this waits as standing: only a car that can still stop before its gap lets it in [m/s]


class RoutedCars:
    """The roads, lane plans, references and bands of the controlled cars from SUMO's routes,
    made as they depart and remade as their lane changes wait for gaps (see the module);
    ``prepare`` is the run's :attr:`Setup.prepare`, ``counts`` its figures of lane changes."""

    def __init__(self, scenario: Scenario, net, vehicles: list[RoutedVehicle], robots, sim: Simulator | None):
        self.scenario, self.net, self.vehicles, self.robots, self.sim = scenario, net, vehicles, robots, sim
        lc = lane_change_params(scenario)
        self.lc = lc
        self.roads: dict[tuple[str, ...], tuple[network.Road, list[PathReference]]] = {}
        self.edges = [route_edges(scenario, net, v) for v in vehicles]
        rng = np.random.default_rng(scenario["scenario.seed"])
        exits = lc.exit_lanes
        self.exit = [int(rng.choice(exits)) if exits else None for _ in vehicles]
        self.exit_at = lc.finish_margin + rng.uniform(0.0, lc.exit_spread, len(vehicles))
        for k, v in enumerate(vehicles):
            lanes = self.road(self.edges[k], v).n_lanes
            if self.exit[k] is not None and self.exit[k] >= lanes:
                raise ScenarioError(scenario.source, "lane_change.exit_lanes", f"lanes of every controlled car's road "
                                    f"({v.id}'s route has {lanes} car lanes, 0..{lanes - 1})", self.exit[k])
        n = len(vehicles)
        self.tasks = [PathReference([parking_spot(k)[:2], parking_spot(k)[:2] + [1.0, 0.0]], lc.speed, stop_at_end=False)
                      for k in range(n)]
        self.bands: list = [None] * n
        self.finish: list[tuple[PathReference, float] | None] = [None] * n
        self.plans: list[LanePlan | None] = [None] * n
        self.free_flow = np.full(n, np.nan)
        self.done = np.zeros(n, dtype=bool)
        self.admitted = np.zeros(n, dtype=bool)
        self.cone_centres: list[np.ndarray] | None = None
        self.coordinator = None
        self.sumo_drives = False  # SUMO's own driver moves the cars: it gets each car's lanes, and judges the gaps itself
        self.rule = GapRule(lc.gap_time, lc.gap_decel, lc.gap_min) if lc.gap_acceptance else None
        #: how far the tracking law looks ahead [m], and from how far before a change its gap is judged [m]:
        #: beyond where the MPC's reference (the horizon at the cruise speed) and that law reach
        self.lookahead = max(scenario["aac.lookahead"], scenario["lfc.lookahead"])
        self.preview = lc.speed * scenario["controller.horizon"] * scenario["scenario.dt"] + self.lookahead
        self.counts = dict(lane_changes=0, lane_change_waits=0, lane_change_aborts=0, exits_missed=0)
        self._s: dict[int, float] = {}  # arc lengths of this period's cars along their start lanes

    def road(self, edges: tuple[str, ...], v: RoutedVehicle) -> network.Road:
        """The (smoothed) road of route ``edges``; its lanes' centre lines as paths in :meth:`lines`."""
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
            rd = smooth_road(network.chain_road(chain))
            self.roads[edges] = rd, [PathReference(line, 1.0, stop_at_end=False) for line in rd.lanes]
        return self.roads[edges][0]

    def lines(self, k: int) -> list[PathReference]:
        """The centre lines of car ``k``'s road, as paths."""
        return self.roads[self.edges[k]][1]

    def prepare(self, world: WorldState) -> WorldState:
        """Give the cars SUMO departed since the last period their lane plans (and the
        coordinator a fresh start for them), judge the gaps of the lane changes at hand, and
        take the finished cars off the road."""
        for k in np.flatnonzero(world.on_road & ~self.admitted):
            self.admit(world, int(k))
        if not self.sumo_drives:
            self.judge(world)
        leaving = np.flatnonzero(self.done & world.on_road)
        for k in leaving:  # at its route's end, the period after it finished: SUMO takes it as arrived (it said vaporized)
            self.sim.retire(int(k), arrived=True)
        world = self.sim.observe() if leaving.size else world
        if not self.sumo_drives and self.finished(world).all():
            # the run completes now, with the cars that finish now still on the road (steps.csv
            # marks them arrived there): SUMO takes them as arrived too, else tripinfo lacked them
            for k in np.flatnonzero(world.on_road):
                self.sim.arrive(int(k))
        return world

    def admit(self, world: WorldState, k: int) -> None:
        lc, v = self.lc, self.vehicles[k]
        rd = self.road(self.edges[k], v)
        if self.cone_centres is None:
            self.cone_centres = [o.centre for o in world.obstacles if o.kind == "cone"]
        closed = closures(rd, self.cone_centres)
        state = world.states[k]
        lines = self.lines(k)
        start = int(np.argmin([line.project(state[:2])[1] for line in lines]))
        s0 = lines[start].project(state[:2])[0]
        changes = lane_plan(rd, start, s0, closed, self.exit[k], lc.change_start, lc.change_length, lc.closure_lead,
                            self.exit_at[k], lc.closure_window)
        self.plans[k] = LanePlan(rd, start, s0, ahead=changes)
        self.rebuild(k)
        self.admitted[k] = True
        line, end_s = self.finish[k]
        self.free_flow[k] = world.t + self.tasks[k].project(line.pose_at(end_s)[0, :2])[0] / lc.speed
        self.coordinator.admit(world, k)
        if self.sumo_drives:  # each change asked once the car has driven to its begin (its start lane's metres)
            self.sim.order_lanes(k, [LaneOrder(max(c.begin - s0, 0.0), lane_indices(self.net, self.edges[k], c.lane)) for c in changes])

    def rebuild(self, k: int) -> None:
        """Car ``k``'s reference, band and finish line from its lane plan. While it waits for a
        gap (and slows), its speed is capped at ``gap_speed`` of the cruise speed until its next
        change has ended, and out of a closed lane without an accepted gap also by standing
        ``lookahead`` before the change's latest begin (or its begin, once that has moved
        beyond; braking at ``CURVE_DECEL``); while it lets a car in, by coming down to
        ``courtesy_v`` at its ``courtesy`` arc length (braking at ``CURVE_DECEL``)."""
        lc, p = self.lc, self.plans[k]
        changes = p.done + p.ahead
        points, s = planned_path(p.road, p.start, p.s0, changes)
        caps = None
        if p.waiting and p.ahead:
            c = p.ahead[0]
            caps = np.where(s <= c.begin + c.length, lc.gap_speed * lc.speed if p.slow else np.inf, np.inf)
            if c.kind == "closure" and not p.accepted:
                stand = max(c.begin, c.latest) - self.lookahead
                caps = np.minimum(caps, np.sqrt(2.0 * CURVE_DECEL * np.clip(stand - s, 0.0, None)))
        if p.courtesy_for >= 0:
            merge = np.sqrt(p.courtesy_v**2 + 2.0 * CURVE_DECEL * np.clip(p.courtesy - s, 0.0, None))
            caps = merge if caps is None else np.minimum(caps, merge)
        self.tasks[k] = lane_reference(points, lc.speed, min(lc.curve_lat_accel, self.scenario["robot.a_lat_max"]), caps)
        self.bands[k] = planned_band(p.road, p.start, changes, 0.5 * self.robots[k].width + ROAD_MARGIN)
        line = self.lines(k)[p.final()]
        self.finish[k] = line, max(line.length - END_MARGIN, line.project(points[0])[0])

    def arc(self, world: WorldState, k: int) -> float:
        """Car ``k``'s arc length [m] along its start lane now (once per period)."""
        if k not in self._s:
            self._s[k] = self.lines(k)[self.plans[k].start].project(world.states[k, :2])[0]
        return self._s[k]

    def judge(self, world: WorldState) -> None:
        """Every car's lane changes at hand this period (see the module): begin, wait, turn
        back or give up; a car whose plan changed gets its new reference, and its coordinator
        drops its stored plan."""
        self._s = {}
        for k in np.flatnonzero(self.admitted & world.on_road & ~self.done):
            k, p = int(k), self.plans[k]
            changed = False
            if p.courtesy_for >= 0 and not self.courteous(world, k):
                p.courtesy_for, p.courtesy, p.courtesy_v, changed = -1, -np.inf, 0.0, True
            if p.ahead or not p.crossed:
                changed |= self.step(world, k, p)
            if changed:
                self.rebuild(k)
                self.coordinator.retask(k)

    def courteous(self, world: WorldState, j: int) -> bool:
        """Whether car ``j`` still lets its car in: that one is on the road and still waits."""
        k = self.plans[j].courtesy_for
        return bool(world.on_road[k] and not self.done[k] and self.plans[k].waiting)

    def let_in(self, world: WorldState, j: int, k: int) -> bool:
        """Whether car ``j`` lets car ``k`` in ahead of it (see the module): its rear axle comes
        down to ``k``'s speed (at most ``gap_speed`` of the cruise speed) where the rule's gap
        behind ``k`` begins (along ``j``'s start lane); not when ``k`` stands and ``j`` can no
        longer stop before that point at its comfort deceleration (it would stop beside it)."""
        p, rule = self.plans[j], self.rule
        v = min(max(float(world.states[k, 3]), 0.0), self.lc.gap_speed * self.lc.speed)
        ahead = self.lines(j)[p.start].project(world.states[k, :2])[0]  # k's rear axle along j's start lane
        robot_j, robot_k = self.robots[j], self.robots[k]
        merge = (ahead - (robot_j.centre_offset + 0.5 * robot_j.length) - (0.5 * robot_k.length - robot_k.centre_offset)
                 - rule.min_gap - rule.time_gap * v)
        s, v_j = self.arc(world, j), max(float(world.states[j, 3]), 0.0)
        if v < STANDING and v_j**2 - v**2 > 2.0 * robot_j.model.limits.comfort_decel * max(merge - s, 0.0):
            if p.courtesy_for == k:  # it can no longer: it goes on
                p.courtesy_for, p.courtesy, p.courtesy_v = -1, -np.inf, 0.0
                self.rebuild(j)
                self.coordinator.retask(j)
            return False
        if p.courtesy_for != k or abs(p.courtesy - merge) >= MERGE_MOVE:
            p.courtesy_for, p.courtesy, p.courtesy_v = k, merge, v
            self.rebuild(j)
            self.coordinator.retask(j)
        return True

    def step(self, world: WorldState, k: int, p: LanePlan) -> bool:
        """One period of car ``k``'s lane plan ``p``; whether the plan changed."""
        s, lines = self.arc(world, k), self.lines(k)
        if not p.crossed:
            c, origin = p.done[-1], p.origin()
            here = world.states[k, :2]
            if s >= c.begin + c.length or lines[c.lane].project(here)[1] < lines[origin].project(here)[1]:
                p.crossed = True
            elif c.kind != "back" and s + c.length <= c.latest and not self.safe(world, k, origin, c.lane, headway=False).safe:
                p.done.append(Change(origin, s, c.length, s, "back"))
                p.ahead.insert(0, c._replace(begin=min(c.latest, s + c.length + POSTPONE_STEP)))
                p.postpone(p.ahead[0].begin)
                p.crossed, p.accepted, p.waiting = True, False, True
                self.counts["lane_change_aborts"] += 1
                return True
            else:
                return False
        if not p.ahead:
            return False
        c = p.ahead[0]
        if s + self.preview < c.begin:
            return False
        verdict = self.safe(world, k, p.lane(), c.lane, headway=True)
        if verdict.safe:
            changed = p.waiting and c.kind == "closure" and not p.accepted  # the stop before it is lifted
            p.accepted = True
            if s >= c.begin:
                p.done.append(p.ahead.pop(0))
                p.crossed, p.accepted, p.waiting = False, False, False
                self.counts["lane_changes"] += 1
            return changed
        was = p.accepted
        p.accepted = False
        if s + self.preview >= c.latest and c.kind == "exit":  # the last resort: it finishes in its lane
            p.ahead = []
            p.waiting = False
            self.counts["exits_missed"] += 1
            return True
        begin = min(s + self.preview + POSTPONE_STEP, c.latest)
        if c.kind == "closure" and s + self.lookahead > c.begin + MERGE_MOVE:
            begin = s + self.lookahead  # it went beyond where it was to stand: it stands where it is now
        # a controlled car behind that lets this one in: it keeps its speed; otherwise it slows, and what holds it up moves on
        slow = not (verdict.robot >= 0 and verdict.along < 0.0 and not self.done[verdict.robot] and self.let_in(world, verdict.robot, k))
        if begin <= c.begin and p.waiting and was == p.accepted and slow == p.slow:
            return False
        self.counts["lane_change_waits"] += not p.waiting
        p.waiting, p.slow = True, slow
        p.postpone(max(begin, c.begin))
        return True

    def safe(self, world: WorldState, k: int, a: int, b: int, headway: bool) -> GapVerdict:
        """Whether car ``k`` may move from lane ``a`` into lane ``b`` now: every lane it moves
        into leaves it a safe gap (always, without ``lane_change.gap_acceptance``); the first
        unsafe lane's verdict."""
        if self.rule is None:
            return GapVerdict(True, np.inf)
        p, lines = self.plans[k], self.lines(k)
        for lane in crossed_lanes(a, b):
            also = tuple(int(j) for j in np.flatnonzero(self.admitted & world.on_road & ~self.done)
                         if j != k and self.plans[j].road is p.road and self.plans[j].moving()
                         and lane in self.plans[j].intents(self.arc(world, int(j)), self.preview))
            verdict = judge_gap(world, k, lines[lane], 0.5 * p.road.widths[lane], self.rule, headway, also)
            if not verdict.safe:
                return verdict
        return verdict

    def finished(self, world: WorldState) -> np.ndarray:
        """Cars that reached their last lane near their route's end, or that SUMO took off."""
        for k in np.flatnonzero(~self.done & world.on_road):
            line, end_s = self.finish[k]
            s, lateral = line.project(world.states[k, :2])
            self.done[k] = s >= end_s and lateral <= self.lc.lane_tolerance
        for k in np.flatnonzero(~self.done & ~world.on_road):
            self.done[k] = self.robots[k].name in self.sim.removed
        return self.done.copy()


def build_routed(scenario: Scenario, net_path: Path, routes: list[Path], options: SumoOptions) -> Setup:
    """The lane change's Setup with the controlled cars of SUMO's routes (see the module)."""
    vehicles = routed_vehicles(scenario, routes)
    net = network.read(net_path, "sumo.net", scenario.source)
    robots = routed_robots(scenario, vehicles, lane_change_params(scenario).speed, "lane_change.speed")
    cars = RoutedCars(scenario, net, vehicles, robots, None)
    cars.sumo_drives = simulator_drives(scenario)
    # SUMO's driver: our gap rule counted nothing
    return routed_setup(scenario, cars, robots, vehicles, options, figures=None if cars.sumo_drives else lambda: dict(cars.counts))
