"""SUMO co-simulation through libsumo (traci when the GUI is shown).

SUMO hosts the world: the network, cones (stopped vehicles of a cone vType), pedestrians and any
other traffic, which SUMO moves itself. Our controlled vehicles are inserted with speed mode and
lane-change mode 0 and, every step, placed at the pose our bicycle model reached with
``vehicle.moveToXY(..., keepRoute=2)``; their poses are then read back from SUMO. Their speed is
our model's: after ``moveToXY`` SUMO only knows the distance travelled in the step.

Every step SUMO's own collision check (``simulation.getCollisions``) is read beside our footprint
check. Our check measures the agents' bodies; the coordinators see each SUMO-driven car as the
rectangle along its lane that covers its body and the box SUMO's check gives it (a car changing
lanes counts there with its rear where its front is), until its lane change ends
(:func:`~aac_sumo.sim.sumo_frames.collision_cover`). A controlled vehicle SUMO removes (say, it
left the network at the road's end) drives on in our model alone, as its reference does beyond
the road (a car frozen there stood in the way of the cars behind it as a ghost), counts as
finished, is left out of the collision checks, and the event is reported on stderr and in
:attr:`SumoSimulator.events`. The network's pedestrian crossings are read once at the start
(:meth:`SumoSimulator.crossings`), for the metrics.

**SUMO drives** (``SumoOptions.sumo_drives``, the ``sumo`` coordinator's mode): SUMO's own
car-following and lane-change models (LC2013; SL2015 with ``lateral_resolution`` > 0) move the
controlled vehicles instead of our model, and :meth:`SumoSimulator.step` ignores its inputs. A
placed vehicle is inserted as a SUMO user inserts one (``vehicle.add`` with the lane, lane
position and speed of its start state, the edge SUMO's ``convertRoad`` finds under its front),
with SUMO's default vType apart from our length and width; a routed one keeps SUMO's control from
its departure. Speed mode and lane-change mode stay SUMO's defaults and nothing moves them with
``moveToXY``. The experiment hands each vehicle its lanes (:class:`LaneOrder`,
:meth:`SumoSimulator.order_lanes`), asked with ``vehicle.changeLane`` once the vehicle has driven
far enough. Their states (pose and speed) are read from SUMO, and each step reports the inputs
that match SUMO's motion (:attr:`~aac_sumo.sim.base.ContactReport.applied`: the change of speed
over the step, and the steering angle whose yaw rate turns the heading as SUMO's angle turned),
so that the runner records what SUMO's driver did. A vehicle SUMO removes leaves the road.
"""

from __future__ import annotations

import math
import multiprocessing
import re
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aac_sumo.dynamics import FleetModel
from aac_sumo.network import VEHICLE_CLASS, sumo_binary
from aac_sumo.sim.base import ContactReport, Crossing, Simulator, agent_rows, footprint_contacts
from aac_sumo.sim.isolated import IsolatedSimulator
from aac_sumo.sim.sumo_frames import (
    body_from_sumo, collision_cover, crossing_from_sumo, lane_change_sweep, state_from_sumo, sumo_from_state,
    velocity_from_sumo,
)
from aac_sumo.world import Obstacle, RobotSpec, WorldState, parking_spot

ROUTE_ID = "aac_road"
#: How long [s] a lane SUMO's driver is asked to take (``vehicle.changeLane``) is held: the whole run.
LANE_HOLD = 1e6
#: netconvert's id of a pedestrian crossing's lane: ``:NODE_cK_0`` (walking areas are ``:NODE_wK_0``).
CROSSING_LANE = re.compile(r"^:.+_c\d+_\d+$")
#: The width [m] of the lanes a crossing crosses when no vehicle lane cuts its centre-line.
DEFAULT_LANE_WIDTH = 3.2


class SumoError(RuntimeError):
    """SUMO failed (start-up or mid-run); the message says what SUMO said and when."""


#: SUMO prints at most this many warnings of one kind, then a count (``--aggregate-warnings``),
#: unless ``sumo.extra_args`` sets it: a car SUMO thinks is braking too hard is warned about every
#: step (4,600 lines in one highway run). Its collisions are read through the API either way.
AGGREGATE_WARNINGS = 5
#: SUMO's own output files on request (``sumo.outputs``): name -> (option, file name).
OUTPUTS = {
    "fcd": ("--fcd-output", "fcd.xml"),
    "tripinfo": ("--tripinfo-output", "tripinfo.xml"),
    "collision": ("--collision-output", "collision.xml"),
    "summary": ("--summary-output", "summary.xml"),
    "lanechange": ("--lanechange-output", "lanechange.xml"),
}


