"""S2, lane change (paper Table II): ``lane_change.vehicles`` MPC-controlled cars on a multi-lane
SUMO road change lanes among cones and crossing pedestrians, in SUMO co-simulation.

Vehicle k starts in lane ``k mod lanes`` (lane 0 = rightmost), staggered along the road, at the
cruise speed. The cone lane is the lane most cones stand on (lane 0 without cones). Every
vehicle's target lane (see :func:`target_lane`): the cone lane's vehicles move to the
neighbouring lane, the others one lane further away from the cones, the outermost lane's one lane
back towards them (never into the cone lane; a vehicle with no such lane keeps its lane).

Each reference is the vehicle's own pre-planned lane-change path, independent of the other
vehicles and obstacles (as in the paper): at road fraction ``u`` the point
``(1 - w) * start_lane(u) + w * target_lane(u)`` with ``w`` a quintic smoothstep over
``change_length`` metres beginning ``change_start`` metres after the start; lane centre lines come
from the network (sumolib), so curved roads work. A vehicle has finished when it is within
``lane_tolerance`` of its target lane's centre line and its rear axle is ``finish_margin`` beyond
the last cone (beyond the end of its lane change, without cones), or when SUMO removed it.
The MPC keeps each vehicle's rear axle within the lanes its lane change spans (a lateral band,
half a car width plus ``ROAD_MARGIN`` inside their outer edges): it may wait behind a stopped
car but not swerve into a third lane, such as the one the cones close. Beyond the end of its lane
change the band narrows to the target lane: a vehicle that has changed lanes brakes for a car
that cuts in instead of swerving back into the lane it left (where cones may stand).
"""

from __future__ import annotations

import copy
import os
import shlex
import sys
from collections import Counter
from pathlib import Path
from typing import Callable

import numpy as np

from aac_sumo import network
from aac_sumo.config import package_data
from aac_sumo.config import Scenario, ScenarioError
from aac_sumo.experiments.common import Setup, check_start, coordinator, robot_spec, simulator_drives
from aac_sumo.experiments.sumo_driver import lane_indices
from aac_sumo.experiments.routed_cars import build_routed
from aac_sumo.experiments.lane_change_params import LaneChangeParams, lane_change_params
from aac_sumo.experiments.lane_geometry import (
    BAND_SETTLE, MIN_LANES, ROAD_MARGIN, blend, lane_edges, smooth_reference,
)
from aac_sumo.geometry import along
from aac_sumo.references import LateralBand, PathReference
from aac_sumo.registry import register_experiment
from aac_sumo.sim.sumo_options import LaneOrder, SumoOptions, SumoParams, sumo_params
from aac_sumo.sim.sumo import sumo_simulator
from aac_sumo.sim.sumo_config import SumoConfig, read_config, xml_problem
from aac_sumo.world import RobotSpec, WorldState

BUNDLED_NET_DIR = package_data.networks_dir() / "lane_change"  # the checkout's sumo_networks/, or a wheel's package data
BUNDLED_NET = BUNDLED_NET_DIR / "lane_change.net.xml"
BUNDLED_ROUTES = [BUNDLED_NET_DIR / "cones.rou.xml", BUNDLED_NET_DIR / "pedestrians.rou.xml"]
#: A finished car leaves our road where it would have to brake harder than this [m/s^2] to stop
#: at its lane's end: SUMO's default vType deceleration (:func:`arrivals`).
ARRIVAL_DECEL = 4.5


def target_lane(lane: int, cone_lane: int, lanes: int) -> int:
    """The lane a vehicle starting in ``lane`` changes to, given the cone lane."""
    if lane == cone_lane:
        return lane + 1 if lane + 1 < lanes else lane - 1
    away = lane + 1 if lane > cone_lane else lane - 1
    if 0 <= away < lanes:
        return away
    back = lane - 1 if lane > cone_lane else lane + 1
    return lane if back == cone_lane else back


