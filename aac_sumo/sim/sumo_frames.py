"""The one conversion between SUMO's vehicle pose and our rear-axle state.

SUMO places a vehicle by its front-bumper centre ``(x, y)`` [m] and its angle in navigational
degrees (0 = north, clockwise). We use the rear-axle midpoint and the heading [rad]
counter-clockwise from +x. With equal overhangs the rear axle lies ``(length + wheelbase) / 2``
behind the front bumper along the heading.
"""

from __future__ import annotations

import math

import numpy as np


def bumper_to_axle(length: float, wheelbase: float) -> float:
    """Distance [m] from the rear-axle midpoint forward to the front-bumper centre."""
    return 0.5 * (length + wheelbase)


def state_from_sumo(x: float, y: float, angle_deg: float, speed: float, length: float, wheelbase: float) -> np.ndarray:
    """Our state ``[x, y, heading, v]`` (rear axle, heading in (-pi, pi]) from a SUMO pose."""
    heading = math.atan2(math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg)))
    back = bumper_to_axle(length, wheelbase)
    return np.array([x - back * math.cos(heading), y - back * math.sin(heading), heading, speed])


def sumo_from_state(state, length: float, wheelbase: float) -> tuple[float, float, float]:
    """SUMO pose ``(x, y, angle_deg)`` (front bumper, navigational degrees in [0, 360)) of ``state``."""
    x, y, heading = float(state[0]), float(state[1]), float(state[2])
    ahead = bumper_to_axle(length, wheelbase)
    angle = (90.0 - math.degrees(heading)) % 360.0
    return x + ahead * math.cos(heading), y + ahead * math.sin(heading), angle
