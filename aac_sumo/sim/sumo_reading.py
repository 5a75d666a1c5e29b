"""What the SUMO co-simulation (:class:`~aac_sumo.sim.sumo.SumoSimulator`) reads back from SUMO
after each step: the controlled vehicles SUMO departed or removed and their poses, the agents that
are not ours as obstacles, and the network's pedestrian crossings."""

from __future__ import annotations

import math
import re
import sys

import numpy as np

from aac_sumo.network import VEHICLE_CLASS
from aac_sumo.sim.base import Crossing
from aac_sumo.sim.sumo_frames import (BLINKER_LEFT, BLINKER_RIGHT, angle_as_sumo_keeps, body_from_sumo, collision_cover, crossing_from_sumo,
                                      lane_change_sweep, lane_direction, signalled_sweep, state_from_sumo, sumo_from_state, velocity_from_sumo)
from aac_sumo.world import Obstacle, parking_spot


#: netconvert's id of a pedestrian crossing's lane: ``:NODE_cK_0`` (walking areas are ``:NODE_wK_0``).
CROSSING_LANE = re.compile(r"^:.+_c\d+_\d+$")


#: The width [m] of the lanes a crossing crosses when no vehicle lane cuts its centre-line.
DEFAULT_LANE_WIDTH = 3.2
#: A SUMO vehicle's course (:attr:`~aac_sumo.world.Obstacle.course`) reaches this far [m] beyond
#: where it could stop braking at COURSE_DECEL [m/s^2] (gentler than any braking course's).
COURSE_REACH = 10.0
COURSE_DECEL = 1.0


