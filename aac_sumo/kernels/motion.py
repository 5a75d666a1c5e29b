"""Compiled rollouts of the kinematic bicycle model (the loop form of :func:`aac_sumo.dynamics.bicycle_step`):
steering within the vehicle's limits, open-loop rollouts, footprints along them, braking tails, and the
tracking law's course (:func:`aac_sumo.coordination.tracking.track`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aac_sumo.kernels.paths import closest_on_polyline


@numba.njit(cache=True)
def limited_steer(steer, v, accel, previous, wheelbase, steer_limits, dt):
    """``steer`` [rad] within the vehicle limits ``steer_limits`` = ``[steer_max, a_lat_max,
    steer_rate_max]``: within ``previous`` +- ``steer_rate_max * dt``, then within the
    lateral-acceleration bound ``atan(a_lat_max L / v^2)`` at the larger of ``|v|`` and
    ``|v + accel dt|`` and within ``steer_max`` (as :meth:`aac_sumo.dynamics.BicycleModel.limit_steer`)."""
    rate = steer_limits[2] * dt
    steer = min(max(steer, previous - rate), previous + rate)
    speed = max(abs(v), abs(v + accel * dt))
    bound = steer_limits[0]
    if speed > 0.0:
        bound = min(bound, math.atan(steer_limits[1] * wheelbase / (speed * speed)))
    return min(max(steer, -bound), bound)


@numba.njit(cache=True)
def _heading_hold(heading, h, v, wheelbase, gain, dt):
    """The steering [rad] that turns heading ``h`` towards ``heading`` by the share ``gain`` of
    the error in one period at speed ``v`` (zero at standstill), before any limit."""
    if v == 0.0:
        return 0.0
    error = heading - h
    error = math.atan2(math.sin(error), math.cos(error))
    sign = 1.0 if v > 0.0 else -1.0
    return math.atan2(wheelbase * (gain * error) * sign, abs(v) * dt)


@numba.njit(cache=True)
def heading_along(row, spacing, distance):
    """Heading [rad] ``distance`` [m] along a path whose headings ``row`` (L,) [rad, unwrapped]
    are sampled every ``spacing`` [m] from where the robot is: linear between samples, the
    first before them and the last beyond them (one sample: a constant heading)."""
    last = row.shape[0] - 1
    if last == 0 or distance <= 0.0:
        return row[0]
    x = distance / spacing
    j = int(x)
    if j >= last:
        return row[last]
    return row[j] + (x - j) * (row[j + 1] - row[j])


@numba.njit(cache=True)
def rollouts(states, inputs, dt, wheelbase, v_min, v_max):
    """Rear-axle states (m, K+1, 4) of robots starting from ``states`` (m, 4) under ``inputs``
    (m, K, 2) ``[accel, steer]``; after every Euler bicycle step the speed is clipped into
    ``[v_min, v_max]``. Per-robot constants are arrays (m,)."""
    m, steps = inputs.shape[0], inputs.shape[1]
    out = np.empty((m, steps + 1, 4))
    for i in range(m):
        x, y, h, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
        out[i, 0, 0], out[i, 0, 1], out[i, 0, 2], out[i, 0, 3] = x, y, h, v
        for k in range(steps):
            x, y, h, v = _bicycle_step(x, y, h, v, inputs[i, k, 0], inputs[i, k, 1], dt, wheelbase[i], v_min[i], v_max[i])
            out[i, k + 1, 0], out[i, k + 1, 1], out[i, k + 1, 2], out[i, k + 1, 3] = x, y, h, v
    return out


@numba.njit(cache=True)
def footprint_rows(states, offset, length, width):
    """Footprint rows ``[cx, cy, length, width, heading]`` (m, K, 5) of robots at rear-axle
    ``states`` (m, K, 4) whose footprint centre lies ``offset`` (m,) [m] ahead of the rear axle
    and whose footprint measures ``length`` x ``width`` (m,) [m]."""
    m, stages = states.shape[0], states.shape[1]
    out = np.empty((m, stages, 5))
    for i in range(m):
        for k in range(stages):
            h = states[i, k, 2]
            out[i, k, 0] = states[i, k, 0] + offset[i] * math.cos(h)
            out[i, k, 1] = states[i, k, 1] + offset[i] * math.sin(h)
            out[i, k, 2], out[i, k, 3], out[i, k, 4] = length[i], width[i], h
    return out


@numba.njit(cache=True)
def _bicycle_step(x, y, h, v, accel, steer, dt, wheelbase, v_min, v_max):
    """One Euler step of :func:`aac_sumo.dynamics.bicycle_step`, the new speed clipped into ``[v_min, v_max]``."""
    return (x + v * math.cos(h) * dt, y + v * math.sin(h) * dt, h + v * math.tan(steer) / wheelbase * dt,
            min(max(v + accel * dt, v_min), v_max))


@numba.njit(cache=True)
def braking_tail(state, previous_steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, max_steps, points, seg_len,
                 cum, seg_heading, t_max, chunk_centre, chunk_radius, chunk):
    """Inputs (K, 2) and rear-axle states (K+1, 4) of one robot braking from ``state`` (4,) to
    standstill: acceleration ``clip(-v / dt, -decel, decel)`` [m/s^2] and steering that turns
    its heading towards ``heading`` [rad] with time constant ``turn_time`` [s] within
    :func:`limited_steer` of ``steer_limits`` (3,) from ``previous_steer`` [rad] (as
    :func:`braking_courses`), until the speed is within 1e-12 m/s of zero or after
    ``max_steps`` periods. With a path ``points`` (M, 2) (not empty; the arrays of
    :meth:`~aac_sumo.references.PathReference.arrays`) the heading it turns towards is, each
    period, the path's where the robot's projection will be ``turn_time`` on at its speed: it
    brakes along a lane that curves."""
    states = np.empty((max_steps + 1, 4))
    inputs = np.empty((max_steps, 2))
    x, y, h, v = state[0], state[1], state[2], state[3]
    states[0, 0], states[0, 1], states[0, 2], states[0, 3] = x, y, h, v
    gain = min(1.0, dt / turn_time)
    k = 0
    steer = previous_steer
    n_seg = seg_len.shape[0]
    while k < max_steps and abs(v) > 1e-12:
        accel = min(max(-v / dt, -decel), decel)
        if points.shape[0] > 0:
            i, t, _ = closest_on_polyline(points, seg_len, t_max, x, y, chunk_centre, chunk_radius, chunk)
            ahead = cum[i] + t * seg_len[i] + abs(v) * turn_time
            j = min(max(np.searchsorted(cum, ahead, side="right") - 1, 0), n_seg - 1)
            heading = seg_heading[j]
        steer = limited_steer(_heading_hold(heading, h, v, wheelbase, gain, dt), v, accel, steer, wheelbase, steer_limits, dt)
        x, y, h, v = _bicycle_step(x, y, h, v, accel, steer, dt, wheelbase, v_min, v_max)
        inputs[k, 0], inputs[k, 1] = accel, steer
        k += 1
        states[k, 0], states[k, 1], states[k, 2], states[k, 3] = x, y, h, v
    return states[: k + 1], inputs[:k]


@numba.njit(cache=True)
def tracking_course(x, y, h, v, steps, dt, wheelbase, a_min, a_max, steer_max, v_min, v_max, a_lat_max, a_lat_comfort, steer_rate_max, comfort,
                    previous_steer, points, seg_len, cum, seg_dir, seg_heading, t_max, chunk_centre, chunk_radius, chunk, limits,
                    speed, decel, stop_at_end, approach, lookahead, lookahead_time, lookahead_min, speed_gain, offset, target_speed):
    """Inputs (steps, 2) ``[accel, steer]`` of the tracking law (the loop form of
    :func:`aac_sumo.coordination.tracking.track`) applied period after period from the rear-axle
    state ``(x, y, h, v)``, each step of :func:`_bicycle_step` with the inputs clipped to the
    robot's bounds. Pure pursuit of the path point :func:`pursuit_distance` [m] beyond the projection
    (clamped to the end of a path that stops), moved ``offset`` [m] to the right; within
    ``approach`` [m] of the goal of a path that stops, straight at the goal at the speed that
    stops there. The speed loop drives towards the path's speed at the projection (its
    ``limits`` (M,) over ``cum`` when non-empty, its stopping profile at ``decel``), or
    ``target_speed`` when that is not NaN, braking at most at ``comfort``; above a stopping
    profile it brakes at least as hard as stops it at the goal (the loop alone lags it); the
    steering keeps the rate limit from the one before and the lateral limit ``a_lat_max`` at the larger of the
    speeds now and after the period, and comes within the comfort limit ``a_lat_comfort`` as
    far as the rate limit lets it (a car beyond it, on a plan made within the car's full limits,
    is brought back within it at the steering rate, not in one period)."""
    out = np.empty((steps, 2))
    steer_prev = previous_steer
    for k in range(steps):
        i, t, _ = closest_on_polyline(points, seg_len, t_max, x, y, chunk_centre, chunk_radius, chunk)
        accel, steer = _tracking_step(i, t, x, y, h, v, dt, wheelbase, a_max, steer_max, a_lat_max, a_lat_comfort, steer_rate_max, comfort,
                                      steer_prev, points, seg_len, cum, seg_dir, seg_heading, limits, speed, decel, stop_at_end, approach,
                                      lookahead, lookahead_time, lookahead_min, speed_gain, offset, target_speed)
        out[k, 0], out[k, 1] = accel, steer
        x, y, h, v = _bicycle_step(x, y, h, v, min(max(accel, a_min), a_max), min(max(steer, -steer_max), steer_max), dt, wheelbase,
                                   v_min, v_max)
        steer_prev = steer
    return out


@numba.njit(cache=True)
def pursuit_distance(lookahead, lookahead_time, lookahead_min, v):
    """How far [m] beyond its projection the tracking law aims: ``lookahead``; with
    ``lookahead_time`` > 0 [s], the distance the car covers in that time at its speed ``v`` [m/s]
    where that is shorter, but at least ``lookahead_min`` [m] (a car turning a tight corner
    slowly aims at the corner, not at the street beyond it)."""
    if lookahead_time <= 0.0:
        return lookahead
    return min(lookahead, max(lookahead_min, lookahead_time * abs(v)))


@numba.njit(cache=True)
def _tracking_step(i, t, x, y, h, v, dt, wheelbase, a_max, steer_max, a_lat_max, a_lat_comfort, steer_rate_max, comfort, steer_prev, points,
                   seg_len, cum, seg_dir, seg_heading, limits, speed, decel, stop_at_end, approach, lookahead, lookahead_time, lookahead_min,
                   speed_gain, offset, target_speed):
    """One period of :func:`tracking_course` from the rear-axle state ``(x, y, h, v)`` that
    projects at fraction ``t`` of the path's segment ``i``: its ``(accel, steer)``, before the
    robot's bounds clip them."""
    n_seg = seg_len.shape[0]
    length = cum[n_seg]
    gx, gy = points[n_seg, 0], points[n_seg, 1]
    s0 = cum[i] + t * seg_len[i]
    look = pursuit_distance(lookahead, lookahead_time, lookahead_min, v)
    sl = min(s0 + look, length) if stop_at_end else s0 + look
    j = min(max(np.searchsorted(cum, sl, side="right") - 1, 0), n_seg - 1)
    local = sl - cum[j]
    if stop_at_end:
        local = min(max(local, 0.0), seg_len[j])
    px, py, ph = points[j, 0] + local * seg_dir[j, 0], points[j, 1] + local * seg_dir[j, 1], seg_heading[j]
    tx, ty = px + offset * math.sin(ph), py - offset * math.cos(ph)
    near_goal = stop_at_end and math.hypot(gx - x, gy - y) <= approach
    if near_goal:
        tx, ty = gx, gy
    rx, ry = tx - x, ty - y
    dist = math.hypot(rx, ry)
    steer = 0.0 if dist < 1e-6 else math.atan2(2.0 * wheelbase * math.sin(math.atan2(ry, rx) - h), dist)
    rest = dist if near_goal else max(length - s0, 0.0)  # to the goal of a path that stops [m]
    if near_goal:
        want = min(speed, math.sqrt(2.0 * decel * dist))
    else:
        cap = speed if limits.shape[0] == 0 else np.interp(s0, cum, limits)
        want = min(speed, cap) if not stop_at_end else min(cap, math.sqrt(2.0 * decel * rest))
        if not math.isnan(target_speed):
            want = target_speed
    accel = speed_gain * (want - v)
    if stop_at_end and v > want and v > 0.0:  # the proportional loop lags the stopping profile: brake to stop at the goal
        accel = min(accel, -v * v / (2.0 * max(rest, 1e-6)))
    accel = min(max(accel, -comfort), a_max)
    rate = steer_rate_max * dt
    lo, hi = steer_prev - rate, steer_prev + rate
    steer = min(max(steer, lo), hi)
    fastest = max(abs(v), abs(v + accel * dt))
    soft = min(math.atan2(a_lat_comfort * wheelbase, fastest * fastest), steer_max)
    if hi < -soft or lo > soft:  # the rate window lies beyond the comfort limit: as near it as the window allows
        steer = hi if hi < -soft else lo
    else:
        steer = min(max(steer, max(-soft, lo)), min(soft, hi))
    bound = min(math.atan2(a_lat_max * wheelbase, fastest * fastest), steer_max)
    return accel, min(max(steer, -bound), bound)