def lane_change_path(rd: network.Road, start: int, target: int, s0: float, change_start: float, change_length: float) -> np.ndarray:
    """Waypoints (M, 2) [m] of the rear axle from arc length ``s0`` of lane ``start`` to the road's
    end, blending into lane ``target`` between ``s0 + change_start`` and ``+ change_length``."""
    return blend(rd.lanes[start], rd.lanes[target], s0, s0 + change_start, change_length)


def lane_change_band(rd: network.Road, start: int, target: int, change_end: float, margin: float) -> LateralBand:
    """The lateral band of a vehicle changing from lane ``start`` to ``target``: both lanes until
    its lane change ends (arc length ``change_end`` of lane ``start``), then, over
    ``BAND_SETTLE`` metres, the target lane alone; ``margin`` [m] inside the edges."""
    right, left = lane_edges(rd, min(start, target), max(start, target))
    if start < target:  # moving left: the start lane's right edge gives way to the target's
        right = blend(right, lane_edges(rd, target, target)[0], 0.0, change_end, BAND_SETTLE)
    elif start > target:
        left = blend(left, lane_edges(rd, target, target)[1], 0.0, change_end, BAND_SETTLE)
    return LateralBand(right, left, margin)


def scenario_file(scenario: Scenario, text: str, key: str) -> Path:
    """The file ``text`` names in ``key``: against the current directory, then the scenario
    file's directory; exit-2 error naming ``key`` when it does not exist."""
    path = Path(text.strip()).expanduser()
    if not path.is_absolute() and not path.exists():
        beside = Path(scenario.source).parent / path
        path = beside if beside.exists() else path
    if not path.is_file():
        hint = network.build_hint(path) if path.name.endswith((".net.xml", ".net.xml.gz")) else ""
        raise ScenarioError(scenario.source, key, f"an existing file{hint}", text)
    return path


def network_files(scenario: Scenario) -> tuple[Path, list[Path]]:
    """The network and route files of ``[sumo]`` (:func:`scenario_file`), those of ``sumo.config``
    included; route files that are not well-formed XML are an exit-2 error naming their key."""
    su = sumo_params(scenario)
    routes = [route_file(scenario, scenario_file(scenario, r, "sumo.routes"), "sumo.routes") for r in su.routes.split(",") if r.strip()]
    if su.config.strip():
        cfg = sumo_config(scenario)
        if su.net.strip() and cfg.net is not None:
            raise ScenarioError(scenario.source, "sumo.net", f"empty when sumo.config names the network ({cfg.path} has net-file {cfg.net})",
                                su.net)
        if cfg.net is None and not su.net.strip():
            raise ScenarioError(scenario.source, "sumo.config", f"a net-file in {cfg.path} (or sumo.net)", su.config)
        missing = [p for p in [cfg.net, *cfg.routes] if p is not None and not p.is_file()]
        if missing:
            build = network.build_hint(missing[0]) if missing[0] == cfg.net else ""
            raise ScenarioError(scenario.source, "sumo.config", f"the files {cfg.path} names to exist{build}", str(missing[0]))
        for path in cfg.routes:
            route_file(scenario, path, "sumo.config")
        return (cfg.net or scenario_file(scenario, su.net, "sumo.net")), cfg.routes + routes
    if not su.net.strip():
        return BUNDLED_NET, BUNDLED_ROUTES if not su.routes.strip() else routes
    return scenario_file(scenario, su.net, "sumo.net"), routes


def route_file(scenario: Scenario, path: Path, key: str) -> Path:
    """``path`` when it is well-formed XML, else an exit-2 error naming ``key`` (SUMO's own
    message on a broken file names neither)."""
    problem = xml_problem(path)
    if problem is not None:
        raise ScenarioError(scenario.source, key, f"SUMO route files in XML ({path}: {problem})", str(path))
    return path


