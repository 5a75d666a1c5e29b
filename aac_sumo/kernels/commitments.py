"""Compiled loops of the commitment book (:mod:`aac_sumo.coordination.commitments`): stopping courses,
the clearance of one course against many, and the groups of robots whose courses meet.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aac_sumo.kernels.geometry import rect_clearance
from aac_sumo.kernels.motion import braking_tail, rollouts
from aac_sumo.kernels.paths import closest_on_polyline


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
def _ragged_gap(own, r_own, flat, first, count, radius, margin):
    """:func:`course_clearance` of ``own`` (K, 5) against the course of ``count`` rows from row
    ``first`` of ``flat`` (half diagonal ``radius``), each standing at its last row once ended."""
    best = np.inf
    for k in range(max(own.shape[0], count)):
        a = own[min(k, own.shape[0] - 1)]
        b = flat[first + min(k, count - 1)]
        apart = math.hypot(a[0] - b[0], a[1] - b[1]) - r_own - radius
        best = min(best, apart if apart >= margin else rect_clearance(a, b))
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
    stage's disc gap from below. The course of the least bound is compared first; after it, a
    course whose bound is at least ``margin`` and above the least clearance found so far is
    skipped: its clearance is at least its bound, so it can neither give nor tie the least
    (which only falls), and the result is the same as comparing every course."""
    n_own = own.shape[0]
    r_own = 0.5 * math.hypot(own[0, 2], own[0, 3])
    x_lo, x_hi, y_lo, y_hi = own[0, 0], own[0, 0], own[0, 1], own[0, 1]
    for k in range(1, n_own):
        x_lo, x_hi = min(x_lo, own[k, 0]), max(x_hi, own[k, 0])
        y_lo, y_hi = min(y_lo, own[k, 1]), max(y_hi, own[k, 1])
    count_j = starts.shape[0]
    bound = np.empty(count_j)
    radius = np.empty(count_j)
    least = -1
    for j in range(count_j):
        radius[j] = 0.5 * math.hypot(flat[starts[j], 2], flat[starts[j], 3])
        dx = max(boxes[j, 0] - x_hi, x_lo - boxes[j, 2], 0.0)
        dy = max(boxes[j, 1] - y_hi, y_lo - boxes[j, 3], 0.0)
        bound[j] = math.hypot(dx, dy) - r_own - radius[j]
        if j != skip and (least < 0 or bound[j] < bound[least]):
            least = j
    if least < 0:
        return np.inf, -1
    best, nearest = _ragged_gap(own, r_own, flat, starts[least], lengths[least], radius[least], margin), least
    for j in range(count_j):
        if j == skip or j == least or (bound[j] >= margin and bound[j] > best):
            continue
        gap = _ragged_gap(own, r_own, flat, starts[j], lengths[j], radius[j], margin)
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
def stopping_course(state, head, previous_steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, points, seg_len,
                    cum, seg_heading, t_max, chunk_centre, chunk_radius, chunk, along):
    """States (T+1, 4) and inputs (T, 2) of one robot from ``state`` (4,): the inputs ``head``
    (m, 2) (:func:`rollouts`), then :func:`braking_tail` at ``decel`` [m/s^2] from the head's
    last steering (``previous_steer`` without a head), turning towards ``heading`` [rad], or,
    when the path ``points`` (M, 2) is not empty, towards the heading of the path's segment where
    the head ends (of the later segment at a vertex; the path as
    :meth:`~aac_sumo.references.PathReference.arrays` gives it), for at most
    ``ceil(|v| / decel / dt) + 2`` periods; with ``along``, towards the path's heading
    where the robot will be, period after period (a lane: :func:`braking_tail`)."""
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
    if along and points.shape[0] > 0:
        tail_states, tail_inputs = braking_tail(last, steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, max_steps,
                                                points, seg_len, cum, seg_heading, t_max, chunk_centre, chunk_radius, chunk)
    else:
        tail_states, tail_inputs = braking_tail(last, steer, heading, decel, wheelbase, v_min, v_max, steer_limits, dt, turn_time, max_steps,
                                                points[:0], seg_len[:0], cum, seg_heading[:0], t_max[:0], chunk_centre[:0], chunk_radius[:0],
                                                chunk)
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
