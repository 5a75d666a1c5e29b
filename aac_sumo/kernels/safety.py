"""Compiled loops of the safety stop (:mod:`aac_sumo.coordination.safety`): braking courses along the
path, the rule that flags unsafe courses, and its rounds of gentler braking.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aac_sumo.kernels.geometry import rect_clearance
from aac_sumo.kernels.motion import _bicycle_step, _heading_hold, footprint_rows, heading_along, limited_steer


#: Gap [m] the safety stop keeps from obstacles that stand (cones) instead of its margin. SUMO
#: measures a car's gap to a stopped vehicle along their lane, not between footprints; on a curve
#: the two differ by millimetres, and a car stopped in exact contact is a collision to SUMO.
STANDING_GAP = 0.05


@numba.njit(cache=True)
def braking_courses(states, first, use_first, previous_steer, headings, spacing, wheelbase, a_min, a_max, v_min, v_max,
                    steer_limits, dt, turn_time, steps):
    """Rear-axle states (m, steps+1, 4) of robots starting from ``states`` (m, 4): each applies
    ``first`` (m, 2) once when ``use_first``, then brakes to a stop, its acceleration
    ``clip(-v / dt, a_min, a_max)`` and its steering turning its heading with time constant
    ``turn_time`` towards its path's: ``headings`` (m, L) sampled every ``spacing`` [m] along
    it from where the robot starts (:func:`heading_along`), taken ``|v| turn_time`` beyond the
    distance it has covered, where the heading it turns to now will have been reached (so it
    follows a curved lane instead of running off it along a tangent; L = 1: one constant
    heading). Steering stays within :func:`limited_steer` of ``steer_limits`` (m, 3) from the
    steering before (``previous_steer`` (m,) at the start, zero at standstill); after every
    Euler bicycle step the speed is clipped into ``[v_min, v_max]``. Per-robot constants are
    arrays (m,)."""
    m = states.shape[0]
    out = np.empty((m, steps + 1, 4))
    gain = min(1.0, dt / turn_time)
    for i in range(m):
        x, y, h, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
        out[i, 0, 0], out[i, 0, 1], out[i, 0, 2], out[i, 0, 3] = x, y, h, v
        steer = previous_steer[i]
        covered = 0.0
        for k in range(steps):
            if k == 0 and use_first:
                accel, steer = first[i, 0], first[i, 1]
            else:
                accel = min(max(-v / dt, a_min[i]), a_max[i])
                wanted = _heading_hold(heading_along(headings[i], spacing, covered + abs(v) * turn_time), h, v, wheelbase[i], gain, dt)
                steer = limited_steer(wanted, v, accel, steer, wheelbase[i], steer_limits[i], dt)
            covered += abs(v) * dt
            x, y, h, v = _bicycle_step(x, y, h, v, accel, steer, dt, wheelbase[i], v_min[i], v_max[i])
            out[i, k + 1, 0], out[i, k + 1, 1], out[i, k + 1, 2], out[i, k + 1, 3] = x, y, h, v
    return out


@numba.njit(cache=True)
def _course_discs(rows):
    """Per course of footprint rows ``rows`` (C, K+1, 5), a disc ``[cx, cy, r]`` [m] holding its
    footprints' circumscribed discs at every stage k >= 1."""
    out = np.empty((rows.shape[0], 3))
    for c in range(rows.shape[0]):
        lo_x, hi_x, lo_y, hi_y = np.inf, -np.inf, np.inf, -np.inf
        for k in range(1, rows.shape[1]):
            lo_x, hi_x = min(lo_x, rows[c, k, 0]), max(hi_x, rows[c, k, 0])
            lo_y, hi_y = min(lo_y, rows[c, k, 1]), max(hi_y, rows[c, k, 1])
        cx, cy, r = 0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y), 0.0
        for k in range(1, rows.shape[1]):
            r = max(r, math.hypot(rows[c, k, 0] - cx, rows[c, k, 1] - cy) + 0.5 * math.hypot(rows[c, k, 2], rows[c, k, 3]))
        out[c, 0], out[c, 1], out[c, 2] = cx, cy, r
    return out