@dataclass
class SumoOptions:
    """How to start SUMO: network, route files (cones, pedestrians, other traffic), the vTypes
    that are cones, GUI, SUMO's random seed, the GUI's delay, the folder ``output_dir`` of
    SUMO's own files (None: none), and which of ``OUTPUTS`` to write there. With a folder,
    SUMO's messages (warnings included) go to ``sumo.log`` in it; without one they are off. A
    user's ``config`` (.sumocfg) is loaded first and ``extra_args`` follow it; the options set
    here come last and apply.
    The GUI starts running at once and stays open when the run ends, until its window is closed."""

    net: Path
    routes: list[Path] = field(default_factory=list)
    cone_types: tuple[str, ...] = ("cone",)
    gui: bool = False
    seed: int = 0
    delay: float = 0.0  # sumo-gui's pause per simulation step [ms]
    output_dir: Path | None = None
    outputs: tuple[str, ...] = ()
    config: Path | None = None  # a user's .sumocfg, loaded first: ours override what it sets
    extra_args: tuple[str, ...] = ()  # more SUMO options, before ours
    lateral_resolution: float = 0.0  # SUMO's sublane model's lateral resolution [m]; 0: off (not set by us)
    sumo_drives: bool = False  # SUMO's own driver moves the controlled vehicles (see the module)

    def our_options(self, dt: float) -> dict[str, str]:
        """The SUMO options the co-simulation sets itself, name -> value."""
        return {"step-length": repr(dt), "seed": str(self.seed), "collision.action": "warn", "collision.mingap-factor": "0",
                "collision.check-junctions": "true", "intermodal-collision.action": "warn", "time-to-teleport": "-1",
                **({"lateral-resolution": repr(float(self.lateral_resolution))} if self.lateral_resolution > 0 else {})}

    def command(self, dt: float) -> list[str]:
        cmd = [sumo_binary("sumo-gui" if self.gui else "sumo")] + (["-c", str(self.config)] if self.config else [])
        cmd += list(self.extra_args) + ["-n", str(self.net)]
        for name, value in self.our_options(dt).items():
            cmd += [f"--{name}", value]
        cmd += ["--no-step-log", "--duration-log.disable"]
        cmd += ["--log", str(self.output_dir / "sumo.log")] if self.output_dir is not None else ["--no-warnings"]
        if self.output_dir is not None and "--aggregate-warnings" not in self.extra_args:
            cmd += ["--aggregate-warnings", str(AGGREGATE_WARNINGS)]
        if self.routes:
            cmd += ["-r", ",".join(str(p) for p in self.routes)]
        for name in self.outputs:
            option, filename = OUTPUTS[name]
            cmd += [option, str(self.output_dir / filename)]
        if self.gui:
            cmd += ["--start", "--delay", repr(float(self.delay))]
        return cmd


@dataclass(frozen=True)
class LaneOrder:
    """A lane SUMO's driver is asked to take once the vehicle has driven ``after`` metres since
    its departure (SUMO's odometer, ``vehicle.getDistance``): per edge id, that lane's SUMO index
    on the edge (lane counts and sidewalks may differ between edges). On an edge it does not
    name (a junction's internal lane) the last lane asked holds."""

    after: float
    lanes: dict[str, int]


#: sumo-gui colours (RGBA) of the controlled vehicles: plain, holding authority, in a safety stop.
PLAIN, AUTHORITY, SAFETY_STOP = (30, 120, 255, 255), (255, 200, 0, 255), (230, 20, 20, 255)


def _api(gui: bool):
    """libsumo (fast, in-process, no GUI) or traci (socket, drives sumo-gui)."""
    if gui:
        import traci

        return traci
    import libsumo

    return libsumo


