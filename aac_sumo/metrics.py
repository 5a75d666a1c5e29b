"""Per-step measurements and the run metrics of CONTRACT.md, computed from recorded data."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param, section
from aac_sumo.geometry import pairwise_rect_clearance, rect_corners
from aac_sumo.kernels.metrics import times_to_collision
from aac_sumo.neighbours import nearest_distances
from aac_sumo.world import WorldState

@section("metrics")
@dataclass(frozen=True)
class MetricsParams:
    """Section ``[metrics]``: the thresholds of the run metrics (aggressive driving, stopped,
    time-to-collision) and of the deadlock rule, in SI units."""

    accel_threshold: float = param(3.0, "|longitudinal acceleration| that counts as aggressive [m/s^2]", **P)
    lat_accel_threshold: float = param(3.0, "lateral acceleration v^2 |curvature| that counts as aggressive [m/s^2]", **P)
    stop_speed: float = param(0.05, "speed below which a robot counts as stopped [m/s]", **NN)
    ttc_max: float = param(10.0, "time-to-collision above this is no conflict and stays out of ttc_mean_s [s]", **P)
    deadlock_time: float = param(5.0, "a run ends as a deadlock when no unfinished robot got further than stop_speed * "
                                 "deadlock_time, at any time in the last deadlock_time, from where it was deadlock_time before "
                                 "(a robot that drove off and came back is not stuck) [s]", **P)


#: metrics.json keys, in the order they are written.
METRIC_KEYS = (
    "scenario", "coordinator", "barrier", "horizon", "seed", "n_robots", "completed", "task_duration_s",
    "compute_ms_mean", "compute_ms_median", "compute_ms_p95", "solves", "infeasible_solves",
    "infeasibility_rate", "min_distance_m", "min_clearance_m", "collisions", "sim_collisions", "ttc_mean_s",
    "aggressive_driving_rate", "tracking_error_m", "authority_jain", "delay_jain", "delay_max_s",
    "realtime_factor", "safety_stops", "deadlock", "min_pedestrian_clearance_m", "setup_s", "capped_solves",
    "emergency_brakes", "aggressive_by_mode", "accel_p95", "lat_accel_p95", "jerk_p95", "pedestrian_wait_s",
    "red_light_violations", "right_of_way_violations",
)
#: Where an applied input comes from (``steps.csv``'s ``mode``), in the order ``aggressive_by_mode`` reports them.
MODES = ("mpc", "creep", "plan", "tracking", "safety_stop", "fallback", "hold")
ROBOT_KINDS = ("robot", "scripted")


def time_to_collision(world: WorldState) -> np.ndarray:
    """Per controlled robot, the smallest TTC [s] to anything ahead that it closes in on, NaN if none.

    Everything moves at its current velocity (robots along their heading). With the closing
    velocity ``w`` = the ego's velocity minus the other's, the other counts when ``w`` points
    ahead of the ego (a positive component along its heading: the ego drives into it, not the
    other way round) and the ego's footprint, translated along ``w``, touches the other's
    footprint. TTC = that true footprint gap along ``w`` / the closing speed ``|w|``, exact for
    any orientation of either footprint (:func:`aac_sumo.kernels.metrics.times_to_collision`); 0 when
    the footprints already touch.
    """
    heading, speed = world.states[:, 2], world.states[:, 3]
    obstacles = [o for o in world.obstacles if o.kind != "signal"]  # a stop line is no agent to collide with
    rows = np.vstack([world.robot_footprints()] + [o.footprint()[None, :] for o in obstacles])
    velocity = np.vstack([speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])]
                         + [np.asarray(o.velocity, dtype=float)[None, :] for o in obstacles])
    ttc = times_to_collision(rows, velocity, len(world.robots))
    return np.where(np.isfinite(ttc), ttc, np.nan)


def nearest_robot_distance(world: WorldState) -> np.ndarray:
    """Per controlled robot, the centre distance [m] to the nearest other robot (controlled or a
    scripted robot such as the braking lead), inf if there is none."""
    centres = world.robot_centres()
    others = [o.centre for o in world.obstacles if o.kind in ROBOT_KINDS]
    return nearest_distances(centres, np.vstack([centres] + ([np.array(others)] if others else [])))


def pedestrian_clearance(world: WorldState) -> np.ndarray:
    """Per controlled robot, the smallest footprint gap [m] to a pedestrian, inf without any."""
    peds = [o.footprint() for o in world.obstacles if o.kind == "pedestrian"]
    if not peds:
        return np.full(len(world.robots), np.inf)
    return pairwise_rect_clearance(world.robot_footprints(), np.array(peds)).min(axis=1)


def jain(values) -> float | None:
    """Jain's fairness index ``(sum x)^2 / (n sum x^2)``; 1 is perfectly fair. None if empty or all zero."""
    x = np.asarray(values, dtype=float)
    if x.size == 0 or not np.any(x):
        return None
    return float(x.sum() ** 2 / (x.size * (x**2).sum()))