@numba.njit(cache=True)
def continuation_inputs(x, y, h, v, steps, t0, dt, stops, cap_decel, accel_up, calm, lag, wheelbase, a_min, a_max, steer_max, v_min, v_max,
                        a_lat_max, a_lat_comfort, steer_rate_max, comfort, previous_steer, points, seg_len, cum, seg_dir, seg_heading, t_max,
                        chunk_centre, chunk_radius, chunk, limits, speed, decel, lookahead, lookahead_time, lookahead_min, speed_gain, offset,
                        hard, hard_decel, accel_prev, jerk):
    """Inputs (steps, 2) of a continuation along a path that does not stop, from the rear-axle
    state ``(x, y, h, v)`` reached ``t0`` periods of ``dt`` [s] from now: each period the speed
    that reaches, in ``lag`` [s], the lower of the path's speed, the anticipation's speed cap
    (braking at ``cap_decel`` [m/s^2] to every stop row ``[s_stop, v_lead, grow]`` of ``stops``
    (K, 3), each moving on at its ``v_lead`` meanwhile) and the speed from which braking at
    ``hard_decel`` stops at each arc length of ``hard`` (H,) [m], where the car will be ``lag`` on, within
    [-``calm``, ``accel_up``] and, with ``jerk`` > 0 [m/s^3], at most what easing off at ``jerk``
    from reaches the target with no acceleration left (sqrt(2 ``jerk`` |target - v|)) and within ``jerk`` * ``dt`` of the
    acceleration before (``accel_prev`` [m/s^2] before the first period), except that it slows
    for a standing point of ``hard`` as fast as it must (that stop keeps its bound); the steering of
    one period of :func:`tracking_course` with that target speed (aiming :func:`pursuit_distance` ahead); then one
    :func:`_bicycle_step`. The compiled loop of
    :meth:`~aac_sumo.coordination.aac.committed.CommittedAac.continued_commitment`."""
    out = np.empty((steps, 2))
    steer, before = previous_steer, accel_prev
    for k in range(steps):
        t = (t0 + k) * dt
        i, f, _ = closest_on_polyline(points, seg_len, t_max, x, y, chunk_centre, chunk_radius, chunk)
        ahead = (cum[i] + f * seg_len[i]) + max(v, 0.0) * lag
        cap = math.inf
        for r in range(stops.shape[0]):
            room = (stops[r, 0] + stops[r, 1] * t) - ahead
            lead, bk = stops[r, 1], cap_decel * stops[r, 2]
            cap = min(cap, max(math.sqrt(max(bk**2 + lead**2 + 2.0 * cap_decel * room, 0.0)) - bk, 0.0))
        hard_cap = math.inf
        for r in range(hard.shape[0]):
            hard_cap = min(hard_cap, math.sqrt(2.0 * hard_decel * max(hard[r] - ahead, 0.0)))
        cap = min(cap, hard_cap)
        path_speed = speed if limits.shape[0] == 0 else min(speed, np.interp(ahead, cum, limits))
        target = min(cap, path_speed)
        turn = _tracking_step(i, f, x, y, h, v, dt, wheelbase, a_max, steer_max, a_lat_max, a_lat_comfort, steer_rate_max, comfort, steer,
                              points, seg_len, cum, seg_dir, seg_heading, limits, speed, decel, False, 0.0, lookahead, lookahead_time, lookahead_min,
                              speed_gain, offset,
                              target)[1]
        gap = target - v
        accel = min(max(gap / lag, -calm), accel_up)
        if jerk > 0.0 and hard_cap <= target:  # towards a standing point ahead: speeding up at jerk, braking as it must
            accel = min(max(min(accel, before + jerk * dt), -calm), accel_up)
        elif jerk > 0.0:  # no faster than it can ease off at jerk to reach the target with no acceleration left
            accel = math.copysign(min(abs(accel), math.sqrt(2.0 * jerk * abs(gap))), gap)
            accel = min(max(min(max(accel, before - jerk * dt), before + jerk * dt), -calm), accel_up)
        out[k, 0], out[k, 1] = accel, turn
        x, y, h, v = _bicycle_step(x, y, h, v, accel, turn, dt, wheelbase, v_min, v_max)
        steer, before = turn, accel
    return out