class SumoSimulator(Simulator):
    """The :class:`Simulator` interface over a running SUMO: starts it, inserts ``robots`` at
    rear-axle ``states`` (n, 4) on the route ``edges``, and steps one period ``dt`` [s] at a time.
    World time 0 is the first SUMO step after insertion.

    The robots named in ``routed`` are vehicles of SUMO's own route files instead: they are not
    on the road (:attr:`WorldState.present`) until SUMO departs them, from then on ours (speed
    and lane-change mode 0, moved by our model), and off the road again once SUMO removes them
    (their route ended) or :meth:`retire` takes them out."""

    def __init__(self, robots: list[RobotSpec], states: np.ndarray, dt: float, edges: list[str], options: SumoOptions,
                 routed: frozenset[str] = frozenset()):
        self.robots = list(robots)
        self.states = np.array(states, dtype=float)
        self.dt = dt
        self.options = options
        self.api = _api(options.gui)
        self.routed = frozenset(routed)
        self.present = np.array([r.name not in self.routed for r in self.robots], dtype=bool)
        self.index = {r.name: i for i, r in enumerate(self.robots)}
        for i in np.flatnonzero(~self.present):
            self.states[i] = parking_spot(int(i))
        self.removed: set[str] = set()
        self.wrecked: set[str] = set()
        self.events: list[str] = []
        self._sim_pairs: set[tuple[str, str]] = set()
        self._obstacle_dims: dict[str, tuple[float, float, str]] = {}
        self._walkway_lanes: dict[str, float | None] = {}  # lane id -> its length [m] when only pedestrians may use it
        self.t = 0.0
        self.drives = options.sumo_drives
        self.orders: dict[int, list[LaneOrder]] = {}  # SUMO-driven vehicles' lanes, by robot index (order_lanes)
        self._asked: dict[int, int] = {}  # the lane index last asked of each, by robot index
        self._applied = np.zeros((len(self.robots), 2))
        self.model = FleetModel([r.model for r in self.robots])
        try:
            self.api.start(options.command(dt))
        except Exception as exc:
            raise SumoError(f"SUMO did not start ({_first_line(exc)}); command: {' '.join(options.command(dt))}") from None
        self._running = True
        try:
            with self._sumo_errors("inserting the controlled vehicles"):
                self._insert(edges)
                self.api.simulationStep()
                self.t0 = self.api.simulation.getTime()
                self._take_departed()
                missing = [r.name for r in self.robots if r.name not in self.routed and r.name not in set(self.api.vehicle.getIDList())]
                if missing:
                    raise SumoError(f"SUMO did not insert {', '.join(missing)} at its start pose")
                self._read_robots()
                self._bodies, self._obstacles = self._read_obstacles()
                self._crossings = self._read_crossings()
        except BaseException:
            self.close()
            raise

    def _insert(self, edges: list[str]) -> None:
        v = self.api.vehicle
        placed = [(i, robot) for i, robot in enumerate(self.robots) if robot.name not in self.routed]
        if placed:
            self.api.route.add(ROUTE_ID, edges)
        for i, robot in placed:
            vtype = f"aac_{robot.length:g}x{robot.width:g}"
            if vtype not in self.api.vehicletype.getIDList():
                self.api.vehicletype.copy("DEFAULT_VEHTYPE", vtype)
                self.api.vehicletype.setLength(vtype, robot.length)
                self.api.vehicletype.setWidth(vtype, robot.width)
                if not self.drives:  # SUMO's driver keeps its own standstill gap
                    self.api.vehicletype.setMinGap(vtype, 0.0)
                self.api.vehicletype.setColor(vtype, PLAIN)
            if self.drives:
                self._insert_driven(robot, self.states[i], edges, vtype)
                continue
            v.add(robot.name, ROUTE_ID, vtype, depart="now", departSpeed=repr(max(float(self.states[i, 3]), 0.0)))
            v.setSpeedMode(robot.name, 0)
            v.setLaneChangeMode(robot.name, 0)
            x, y, angle = sumo_from_state(self.states[i], robot.length, robot.model.wheelbase)
            v.moveToXY(robot.name, "", -1, x, y, angle, keepRoute=2)

    def _insert_driven(self, robot: RobotSpec, state: np.ndarray, edges: list[str], vtype: str) -> None:
        """Insert ``robot`` for SUMO's driver at ``state``: on the lane and lane position SUMO
        finds under its front bumper, at its speed, on the route from that edge on."""
        x, y, _ = sumo_from_state(state, robot.length, robot.model.wheelbase)
        edge, pos, lane = self.api.simulation.convertRoad(x, y, False, VEHICLE_CLASS)
        if edge not in edges:
            raise SumoError(f"{robot.name}'s start ({x:.1f}, {y:.1f}) lies on {edge or 'no edge'}, not on the road {' '.join(edges)}")
        route = ROUTE_ID if edge == edges[0] else f"{ROUTE_ID}@{edge}"
        if route not in self.api.route.getIDList():
            self.api.route.add(route, edges[edges.index(edge):])
        self.api.vehicle.add(robot.name, route, vtype, depart="now", departLane=str(lane), departPos=repr(float(pos)),
                             departSpeed=repr(float(state[3])))

    def limit_speed(self, i: int, speed: float) -> None:
        """SUMO's driver drives robot ``i`` at ``speed`` [m/s] at most (``vehicle.setMaxSpeed``;
        its desired speed is otherwise the lane's limit times its speed factor); only when SUMO drives."""
        if not self.drives:
            raise SumoError("speed limits for SUMO's driver need SUMO's own driver (SumoOptions.sumo_drives)")
        self.api.vehicle.setMaxSpeed(self.robots[i].name, float(speed))

    def order_lanes(self, i: int, orders: list[LaneOrder]) -> None:
        """The lanes SUMO's driver is to take with robot ``i`` (see :class:`LaneOrder`), in the
        order they come; only when SUMO drives."""
        if not self.drives:
            raise SumoError("lane orders need SUMO's own driver (SumoOptions.sumo_drives)")
        self.orders[i] = sorted(orders, key=lambda o: o.after)

    def _ask_lanes(self) -> None:
        """Ask SUMO's driver (``vehicle.changeLane``) for the lane of each vehicle's last order
        it has driven far enough for, on the edge it is on, when that differs from the last asked."""
        v = self.api.vehicle
        for i, orders in self.orders.items():
            name = self.robots[i].name
            if name in self.removed or not self.present[i]:
                continue
            distance = v.getDistance(name)
            due = [o for o in orders if o.after <= distance]
            if not due:
                continue
            lane = due[-1].lanes.get(v.getRoadID(name))
            if lane is not None and self._asked.get(i) != lane:
                v.changeLane(name, lane, LANE_HOLD)
                self._asked[i] = lane

    # -- reading -----------------------------------------------------------------------------

    def _note_removed(self) -> None:
        """Note every controlled vehicle SUMO no longer has: a routed one leaves the road, a
        placed one is reported once (it drives on in our model)."""
        present = set(self.api.vehicle.getIDList())
        for i, robot in enumerate(self.robots):
            if robot.name in self.removed or robot.name in present or not self.present[i]:
                continue
            self.removed.add(robot.name)
            if robot.name in self.routed or self.drives:
                self._park(i)
                continue
            event = f"t={self.t:.2f} s: SUMO removed controlled vehicle {robot.name}; it drives on off SUMO's road, counted finished"
            self.events.append(event)
            print(f"aac-sumo: warning: {event}", file=sys.stderr)

    def _park(self, i: int) -> None:
        self.present[i] = False
        self.states[i] = parking_spot(i)

    def _take_departed(self) -> None:
        """Make the routed vehicles SUMO departed in its last step ours, at the pose and speed
        SUMO gave them."""
        v = self.api.vehicle
        for vid in self.api.simulation.getDepartedIDList():
            i = self.index.get(vid)
            if i is None or vid not in self.routed or self.present[i] or vid in self.removed:
                continue
            if not self.drives:
                v.setSpeedMode(vid, 0)
                v.setLaneChangeMode(vid, 0)
            robot = self.robots[i]
            x, y = v.getPosition(vid)
            self.states[i] = state_from_sumo(x, y, v.getAngle(vid), v.getSpeed(vid), robot.length, robot.model.wheelbase)
            self.present[i] = True

    def retire(self, i: int) -> None:
        """Take routed robot ``i`` off the road: SUMO removes it, and it stands parked."""
        name = self.robots[i].name
        if name in self.removed or not self.present[i]:
            return
        with self._sumo_errors(f"removing {name}"):
            self.api.vehicle.remove(name)
        self.removed.add(name)
        self._park(i)

    def _read_robots(self) -> None:
        """Poses of the controlled vehicles after the last SUMO step; notice removed ones."""
        v = self.api.vehicle
        self._note_removed()
        for i, robot in enumerate(self.robots):
            if robot.name in self.removed or not self.present[i]:
                continue
            x, y = v.getPosition(robot.name)
            angle = v.getAngle(robot.name)
            if self.drives:
                self.states[i] = state_from_sumo(x, y, angle, v.getSpeed(robot.name), robot.length, robot.model.wheelbase)
            else:
                self.states[i, :3] = state_from_sumo(x, y, angle, 0.0, robot.length, robot.model.wheelbase)[:3]

    def _read_crossings(self) -> list[Crossing]:
        """The network's pedestrian crossings (lanes named as :data:`CROSSING_LANE` that
        pedestrians may use), each with the median width of the vehicle lanes (open to
        ``passenger``) whose centre-lines cut its centre-line, :data:`DEFAULT_LANE_WIDTH` if none."""
        lane = self.api.lane
        ids = lane.getIDList()
        found = [(i, np.array(lane.getShape(i), dtype=float)) for i in ids if CROSSING_LANE.match(i) and "pedestrian" in lane.getAllowed(i)]
        if not found:
            return []
        roads = [(np.array(lane.getShape(i), dtype=float), lane.getWidth(i)) for i in ids
                 if not CROSSING_LANE.match(i) and (not lane.getAllowed(i) or VEHICLE_CLASS in lane.getAllowed(i))]
        crossings = []
        for i, shape in found:
            widths = [w for road, w in roads if polylines_cross(shape, road)]
            crossings.append(crossing_from_sumo(i, shape, lane.getWidth(i), float(np.median(widths)) if widths else DEFAULT_LANE_WIDTH))
        return crossings

    def _dims(self, domain, oid: str) -> tuple[float, float, str]:
        if oid not in self._obstacle_dims:
            self._obstacle_dims[oid] = (domain.getLength(oid), domain.getWidth(oid), domain.getTypeID(oid))
        return self._obstacle_dims[oid]

    def _walkway(self, person: str) -> tuple[float, float] | None:
        """How far [m] the ends of the walkway ``person`` walks on lie from her (the lane's
        start and end), when her lane is one only pedestrians may use on a normal edge (a
        sidewalk or footpath, not a crossing or a walking area, whose ids start with ':');
        None otherwise."""
        lane = self.api.person.getLaneID(person)
        if not lane or lane.startswith(":"):
            return None
        if lane not in self._walkway_lanes:
            allowed = set(self.api.lane.getAllowed(lane))
            self._walkway_lanes[lane] = self.api.lane.getLength(lane) if allowed == {"pedestrian"} else None
        length = self._walkway_lanes[lane]
        if length is None:
            return None
        pos = self.api.person.getLanePosition(person)
        return (pos, length - pos)

    def _read_obstacles(self) -> tuple[list[Obstacle], list[Obstacle]]:
        """Every SUMO agent that is not ours: cones (vType in ``cone_types``), other vehicles
        (kind ``scripted``) and pedestrians, with their bodies (footprint centres from SUMO's
        front positions), and as the coordinators see them: a vehicle as the rectangle along its
        lane that also covers the box SUMO's collision check gives it
        (:func:`~aac_sumo.sim.sumo_frames.collision_cover`), and during a lane change also
        where that box goes until the change ends: a car changing lanes is seen in both lanes
        over its length for the whole change, moving along its lane. A body's velocity is its
        speed along its lane plus its lateral speed across it (SUMO's heading of a car changing
        lanes at a crawl is far from where it moves)."""
        bodies, seen = [], []
        ours = {r.name for r in self.robots}
        v = self.api.vehicle
        for domain, kind in ((v, None), (self.api.person, "pedestrian")):
            for oid in domain.getIDList():
                if oid in ours:
                    continue
                length, width, vtype = self._dims(domain, oid)
                x, y = domain.getPosition(oid)
                angle = domain.getAngle(oid)
                centre, heading = body_from_sumo(x, y, angle, length)
                obstacle_kind = kind or ("cone" if vtype in self.options.cone_types else "scripted")
                if obstacle_kind != "scripted":
                    walkway = self._walkway(oid) if kind == "pedestrian" else None
                    body = Obstacle(oid, obstacle_kind, centre, domain.getSpeed(oid) * np.array([math.cos(heading), math.sin(heading)]),
                                    heading, length, width, walkway=walkway)
                    bodies.append(body)
                    seen.append(body)
                    continue
                lane = v.getLaneID(oid)
                lane_angle = self.api.lane.getAngle(lane, v.getLanePosition(oid))
                speed, lateral = v.getSpeed(oid), v.getLateralSpeed(oid)
                bodies.append(Obstacle(oid, obstacle_kind, centre, velocity_from_sumo(speed, lateral, lane_angle), heading, length, width))
                sweep = lane_change_sweep(lateral, v.getLateralLanePosition(oid), self.api.lane.getWidth(lane)) if lateral else 0.0
                centre, heading, length, width = collision_cover(x, y, angle, lane_angle, length, width, sweep)
                seen.append(Obstacle(oid, obstacle_kind, centre, velocity_from_sumo(speed, 0.0, lane_angle), heading, length, width))
        return bodies, seen

    # -- the Simulator interface -------------------------------------------------------------

    def observe(self) -> WorldState:
        return WorldState(self.t, self.states.copy(), self.robots, list(self._obstacles), self.present.copy())

    def step(self, inputs: np.ndarray) -> ContactReport:
        inputs = np.asarray(inputs, dtype=float)
        with self._sumo_errors("stepping"):
            self._note_removed()  # removed since the last step (by another TraCI client, say)
            before = self.states.copy()
            if self.drives:
                self._ask_lanes()
            else:
                moving = np.array([r.name not in self.wrecked for r in self.robots], dtype=bool) & self.present
                self.states[moving] = self.model.step(self.states, inputs, self.dt)[moving]
            for i, robot in enumerate(self.robots):
                if self.drives or robot.name in self.removed or not self.present[i]:
                    continue
                x, y, angle = sumo_from_state(self.states[i], robot.length, robot.model.wheelbase)
                self.api.vehicle.moveToXY(robot.name, "", -1, x, y, angle, keepRoute=2)
                self.api.vehicle.setPreviousSpeed(robot.name, float(self.states[i, 3]))
            self.api.simulationStep()
            self.t = self.api.simulation.getTime() - self.t0
            self._take_departed()
            self._read_robots()
            if self.drives:
                self._applied = applied_inputs(before, self.states, self.dt, np.array([r.model.wheelbase for r in self.robots]))
            self._bodies, self._obstacles = self._read_obstacles()
            sim_pairs = self._sim_collision_pairs()
        report = self._contacts()
        self.wrecked.update(name for pair in report.overlaps for name in pair if name in {r.name for r in self.robots})
        for i, robot in enumerate(self.robots):
            if robot.name in self.wrecked and not self.drives:  # SUMO's driver drives on: its collisions are counted, no more
                self.states[i, 3] = 0.0
        if self.drives:
            report.applied = self._applied.copy()
        report.sim_collisions = len(sim_pairs - self._sim_pairs)
        self._sim_pairs = sim_pairs
        return report

    def _sim_collision_pairs(self) -> set[tuple[str, str]]:
        """SUMO's collisions this step that involve a controlled vehicle, as sorted name pairs."""
        ours = {r.name for r in self.robots}
        return {tuple(sorted((c.collider, c.victim))) for c in self.api.simulation.getCollisions()
                if c.collider in ours or c.victim in ours}

    def _contacts(self) -> ContactReport:
        """Our footprint check on the bodies, leaving out removed vehicles (their clearance is inf)."""
        keep = [i for i, r in enumerate(self.robots) if r.name not in self.removed and self.present[i]]
        world = WorldState(self.t, self.states[keep], [self.robots[i] for i in keep], self._bodies)
        partial = footprint_contacts(world)
        clearance = np.full(len(self.robots), np.inf)
        clearance[keep] = partial.clearance
        return ContactReport(clearance, partial.overlaps)

    def agents(self) -> list[dict]:
        """The agents' bodies (not the collision covers the coordinators see)."""
        return agent_rows(WorldState(self.t, self.states.copy(), self.robots, list(self._bodies), self.present.copy()))

    def crossings(self) -> list[Crossing]:
        """The network's pedestrian crossings, read once at the start (:meth:`_read_crossings`)."""
        return list(self._crossings)

    def show(self, authority: set[str], stopped: set[str]) -> None:
        """In sumo-gui, colour the authority vehicles gold and those in a safety stop red."""
        if not self.options.gui:
            return
        shown = getattr(self, "_shown", {})
        for robot, here in zip(self.robots, self.present):
            colour = SAFETY_STOP if robot.name in stopped else AUTHORITY if robot.name in authority else PLAIN
            if shown.get(robot.name, PLAIN) != colour and robot.name not in self.removed and here:
                self.api.vehicle.setColor(robot.name, colour)
                shown[robot.name] = colour
        self._shown = shown

    def close(self) -> None:
        if getattr(self, "_running", False):
            self._running = False
            if self.options.gui:
                print("aac-sumo: the run has ended; close the sumo-gui window to finish", file=sys.stderr, flush=True)
            try:
                self.api.close()  # traci waits for sumo-gui to exit
            except Exception:  # SUMO already gone; nothing left to release
                pass

    @contextmanager
    def _sumo_errors(self, doing: str):
        """Turn any libsumo/traci exception into one ``SumoError`` line naming the world time."""
        try:
            yield
        except SumoError:
            raise
        except Exception as exc:
            raise SumoError(f"SUMO failed while {doing} at t={self.t:.2f} s: {_first_line(exc)}") from exc


