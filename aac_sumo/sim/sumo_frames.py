"""The one conversion between SUMO's poses and ours: a vehicle's rear-axle state, an agent's
footprint, and the room SUMO's collision check gives a vehicle.

SUMO places a vehicle by its front-bumper centre ``(x, y)`` [m] and its angle in navigational
degrees (0 = north, clockwise). We use the rear-axle midpoint and the heading [rad]
counter-clockwise from +x. With equal overhangs the rear axle lies ``(length + wheelbase) / 2``
behind the front bumper along the heading.
"""

from __future__ import annotations

import math

import numpy as np

from aac_sumo.geometry import along
from aac_sumo.sim.base import Crossing


def bumper_to_axle(length: float, wheelbase: float) -> float:
    """Distance [m] from the rear-axle midpoint forward to the front-bumper centre."""
    return 0.5 * (length + wheelbase)


def state_from_sumo(x: float, y: float, angle_deg: float, speed: float, length: float, wheelbase: float) -> np.ndarray:
    """Our state ``[x, y, heading, v]`` (rear axle, heading in (-pi, pi]) from a SUMO pose."""
    heading = heading_from_sumo(angle_deg)
    back = bumper_to_axle(length, wheelbase)
    return np.array([x - back * math.cos(heading), y - back * math.sin(heading), heading, speed])


def sumo_from_state(state, length: float, wheelbase: float) -> tuple[float, float, float]:
    """SUMO pose ``(x, y, angle_deg)`` (front bumper, navigational degrees in [0, 360)) of ``state``."""
    x, y, heading = float(state[0]), float(state[1]), float(state[2])
    ahead = bumper_to_axle(length, wheelbase)
    angle = (90.0 - math.degrees(heading)) % 360.0
    return x + ahead * math.cos(heading), y + ahead * math.sin(heading), angle


def angle_as_sumo_keeps(angle_deg: float) -> float:
    """The angle [navigational degrees, in [0, 360)] SUMO reports (``vehicle.getAngle``) for a
    vehicle placed at ``angle_deg`` (``moveToXY``): it keeps a vehicle's angle in radians
    (``GeomHelper::fromNaviDegree``) and turns it back into degrees (``GeomHelper::naviDegree``),
    which may change its last bit. For a car SUMO no longer has (it took it as arrived) this is
    the pose it would have read back: the run stays bit for bit the one it was with the car in
    SUMO (``tests/test_sumo_frames.py`` checks it against libsumo)."""
    radians = math.pi / 2.0 - angle_deg * math.pi / 180.0
    degrees = (math.pi / 2.0 - radians) * 180.0 / math.pi
    if degrees < 0.0:
        degrees += 360.0
    elif degrees >= 360.0:
        degrees -= 360.0
    return degrees


def heading_from_sumo(angle_deg: float) -> float:
    """Heading [rad] counter-clockwise from +x, in (-pi, pi], of a SUMO angle (navigational degrees)."""
    return math.atan2(math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg)))


def body_from_sumo(x: float, y: float, angle_deg: float, length: float) -> tuple[np.ndarray, float]:
    """Footprint centre ``(cx, cy)`` [m] and heading [rad] of a body SUMO places by its front
    ``(x, y)`` and ``angle_deg`` (half its length behind the front, along its heading)."""
    heading = heading_from_sumo(angle_deg)
    return np.array([x - 0.5 * length * math.cos(heading), y - 0.5 * length * math.sin(heading)]), heading


def collision_cover(x: float, y: float, angle_deg: float, lane_angle_deg: float, length: float, width: float,
                    sweep: float = 0.0) -> tuple[np.ndarray, float, float, float]:
    """The smallest rectangle along the vehicle's lane that covers both its body and the box
    SUMO's collision check gives it, now and ``sweep`` [m] further across its lane (positive to
    the left: where a lane change under way takes its front, :func:`lane_change_sweep`):
    ``(centre (2,) [m], heading [rad], length, width [m])``.

    With lateral dynamics (a continuous lane change, ``--lanechange.duration`` > 0, or the
    sublane model) SUMO checks two vehicles on a lane as boxes along the lane: from the front
    bumper's lane position back by the vehicle's length, and across it the vehicle's width
    centred on the front's lateral position, whatever the vehicle's angle (``MSLane``'s
    collision check; tests/test_sumo.py reproduces it). A car pulling out at an angle thus
    counts with its rear already where its front is, in the lane it moves into. Its body and
    that box coincide when it drives along its lane (``angle_deg == lane_angle_deg``); with
    ``sweep``, a car changing lanes is in both lanes over its length until its change ends.
    """
    heading, lane = heading_from_sumo(angle_deg), heading_from_sumo(lane_angle_deg)
    delta = heading - lane  # the body's angle to the lane
    c, s = math.cos(delta), math.sin(delta)
    half = 0.5 * width
    # corners in the lane's frame (along, across) relative to the front bumper's centre
    along = [0.0, 0.0, -length, -length, half * s, -half * s, -length * c + half * s, -length * c - half * s]
    across = [half, -half, half, -half, -half * c, half * c, -length * s - half * c, -length * s + half * c, sweep + half, sweep - half]
    lo_a, hi_a, lo_c, hi_c = min(along), max(along), min(across), max(across)
    mid_a, mid_c = 0.5 * (lo_a + hi_a), 0.5 * (lo_c + hi_c)
    cl, sl = math.cos(lane), math.sin(lane)
    centre = np.array([x + mid_a * cl - mid_c * sl, y + mid_a * sl + mid_c * cl])
    return centre, lane, hi_a - lo_a, hi_c - lo_c