def authority_share(steps: pd.DataFrame) -> pd.Series:
    """Per robot, authority periods received over its summed fair shares, counted while robots
    are unfinished: in each period the robots that have not yet arrived share one fair unit of
    authority equally (1/m each of m). Without an ``arrived`` column every robot counts in
    every period. Robots that arrived before the first period are left out."""
    rows = steps[~steps["arrived"].astype(bool)] if "arrived" in steps else steps
    share = 1.0 / rows.groupby("t")["robot"].transform("size")
    fair = share.groupby(rows["robot"]).sum()
    got = rows["authority"].astype(float).groupby(rows["robot"]).sum()
    return got / fair


def authority_jain(steps: pd.DataFrame) -> float | None:
    """Jain's index over robots of :func:`authority_share`; pure round robin over robots that
    stay unfinished gives 1. None when no robot is unfinished."""
    rows = steps[~steps["arrived"].astype(bool)] if "arrived" in steps else steps
    if rows.empty:
        return None
    return jain(authority_share(steps))


def _finite(x) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def compute_metrics(steps: pd.DataFrame, periods: pd.DataFrame, info: dict) -> dict:
    """Metrics from the per-robot ``steps`` table and the per-period ``periods`` table.

    ``info`` carries what ran (scenario, coordinator, barrier, horizon, seed, n_robots),
    ``completed``, ``task_duration_s``, ``collisions``, ``sim_collisions``, ``wall_s``, the
    aggressive-driving thresholds, ``wheelbase`` per robot, and optionally ``comfort_decel`` per robot, ``ttc_max``, ``delay_jain``,
    ``delay_max_s``, ``safety_stops``, ``deadlock``, ``setup_s`` (the one-off set-up before the
    first period [s], which ``periods``' ``compute_ms`` and ``realtime_factor`` leave out) and
    ``pedestrian_wait_s`` (:func:`pedestrian_waits` summed; needs the walkers, which ``steps`` lacks).

    ``realtime_factor`` is the simulated time [s] over the run's wall time ``wall_s`` [s] less
    ``setup_s``: how fast the run went once set up (a first run on a machine compiles its
    problems and kernels in the set-up; later runs load them).

    ``accel_p95``, ``lat_accel_p95`` and ``jerk_p95`` are the 95th percentiles of the absolute
    ``accel``, ``lat_accel`` and ``jerk`` columns over every row of ``steps`` (:func:`smoothness`).

    ``tracking_error_m`` is the mean over every row of ``steps`` (every robot at every step) of
    the distance from ``x, y`` to ``ref_x, ref_y`` (null if any row lacks one, never a mean over
    a subset); ``capped_solves`` counts the solves whose
    ``capped`` is true (stopped at the solver's iteration cap, whatever their status).
    """
    compute = periods["compute_ms"].to_numpy() if len(periods) else np.array([])
    solved = steps[steps["status"].notna() & (steps["status"] != "")]
    solves = int(len(solved))
    bad = int((solved["status"] != "solved").sum())
    sim_time = float(periods["t"].max() + info["dt"]) if len(periods) else 0.0
    after_setup_s = info["wall_s"] - (info.get("setup_s") or 0.0) if info.get("wall_s") else None
    m = {k: info.get(k) for k in ("scenario", "coordinator", "barrier", "horizon", "seed", "n_robots")}
    m.update(
        completed=bool(info["completed"]),
        task_duration_s=_finite(info.get("task_duration_s")),
        compute_ms_mean=_finite(np.mean(compute)) if compute.size else None,
        compute_ms_median=_finite(np.median(compute)) if compute.size else None,
        compute_ms_p95=_finite(np.percentile(compute, 95)) if compute.size else None,
        solves=solves,
        infeasible_solves=bad,
        infeasibility_rate=bad / solves if solves else None,
        min_distance_m=_finite(steps["nearest_robot_m"].min()) if len(steps) else None,
        min_clearance_m=_finite(steps["clearance_m"].min()) if len(steps) else None,
        collisions=int(info["collisions"]),
        sim_collisions=info.get("sim_collisions"),
        ttc_mean_s=_ttc_mean(steps["ttc_s"], info.get("ttc_max", np.inf)),
        aggressive_driving_rate=_aggressive_rate(steps, info) if len(steps) else None,
        tracking_error_m=_finite(np.hypot(steps["x"] - steps["ref_x"], steps["y"] - steps["ref_y"]).mean(skipna=False)) if len(steps) else None,
        authority_jain=authority_jain(steps) if len(steps) else None,
        delay_jain=info.get("delay_jain"),
        delay_max_s=info.get("delay_max_s"),
        realtime_factor=_finite(sim_time / after_setup_s) if after_setup_s else None,
        safety_stops=int(info.get("safety_stops", 0)),
        deadlock=bool(info.get("deadlock", False)),
        min_pedestrian_clearance_m=_finite(steps["pedestrian_clearance_m"].min()) if "pedestrian_clearance_m" in steps and len(steps) else None,
        setup_s=_finite(info.get("setup_s")),
        capped_solves=int(solved["capped"].fillna(False).astype(bool).sum()) if "capped" in solved else 0,
        emergency_brakes=_emergency_brakes(steps, info) if len(steps) and "comfort_decel" in info else None,
        aggressive_by_mode=_aggressive_by_mode(steps, info) if len(steps) else None,
        pedestrian_wait_s=_finite(info.get("pedestrian_wait_s")),
        red_light_violations=None,  # the city's (Setup.figures): junctions with signals and right of way
        right_of_way_violations=None,
        **smoothness(steps),
    )
    return {k: m[k] for k in METRIC_KEYS} | {k: v for k, v in m.items() if k not in METRIC_KEYS}


