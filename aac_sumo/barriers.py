"""Safety regions of obstacles and the discrete-time barrier condition.

Two shapes, both ellipses in the world frame:

* **F-CBF** (paper eqs. 6-7): semi-axes grow with the obstacle's speed through a sigmoid,
  ``a = L/2 + mu1 * sigma(|v_par| - v0) * |v_par|``, ``b = W/2 + mu2 * sigma(|v_perp| - v0) * |v_perp|``,
  with the major axis along the obstacle's velocity (its heading when it stands still).
* **CBF**: the obstacle's fixed footprint ellipse ``(L/2, W/2)`` along its heading.

The ego robot is covered by discs of radius ``r`` whose centres lie on its body axis; the
barrier keeps every disc centre outside the safety ellipse grown by ``d = r + d_safe``. Inside
the MPC this is the algebraic form ``h = (x'/A)^2 + (y'/B)^2 - 1`` of an ellipse ``(A, B)`` that
provably contains the Minkowski sum ``ellipse + disc(d)`` (see :func:`inflate_for_disc`), so every
point the MPC accepts has exact signed distance ``>= d`` from the safety ellipse.

The obstacle's shape at each MPC stage comes from its predicted velocity at that stage, which
is how the paper's shape-change term (rho) enters the discrete condition
``h(x_{k+1}, ob_{k+1}) - (1 - gamma) h(x_k, ob_k) >= 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param
from aac_sumo.kernels.geometry import swept_hull_ellipses

BARRIERS = ("fcbf", "cbf")
#: Per-stage, per-slot parameter layout fed to the MPC.
STAGE_FIELDS = ("cx", "cy", "cos", "sin", "inv_a2", "inv_b2", "active")
N_STAGE_FIELDS = len(STAGE_FIELDS)


@dataclass(frozen=True)
class FcbfParams:
    """Shape parameters of the F-CBF ellipse: gains [s], sigmoid steepness [s/m], threshold [m/s]."""

    mu1: float = param(0.2, "F-CBF gain along the velocity [s]", **NN)
    mu2: float = param(0.2, "F-CBF gain across the velocity [s]", **NN)
    k: float = param(2.0, "F-CBF sigmoid steepness k [s/m]", key="sigmoid_k", **P)
    v0: float = param(1.0, "F-CBF sigmoid threshold v0 [m/s]", **NN)


def sigmoid(x, k: float):
    """Logistic function ``1 / (1 + exp(-k x))``, numerically safe for large |k x|."""
    return 0.5 * (1.0 + np.tanh(0.5 * k * np.asarray(x, dtype=float)))


def fcbf_stretch(velocity, heading, params: FcbfParams, v_eps: float = 1e-3):
    """F-CBF growth of the semi-axes [m] and the ellipse orientation [rad].

    ``velocity`` (..., 2) is world-frame [m/s], ``heading`` (...) [rad]. The orientation is the
    velocity heading, or ``heading`` below ``v_eps``; the velocity is split into the components
    along and across it, giving ``mu1 * sigma(|v_par| - v0) * |v_par|`` and the same across.
    """
    velocity = np.asarray(velocity, dtype=float)
    speed = np.hypot(velocity[..., 0], velocity[..., 1])
    phi = np.where(speed > v_eps, np.arctan2(velocity[..., 1], velocity[..., 0]), heading)
    v_par = np.abs(velocity[..., 0] * np.cos(phi) + velocity[..., 1] * np.sin(phi))
    v_perp = np.abs(-velocity[..., 0] * np.sin(phi) + velocity[..., 1] * np.cos(phi))
    da = params.mu1 * sigmoid(v_par - params.v0, params.k) * v_par
    db = params.mu2 * sigmoid(v_perp - params.v0, params.k) * v_perp
    return da, db, phi


def fcbf_axes(length, width, velocity, heading, params: FcbfParams, v_eps: float = 1e-3):
    """F-CBF safety ellipse semi-axes [m] and orientation [rad] of obstacles: the footprint's
    ``(L/2, W/2)`` grown by :func:`fcbf_stretch`. ``length``, ``width`` and ``heading`` have
    shape (...); ``velocity`` has shape (..., 2) in the world frame [m/s]."""
    da, db, phi = fcbf_stretch(velocity, heading, params, v_eps)
    return 0.5 * np.asarray(length) + da, 0.5 * np.asarray(width) + db, phi


def cbf_axes(length, width, heading):
    """Plain-CBF ellipse: the fixed footprint ellipse ``(L/2, W/2)`` along the obstacle's heading."""
    return 0.5 * np.asarray(length, dtype=float), 0.5 * np.asarray(width, dtype=float), np.asarray(heading, dtype=float)


