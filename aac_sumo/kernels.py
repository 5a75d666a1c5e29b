"""Compiled inner loops (numba) of the coordinators' per-period work, on plain arrays.

Each kernel is the loop form of a numpy definition elsewhere, and a test pins it to that
definition: :func:`braking_courses` steps :func:`aac_sumo.dynamics.bicycle_step` under the
braking law (:func:`aac_sumo.dynamics.heading_hold_steer` steering). Units: m, s, rad. Numba
caches the compiled code beside this file, so only the first run on a machine compiles it.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def braking_courses(states, first, use_first, headings, wheelbase, a_min, a_max, v_min, v_max, steer_max,
                    dt, turn_time, steps):
    """Rear-axle states (m, steps+1, 4) of robots starting from ``states`` (m, 4): each applies
    ``first`` (m, 2) once when ``use_first``, then brakes to a stop, its acceleration
    ``clip(-v / dt, a_min, a_max)`` and its steering turning its heading towards ``headings``
    (m,) with time constant ``turn_time`` within ``steer_max`` (zero at standstill); after
    every Euler bicycle step the speed is clipped into ``[v_min, v_max]``. Per-robot
    constants are arrays (m,)."""
    m = states.shape[0]
    out = np.empty((m, steps + 1, 4))
    gain = min(1.0, dt / turn_time)
    for i in range(m):
        x, y, h, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
        out[i, 0, 0], out[i, 0, 1], out[i, 0, 2], out[i, 0, 3] = x, y, h, v
        for k in range(steps):
            if k == 0 and use_first:
                accel, steer = first[i, 0], first[i, 1]
            else:
                accel = min(max(-v / dt, a_min[i]), a_max[i])
                steer = 0.0
                if v != 0.0:
                    error = headings[i] - h
                    error = math.atan2(math.sin(error), math.cos(error))
                    sign = 1.0 if v > 0.0 else -1.0
                    steer = math.atan2(wheelbase[i] * (gain * error) * sign, abs(v) * dt)
                    steer = min(max(steer, -steer_max[i]), steer_max[i])
            x, y, h, v = (x + v * math.cos(h) * dt, y + v * math.sin(h) * dt,
                          h + v * math.tan(steer) / wheelbase[i] * dt, v + accel * dt)
            v = min(max(v, v_min[i]), v_max[i])
            out[i, k + 1, 0], out[i, k + 1, 1], out[i, k + 1, 2], out[i, k + 1, 3] = x, y, h, v
    return out
