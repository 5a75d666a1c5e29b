"""SUMO co-simulation through libsumo (traci when the GUI is shown).

SUMO hosts the world: the network, cones (stopped vehicles of a cone vType), pedestrians and any
other traffic, which SUMO moves itself. Our controlled vehicles are inserted with speed mode and
lane-change mode 0 and, every step, placed at the pose our bicycle model reached with
``vehicle.moveToXY(..., keepRoute=2)``; their poses are then read back from SUMO. Their speed is
our model's: with each move SUMO is given the speed the model reached (``vehicle.setSpeed`` in the
same step), so that SUMO's speed of the car (``vehicle.getSpeed``, ``fcd.xml``, what its own cars
follow) is ours at every step, and its acceleration ours. Without it SUMO derives the speed from
the distance moved along the lane, the speed of the step before (our model moves a car over a
step at the speed it had at the step's start), less when it drives at an angle to the lane; and
``vehicle.setPreviousSpeed``, which this replaced, changed nothing SUMO reports after the step
but its acceleration, with the wrong sign.

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

**SUMO drives** (:attr:`~aac_sumo.sim.sumo_options.SumoOptions.sumo_drives`, the ``sumo`` coordinator's mode): SUMO's own
car-following and lane-change models (LC2013; SL2015 with ``lateral_resolution`` > 0) move the
controlled vehicles instead of our model, and :meth:`SumoSimulator.step` ignores its inputs. A
placed vehicle is inserted as a SUMO user inserts one (``vehicle.add`` with the lane, lane
position and speed of its start state, the edge SUMO's ``convertRoad`` finds under its front),
with SUMO's default vType apart from our length and width; a routed one keeps SUMO's control from
its departure. Speed mode and lane-change mode stay SUMO's defaults and nothing moves them with
``moveToXY``. The experiment hands each vehicle its lanes (:class:`~aac_sumo.sim.sumo_options.LaneOrder`,
:meth:`SumoSimulator.order_lanes`), asked with ``vehicle.changeLane`` once the vehicle has driven
far enough. Their states (pose and speed) are read from SUMO, and each step reports the inputs
that match SUMO's motion (:attr:`~aac_sumo.sim.base.ContactReport.applied`: the change of speed
over the step, and the steering angle whose yaw rate turns the heading as SUMO's angle turned),
so that the runner records what SUMO's driver did. A vehicle SUMO removes leaves the road.
"""

from __future__ import annotations

import contextlib
import io
import multiprocessing
import subprocess
import sys
import tempfile

import numpy as np

from aac_sumo.dynamics import FleetModel
from aac_sumo.network import VEHICLE_CLASS
from aac_sumo.sim.base import ContactReport, Crossing, Simulator, agent_rows, footprint_contacts
from aac_sumo.sim.isolated import IsolatedSimulator
from aac_sumo.sim.sumo_frames import applied_inputs, sumo_from_state
from aac_sumo.sim.sumo_options import LaneOrder, SumoError, SumoOptions
from aac_sumo.sim.sumo_reading import SumoReading
from aac_sumo.world import RobotSpec, WorldState, parking_spot

ROUTE_ID = "aac_road"
#: TraCI's reasons for ``vehicle.remove`` (traci.constants): arrived at its destination, vaporized.
REMOVE_ARRIVED, REMOVE_VAPORIZED = 2, 3
#: How long [s] a lane SUMO's driver is asked to take (``vehicle.changeLane``) is held: the whole run.
LANE_HOLD = 1e6


#: sumo-gui colours (RGBA) of the controlled vehicles: plain, holding authority, in a safety stop.
PLAIN, AUTHORITY, SAFETY_STOP = (30, 120, 255, 255), (255, 200, 0, 255), (230, 20, 20, 255)


def _api(gui: bool):
    """libsumo (fast, in-process, no GUI) or traci (socket, drives sumo-gui)."""
    if gui:
        import traci

        return traci
    import libsumo

    return libsumo