def sumo_simulator(robots: list[RobotSpec], states: np.ndarray, dt: float, edges: list[str], options: SumoOptions,
                   isolate: bool = True, routed: frozenset[str] = frozenset()) -> Simulator:
    """A :class:`SumoSimulator` (arguments as its own), with ``isolate`` in a process of its own
    (:class:`~aac_sumo.sim.isolated.IsolatedSimulator`), so that a SUMO crash ends in a
    :class:`SumoError` instead of ending the run. sumo-gui is a process of its own already and
    runs in-process, as does every run from a daemonic process (a Dask worker), which may not
    start children."""
    if isolate and not options.gui and not multiprocessing.current_process().daemon:
        return IsolatedSimulator(SumoSimulator, (robots, states, dt, edges, options, routed), name="SUMO", error=SumoError,
                                 mirror=("t", "dt", "removed", "events"))
    return SumoSimulator(robots, states, dt, edges, options, routed)


#: The steering angle [rad] the inputs :func:`applied_inputs` reports stay within (a lane change
#: SUMO makes in one step turns no heading; a car turning on the spot would need 90 degrees).
APPLIED_STEER_MAX = 1.5


def applied_inputs(before: np.ndarray, after: np.ndarray, dt: float, wheelbase: np.ndarray) -> np.ndarray:
    """The inputs ``[accel, steer]`` (n, 2) of the bicycle model that match a step of ``dt`` [s]
    from states ``before`` to ``after`` (n, 4) SUMO's driver made: the change of speed over the
    step, and the steering angle whose yaw rate ``v tan(steer) / wheelbase`` at the speed before
    turns the heading as it turned (0 below 0.1 m/s; within ``APPLIED_STEER_MAX``)."""
    accel = (after[:, 3] - before[:, 3]) / dt
    turn = np.angle(np.exp(1j * (after[:, 2] - before[:, 2]))) / dt
    v = before[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        steer = np.where(np.abs(v) > 0.1, np.arctan(wheelbase * turn / np.where(np.abs(v) > 0.1, v, 1.0)), 0.0)
    return np.column_stack([accel, np.clip(steer, -APPLIED_STEER_MAX, APPLIED_STEER_MAX)])


def polylines_cross(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether polylines ``a`` (m, 2) and ``b`` (k, 2) [m] intersect (a segment of each meets
    one of the other, touching included)."""
    if len(a) < 2 or len(b) < 2 or np.any(a.min(axis=0) > b.max(axis=0)) or np.any(b.min(axis=0) > a.max(axis=0)):
        return False
    p, r = a[:-1, None, :], (a[1:] - a[:-1])[:, None, :]
    q, s = b[None, :-1, :], (b[1:] - b[:-1])[None, :, :]
    cross = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
    d = q - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (d[..., 0] * s[..., 1] - d[..., 1] * s[..., 0]) / cross
        u = (d[..., 0] * r[..., 1] - d[..., 1] * r[..., 0]) / cross
    return bool(np.any((cross != 0) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)))


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
