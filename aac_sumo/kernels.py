"""Compiled inner loops (numba) of the coordinators' per-period work, on plain arrays.

Each kernel is the loop form of a numpy definition elsewhere, or of the function it replaced,
and a test pins it to that definition: :func:`rollouts` and :func:`braking_courses` step
:func:`aac_sumo.dynamics.bicycle_step` (the latter under the braking law, steering as
:func:`aac_sumo.dynamics.heading_hold_steer`), :func:`footprint_rows` gives
:meth:`aac_sumo.world.WorldState.robot_footprints` along trajectories, :func:`rect_clearance`
(and :func:`pairwise_clearance`) is :func:`aac_sumo.geometry.rect_clearance_rows`,
:func:`stop_flags` and :func:`gentlest_stops` are the safety stop's rule and its rounds of
gentler braking, :func:`grow_trees`, :func:`closest_on_polyline`, :func:`polyline_offsets` and
:func:`times_to_collision` the loops of the proximity decision, path projection, the lateral
band's offsets and the time to collision, :func:`stop_rows` the anticipation's stop rows (:func:`aac_sumo.coordination.anticipation.stop_points`, pinned to its numpy form in ``tests/test_stop_points.py``), :func:`tracking_course` the tracking law's rollout
(:func:`aac_sumo.coordination.tracking.track`), and :func:`grid_path`, :func:`distance_field`,
:func:`shortcut` and :func:`rects_within` the detour planner's (:mod:`aac_sumo.coordination.detour`). They import nothing else of this package.
Units: m, s, rad. Numba caches the compiled code beside this file, so only the first run on a
machine compiles it.
"""

from __future__ import annotations

import heapq
import math

import numba
import numpy as np

#: Gap [m] the safety stop keeps from obstacles that stand (cones) instead of its margin. SUMO
#: measures a car's gap to a stopped vehicle along their lane, not between footprints; on a curve
#: the two differ by millimetres, and a car stopped in exact contact is a collision to SUMO.
STANDING_GAP = 0.05


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
def path_headings(cum, seg_heading, s0, count, spacing):
    """Headings (count,) [rad] of a path (cumulative arc lengths ``cum`` (M,), segment headings
    (M-1,)) at arc lengths ``s0 + spacing * k`` [m], as :meth:`aac_sumo.references.PathReference.pose_at`
    gives them, unwrapped as ``numpy.unwrap`` does."""
    out = np.empty(count)
    last = seg_heading.shape[0] - 1
    correction, raw = 0.0, 0.0
    for k in range(count):
        j = min(max(np.searchsorted(cum, s0 + spacing * k, side="right") - 1, 0), last)
        h = seg_heading[j]
        if k:
            d = h - raw
            dd = (d + math.pi) % (2.0 * math.pi) - math.pi
            if dd == -math.pi and d > 0.0:
                dd = math.pi
            if abs(d) >= math.pi:
                correction += dd - d
        raw = h
        out[k] = h + correction
    return out


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
def grow_trees(starts, samples, blockers, blocker_radius, foreign, step):
    """Grow one sampling tree per row of ``starts`` (R, 2) [m] towards its ``samples`` (R, K, 2)
    in order: each sample's nearest node (first on ties) steps at most ``step`` [m] towards it.
    A new node's collision cost sums ``(1 - d / r)^2`` over the ``blockers`` (M, 2) it is
    closer to than their ``blocker_radius`` (M,), counting only those ``foreign`` (R, M) to
    the tree; its path cost adds its parent's. Returns nodes (R, K+1, 2) and path costs
    (R, K+1), the root first."""
    r_count, k_count = samples.shape[0], samples.shape[1]
    nodes = np.empty((r_count, k_count + 1, 2))
    path_cost = np.zeros((r_count, k_count + 1))
    for r in range(r_count):
        nodes[r, 0, 0], nodes[r, 0, 1] = starts[r, 0], starts[r, 1]
        for it in range(k_count):
            sx, sy = samples[r, it, 0], samples[r, it, 1]
            near, best = 0, np.inf
            for j in range(it + 1):
                dx, dy = sx - nodes[r, j, 0], sy - nodes[r, j, 1]
                d2 = dx * dx + dy * dy
                if d2 < best:
                    near, best = j, d2
            qx, qy = nodes[r, near, 0], nodes[r, near, 1]
            dx, dy = sx - qx, sy - qy
            length = math.hypot(dx, dy)
            scale = step / max(length, 1e-12) if length > step else 1.0
            nx, ny = qx + scale * dx, qy + scale * dy
            cost = 0.0
            for b in range(blockers.shape[0]):
                if foreign[r, b]:
                    closeness = max(1.0 - math.hypot(nx - blockers[b, 0], ny - blockers[b, 1]) / blocker_radius[b], 0.0)
                    cost += closeness * closeness
            nodes[r, it + 1, 0], nodes[r, it + 1, 1] = nx, ny
            path_cost[r, it + 1] = path_cost[r, near] + cost
    return nodes, path_cost