def _ttc_mean(ttc: pd.Series, ttc_max: float) -> float | None:
    """Mean TTC [s] over the steps with a conflict: closing in, TTC at most ``ttc_max``."""
    conflicts = ttc[ttc <= ttc_max]
    return _finite(conflicts.mean()) if len(conflicts) else None


#: How far [m/s^2] beyond a threshold a value may be by rounding or by the solver's tolerance on its bounds alone and still
#: not exceed it: an input at the comfort bound, 2 m/s^2, came out as 2.0000000000000018 from a ramp summed stage by stage,
#: and as 2.000000005 from fatrop's plans braking at that bound in the city.
ROUNDING = 1e-6


def _aggressive_steps(steps: pd.DataFrame, info: dict) -> pd.Series:
    """Whether each step's applied |accel| or v^2 |tan(steer)| / L exceeds the thresholds (by
    more than ``ROUNDING``)."""
    wheelbase = steps["robot"].map(info["wheelbase"])
    lat = steps["v"] ** 2 * np.abs(np.tan(steps["steer"])) / wheelbase
    return (steps["accel"].abs() > info["accel_threshold"] + ROUNDING) | (lat > info["lat_accel_threshold"] + ROUNDING)


def _aggressive_rate(steps: pd.DataFrame, info: dict) -> float:
    """Share of robots whose applied |accel| or v^2 |tan(steer)| / L ever exceeds the thresholds."""
    return float(_aggressive_steps(steps, info).groupby(steps["robot"]).any().mean())