class SumoSimulator(SumoReading, Simulator):
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
        self.arrived: set[str] = set()  # SUMO took them as arrived (arrive); they drive on, on our road
        self.wrecked: set[str] = set()
        self.events: list[str] = []
        self._sim_pairs: set[tuple[str, str]] = set()
        self._obstacle_dims: dict[str, tuple[float, float, str]] = {}
        self._walkway_lanes: dict[str, float | None] = {}  # lane id -> its length [m] when only pedestrians may use it
        self._lane_shapes: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # lane id -> its centre-line points and their arc lengths
        self.t = 0.0
        self.drives = options.sumo_drives
        self.orders: dict[int, list[LaneOrder]] = {}  # SUMO-driven vehicles' lanes, by robot index (order_lanes)
        self._asked: dict[int, int] = {}  # the lane index last asked of each, by robot index
        self._applied = np.zeros((len(self.robots), 2))
        self.model = FleetModel([r.model for r in self.robots])
        try:
            if options.gui:
                _start_gui(self.api, options.command(dt))
            else:
                self.api.start(options.command(dt))
        except Exception as exc:
            raise SumoError(f"SUMO did not start ({_first_line(exc)}); command: {' '.join(options.command(dt))}") from None
        self._running = True
        try:
            with self._sumo_errors("inserting the controlled vehicles"):
                self._declare_types()
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
            self._make_ours(i)
            x, y, angle = sumo_from_state(self.states[i], robot.length, robot.model.wheelbase)
            v.moveToXY(robot.name, "", -1, x, y, angle, keepRoute=2)

    def _make_ours(self, i: int) -> None:
        """Robot ``i``'s SUMO vehicle moves as our model moves it: speed and lane-change mode 0
        (and, with ``declared_decel``, that deceleration as its vType's ``decel``),
        and a speed SUMO allows it on every car lane of the network at least its top speed
        ``v_max``: its maximum speed and speed factor are raised where they fall short (the
        slowest lane's limit times the speed factor). SUMO caps the speed it derives from a
        ``moveToXY`` move at that allowed speed, so that a car crossing onto a slower lane
        (the highway's work zone) was slowed there in SUMO's eyes alone: fcd.xml showed 12.49
        m/s where it drove 16, and SUMO warned of emergency braking every step."""
        name, v = self.robots[i].name, self.api.vehicle
        v.setSpeedMode(name, 0)
        v.setLaneChangeMode(name, 0)
        if self.options.declared_decel > 0.0:
            v.setDecel(name, self.options.declared_decel)
        top = float(self.robots[i].model.limits.v_max)
        if v.getMaxSpeed(name) < top:
            v.setMaxSpeed(name, top)
        factor = top / self._slowest_limit()
        if v.getSpeedFactor(name) < factor:
            v.setSpeedFactor(name, factor)

    def _slowest_limit(self) -> float:
        """The lowest speed limit [m/s] of the network's lanes open to cars (junctions'
        internal lanes included), read once."""
        if getattr(self, "_slowest", None) is None:
            lane = self.api.lane
            limits = [lane.getMaxSpeed(k) for k in lane.getIDList() if not lane.getAllowed(k) or VEHICLE_CLASS in lane.getAllowed(k)]
            self._slowest = max(min(limits, default=1.0), 0.1)
        return self._slowest

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
        """The lanes SUMO's driver is to take with robot ``i`` (see :class:`~aac_sumo.sim.sumo_options.LaneOrder`), in the
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

    def retire(self, i: int, arrived: bool = False) -> None:
        """Take robot ``i`` off the road: SUMO removes it (as arrived at its destination when
        ``arrived``, so that SUMO's tripinfo lists its trip; else as vaporized), unless it took
        it as arrived already (:meth:`arrive`), and it stands parked."""
        name = self.robots[i].name
        if name in self.removed or not self.present[i]:
            return
        if name not in self.arrived:
            with self._sumo_errors(f"removing {name}"):
                self.api.vehicle.remove(name, REMOVE_ARRIVED if arrived else REMOVE_VAPORIZED)
        self.removed.add(name)
        self._park(i)

    def arrive(self, i: int) -> None:
        """Robot ``i`` has finished its task: SUMO removes it as arrived at its destination now
        (its ``tripinfo`` trip ends at this time, where it stands), and our model drives it on, on
        our road, where the coordinators and our footprint check still see it, until
        :meth:`retire` parks it. SUMO no longer has it: its own cars, walkers and collision
        check no longer see it, and ``fcd.xml`` ends its track here. Only for a car we move
        (not under SUMO's driver)."""
        name = self.robots[i].name
        if self.drives:
            raise SumoError("arrive moves SUMO's idea of a car we drive; SUMO's own driver arrives by its route")
        if name in self.removed or name in self.arrived or not self.present[i]:
            return
        with self._sumo_errors(f"removing {name} as arrived"):
            self.api.vehicle.remove(name, REMOVE_ARRIVED)
        self.arrived.add(name)

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
                if self.drives or robot.name in self.removed or robot.name in self.arrived or not self.present[i]:
                    continue
                x, y, angle = sumo_from_state(self.states[i], robot.length, robot.model.wheelbase)
                self.api.vehicle.moveToXY(robot.name, "", -1, x, y, angle, keepRoute=2)
                self.api.vehicle.setSpeed(robot.name, max(float(self.states[i, 3]), 0.0))  # SUMO's speed: ours (below)
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
            if shown.get(robot.name, PLAIN) != colour and robot.name not in self.removed | self.arrived and here:
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

    @contextlib.contextmanager
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
                                 mirror=("t", "dt", "removed", "arrived", "events"))
    return SumoSimulator(robots, states, dt, edges, options, routed)


def _start_gui(traci, cmd: list[str]) -> None:
    """Start sumo-gui (``cmd``) and connect traci to it, as ``traci.start`` does, but with its
    messages in a file and traci's retries silent: when sumo-gui exits before it answers (no
    display it can open), raise at once with its first message. ``traci.start`` tried 60
    ports in a row, each a new sumo-gui, for a minute and 240 lines of retries."""
    with tempfile.TemporaryFile() as messages:
        proc = subprocess.Popen(cmd + ["--remote-port", str(traci.getFreeSocketPort())], stderr=messages)
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # traci's "Retrying in 1 seconds" while sumo-gui loads
                traci.init(int(proc.args[-1]), proc=proc)
        except Exception as exc:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
            messages.seek(0)
            said = [line.strip() for line in messages.read().decode(errors="replace").splitlines() if line.strip()]
            raise RuntimeError(said[0] if said else f"sumo-gui exited ({_first_line(exc)})") from None


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