@numba.njit(cache=True)
def _vertex_gap(ax, ay, al, aw, ah, bx, by, bl, bw, bh):
    """Least distance [m] from the corners of rectangle a to rectangle b (0 for a corner inside b)."""
    ca, sa, cb, sb = math.cos(ah), math.sin(ah), math.cos(bh), math.sin(bh)
    best = np.inf
    for su, sv in ((1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0)):
        du, dv = 0.5 * al * su, 0.5 * aw * sv
        dx, dy = ax + ca * du - sa * dv - bx, ay + sa * du + ca * dv - by
        qu = max(abs(cb * dx + sb * dy) - 0.5 * bl, 0.0)
        qv = max(abs(-sb * dx + cb * dy) - 0.5 * bw, 0.0)
        best = min(best, math.hypot(qu, qv))
    return best


@numba.njit(cache=True)
def rect_clearance(a, b):
    """Signed clearance [m] between rectangle rows ``a`` and ``b`` ``[cx, cy, length, width,
    heading]``, as :func:`aac_sumo.geometry.rect_clearance_rows`: the exact gap when apart,
    minus the penetration depth along the best separating axis when they overlap."""
    ax, ay, al, aw, ah = a[0], a[1], a[2], a[3], a[4]
    bx, by, bl, bw, bh = b[0], b[1], b[2], b[3], b[4]
    dx, dy = bx - ax, by - ay
    la, wa, lb, wb = 0.5 * al, 0.5 * aw, 0.5 * bl, 0.5 * bw
    cd, sd = abs(math.cos(bh - ah)), abs(math.sin(bh - ah))
    ca, sa, cb, sb = math.cos(ah), math.sin(ah), math.cos(bh), math.sin(bh)
    overlap = min(la + lb * cd + wb * sd - abs(dx * ca + dy * sa),
                  wa + lb * sd + wb * cd - abs(-dx * sa + dy * ca),
                  lb + la * cd + wa * sd - abs(dx * cb + dy * sb),
                  wb + la * sd + wa * cd - abs(-dx * sb + dy * cb))
    if overlap > 0.0:
        return -overlap
    return min(_vertex_gap(ax, ay, al, aw, ah, bx, by, bl, bw, bh), _vertex_gap(bx, by, bl, bw, bh, ax, ay, al, aw, ah))