def inflate_for_disc(a, b, d, toward=None):
    """Semi-axes ``(A, B)`` of an ellipse containing ``ellipse(a, b) + disc(d)`` (Minkowski sum).

    For any ``e > 0``, ``(sqrt(S) + d)^2 <= (1 + e) S + (1 + 1/e) d^2`` bounds the support function
    ``S(u) = a^2 u_x^2 + b^2 u_y^2`` of the grown set, so ``A^2 = (1 + e) a^2 + (1 + 1/e) d^2`` and
    ``B^2 = (1 + e) b^2 + (1 + 1/e) d^2`` always contain it. The bound is exact in the direction
    ``u`` with ``e = d / sqrt(S(u))``. ``toward`` (..., 2), a point in the ellipse's local frame,
    picks ``u`` as the ellipse normal where the ray to that point leaves the ellipse, so the
    region is tight on the side facing the ego; without it ``e = d / sqrt(a b)``.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    d = np.asarray(d, dtype=float)
    if toward is None:
        support = a * b
    else:
        local = np.asarray(toward, dtype=float)
        nx, ny = local[..., 0] / a**2, local[..., 1] / b**2  # normal direction, up to scale
        length = np.hypot(nx, ny)
        big = np.abs(np.stack(np.broadcast_arrays(nx, ny))).max(axis=0)
        tiny = (length < 1e-150) & (big > 0)  # a norm that underflows (denormal components): scale to 1 first
        nx, ny = np.where(tiny, nx / np.where(tiny, big, 1.0), nx), np.where(tiny, ny / np.where(tiny, big, 1.0), ny)
        length = np.where(tiny, np.hypot(nx, ny), length)
        safe = np.where(length > 0, length, 1.0)
        ux, uy = np.where(length > 0, nx / safe, 1.0), np.where(length > 0, ny / safe, 0.0)
        support = (a * ux) ** 2 + (b * uy) ** 2
    root = np.sqrt(support)  # e = d / root; (1 + 1/e) d^2 = d^2 + d root, free of 1/e
    return (np.sqrt(a**2 * (1.0 + d / root) + d**2 + d * root),
            np.sqrt(b**2 * (1.0 + d / root) + d**2 + d * root))


def barrier_value(px, py, cx, cy, cos_phi, sin_phi, inv_a2, inv_b2):
    """Algebraic barrier ``(x'/A)^2 + (y'/B)^2 - 1`` of a point; works for numpy and casadi."""
    dx = px - cx
    dy = py - cy
    xl = cos_phi * dx + sin_phi * dy
    yl = -sin_phi * dx + cos_phi * dy
    return xl * xl * inv_a2 + yl * yl * inv_b2 - 1.0


#: Per-slot layout of the MPC's terminal stopping condition: the stage fields, then ``along`` (1:
#: the region lies across the ego's line of travel) and ``give`` [m] (how far the along form may be
#: broken, where even braking at once breaks it).
TERMINAL_FIELDS = STAGE_FIELDS + ("along", "give")
N_TERMINAL_FIELDS = len(TERMINAL_FIELDS)


def support(params: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Support [m] in the unit world ``direction`` (2,) of regions given as MPC stage parameters
    (..., >= 6): the largest extent of each ellipse from its centre along that direction."""
    ul = params[..., 2] * direction[0] + params[..., 3] * direction[1]
    vl = -params[..., 3] * direction[0] + params[..., 2] * direction[1]
    return np.sqrt(ul**2 / params[..., 4] + vl**2 / params[..., 5])


def stopping_barrier(px, py, ux, uy, stop, cx, cy, cos_phi, sin_phi, inv_a2, inv_b2, along, give, xp=np):
    """Terminal stopping condition (>= 0) of an ego disc at ``(px, py)`` that stops ``stop`` [m]
    further on in the unit direction ``(ux, uy)``, against a region given as in :func:`barrier_value`.

    ``along = 0``: the algebraic barrier of the stopping point. ``along = 1`` (a region on the
    line of travel, where the stopping point could jump past it): the distance [m] by which the
    stopping point stays short of the region's near edge, its support ``sqrt((u'A)^2 + (v'B)^2)``
    in the direction of travel, plus ``give``. ``xp`` is numpy or casadi."""
    end = barrier_value(px + stop * ux, py + stop * uy, cx, cy, cos_phi, sin_phi, inv_a2, inv_b2)
    ul, vl = cos_phi * ux + sin_phi * uy, -sin_phi * ux + cos_phi * uy
    short = (cx - px) * ux + (cy - py) * uy - stop - xp.sqrt(ul * ul / inv_a2 + vl * vl / inv_b2) + give
    return along * short + (1 - along) * end


@dataclass(frozen=True)
class ObstaclePrediction:
    """Predicted obstacle over the horizon: centres (N+1, 2) [m], velocities (N+1, 2) [m/s],
    headings (N+1,) [rad], and its footprint length/width [m]. A batch of M obstacles carries a
    leading axis: centres (M, N+1, 2), ..., and length/width (M, 1)."""

    centres: np.ndarray
    velocities: np.ndarray
    headings: np.ndarray
    length: float | np.ndarray
    width: float | np.ndarray


