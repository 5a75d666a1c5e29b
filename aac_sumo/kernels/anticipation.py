"""Compiled loops of the anticipated reference (:mod:`aac_sumo.coordination.anticipation`): the stop
rows of what lies ahead on a path and the speeds ramped towards them.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aac_sumo.kernels.paths import closest_on_polyline


@numba.njit(cache=True)
def ramped_speeds(s0, v0, steps, dt, decel, accel, brake, stops, speed, path_s, limits, stop_at_end, path_decel, length):
    """Arc lengths and speeds (steps+1,) of a reference that starts at ``s0`` [m] and ``v0``
    [m/s] and changes speed by at most ``accel`` / ``decel`` [m/s^2] per second towards the
    path's speed at each stage (``speed``, below ``limits`` over ``path_s`` when it has any,
    and its stopping profile at ``path_decel`` before ``length`` when ``stop_at_end``), capped
    by braking at ``decel`` to every stop row ``[s_stop, v_lead, grow]`` (K, 3) of ``stops``
    (as :func:`aac_sumo.coordination.anticipation.speed_cap`: a row already passed caps below its
    ``v_lead``, so that a gap that has closed opens again at ``decel``). A row that braking at ``decel``
    can no longer meet (seen late: a walker who stepped towards the path) is met braking as
    hard as it needs to come down to its ``v_lead`` within its room (the closing speed squared
    over twice the room), up to ``brake`` [m/s^2] (``brake <= decel``: never harder than ``decel``).
    So is a speed limit ahead that a robot above its path's ``limits`` can no longer meet at
    ``decel`` (:func:`limit_rate`: a car SUMO inserted at speed shortly before a corner)."""
    s = np.empty(steps + 1)
    v = np.empty(steps + 1)
    s[0], v[0] = s0, max(v0, 0.0)
    onto_limits = limit_rate(s0, v[0], decel, brake, path_s, limits)
    for k in range(steps + 1):
        if k:
            target = speed
            rate = decel
            if limits.shape[0]:
                limit = np.interp(s[k], path_s, limits)
                target = min(target, limit)
                if v[k - 1] > limit:
                    rate = onto_limits
            if stop_at_end:
                target = min(target, math.sqrt(2.0 * path_decel * max(length - s[k], 0.0)))
            for r in range(stops.shape[0]):
                ahead = stops[r, 0] + stops[r, 1] * k * dt - s[k]  # what moves goes on at its speed
                room = max(ahead, 0.0)
                bk = decel * stops[r, 2]
                target = min(target, math.sqrt(max(bk * bk + stops[r, 1] ** 2 + 2.0 * decel * ahead, 0.0)) - bk)
                closing = v[k - 1] - stops[r, 1]
                if brake > decel and closing > 0.0:  # the rate that comes down to v_lead (going on at its speed) within the room left, grow v kept
                    left = room - stops[r, 2] * v[k - 1]
                    rate = max(rate, min(brake, closing * closing / (2.0 * left)) if left > 0.0 else brake)
            v[k] = max(min(max(target, v[k - 1] - rate * dt), v[k - 1] + accel * dt), 0.0)
        if k < steps:
            s[k + 1] = s[k] + v[k] * dt
    return s, v


@numba.njit(cache=True)
def limit_rate(s0, v0, decel, brake, path_s, limits):
    """The constant deceleration [m/s^2] with which a robot at arc length ``s0`` [m] and speed
    ``v0`` [m/s] comes down to every speed limit of ``limits`` over ``path_s`` ahead of it:
    ``decel``, or where that is too gentle (the robot is above the ramps that lead down to
    them), as hard as it needs up to ``brake``: the largest ``(v0^2 - limit^2) / 2 d`` over the
    limits' low points (where they stop falling) ``d`` [m] ahead within its stopping distance
    at ``decel``. (On a ramp it is above, the point nearest it would ask for more: it meets the
    ramp further on, at its steeper rate.)"""
    rate = decel
    if brake <= decel or limits.shape[0] == 0:
        return rate
    reach = v0 * v0 / (2.0 * decel)
    last = path_s.shape[0] - 1
    for j in range(max(np.searchsorted(path_s, s0, side="right"), 1), last + 1):
        d = path_s[j] - s0
        if d > reach:
            break
        if limits[j - 1] > limits[j] and (j == last or limits[j + 1] >= limits[j]):
            rate = max(rate, min(brake, (v0 * v0 - limits[j] * limits[j]) / (2.0 * d)))
    return rate


#: A walker moving away from a robot's path faster than this [m/s] is not taken to step back towards it.
WALK_AWAY = 0.1


#: The time gap behind a leader grows from none (standing) to the whole at this leader speed [m/s].
TIME_GAP_SPEED = 1.0


@numba.njit(cache=True)
def stop_rows(points, seg_len, cum, seg_dir, seg_heading, t_max, chunk_centre, chunk_radius, chunk, stop_at_end,
              ego, s0, off0, centres, headings, lengths, widths, velocity, walker, step_out, accel, skip, held_since, t, rules):
    """The loop form of :func:`aac_sumo.coordination.anticipation.stop_points` for one robot on
    one path (the path's arrays as :meth:`aac_sumo.references.PathReference.arrays` gives them).

    ``ego`` = ``[x, y, v, length, width, centre_offset, comfort_decel]`` of the robot (rear
    axle [m], speed [m/s], footprint [m], deceleration [m/s^2]), projected at arc length ``s0``
    [m], ``off0`` [m] off the path. The agents (K rows: footprint centres, headings, lengths,
    widths, velocities, walker flags, how fast each walker may step out of her way [m/s], accelerations)
    are everything on the road; row ``skip`` is the robot itself. ``held_since`` (K,) [s]: when
    each walker last counted (-inf: never). ``rules`` = ``[look, lateral_margin, cut_in,
    pedestrian_margin, decel, gap, time_gap, hold]``
    (:class:`~aac_sumo.coordination.anticipation.Anticipation`).

    Returns the stop rows (R, 3) ``[s_stop, v_lead, grow]``, those of braking vehicles' stopping
    points last, and per agent whether it counted as a walker near the path at time ``t`` [s]
    before the hold and the point of no return (the caller's ``held`` is set to ``t`` there)."""
    look, lateral_margin, cut_in, ped_margin, decel, gap, time_gap, hold = (
        rules[0], rules[1], rules[2], rules[3], rules[4], rules[5], rules[6], rules[7])
    x, y, v, length, width, centre_offset = ego[0], ego[1], abs(ego[2]), ego[3], ego[4], ego[5]
    comfort = ego[6]
    front = centre_offset + 0.5 * length
    k_count = centres.shape[0]
    n_seg = seg_len.shape[0]
    rows = np.empty((2 * k_count, 3))
    extra = np.empty((k_count, 3))
    counted = np.zeros(k_count, dtype=np.bool_)
    n_rows = 0
    n_extra = 0
    pace = max(v, 1.0)
    arrive_max = (look + ped_margin + length + 1.0) / pace  # a bound on every agent's ``passed`` (walkers are small)
    for k in range(k_count):
        if k == skip:
            continue
        vx, vy = velocity[k, 0], velocity[k, 1]
        speed = math.hypot(vx, vy)
        ped_reach = step_out[k]
        reach_max = speed * arrive_max + ped_reach * arrive_max if walker[k] else speed * cut_in
        bound = (off0 + look + max(ped_margin, lateral_margin) + 0.5 * math.hypot(lengths[k], widths[k]) + 0.5 * width + reach_max)
        cx, cy = centres[k, 0], centres[k, 1]
        if not math.hypot(cx - x, cy - y) <= bound + 1e-6:
            continue
        i, frac, off = closest_on_polyline(points, seg_len, t_max, cx, cy, chunk_centre, chunk_radius, chunk)
        s = cum[i] + frac * seg_len[i]
        ahead = s - s0
        if not (ahead > 0.0 and ahead <= look):
            continue
        # the path's pose at s (PathReference.pose_at)
        j = min(max(np.searchsorted(cum, s, side="right") - 1, 0), n_seg - 1)
        local = s - cum[j]
        if stop_at_end:
            local = min(max(local, 0.0), seg_len[j])
        px, py = points[j, 0] + local * seg_dir[j, 0], points[j, 1] + local * seg_dir[j, 1]
        direction = seg_heading[j]
        rel = headings[k] - direction
        tx, ty = math.cos(direction), math.sin(direction)
        nx, ny = -ty, tx
        side = -1.0 if nx * (cx - px) + ny * (cy - py) < 0.0 else 1.0
        sin_rel, cos_rel = abs(math.sin(rel)), abs(math.cos(rel))
        gap_across = off - (0.5 * lengths[k] * sin_rel + 0.5 * widths[k] * cos_rel) - 0.5 * width
        across = -side * (vx * nx + vy * ny)
        toward = max(0.0, across)
        along = 0.5 * lengths[k] * cos_rel + 0.5 * widths[k] * sin_rel
        passed = (ahead + along + ped_margin + 0.5 * length - centre_offset) / pace  # when its rear is past her and the margin
        if walker[k]:
            if across < -WALK_AWAY:  # she walks away from the path: not taken to turn back
                ped_reach = 0.0
            reach = max(toward * passed, ped_reach * min(passed, v / decel))
            counts = gap_across - reach <= ped_margin
            if counts:
                counted[k] = True
            elif t - held_since[k] <= hold and across >= 0.0:
                counts = True
            lead, keep, grow = 0.0, ped_margin, ped_reach / decel
        else:
            counts = gap_across - toward * cut_in <= lateral_margin
            lead, keep = max(vx * tx + vy * ty, 0.0), 0.0
            grow = time_gap * min(lead / TIME_GAP_SPEED, 1.0)  # the time gap at the robot's own speed, behind a moving leader
        behind_it = s - along - front - gap
        s_stop = behind_it - keep
        if walker[k] and counts and gap_across > ped_margin and v * v > 2.0 * comfort * max(s_stop - s0, 0.0):
            if gap_across - toward * passed > ped_margin:  # past the point of no return
                counts = False
        if not counts:
            continue
        rows[n_rows, 0], rows[n_rows, 1], rows[n_rows, 2] = s_stop, lead, grow
        n_rows += 1
        if not walker[k] and accel[k] < 0.0 and lead > 0.0:
            extra[n_extra, 0], extra[n_extra, 1], extra[n_extra, 2] = behind_it + lead * lead / (-2.0 * accel[k]), 0.0, 0.0
            n_extra += 1
    rows[n_rows:n_rows + n_extra] = extra[:n_extra]
    return rows[:n_rows + n_extra], counted