def _aggressive_by_mode(steps: pd.DataFrame, info: dict) -> dict:
    """Share of the aggressive steps that each input source (``mode``, see ``MODES``; a braking
    fallback after a failed solve counts as ``fallback``) applied; empty without any."""
    flagged = _aggressive_steps(steps, info)
    if not flagged.any():
        return {}
    mode = steps["mode"].where(~((steps["mode"] == "mpc") & steps["status"].notna() & (steps["status"] != "solved")), "fallback")
    counts = mode[flagged].value_counts()
    order = [m for m in MODES if m in counts] + sorted(set(counts.index) - set(MODES))
    return {m: float(counts[m] / flagged.sum()) for m in order}


def emergency_brake_steps(steps: pd.DataFrame, info: dict) -> pd.Series:
    """Whether each step brakes harder than its robot's comfort deceleration (``info``'s
    ``comfort_decel`` per robot name [m/s^2])."""
    return steps["accel"] < -steps["robot"].map(info["comfort_decel"]) - 1e-9


def _emergency_brakes(steps: pd.DataFrame, info: dict) -> int:
    """Episodes of braking harder than the comfort deceleration: runs of consecutive such steps
    of one robot count once."""
    hard = emergency_brake_steps(steps, info)
    starts = hard & ~hard.groupby(steps["robot"]).shift(fill_value=False)
    return int(starts.sum())


#: ``steps.csv`` columns whose absolute values' 95th percentiles are the smoothness metrics, by metric key.
SMOOTHNESS = {"accel_p95": "accel", "lat_accel_p95": "lat_accel", "jerk_p95": "jerk"}


def smoothness(steps: pd.DataFrame) -> dict:
    """``accel_p95`` [m/s^2], ``lat_accel_p95`` [m/s^2] and ``jerk_p95`` [m/s^3]: the 95th
    percentile (linear interpolation) of |applied acceleration|, |lateral acceleration| and
    |jerk| over every recorded step of every controlled robot (the runner records only robots on
    the road). A robot's first step has no jerk (NaN) and is left out of ``jerk_p95`` only.
    None for a column that is missing or has no finite value."""
    out = {}
    for key, column in SMOOTHNESS.items():
        values = steps[column].to_numpy(dtype=float) if column in steps else np.zeros(0)
        values = np.abs(values[np.isfinite(values)])
        out[key] = float(np.percentile(values, 95)) if values.size else None
    return out


#: How far [m] before a crossing a standing car's front counts as waiting for it (``pedestrian_wait_s``).
CROSSING_REACH = 30.0


def crossing_lane_part(shape: np.ndarray, width: float, centre: np.ndarray, heading: float, half_band: float) -> np.ndarray:
    """The part of a crossing within a car's lane: rectangles ``[cx, cy, length, width, heading]``
    (k, 5), world frame [m], one per segment of the crossing's centre-line ``shape`` (m, 2) [m]
    that passes within ``half_band`` [m] across ``heading`` [rad] of the car's footprint centre
    ``centre`` (2,): the segment clipped to that band, the crossing's ``width`` [m] wide. (0, 5)
    when the crossing does not cross the band."""
    normal = np.array([-np.sin(heading), np.cos(heading)])
    across = (shape - centre) @ normal
    rows = []
    for a, b, qa, qb in zip(shape[:-1], shape[1:], across[:-1], across[1:]):
        if abs(qb - qa) < 1e-12:
            lo, hi = (0.0, 1.0) if abs(qa) <= half_band else (1.0, 0.0)
        else:
            ta, tb = (-half_band - qa) / (qb - qa), (half_band - qa) / (qb - qa)
            lo, hi = max(0.0, min(ta, tb)), min(1.0, max(ta, tb))
        if hi <= lo:
            continue
        p, q = a + lo * (b - a), a + hi * (b - a)
        rows.append([*(0.5 * (p + q)), float(np.hypot(*(q - p))), width, float(np.arctan2(*(b - a)[::-1]))])
    return np.array(rows, dtype=float).reshape(-1, 5)