@numba.njit(cache=True)
def pairwise_clearance(a, b):
    """Clearance matrix (n, m) [m] of :func:`rect_clearance` between rectangle rows ``a`` (n, 5)
    and ``b`` (m, 5)."""
    out = np.empty((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            out[i, j] = rect_clearance(a[i], b[j])
    return out


@numba.njit(cache=True)
def _half_extent(rect, nx, ny):
    """Half the length [m] of rectangle row ``rect`` ``[cx, cy, length, width, heading]``
    projected on the unit axis ``(nx, ny)``."""
    c, s = math.cos(rect[4]), math.sin(rect[4])
    return 0.5 * rect[2] * abs(c * nx + s * ny) + 0.5 * rect[3] * abs(-s * nx + c * ny)


@numba.njit(cache=True)
def sweep_gap(a, b, dx, dy):
    """How far [m] rectangle row ``a`` ``[cx, cy, length, width, heading]`` can translate along
    the unit direction ``(dx, dy)`` before its footprint touches rectangle row ``b``'s: 0 when
    they already touch or overlap, inf when it never does.

    Exact for any orientations: ``a`` shifted by ``s (dx, dy)`` meets ``b`` exactly when their
    projections overlap on each of the four edge normals of the two rectangles (the separating
    axis theorem; these are the edge normals of their Minkowski difference), and on each axis
    that holds for an interval of ``s``; the gap is the least ``s >= 0`` in all four intervals."""
    lo, hi = 0.0, np.inf
    for axis in range(4):
        h = a[4] if axis < 2 else b[4]
        if axis % 2 == 0:
            nx, ny = math.cos(h), math.sin(h)
        else:
            nx, ny = -math.sin(h), math.cos(h)
        sep = (b[0] - a[0]) * nx + (b[1] - a[1]) * ny  # centre of b relative to a's, on this axis
        reach = _half_extent(a, nx, ny) + _half_extent(b, nx, ny)
        rate = dx * nx + dy * ny
        if abs(rate) < 1e-12:  # moving parallel to this axis's lines: the overlap never changes
            if abs(sep) > reach:
                return np.inf
            continue
        s1, s2 = (sep - reach) / rate, (sep + reach) / rate
        lo, hi = max(lo, min(s1, s2)), min(hi, max(s1, s2))
        if lo > hi:
            return np.inf
    return lo


@numba.njit(cache=True)
def times_to_collision(rows, velocity, n):
    """Per robot i < n, the least time to collision [s] with the others: footprint rows ``rows``
    (M, 5) ``[cx, cy, length, width, heading]`` and velocities ``velocity`` (M, 2) [m/s] of
    everything, the first n being the robots themselves. For each other j, the closing
    velocity is ``w = velocity[i] - velocity[j]``; j counts when ``w`` points ahead of robot i
    (positive along its heading, so i is the one driving into j) and i's footprint, translated
    along ``w``, touches j's: TTC = :func:`sweep_gap` along ``w`` / ``|w|``. inf when nothing
    counts."""
    m = rows.shape[0]
    out = np.full(n, np.inf)
    for i in range(n):
        hx, hy = math.cos(rows[i, 4]), math.sin(rows[i, 4])
        for j in range(m):
            if j == i:
                continue
            wx, wy = velocity[i, 0] - velocity[j, 0], velocity[i, 1] - velocity[j, 1]
            closing = math.hypot(wx, wy)
            if closing <= 1e-6 or wx * hx + wy * hy <= 1e-6:
                continue
            out[i] = min(out[i], sweep_gap(rows[i], rows[j], wx / closing, wy / closing) / closing)
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


@numba.njit(cache=True)
def _closest_in(points, seg_len, t_max, px, py, first, last, best_i, best_t, best_d):
    """:func:`closest_on_polyline` over segments ``first..last-1``, starting from the best so far."""
    for i in range(first, last):
        ax, ay = points[i, 0], points[i, 1]
        dx, dy = points[i + 1, 0] - ax, points[i + 1, 1] - ay
        t = min(max(((px - ax) * dx + (py - ay) * dy) / seg_len[i] ** 2, 0.0), t_max[i])
        d = math.hypot(ax + t * dx - px, ay + t * dy - py)
        if d < best_d or (d == best_d and i < best_i):
            best_i, best_t, best_d = i, t, d
    return best_i, best_t, best_d


@numba.njit(cache=True)
def closest_on_polyline(points, seg_len, t_max, px, py, chunk_centre, chunk_radius, chunk):
    """The segment ``i`` of polyline ``points`` (M, 2) [m] (segment lengths ``seg_len`` (M-1,))
    closest to the point ``(px, py)`` (the first on ties), the fraction ``t`` of it, clipped
    into ``[0, t_max[i]]``, at which the closest point lies, and the distance [m] to it.

    Segments come in chunks of ``chunk``, chunk ``c`` within ``chunk_radius[c]`` of
    ``chunk_centre[c]`` (:func:`polyline_chunks`): the chunks are scanned nearest bound first,
    and those whose bound is beyond the best distance found are skipped, with the same answer
    as a scan of every segment. The last segment, which may carry on past the end
    (``t_max`` above 1), is always scanned."""
    n = seg_len.shape[0]
    best_i, best_t, best_d = _closest_in(points, seg_len, t_max, px, py, n - 1, n, 0, 0.0, np.inf)
    bound = np.empty(chunk_radius.shape[0])
    for c in range(bound.shape[0]):
        bound[c] = max(math.hypot(chunk_centre[c, 0] - px, chunk_centre[c, 1] - py) - chunk_radius[c], 0.0)
    for c in np.argsort(bound):
        if bound[c] > best_d:
            break
        best_i, best_t, best_d = _closest_in(points, seg_len, t_max, px, py, c * chunk, min((c + 1) * chunk, n), best_i, best_t, best_d)
    return best_i, best_t, best_d


@numba.njit(cache=True)
def project_points(points, seg_len, cum, t_max, queries, chunk_centre, chunk_radius, chunk):
    """Arc lengths (K,) [m] along polyline ``points`` (cumulative lengths ``cum``) of the
    closest points to ``queries`` (K, 2), and the distances (K,) [m] to them
    (:func:`closest_on_polyline` each)."""
    s = np.empty(queries.shape[0])
    d = np.empty(queries.shape[0])
    for k in range(queries.shape[0]):
        i, t, d[k] = closest_on_polyline(points, seg_len, t_max, queries[k, 0], queries[k, 1], chunk_centre, chunk_radius, chunk)
        s[k] = cum[i] + t * seg_len[i]
    return s, d


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
    over twice the room), up to ``brake`` [m/s^2] (``brake <= decel``: never harder than ``decel``)."""
    s = np.empty(steps + 1)
    v = np.empty(steps + 1)
    s[0], v[0] = s0, max(v0, 0.0)
    for k in range(steps + 1):
        if k:
            target = speed
            if limits.shape[0]:
                target = min(target, np.interp(s[k], path_s, limits))
            if stop_at_end:
                target = min(target, math.sqrt(2.0 * path_decel * max(length - s[k], 0.0)))
            rate = decel
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


def polyline_chunks(points: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres (C, 2) and radii (C,) [m] of circles holding the segments of ``points`` (M, 2),
    ``chunk`` segments each (the last chunk may be shorter): the bounds of :func:`closest_on_polyline`."""
    n = len(points) - 1
    starts = np.arange(0, n, chunk)
    centres, radii = np.empty((len(starts), 2)), np.empty(len(starts))
    for row, start in enumerate(starts):
        part = points[start:min(start + chunk, n) + 1]
        centres[row] = 0.5 * (part.min(axis=0) + part.max(axis=0))
        radii[row] = np.hypot(part[:, 0] - centres[row, 0], part[:, 1] - centres[row, 1]).max()
    return centres, radii


@numba.njit(cache=True)
def polyline_offsets(points, polyline):
    """Signed distance [m] (K,) of each of ``points`` (K, 2) to ``polyline`` (M, 2), M >= 2, its
    end segments carried on straight: positive to the left of its direction of travel, on the
    side of the nearest segment (the first on ties), as :func:`aac_sumo.geometry.polyline_offset`."""
    out = np.empty(points.shape[0])
    last = polyline.shape[0] - 2
    for k in range(points.shape[0]):
        px, py = points[k, 0], points[k, 1]
        best, best_i = np.inf, 0
        for i in range(last + 1):
            ax, ay = polyline[i, 0], polyline[i, 1]
            dx, dy = polyline[i + 1, 0] - ax, polyline[i + 1, 1] - ay
            length2 = dx * dx + dy * dy
            t = ((px - ax) * dx + (py - ay) * dy) / length2 if length2 >= 1e-18 else 0.0  # under 1 nm: a point, not carried on
            if i > 0:
                t = max(t, 0.0)
            if i < last:
                t = min(t, 1.0)
            gx, gy = px - (ax + t * dx), py - (ay + t * dy)
            dist = math.sqrt(gx * gx + gy * gy)
            if dist < best:
                best, best_i = dist, i
        ax, ay = polyline[best_i, 0], polyline[best_i, 1]
        dx, dy = polyline[best_i + 1, 0] - ax, polyline[best_i + 1, 1] - ay
        out[k] = -best if dx * (py - ay) - dy * (px - ax) < 0.0 else best
    return out


@numba.njit(cache=True)
def braking_tail(state, previous_steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, max_steps):
    """Inputs (K, 2) and rear-axle states (K+1, 4) of one robot braking from ``state`` (4,) to
    standstill: acceleration ``clip(-v / dt, -decel, decel)`` [m/s^2] and steering that turns
    its heading towards ``heading`` [rad] with time constant ``turn_time`` [s] within
    :func:`limited_steer` of ``steer_limits`` (3,) from ``previous_steer`` [rad] (as
    :func:`braking_courses`), until the speed is within 1e-12 m/s of zero or after
    ``max_steps`` periods."""
    states = np.empty((max_steps + 1, 4))
    inputs = np.empty((max_steps, 2))
    x, y, h, v = state[0], state[1], state[2], state[3]
    states[0, 0], states[0, 1], states[0, 2], states[0, 3] = x, y, h, v
    gain = min(1.0, dt / turn_time)
    k = 0
    steer = previous_steer
    while k < max_steps and abs(v) > 1e-12:
        accel = min(max(-v / dt, -decel), decel)
        steer = limited_steer(_heading_hold(heading, h, v, wheelbase, gain, dt), v, accel, steer, wheelbase, steer_limits, dt)
        x, y, h, v = _bicycle_step(x, y, h, v, accel, steer, dt, wheelbase, v_min, v_max)
        inputs[k, 0], inputs[k, 1] = accel, steer
        k += 1
        states[k, 0], states[k, 1], states[k, 2], states[k, 3] = x, y, h, v
    return states[: k + 1], inputs[:k]


@numba.njit(cache=True)
def course_clearance(own, others, margin):
    """Least footprint clearance [m] between the course ``own`` (K, 5) and the courses
    ``others`` (M, K, 5), stage by stage (footprint rows ``[cx, cy, length, width, heading]``),
    as :func:`rect_clearance`. Stages where two circumscribed discs lie at least ``margin``
    apart are not measured exactly (they count as that disc gap, a lower bound above
    ``margin``), so the result is exact wherever it is below ``margin``; inf without others."""
    best = np.inf
    r_own = 0.5 * math.hypot(own[0, 2], own[0, 3])
    for j in range(others.shape[0]):
        r_other = 0.5 * math.hypot(others[j, 0, 2], others[j, 0, 3])
        for k in range(own.shape[0]):
            apart = math.hypot(own[k, 0] - others[j, k, 0], own[k, 1] - others[j, k, 1]) - r_own - r_other
            if apart >= margin:
                best = min(best, apart)
            else:
                best = min(best, rect_clearance(own[k], others[j, k]))
    return best


@numba.njit(cache=True)
def ragged_nearest(own, flat, starts, lengths, boxes, skip, margin):
    """:func:`course_clearance` of the course ``own`` (K, 5) against courses of different
    lengths stored one after the other in ``flat`` (T, 5), and the course that gives it (the
    lowest index on ties; -1 without courses): course j is rows ``starts[j]`` to ``starts[j] +
    lengths[j] - 1``, and each course (``own`` too) stands at its last row once it has ended.
    Course ``skip`` is left out (-1: none). Each pair is compared over the stages until both
    have ended.

    ``boxes`` (J, 4) ``[x_lo, y_lo, x_hi, y_hi]`` [m] bound each course's footprint centres
    (:func:`course_boxes`). The gap between two boxes less both half diagonals bounds every
    stage's disc gap from below, so the courses are visited nearest box first, and the visit
    stops at the first course whose bound is at least ``margin`` and above the least
    clearance found: no course after it can give a smaller value, so the result is the same
    as comparing every course."""
    n_own = own.shape[0]
    r_own = 0.5 * math.hypot(own[0, 2], own[0, 3])
    x_lo, x_hi, y_lo, y_hi = own[0, 0], own[0, 0], own[0, 1], own[0, 1]
    for k in range(1, n_own):
        x_lo, x_hi = min(x_lo, own[k, 0]), max(x_hi, own[k, 0])
        y_lo, y_hi = min(y_lo, own[k, 1]), max(y_hi, own[k, 1])
    count_j = starts.shape[0]
    bound = np.empty(count_j)
    radius = np.empty(count_j)
    for j in range(count_j):
        radius[j] = 0.5 * math.hypot(flat[starts[j], 2], flat[starts[j], 3])
        dx = max(boxes[j, 0] - x_hi, x_lo - boxes[j, 2], 0.0)
        dy = max(boxes[j, 1] - y_hi, y_lo - boxes[j, 3], 0.0)
        bound[j] = math.hypot(dx, dy) - r_own - radius[j]
    best, nearest = np.inf, -1
    for j in np.argsort(bound, kind="mergesort"):
        if j == skip:
            continue
        if bound[j] >= margin and bound[j] > best:
            break
        first, count = starts[j], lengths[j]
        for k in range(max(n_own, count)):
            a = own[min(k, n_own - 1)]
            b = flat[first + min(k, count - 1)]
            apart = math.hypot(a[0] - b[0], a[1] - b[1]) - r_own - radius[j]
            gap = apart if apart >= margin else rect_clearance(a, b)
            if gap < best or (gap == best and j < nearest):
                best, nearest = gap, j
    return best, nearest


@numba.njit(cache=True)
def course_boxes(flat, starts, lengths):
    """Per course of ``flat`` (see :func:`ragged_nearest`), the box ``[x_lo, y_lo, x_hi, y_hi]``
    [m] (J, 4) of its footprint centres."""
    out = np.empty((starts.shape[0], 4))
    for j in range(starts.shape[0]):
        first = starts[j]
        out[j, 0], out[j, 2] = flat[first, 0], flat[first, 0]
        out[j, 1], out[j, 3] = flat[first, 1], flat[first, 1]
        for r in range(first + 1, first + lengths[j]):
            out[j, 0], out[j, 2] = min(out[j, 0], flat[r, 0]), max(out[j, 2], flat[r, 0])
            out[j, 1], out[j, 3] = min(out[j, 1], flat[r, 1]), max(out[j, 3], flat[r, 1])
    return out


@numba.njit(cache=True)
def tracking_course(x, y, h, v, steps, dt, wheelbase, a_min, a_max, steer_max, v_min, v_max, a_lat_max, a_lat_comfort, steer_rate_max, comfort,
                    previous_steer, points, seg_len, cum, seg_dir, seg_heading, t_max, chunk_centre, chunk_radius, chunk, limits,
                    speed, decel, stop_at_end, approach, lookahead, speed_gain, offset, target_speed):
    """Inputs (steps, 2) ``[accel, steer]`` of the tracking law (the loop form of
    :func:`aac_sumo.coordination.tracking.track`) applied period after period from the rear-axle
    state ``(x, y, h, v)``, each step of :func:`_bicycle_step` with the inputs clipped to the
    robot's bounds. Pure pursuit of the path point ``lookahead`` [m] beyond the projection
    (clamped to the end of a path that stops), moved ``offset`` [m] to the right; within
    ``approach`` [m] of the goal of a path that stops, straight at the goal at the speed that
    stops there. The speed loop drives towards the path's speed at the projection (its
    ``limits`` (M,) over ``cum`` when non-empty, its stopping profile at ``decel``), or
    ``target_speed`` when that is not NaN, braking at most at ``comfort``; the steering keeps
    the rate limit from the one before and the lateral limit ``a_lat_max`` at the larger of the
    speeds now and after the period, and comes within the comfort limit ``a_lat_comfort`` as
    far as the rate limit lets it (a car beyond it, on a plan made within the car's full limits,
    is brought back within it at the steering rate, not in one period)."""
    out = np.empty((steps, 2))
    n_seg = seg_len.shape[0]
    length = cum[n_seg]
    gx, gy = points[n_seg, 0], points[n_seg, 1]
    steer_prev = previous_steer
    for k in range(steps):
        i, t, _ = closest_on_polyline(points, seg_len, t_max, x, y, chunk_centre, chunk_radius, chunk)
        s0 = cum[i] + t * seg_len[i]
        sl = min(s0 + lookahead, length) if stop_at_end else s0 + lookahead
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
        if near_goal:
            want = min(speed, math.sqrt(2.0 * decel * dist))
        else:
            cap = speed if limits.shape[0] == 0 else np.interp(s0, cum, limits)
            want = min(speed, cap) if not stop_at_end else min(cap, math.sqrt(2.0 * decel * max(length - s0, 0.0)))
            if not math.isnan(target_speed):
                want = target_speed
        accel = min(max(speed_gain * (want - v), -comfort), a_max)
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
        steer = min(max(steer, -bound), bound)
        out[k, 0], out[k, 1] = accel, steer
        x, y, h, v = _bicycle_step(x, y, h, v, min(max(accel, a_min), a_max), min(max(steer, -steer_max), steer_max), dt, wheelbase,
                                   v_min, v_max)
        steer_prev = steer
    return out


@numba.njit(cache=True)
def grid_path(cost, start, goal):
    """Cheapest 8-connected path of cells from ``start`` to ``goal`` (row, column) over the cell
    costs ``cost`` (rows, columns) [per cell side], each at least 1 (inf: blocked); a step's
    cost is its length in cell sides times the mean of its two cells' costs (A* with the octile
    distance, admissible since every cost is at least 1). Returns the flat cell indices (K,)
    from start to goal, empty when the goal cannot be reached."""
    rows, cols = cost.shape
    n = rows * cols
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    s, t = start[0] * cols + start[1], goal[0] * cols + goal[1]
    g[s] = 0.0
    heap = [(0.0, s)]
    diag = math.sqrt(2.0)
    while len(heap):
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == t:
            break
        closed[u] = True
        ur, uc = u // cols, u % cols
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                if dr == 0 and dc == 0:
                    continue
                vr, vc = ur + dr, uc + dc
                if vr < 0 or vr >= rows or vc < 0 or vc >= cols:
                    continue
                v = vr * cols + vc
                if closed[v] or not math.isfinite(cost[vr, vc]):
                    continue
                step = (diag if dr != 0 and dc != 0 else 1.0) * 0.5 * (cost[ur, uc] + cost[vr, vc])
                if g[u] + step < g[v]:
                    g[v] = g[u] + step
                    parent[v] = u
                    ar, ac = abs(vr - goal[0]), abs(vc - goal[1])
                    h = max(ar, ac) + (diag - 1.0) * min(ar, ac)
                    heapq.heappush(heap, (g[v] + h, v))
    if not math.isfinite(g[t]):
        return np.empty(0, dtype=np.int64)
    k, u = 1, t
    while u != s:
        u = parent[u]
        k += 1
    out = np.empty(k, dtype=np.int64)
    u = t
    for i in range(k - 1, -1, -1):
        out[i] = u
        u = parent[u]
    return out


@numba.njit(cache=True)
def _rect_distance(px, py, rect, c, s):
    """Distance [m] from the point (``px``, ``py``) to the rectangle ``rect`` ``[cx, cy, length,
    width, heading]`` whose heading has cosine ``c`` and sine ``s`` (0 inside)."""
    dx, dy = px - rect[0], py - rect[1]
    qx = abs(c * dx + s * dy) - 0.5 * rect[2]
    qy = abs(-s * dx + c * dy) - 0.5 * rect[3]
    return math.hypot(max(qx, 0.0), max(qy, 0.0))


@numba.njit(cache=True)
def distance_field(lo, cell, rows, cols, rects, reach):
    """Distance [m] from the centre of each cell (``rows``, ``cols``) of the grid whose first cell
    centre is ``lo`` (2,) [m] and whose side is ``cell`` [m] to the nearest of ``rects`` (m, 5),
    for the cells within ``reach`` [m] of a rectangle's enclosing disc (the window of each
    rectangle, whole cells; inf elsewhere). Each value is
    :func:`aac_sumo.geometry.rect_distances` of the cell centre over the rectangles whose
    window holds it."""
    dist = np.full((rows, cols), np.inf)
    for k in range(len(rects)):
        rect = rects[k]
        c, s = math.cos(rect[4]), math.sin(rect[4])
        r = 0.5 * math.hypot(rect[2], rect[3]) + reach
        c0 = max(int(math.floor((rect[0] - r - lo[0]) / cell)), 0)
        r0 = max(int(math.floor((rect[1] - r - lo[1]) / cell)), 0)
        c1 = min(int(math.ceil((rect[0] + r - lo[0]) / cell)) + 1, cols)
        r1 = min(int(math.ceil((rect[1] + r - lo[1]) / cell)) + 1, rows)
        for row in range(r0, r1):
            py = lo[1] + cell * row
            for col in range(c0, c1):
                d = _rect_distance(lo[0] + cell * col, py, rect, c, s)
                if d < dist[row, col]:
                    dist[row, col] = d
    return dist


@numba.njit(cache=True)
def band_costs(dist, hard, clearance, penalty):
    """Cell costs (rows, cols) from the distances ``dist`` [m] to the nearest footprint: 1 at
    ``clearance`` or beyond, rising linearly to ``1 + penalty`` at ``hard``, inf (blocked) below
    ``hard``."""
    out = np.empty(dist.shape)
    scale = max(clearance - hard, 1e-9)
    for r in range(dist.shape[0]):
        for c in range(dist.shape[1]):
            d = dist[r, c]
            out[r, c] = np.inf if d < hard else 1.0 + penalty * min(max((clearance - d) / scale, 0.0), 1.0)
    return out


@numba.njit(cache=True)
def shortcut(path, kept, rects, hard, cell, samples):
    """Indices (J,) of the corners of ``path`` (K, 2) [m] it needs: from each kept point on, the
    farthest later point up to which the straight segment, sampled ``samples`` times per ``cell``
    [m], keeps from ``rects`` (m, 5) at least the smallest of ``kept`` (K,) [m] over the same
    stretch, at least ``hard``, less half a cell. The first and the last point are always kept."""
    m, last = len(rects), len(path) - 1
    cos, sin, radius = np.empty(m), np.empty(m), np.empty(m)
    for k in range(m):
        cos[k], sin[k] = math.cos(rects[k, 4]), math.sin(rects[k, 4])
        radius[k] = 0.5 * math.hypot(rects[k, 2], rects[k, 3])  # each rectangle lies within this of its centre
    near = np.empty(m, dtype=np.int64)
    out = [0]
    i = 0
    while i < last:
        j = i + 1
        low = min(kept[i], kept[i + 1])
        while j < last:
            low = min(low, kept[j + 1])
            need = max(low, hard) - 0.5 * cell
            ax, ay = path[i, 0], path[i, 1]
            ux, uy = path[j + 1, 0] - ax, path[j + 1, 1] - ay
            length = math.hypot(ux, uy)
            scale = max(length * length, 1e-12)
            count = 0
            for k in range(m):  # only these can be closer than need
                along = min(max(((rects[k, 0] - ax) * ux + (rects[k, 1] - ay) * uy) / scale, 0.0), 1.0)
                if math.hypot(ax + along * ux - rects[k, 0], ay + along * uy - rects[k, 1]) < need + radius[k]:
                    near[count] = k
                    count += 1
            blocked = False
            if count > 0:
                n = max(2, int(math.ceil(samples * length / cell)) + 1)
                step = 1.0 / (n - 1)
                for q in range(n):
                    t = 1.0 if q == n - 1 else q * step
                    px, py = ax + t * ux, ay + t * uy
                    for e in range(count):
                        k = near[e]
                        if _rect_distance(px, py, rects[k], cos[k], sin[k]) < need:
                            blocked = True
                            break
                    if blocked:
                        break
            if blocked:
                break
            j += 1
        out.append(j)
        i = j
    return np.array(out)


@numba.njit(cache=True)
def rects_within(points, rects, reach):
    """Whether each of ``rects`` (m, 5) comes closer than ``reach`` [m] to one of ``points`` (k,
    2) [m] (by :func:`aac_sumo.geometry.rect_distances`), (m,)."""
    out = np.zeros(len(rects), dtype=np.bool_)
    if len(points) == 0:
        return out
    x_lo, x_hi = points[:, 0].min(), points[:, 0].max()
    y_lo, y_hi = points[:, 1].min(), points[:, 1].max()
    for k in range(len(rects)):
        # a rectangle lies within its half diagonal of its centre: one that far beyond the points' box is out of reach
        outside = math.hypot(max(x_lo - rects[k, 0], rects[k, 0] - x_hi, 0.0), max(y_lo - rects[k, 1], rects[k, 1] - y_hi, 0.0))
        if outside > reach + 0.5 * math.hypot(rects[k, 2], rects[k, 3]) + 1e-9:
            continue
        c, s = math.cos(rects[k, 4]), math.sin(rects[k, 4])
        for p in range(len(points)):
            if _rect_distance(points[p, 0], points[p, 1], rects[k], c, s) < reach:
                out[k] = True
                break
    return out


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


@numba.njit(cache=True)
def stopping_course(state, head, previous_steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, points, seg_len,
                    cum, seg_heading, t_max, chunk_centre, chunk_radius, chunk):
    """States (T+1, 4) and inputs (T, 2) of one robot from ``state`` (4,): the inputs ``head``
    (m, 2) (:func:`rollouts`), then :func:`braking_tail` at ``decel`` [m/s^2] from the head's
    last steering (``previous_steer`` without a head), turning towards ``heading`` [rad], or,
    when the path ``points`` (M, 2) is not empty, towards the heading of the path's segment where
    the head ends (of the later segment at a vertex; the path as
    :meth:`~aac_sumo.references.PathReference.arrays` gives it), for at most
    ``ceil(|v| / decel / dt) + 2`` periods."""
    states = rollouts(state.reshape(1, 4), head.reshape(1, head.shape[0], 2), dt, np.array([wheelbase]), np.array([v_min]),
                      np.array([v_max]))[0]
    last = states[states.shape[0] - 1]
    if points.shape[0] > 0:
        i, t, _ = closest_on_polyline(points, seg_len, t_max, last[0], last[1], chunk_centre, chunk_radius, chunk)
        if i + 1 < seg_len.shape[0] and cum[i] + t * seg_len[i] >= cum[i + 1]:
            i += 1  # at the vertex that ends segment i
        heading = seg_heading[i]
    steer = head[head.shape[0] - 1, 1] if head.shape[0] > 0 else previous_steer
    max_steps = int(math.ceil(abs(last[3]) / decel / dt)) + 2
    tail_states, tail_inputs = braking_tail(last, steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, max_steps)
    out_states = np.empty((states.shape[0] + tail_states.shape[0] - 1, 4))
    out_states[: states.shape[0]] = states
    out_states[states.shape[0]:] = tail_states[1:]
    out_inputs = np.empty((head.shape[0] + tail_inputs.shape[0], 2))
    out_inputs[: head.shape[0]] = head
    out_inputs[head.shape[0]:] = tail_inputs
    return out_states, out_inputs


@numba.njit(cache=True)
def pair_components(n, first, second):
    """Connected components of the graph on ``n`` nodes with the edges ``first[e]``-``second[e]``
    (E,): each node's component label (n,), numbered in the order of their lowest nodes."""
    parent = np.arange(n)
    for e in range(first.shape[0]):
        a, b = first[e], second[e]
        while parent[a] != a:
            a = parent[a]
        while parent[b] != b:
            b = parent[b]
        if a != b:
            parent[max(a, b)] = min(a, b)  # every root is its component's lowest node
    label = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):  # a node's root is lower than it, so labelled already
        root = i
        while parent[root] != root:
            root = parent[root]
        if root == i:
            label[i] = count
            count += 1
        else:
            label[i] = label[root]
    return label