@numba.njit(cache=True)
def courses_unsafe(own, brake, targets, skip, eased, growing, margin, tie):
    """Which courses fail the safety stop's rule (bool, m). Robot i's course ``own[i]`` and its
    braking at once ``brake[i]`` (m, K+1, 5) are footprint rows per stage; ``targets`` (T, K+1,
    5) are what it must keep clear of, except where ``skip`` (m, T). Course i fails when at some
    stage k >= 1 its clearance [m] to some target is below ``margin`` and below both the stage-0
    clearance and braking's clearance at stage k by more than ``tie``; where ``eased`` (m, T),
    every clearance counts ``margin - STANDING_GAP`` more (the target counts only within
    :data:`STANDING_GAP`). A ``growing`` (T,) target (a walker's region that
    grows with time) counts only until the course stands (its footprint no longer moves): a
    standing robot cannot run into anyone. Pairs whose circumscribed discs stay ``margin`` apart
    at every stage k >= 1 are not measured, nor (checked first) pairs whose whole courses' discs
    (:func:`_course_discs`) do."""
    m, t_count, stages = own.shape[0], targets.shape[0], own.shape[1]
    out = np.zeros(m, dtype=np.bool_)
    reach_t = _course_discs(targets)
    reach_own = _course_discs(own)
    for i in range(m):
        r_own = 0.5 * math.hypot(own[i, 0, 2], own[i, 0, 3])
        moving = 1  # the stages before it stands for good: after the last one whose footprint moved
        for k in range(stages - 1, 0, -1):
            if own[i, k, 0] != own[i, k - 1, 0] or own[i, k, 1] != own[i, k - 1, 1] or own[i, k, 4] != own[i, k - 1, 4]:
                moving = k + 1
                break
        for t in range(t_count):
            if skip[i, t]:
                continue
            if (math.hypot(reach_own[i, 0] - reach_t[t, 0], reach_own[i, 1] - reach_t[t, 1])
                    - reach_own[i, 2] - reach_t[t, 2] >= margin):
                continue  # the whole courses stay apart: so does every stage
            last = moving if growing[t] else stages
            bound = np.inf
            for k in range(1, stages):
                apart = math.hypot(own[i, k, 0] - targets[t, k, 0], own[i, k, 1] - targets[t, k, 1])
                bound = min(bound, apart - r_own - 0.5 * math.hypot(targets[t, k, 2], targets[t, k, 3]))
            if bound >= margin:
                continue
            extra = max(margin - STANDING_GAP, 0.0) if eased[i, t] else 0.0
            now = rect_clearance(own[i, 0], targets[t, 0]) + extra
            for k in range(1, last):
                later = rect_clearance(own[i, k], targets[t, k]) + extra
                if later < margin and later < now - tie and later < rect_clearance(brake[i, k], targets[t, k]) + extra - tie:
                    out[i] = True
                    break
            if out[i]:
                break
    return out


@numba.njit(cache=True)
def stop_flags(check, rows, fixed, standing, growing, margin, tie, ignored):
    """Which of robots ``check`` (m,) fail the safety stop's rule (bool, m): :func:`courses_unsafe`
    of their courses' footprint rows ``rows`` (n, K+1, 5), every robot's, against every robot's
    course, then ``fixed`` (n + obstacles, K+1, 5: every robot braking at once, then the
    obstacles), skipping itself on either course and the targets ``ignored`` (n, 2 n +
    obstacles) marks for it; ``standing`` (2 n + obstacles) marks the targets that count only
    within :data:`STANDING_GAP`, ``growing`` those that count only while a course moves."""
    n, m = rows.shape[0], check.shape[0]
    targets = np.concatenate((rows, fixed))
    skip = np.zeros((m, targets.shape[0]), dtype=np.bool_)
    eased = np.empty((m, targets.shape[0]), dtype=np.bool_)
    for r in range(m):
        skip[r, :] = ignored[check[r]]
        skip[r, check[r]] = True
        skip[r, n + check[r]] = True
        eased[r, :] = standing
    return courses_unsafe(rows[check], fixed[check], targets, skip, eased, growing, margin, tie)


@numba.njit(cache=True)
def gentlest_stops(check, inputs, steer, states, headings, spacing, wheelbase, a_min, a_max, v_min, v_max, steer_limits, offset,
                   length, width, dt, turn_time, steps, fixed, standing, growing, margin, tie, a_level, ignored):
    """The safety stop's choice for robots ``check`` (m,) given every robot's ``inputs`` (n, 2):
    a robot that fails :func:`stop_flags` on its :func:`braking_courses` course (``steps``
    stages, footprints by :func:`footprint_rows`, braking at ``a_min``) gets
    ``[min(input, share * a_level), steer]`` for share 0, 1/3 and 2/3 in turn, until it passes
    (``ignored`` as for :func:`stop_flags`; ``headings`` (n, L) every ``spacing`` [m] as for
    :func:`braking_courses`); after each round every robot of ``check`` still flagged is checked again against the
    others' new courses. Returns the inputs (n, 2) and which robots of ``check`` still fail
    (bool, m). Per-robot arrays are (n,), ``steer_limits`` (n, 3)."""
    rows = footprint_rows(braking_courses(states, inputs, True, inputs[:, 1], headings, spacing, wheelbase, a_min, a_max, v_min, v_max,
                                          steer_limits, dt, turn_time, steps), offset, length, width)
    chosen = inputs.copy()
    flagged = stop_flags(check, rows, fixed, standing, growing, margin, tie, ignored)
    for share in (0.0, 1.0 / 3.0, 2.0 / 3.0):
        if not flagged.any():
            break
        for r in range(check.shape[0]):
            if flagged[r]:
                i = check[r]
                chosen[i, 0], chosen[i, 1] = min(inputs[i, 0], share * a_level[i]), steer[i]
                course = braking_courses(states[i:i + 1], chosen[i:i + 1], True, chosen[i:i + 1, 1], headings[i:i + 1],
                                         spacing, wheelbase[i:i + 1], a_min[i:i + 1], a_max[i:i + 1], v_min[i:i + 1], v_max[i:i + 1],
                                         steer_limits[i:i + 1], dt, turn_time, steps)
                rows[i] = footprint_rows(course, offset[i:i + 1], length[i:i + 1], width[i:i + 1])[0]
        flagged &= stop_flags(check, rows, fixed, standing, growing, margin, tie, ignored)
    return chosen, flagged