def with_resolved_paths(scenario: Scenario) -> Scenario:
    """``scenario`` with ``sumo.net``, ``sumo.routes`` and ``sumo.config`` as absolute paths
    (:func:`scenario_file`), so that its saved copy (``scenario.toml``) reruns the same run from
    any folder; empty keys stay empty (the bundled files)."""
    data = copy.deepcopy(scenario.data)
    for key in ("net", "routes", "config"):
        text = data["sumo"][key]
        names = [t for t in (text.split(",") if key == "routes" else [text]) if t.strip()]
        data["sumo"][key] = ",".join(str(scenario_file(scenario, t, f"sumo.{key}").resolve()) for t in names)
    return Scenario(data, scenario.source)


def sumo_config(scenario: Scenario) -> SumoConfig:
    """The user's ``sumo.config`` (relative paths as for ``sumo.net``); exit-2 error when it is
    missing or not a SUMO configuration."""
    text = scenario["sumo.config"]
    try:
        return read_config(scenario_file(scenario, text, "sumo.config"))
    except ValueError as exc:
        raise ScenarioError(scenario.source, "sumo.config", str(exc), text) from None


def scenario_road(scenario: Scenario, net_path: Path) -> network.Road:
    """The road of ``[sumo]``: ``sumo.edges``, or the longest chain with ``MIN_LANES`` car lanes."""
    net = network.read(net_path, "sumo.net", scenario.source)
    return network.road(net, scenario["sumo.edges"], MIN_LANES, scenario.source)


def sumo_options(scenario: Scenario, net_path: Path, routes: list[Path]) -> SumoOptions:
    """How to start SUMO for ``scenario`` (``[sumo]``); a user's ``sumo.config`` that sets one
    of the options the co-simulation sets itself gets a one-line note."""
    su = sumo_params(scenario)
    outputs = tuple(dict.fromkeys((["fcd"] if su.fcd else []) + list(su.outputs)))
    out = None
    if su.output_dir.strip() or outputs:
        out = Path(su.output_dir) if su.output_dir.strip() else Path("out") / scenario["scenario.name"]
        out.mkdir(parents=True, exist_ok=True)
    config = sumo_config(scenario) if su.config.strip() else None
    if su.gui and not has_display():
        raise ScenarioError(scenario.source, "sumo.gui", "a display for sumo-gui (DISPLAY or WAYLAND_DISPLAY set); without one, "
                            "run without --gui, or under xvfb-run", "no display")
    options = SumoOptions(net_path, routes, tuple(t.strip() for t in su.cone_types.split(",") if t.strip()),
                          su.gui, scenario["scenario.seed"], su.delay, out, outputs, config.path if config else None,
                          tuple(shlex.split(su.extra_args)), su.lateral_resolution, simulator_drives(scenario), su.declared_decel)
    if config is not None:
        overridden = config.overridden(options.our_options(scenario["scenario.dt"]))
        if overridden:
            print(f"aac-sumo: note: {config.path} sets {', '.join(overridden)}; the scenario's own apply "
                  f"(step-length {scenario['scenario.dt']}, seed {scenario['scenario.seed']}, collisions warned)", file=sys.stderr)
    return options