class SumoReading:
    """The reading half of :class:`~aac_sumo.sim.sumo.SumoSimulator`, which sets the attributes
    it uses: ``api`` (libsumo or traci), ``robots``, ``states``, ``present``, ``index``,
    ``routed``, ``removed``, ``arrived``, ``drives``, ``events``, ``t``, ``options`` and the caches
    ``_obstacle_dims``, ``_walkway_lanes`` and ``_lane_shapes``, and the method ``_make_ours`` (speed modes and allowed speed of a car we move)."""

    def _note_removed(self) -> None:
        """Note every controlled vehicle SUMO no longer has: a routed one leaves the road, a
        placed one is reported once (it drives on in our model)."""
        present = set(self.api.vehicle.getIDList())
        for i, robot in enumerate(self.robots):
            if robot.name in self.removed or robot.name in self.arrived or robot.name in present or not self.present[i]:
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

    def _declare_types(self) -> None:
        """With ``declared_decel``, SUMO's vTypes of the controlled cars of its routes
        (``declared_types``) brake at it before SUMO inserts any of them: ``departSpeed="max"``
        then inserts a car no faster than it can stop at that deceleration behind what stands
        ahead, as every car brakes once ours (``_make_ours``); and each car of
        ``insertion_speeds`` is inserted no faster than its speed there (:meth:`_cap_insertions`).
        Not when SUMO drives them (the baseline keeps its vType)."""
        declared = not self.drives and self.options.declared_decel > 0.0
        self._uncapped = dict(self.options.insertion_speeds) if declared else {}
        if not declared:
            return
        known = set(self.api.vehicletype.getIDList())
        for vtype in self.options.declared_types:
            if vtype in known:
                self.api.vehicletype.setDecel(vtype, self.options.declared_decel)
        self._cap_insertions()

    def _cap_insertions(self) -> None:
        """Each controlled vehicle of ``insertion_speeds`` that SUMO has loaded and not yet
        departed gets its speed there as its maximum speed (``vehicle.setMaxSpeed``), so that
        ``departSpeed="max"`` inserts it no faster; :meth:`_make_ours` raises it again once it
        departs. SUMO loads route files ahead of their departures (``--route-steps``); a vehicle
        loaded in the step it departs keeps its speed."""
        if not self._uncapped:
            return
        v = self.api.vehicle
        for vid in sorted(set(self._uncapped) & set(v.getLoadedIDList())):
            v.setMaxSpeed(vid, min(self._uncapped.pop(vid), v.getMaxSpeed(vid)))

    def _take_departed(self) -> None:
        """Make the routed vehicles SUMO departed in its last step ours, at the pose and speed
        SUMO gave them (the others it has loaded since are capped, :meth:`_cap_insertions`)."""
        v = self.api.vehicle
        departed = self.api.simulation.getDepartedIDList()
        for vid in departed:
            self._uncapped.pop(vid, None)
        self._cap_insertions()
        for vid in departed:
            i = self.index.get(vid)
            if i is None or vid not in self.routed or self.present[i] or vid in self.removed:
                continue
            if not self.drives:
                self._make_ours(i)
            robot = self.robots[i]
            x, y = v.getPosition(vid)
            self.states[i] = state_from_sumo(x, y, v.getAngle(vid), v.getSpeed(vid), robot.length, robot.model.wheelbase)
            self.present[i] = True

    def _read_robots(self) -> None:
        """Poses of the controlled vehicles after the last SUMO step; notice removed ones. A car
        SUMO took as arrived (``arrived``) has the pose our model gave it, as SUMO would have
        read it back (:func:`~aac_sumo.sim.sumo_frames.angle_as_sumo_keeps`)."""
        v = self.api.vehicle
        self._note_removed()
        for i, robot in enumerate(self.robots):
            if robot.name in self.arrived and robot.name not in self.removed and self.present[i]:
                x, y, angle = sumo_from_state(self.states[i], robot.length, robot.model.wheelbase)
                self.states[i, :3] = state_from_sumo(x, y, angle_as_sumo_keeps(angle), 0.0, robot.length, robot.model.wheelbase)[:3]
                continue
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
        where that box goes until the change ends (before one, where its blinker signals it would
        go: :attr:`~aac_sumo.world.Obstacle.signalled`): a car changing lanes is seen in both lanes
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
                pos = v.getLanePosition(oid)
                lane_angle = lane_direction(*self._shape(lane), pos, length, self.api.lane.getAngle(lane, pos))
                speed, lateral = v.getSpeed(oid), v.getLateralSpeed(oid)
                bodies.append(Obstacle(oid, obstacle_kind, centre, velocity_from_sumo(speed, lateral, lane_angle), heading, length, width))
                sweep = lane_change_sweep(lateral, v.getLateralLanePosition(oid), self.api.lane.getWidth(lane)) if lateral else 0.0
                signalled = 0.0 if lateral else self._signalled(oid, lane)
                wish = None
                if signalled:
                    wish_centre, wish_heading, wish_length, wish_width = collision_cover(x, y, angle, lane_angle, length, width, signalled)
                    wish = np.array([*wish_centre, wish_length, wish_width, wish_heading])
                centre, heading, length, width = collision_cover(x, y, angle, lane_angle, length, width, sweep)
                course = None if lateral else self._course(oid, lane, pos, centre, speed)  # changing lanes: straight on
                seen.append(Obstacle(oid, obstacle_kind, centre, velocity_from_sumo(speed, 0.0, lane_angle), heading, length, width,
                                     signalled=wish, course=course))
        return bodies, seen

    def _shape(self, lane: str) -> tuple[np.ndarray, np.ndarray]:
        """Centre-line points (M, 2) [m] of ``lane`` and their arc lengths (M,) [m], cached."""
        if lane not in self._lane_shapes:
            shape = np.asarray(self.api.lane.getShape(lane), dtype=float)[:, :2]
            self._lane_shapes[lane] = (shape, np.r_[0.0, np.cumsum(np.hypot(*np.diff(shape, axis=0).T))])
        return self._lane_shapes[lane]

    def _course(self, oid: str, lane: str, pos: float, centre: np.ndarray, speed: float) -> np.ndarray:
        """:attr:`~aac_sumo.world.Obstacle.course` of SUMO's vehicle ``oid``, whose front is at
        ``pos`` [m] along ``lane`` and whose footprint centre is ``centre``: from the centre
        to its lane's centre-line points ahead of its front, then the junction's internal lane and
        the next lane of each of its upcoming links (``vehicle.getNextLinks``), until the course
        runs COURSE_REACH [m] beyond where it could stop from ``speed`` [m/s] at COURSE_DECEL."""
        reach = COURSE_REACH + speed**2 / (2.0 * COURSE_DECEL)
        shape, arc = self._shape(lane)
        ahead = shape[arc > pos]
        parts, run = [np.asarray(centre, dtype=float)[None, :], ahead], float(arc[-1] - pos)
        for link in self.api.vehicle.getNextLinks(oid) if run < reach else ():
            for nxt in (link[4], link[0]):  # the internal lane through the junction, then the lane it leads to
                if nxt:
                    shape, arc = self._shape(nxt)
                    parts.append(shape)
                    run += float(arc[-1])
            if run >= reach:
                break
        return np.vstack(parts)

    def _signalled(self, oid: str, lane: str) -> float:
        """:func:`~aac_sumo.sim.sumo_frames.signalled_sweep` of SUMO's vehicle ``oid`` on ``lane``."""
        v, signals = self.api.vehicle, self.api.vehicle.getSignals(oid)
        if not signals & (BLINKER_LEFT | BLINKER_RIGHT):
            return 0.0
        index, count = v.getLaneIndex(oid), self.api.edge.getLaneNumber(v.getRoadID(oid))
        return signalled_sweep(signals, v.getLateralLanePosition(oid), self.api.lane.getWidth(lane), index, count - 1 - index)

    def signal_states(self, ids: tuple[str, ...]) -> dict[str, str]:
        """Each traffic light of ``ids``: its link states now, SUMO's string (one character per
        link index: ``G``/``g`` green, ``y`` yellow, ``r`` red, ...)."""
        with self._sumo_errors("reading the traffic lights"):
            return {tls: self.api.trafficlight.getRedYellowGreenState(tls) for tls in ids}

    def signal_phases(self, ids: tuple[str, ...]) -> dict[str, tuple[str, int, float]]:
        """Each traffic light of ``ids``: its program's id, the index of its phase now and the time
        [s] until that phase ends."""
        with self._sumo_errors("reading the traffic lights"):
            tl, now = self.api.trafficlight, self.api.simulation.getTime()
            return {tls: (tl.getProgram(tls), tl.getPhase(tls), tl.getNextSwitch(tls) - now) for tls in ids}

    def lane_vehicles(self, lanes: tuple[str, ...]) -> dict[str, list[tuple[str, float, float]]]:
        """Each lane of ``lanes``: its vehicles now, ``(id, lane position of the front [m], speed [m/s])``."""
        with self._sumo_errors("reading the vehicles at the junctions"):
            v = self.api.vehicle
            return {lane: [(vid, v.getLanePosition(vid), v.getSpeed(vid)) for vid in self.api.lane.getLastStepVehicleIDs(lane)]
                    for lane in lanes}


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