def crossing_ahead(crossings, centre: np.ndarray, front: np.ndarray, heading: float, reach: float = CROSSING_REACH) -> np.ndarray | None:
    """The lane part (:func:`crossing_lane_part`) of the nearest crossing a car faces: the one
    whose part in the car's lane (the band of its ``lane_width`` across ``heading`` [rad] round its
    footprint ``centre``) begins at most ``reach`` [m] ahead of its ``front`` (front-bumper centre
    [m]) along its heading and ends ahead of it (a car whose front passed it is past it). None
    when there is no such crossing. ``crossings`` are :class:`~aac_sumo.sim.base.Crossing`."""
    along = np.array([np.cos(heading), np.sin(heading)])
    best, nearest = None, np.inf
    for crossing in crossings:
        part = crossing_lane_part(crossing.shape, crossing.width, centre, heading, 0.5 * crossing.lane_width)
        if not len(part):
            continue
        ahead = (rect_corners(part).reshape(-1, 2) - front) @ along
        if ahead.max() > 0.0 and ahead.min() <= reach and ahead.min() < nearest:
            best, nearest = part, ahead.min()
    return best


def pedestrian_waits(steps: pd.DataFrame, walkers: pd.DataFrame, crossings, *, centre_offset: dict, length: dict, dt: float,
                     stop_speed: float, margin: float, reach: float = CROSSING_REACH,
                     held: set[tuple[float, str]] = frozenset()) -> pd.Series:
    """Per controlled robot, the seconds it stood (``v`` below ``stop_speed`` [m/s]) with the
    nearest crossing on its way (:func:`crossing_ahead`, its front at most ``reach`` [m] before
    it) clear: no walker's footprint within ``margin`` [m] of that crossing's part in the car's
    lane. Each such row of ``steps`` counts ``dt`` [s].

    ``steps`` has ``t, robot, x, y, heading, v`` (rear axle, world frame); ``walkers`` the
    pedestrians' ``t, x, y, length, width, heading`` (footprint centres, as in
    ``trajectories.csv``); ``centre_offset`` and ``length`` by robot name the distance [m] from
    the rear axle to the footprint centre and the footprint length [m]. Every robot of ``steps``
    has an entry (0 when it never waited). The rows whose ``(t, robot)`` (``t`` rounded to 9
    digits) is in ``held`` do not count: the robot waited for a traffic signal."""
    waits = pd.Series(0.0, index=pd.unique(steps["robot"]), dtype=float)
    standing = steps[steps["v"].abs() < stop_speed]
    if held:
        standing = standing[~pd.MultiIndex.from_arrays([standing["t"].round(9), standing["robot"]]).isin(list(held))]
    if len(standing) and crossings:  # only rows near a crossing can count: a cheap test first
        axle = standing[["x", "y"]].to_numpy(dtype=float)
        near = np.zeros(len(standing), dtype=bool)
        for c in crossings:
            middle = c.shape.mean(axis=0)
            radius = np.hypot(*(c.shape - middle).T).max() + c.width + c.lane_width + reach
            near |= np.hypot(*(axle - middle).T) <= radius + standing["robot"].map(centre_offset).to_numpy() + standing["robot"].map(length).to_numpy()
        standing = standing[near]
    if not len(standing) or not crossings:
        return waits
    by_t = {t: rows[["x", "y", "length", "width", "heading"]].to_numpy(dtype=float)
            for t, rows in walkers.groupby(walkers["t"].round(9))} if len(walkers) else {}
    for t, name, x, y, heading in zip(standing["t"].round(9), standing["robot"], standing["x"], standing["y"], standing["heading"]):
        along = np.array([np.cos(heading), np.sin(heading)])
        centre = np.array([x, y]) + centre_offset[name] * along
        part = crossing_ahead(crossings, centre, centre + 0.5 * length[name] * along, heading, reach)
        if part is None:
            continue
        people = by_t.get(t)
        if people is None or not len(people) or pairwise_rect_clearance(part, people).min() > margin:
            waits[name] += dt
    return waits