@register_experiment("lane_change", params=LaneChangeParams, sections={"sumo": SumoParams})
def build_lane_change(scenario: Scenario) -> Setup:
    lc, su = lane_change_params(scenario), sumo_params(scenario)
    src = scenario.source
    net_path, routes = network_files(scenario)
    scenario = with_resolved_paths(scenario)
    bare = not any(has_obstacles(path, su.cone_types) for path in routes)
    if su.controlled_types or su.controlled_ids:
        return _noted(build_routed(scenario, net_path, routes, sumo_options(scenario, net_path, routes)), bare)
    rd = scenario_road(scenario, net_path)
    n, lanes = lc.vehicles, rd.n_lanes
    robots = [robot_spec(scenario, f"veh{k}") for k in range(n)]
    if lc.speed > robots[0].model.limits.v_max:
        raise ScenarioError(src, "lane_change.speed", f"at most robot.v_max ({robots[0].model.limits.v_max})", lc.speed)

    rng = np.random.default_rng(scenario["scenario.seed"])
    start_lane = np.arange(n) % lanes
    s0 = (lc.start_s + (np.arange(n) // lanes) * lc.spacing + start_lane * lc.spacing / lanes
          + rng.uniform(-lc.start_jitter, lc.start_jitter, n))
    s0 = np.maximum(s0, 0.0)
    change_end = s0 + lc.change_start + lc.change_length
    for k in range(n):
        if change_end[k] > rd.length(start_lane[k]):
            raise ScenarioError(src, "sumo.net", f"a road long enough for lane_change: lane {start_lane[k]} of edges "
                                f"{' '.join(rd.edges)} is {rd.length(start_lane[k]):.0f} m, vehicle veh{k} needs {change_end[k]:.0f} m")
    states = np.zeros((n, 4))
    for k in range(n):
        point, heading = along(rd.lanes[start_lane[k]], s0[k])
        states[k] = [point[0, 0], point[0, 1], heading[0], lc.speed]

    sim = sumo_simulator(robots, states, scenario["scenario.dt"], rd.edges, sumo_options(scenario, net_path, routes), su.isolate)
    try:
        world = sim.observe()
        check_start(scenario, world, "lane_change.spacing")
        cones = [o for o in world.obstacles if o.kind == "cone"]
        centre_lines = [PathReference(line, 1.0, stop_at_end=False) for line in rd.lanes]
        cone_lane = _cone_lane(rd, centre_lines, cones)
        targets = [target_lane(int(a), cone_lane, lanes) for a in start_lane]
        if simulator_drives(scenario):  # SUMO's driver: each car is asked for its target lane once it has driven change_start
            net = network.read(net_path, "sumo.net", src)
            speed = lc.speed if su.driver_speed < 0.0 else su.driver_speed
            for k, b in enumerate(targets):
                sim.order_lanes(k, [LaneOrder(lc.change_start, lane_indices(net, rd.edges, b))])
                if speed > 0.0:  # as fast as our references cruise, unless asked otherwise
                    sim.limit_speed(k, speed)
        run_on = lc.speed * scenario["scenario.duration"]  # beyond the road's end, along it: farther than any car gets
        tasks = [smooth_reference(lane_change_path(rd, int(a), b, s0[k], lc.change_start, lc.change_length), lc.speed,
                                  min(lc.curve_lat_accel, scenario["robot.a_lat_max"]), run_on)
                 for k, (a, b) in enumerate(zip(start_lane, targets))]
        finish_s = []
        for k, b in enumerate(targets):
            line = centre_lines[b]
            done = change_end[k] * rd.length(b) / rd.length(start_lane[k])
            beyond_cones = max((line.project(c.centre)[0] for c in cones), default=-np.inf) + lc.finish_margin
            finish_s.append(max(done, beyond_cones))
            if finish_s[-1] > rd.length(b):
                raise ScenarioError(src, "lane_change.finish_margin", f"a finish within the road: lane {b} is {rd.length(b):.0f} m, "
                                    f"veh{k} finishes at {finish_s[-1]:.0f} m")
        done = np.zeros(n, dtype=bool)

        def finished(w: WorldState) -> np.ndarray:
            for k in np.flatnonzero(~done):
                s, lateral = centre_lines[targets[k]].project(w.states[k, :2])
                done[k] = (s >= finish_s[k] and lateral <= lc.lane_tolerance) or robots[k].name in sim.removed
            return done.copy()

        finish_points = [along(rd.lanes[b], finish_s[k])[0][0] for k, b in enumerate(targets)]
        free_flow = np.array([task.project(p)[0] for task, p in zip(tasks, finish_points)]) / lc.speed
        bands = [lane_change_band(rd, int(a), b, change_end[k], 0.5 * robots[0].width + ROAD_MARGIN)
                 for k, (a, b) in enumerate(zip(start_lane, targets))]
        prepare = None if simulator_drives(scenario) else arrivals(sim, robots, [centre_lines[b] for b in targets],
                                                                 [rd.length(b) for b in targets], finished, scenario["scenario.dt"])
        return _noted(Setup(scenario, sim, coordinator(scenario, tasks, bands, finished), tasks, finished, free_flow, prepare), bare)
    except BaseException:
        sim.close()
        raise


def arrivals(sim, robots: list[RobotSpec], lines: list[PathReference], ends: list[float],
             finished: Callable[[WorldState], np.ndarray], dt: float) -> Callable[[WorldState], WorldState]:
    """The run's ``prepare``, for the cars we move. A car arrives in SUMO's eyes when it finishes
    its task: at the observation where ``finished`` first has it, SUMO removes it as arrived
    (``sim.arrive``: its ``tripinfo`` trip ends then, as the run's ``arrived`` does), and our
    model drives it on along its reference, still seen by the coordinators. Before, SUMO had no
    trip of the cars still driving when the run completed (10 of the demo's 15), and the others
    arrived there some 15 s after they finished. It leaves our road where the road ends: once its
    front is within the distance it needs to stop at ``ARRIVAL_DECEL`` (plus one period) of the
    end of its lane (``lines``, ``ends`` [m] along them), it is parked (``sim.retire``). Before
    that, finished cars drove on beyond the network's end, where SUMO reported emergency stops at
    the lane's end and placed them past it."""
    arrived = np.zeros(len(robots), dtype=bool)

    def prepare(world: WorldState) -> WorldState:
        done = np.asarray(finished(world), dtype=bool)
        for k in np.flatnonzero(done & world.on_road & ~arrived):
            sim.arrive(int(k))
        arrived[done] = True
        leaving = []
        for k in np.flatnonzero(done & world.on_road):
            v = max(float(world.states[k, 3]), 0.0)
            front = lines[k].project(world.states[k, :2])[0] + robots[k].centre_offset + 0.5 * robots[k].length
            if front + v * dt + v * v / (2.0 * ARRIVAL_DECEL) >= ends[k]:
                leaving.append(int(k))
        for k in leaving:
            sim.retire(k, arrived=True)
        return sim.observe() if leaving else world

    return prepare


def _noted(setup: Setup, bare: bool) -> Setup:
    """``setup``, once built, after a one-line note when the route files hold no cones or walkers (``bare``)."""
    if bare:
        print("aac-sumo: note: no cones or walkers in the route files: the task is the lane changes alone", file=sys.stderr)
    return setup


def has_obstacles(path: Path, cone_types: str) -> bool:
    """Whether the route file ``path`` holds a walker (``person``, ``personFlow``) or a vehicle
    or flow of one of ``cone_types`` (comma-separated); unreadable files count as holding some."""
    import xml.etree.ElementTree as ET

    cones = {t.strip() for t in cone_types.split(",") if t.strip()}
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return True
    return any(e.tag in ("person", "personFlow") or (e.tag in ("vehicle", "flow", "trip") and e.get("type") in cones) for e in root.iter())


def _cone_lane(rd: network.Road, centre_lines: list[PathReference], cones) -> int:
    """The lane most cones stand on (within half a lane width of its centre line); 0 without cones."""
    votes = Counter()
    for cone in cones:
        gaps = [line.project(cone.centre)[1] for line in centre_lines]
        lane = int(np.argmin(gaps))
        if gaps[lane] <= 0.5 * rd.widths[lane]:
            votes[lane] += 1
    return votes.most_common(1)[0][0] if votes else 0


def has_display() -> bool:
    """Whether a window can be opened: not on Linux and the BSDs without ``DISPLAY`` or
    ``WAYLAND_DISPLAY`` (sumo-gui then retried for a minute before it failed)."""
    if not sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