def lane_direction(shape: np.ndarray, arc: np.ndarray, pos: float, length: float, tangent_deg: float) -> float:
    """The direction [navigational degrees] of a lane under a vehicle ``length`` [m] long whose
    front is ``pos`` [m] along it (``shape`` (M, 2) [m], the lane's centre-line points at arc
    lengths ``arc`` (M,) [m]): the lane's tangent at the front, ``tangent_deg``, where it runs
    straight under the vehicle, else the chord from the vehicle's back (its length behind the
    front along the lane, carried back along the first segment before the lane's start) to its
    front. SUMO gives a car following a curved lane the chord's angle (front to back,
    ``MSVehicle::computeAngle``) and checks it on the lane as a band along the lane: against the
    tangent, a car turning a corner would seem to stand at an angle to its lane, and its cover
    (:func:`collision_cover`) would swing its rear out into the next lanes."""
    if not np.any((arc[1:-1] > pos - length) & (arc[1:-1] < pos)):
        return tangent_deg
    (back, front), _ = along(shape, [pos - length, pos], extend=True)
    return (90.0 - math.degrees(math.atan2(front[1] - back[1], front[0] - back[0]))) % 360.0


def velocity_from_sumo(speed: float, lateral_speed: float, lane_angle_deg: float) -> np.ndarray:
    """World velocity (2,) [m/s] of a vehicle SUMO moves at ``speed`` along its lane and
    ``lateral_speed`` across it (positive to the left; a continuous lane change moves it across
    at a lane width per ``--lanechange.duration``, whatever its speed), the lane heading
    ``lane_angle_deg`` (navigational degrees)."""
    lane = heading_from_sumo(lane_angle_deg)
    c, s = math.cos(lane), math.sin(lane)
    return np.array([speed * c - lateral_speed * s, speed * s + lateral_speed * c])


def lane_change_sweep(lateral_speed: float, lateral_position: float, lane_width: float) -> float:
    """How far [m] (positive to the left) the front of a car in SUMO's continuous lane change
    still moves across: to the centre of the lane it moves into. ``lateral_speed`` [m/s] gives
    the direction (0: no change, no sweep), ``lateral_position`` [m] is its offset from the
    centre of the lane SUMO has it on (that lane becomes the new one halfway across), and
    ``lane_width`` [m] the lanes' width. At the centre the change ends: SUMO still reports the
    lateral speed at the step that brings it there (never at a change's first step, which has
    moved it already), and the sweep of a whole lane beyond drew a phantom car in the next lane
    for that step."""
    if lateral_speed == 0.0 or lateral_position == 0.0:
        return 0.0
    side = math.copysign(1.0, lateral_speed)
    return -lateral_position if lateral_position * side < 0.0 else side * lane_width - lateral_position


#: SUMO's signal bits of a vehicle's right and left blinkers (``vehicle.getSignals``).
BLINKER_RIGHT, BLINKER_LEFT = 1, 2


def signalled_sweep(signals: int, lateral_position: float, lane_width: float, lanes_right: int, lanes_left: int) -> float:
    """How far [m] (positive to the left) across a car not yet moving across would go in the
    lane change its blinker signals: to the centre of the next lane on the blinker's side, where
    there is one (``lanes_right``, ``lanes_left``: how many lanes of its edge lie on each side of
    its own). SUMO's drivers set a blinker when they want a lane change that the cars beside
    them do not let them make, and then make it as soon as a gap opens; both blinkers (hazard
    lights) and none signal no change (0). ``lateral_position`` [m]: its offset from its lane's
    centre."""
    right, left = bool(signals & BLINKER_RIGHT), bool(signals & BLINKER_LEFT)
    if right == left:
        return 0.0
    if left:
        return lane_width - lateral_position if lanes_left > 0 else 0.0
    return -lane_width - lateral_position if lanes_right > 0 else 0.0


def crossing_from_sumo(lane_id: str, shape, width: float, lane_width: float) -> Crossing:
    """Our :class:`~aac_sumo.sim.base.Crossing` of a SUMO crossing lane ``lane_id``: its shape
    (SUMO's centre-line points, network coordinates, which are our world frame [m]), its
    ``width`` [m] and the width [m] of the vehicle lanes it crosses."""
    return Crossing(lane_id, np.asarray(shape, dtype=float).reshape(-1, 2), float(width), float(lane_width))


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