@numba.njit(cache=True)
def path_poses(points, cum, seg_len, seg_dir, seg_heading, stop_at_end, s):
    """Rows ``[x, y, heading]`` (K, 3) of the polyline ``points`` (M, 2) at the arc lengths ``s``
    (K,) [m]: on the segment each lies on (the first or the last beyond the ends; ``cum`` (M,)
    cumulative arc lengths, ``seg_len``, ``seg_dir`` (M-1, 2) and ``seg_heading`` per segment),
    clamped to it when ``stop_at_end``, else carried on straight past the ends."""
    out = np.empty((s.shape[0], 3))
    last = seg_len.shape[0] - 1
    for k in range(s.shape[0]):
        i = min(max(np.searchsorted(cum, s[k], side="right") - 1, 0), last)
        local = s[k] - cum[i]
        if stop_at_end:
            local = min(max(local, 0.0), seg_len[i])
        out[k, 0] = points[i, 0] + local * seg_dir[i, 0]
        out[k, 1] = points[i, 1] + local * seg_dir[i, 1]
        out[k, 2] = seg_heading[i]
    return out


@numba.njit(cache=True)
def swept_hull_ellipses(rows, theta):
    """Ellipses ``[cx, cy, a, b, theta]`` (m, K, 5) containing, per stage k, the corners of the
    footprints ``rows`` (m, K+1, 5) at k and k+1, oriented by ``theta`` (m, K) [rad]: in the
    frame rotated by theta, centred on the corners' bounding box with its aspect ratio and
    scaled until the farthest corner lies on it. The same numbers, operation for operation, as
    :func:`aac_sumo.geometry.containing_ellipse` of :func:`aac_sumo.geometry.rect_corners` of
    both stages."""
    m, stages = theta.shape
    out = np.empty((m, stages, 5))
    px, py = np.empty(8), np.empty(8)
    su = (1.0, 1.0, -1.0, -1.0)  # the corner signs of rect_corners
    sv = (-1.0, 1.0, 1.0, -1.0)
    for j in range(m):
        for k in range(stages):
            for half in range(2):
                r = rows[j, k + half]
                c, s = math.cos(r[4]), math.sin(r[4])
                for q in range(4):
                    du = 0.5 * r[2] * su[q]
                    dv = 0.5 * r[3] * sv[q]
                    px[4 * half + q] = r[0] + c * du - s * dv
                    py[4 * half + q] = r[1] + s * du + c * dv
            ct, st = math.cos(theta[j, k]), math.sin(theta[j, k])
            u_lo, u_hi, v_lo, v_hi = np.inf, -np.inf, np.inf, -np.inf
            for p in range(8):
                u = ct * px[p] + st * py[p]
                v = -st * px[p] + ct * py[p]
                u_lo, u_hi, v_lo, v_hi = min(u_lo, u), max(u_hi, u), min(v_lo, v), max(v_hi, v)
            uc, vc = 0.5 * (u_lo + u_hi), 0.5 * (v_lo + v_hi)
            hu = max(0.5 * (u_hi - u_lo), 1e-6)
            hv = max(0.5 * (v_hi - v_lo), 1e-6)
            scale = 0.0
            for p in range(8):
                u = ct * px[p] + st * py[p]
                v = -st * px[p] + ct * py[p]
                scale = max(scale, math.sqrt(((u - uc) / hu) ** 2 + ((v - vc) / hv) ** 2))
            scale = max(scale, 1.0) * (1.0 + 1e-9)
            out[j, k, 0] = ct * uc - st * vc
            out[j, k, 1] = st * uc + ct * vc
            out[j, k, 2] = scale * hu
            out[j, k, 3] = scale * hv
            out[j, k, 4] = theta[j, k]
    return out