def predict_constant_velocity(centre, velocity, heading, length, width, horizon: int, dt: float) -> ObstaclePrediction:
    """Constant-velocity prediction over stages ``0..horizon``."""
    steps = np.arange(horizon + 1)[:, None] * dt
    centre = np.asarray(centre, dtype=float)
    velocity = np.asarray(velocity, dtype=float)
    return ObstaclePrediction(
        centres=centre + steps * velocity,
        velocities=np.repeat(velocity[None, :], horizon + 1, axis=0),
        headings=np.full(horizon + 1, float(heading)),
        length=float(length),
        width=float(width),
    )


def stack_predictions(preds: list[ObstaclePrediction]) -> ObstaclePrediction:
    """The batch of ``preds`` (same horizon) along a leading axis."""
    return ObstaclePrediction(np.stack([p.centres for p in preds]), np.stack([p.velocities for p in preds]), np.stack([p.headings for p in preds]),
                              np.array([[p.length] for p in preds], dtype=float), np.array([[p.width] for p in preds], dtype=float))


def safety_ellipses(pred: ObstaclePrediction, barrier: str, fcbf: FcbfParams) -> np.ndarray:
    """Safety ellipse per stage as rows ``[cx, cy, a, b, phi]``: (N+1, 5), or (M, N+1, 5) for a batch."""
    if barrier == "fcbf":
        a, b, phi = fcbf_axes(pred.length, pred.width, pred.velocities, pred.headings, fcbf)
    elif barrier == "cbf":
        shape = np.shape(pred.headings)
        a, b, phi = cbf_axes(np.broadcast_to(pred.length, shape), np.broadcast_to(pred.width, shape), pred.headings)
    else:
        raise ValueError(f"unknown barrier {barrier!r}; expected one of {BARRIERS}")
    return np.stack([pred.centres[..., 0], pred.centres[..., 1], np.broadcast_to(a, phi.shape), np.broadcast_to(b, phi.shape), phi], axis=-1)


def stage_parameters(ellipses: np.ndarray, d, ego=None) -> np.ndarray:
    """MPC parameters (..., 7) of obstacle slots from ellipses (..., 5) and ego clearance ``d`` [m].

    ``d`` broadcasts against ``ellipses[..., 0]`` (a leading axis of clearances gives one set of
    parameters each). ``ego`` (..., 2), the ego's world position (broadcast against
    ``ellipses[..., :2]``), makes each region tightest on the side facing it (see
    :func:`inflate_for_disc`); containment holds either way.
    """
    phi = ellipses[..., 4]
    cos_phi, sin_phi = np.cos(phi), np.sin(phi)
    toward = None
    if ego is not None:
        rel = np.asarray(ego, dtype=float) - ellipses[..., :2]
        toward = np.stack([cos_phi * rel[..., 0] + sin_phi * rel[..., 1], -sin_phi * rel[..., 0] + cos_phi * rel[..., 1]], axis=-1)
    big_a, big_b = inflate_for_disc(ellipses[..., 2], ellipses[..., 3], d, toward)
    out = np.empty(big_a.shape + (N_STAGE_FIELDS,))
    out[..., 0], out[..., 1], out[..., 2], out[..., 3] = ellipses[..., 0], ellipses[..., 1], cos_phi, sin_phi
    out[..., 4], out[..., 5], out[..., 6] = big_a**-2, big_b**-2, 1.0
    return out


@dataclass(frozen=True)
class RegionTrack:
    """Safety ellipses ``[cx, cy, a, b, phi]`` per stage (N+1, 5), already shaped (e.g. around a
    robot's swept convex hull); the planner uses them as they are."""

    name: str
    ellipses: np.ndarray


def hull_safety_ellipses(rows, velocities, headings, barrier: str, fcbf: FcbfParams) -> np.ndarray:
    """Per-stage safety ellipses (m, K, 5) that contain the convex hull of the footprints
    ``rows`` (m, K+1, 5) ``[cx, cy, length, width, heading]`` at stages k and k+1.

    Each stage's base ellipse contains the eight corners (:func:`~aac_sumo.geometry.containing_ellipse`,
    compiled as :func:`~aac_sumo.kernels.geometry.swept_hull_ellipses`, oriented like the F-CBF
    ellipse); F-CBF then grows its axes with the stage ``velocities`` (m, K, 2) as in
    :func:`fcbf_stretch`, which only enlarges it, so containment is kept. Plain CBF uses the
    base ellipse along ``headings`` (m, K).
    """
    if barrier == "fcbf":
        da, db, phi = fcbf_stretch(velocities, headings, fcbf)
    elif barrier == "cbf":
        da, db, phi = 0.0, 0.0, headings
    else:
        raise ValueError(f"unknown barrier {barrier!r}; expected one of {BARRIERS}")
    ellipses = swept_hull_ellipses(np.ascontiguousarray(rows, dtype=float), np.ascontiguousarray(phi, dtype=float))
    ellipses[..., 2] += da
    ellipses[..., 3] += db
    return ellipses


def inactive_slot(horizon: int) -> np.ndarray:
    """Parameters of an unused obstacle slot: far away and switched off (constraint reads 1 >= 0)."""
    row = np.array([1e6, 1e6, 1.0, 0.0, 1e-6, 1e-6, 0.0])
    return np.tile(row, (horizon + 1, 1))
