"""What a run's loop recorded, the metrics assembled from it (see :mod:`aac_sumo.metrics`), and
the result a run returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from aac_sumo.config import Scenario
from aac_sumo.runs.provenance import provenance
from aac_sumo.registry import coordinators
from aac_sumo.metrics import compute_metrics, jain, pedestrian_waits
from aac_sumo.sim.base import Crossing


@dataclass
class RunResult:
    """Metrics, the per-robot step table, the per-period table, every agent's trajectory,
    each robot's goal (the end of its reference path, rear axle [m]), each robot's delay
    (arrival time minus free-flow time [s] by robot name, NaN if it did not arrive; None when the experiment
    has no free-flow times) and the map's pedestrian crossings (:meth:`Simulator.crossings
    <aac_sumo.sim.base.Simulator.crossings>`, None without a map)."""

    metrics: dict
    steps: pd.DataFrame
    periods: pd.DataFrame
    trajectories: pd.DataFrame
    scenario: Scenario
    goals: np.ndarray | None = None
    delays: pd.Series | None = None
    crossings: list[Crossing] | None = None


@dataclass
class Recording:
    """Everything the closed loop recorded: per-robot ``steps`` rows, per-period ``periods``
    rows, every agent's ``traj`` rows, and how the loop ended. ``arrival`` is each task's
    arrival time [s] (NaN if it never arrived); ``crossings`` the map's pedestrian crossings
    (None without a map); ``held`` the ``(t, robot name)`` of the periods in which a robot was
    held by a traffic signal (:attr:`~aac_sumo.experiments.common.Setup.held`)."""

    steps: list = field(default_factory=list)
    periods: list = field(default_factory=list)
    traj: list = field(default_factory=list)
    collisions: int = 0
    sim_collisions: int | None = None
    completed: bool = False
    task_duration: float | None = None
    deadlock: bool = False
    error: str | None = None
    arrival: np.ndarray = field(default_factory=lambda: np.zeros(0))
    crossings: list[Crossing] | None = None
    held: set[tuple[float, str]] = field(default_factory=set)


def assemble_metrics(scenario: Scenario, rec: Recording, steps: pd.DataFrame, periods: pd.DataFrame, *,
                     robots: list, free_flow_s: np.ndarray | None, wall_s: float, setup_s: float,
                     trajectories: pd.DataFrame | None = None) -> dict:
    """The metrics.json of a run: what ran, :func:`~aac_sumo.metrics.compute_metrics` of its
    tables, the delay metrics (when every task arrived and free-flow times exist),
    ``pedestrian_wait_s`` (:func:`wait_by_robot` summed; None without crossings), ``error`` and
    ``incomplete_reason`` (collisions, deadlock or time limit)."""
    c = scenario.data["controller"]
    dt, duration = scenario["scenario.dt"], scenario["scenario.duration"]
    stop, patience = scenario["metrics.stop_speed"], scenario["metrics.deadlock_time"]
    info = dict(
        scenario=scenario["scenario.name"], coordinator=c["coordinator"], barrier=c["barrier"], horizon=c["horizon"],
        seed=scenario["scenario.seed"], n_robots=len(rec.arrival), completed=rec.completed,
        task_duration_s=rec.task_duration, collisions=rec.collisions, sim_collisions=rec.sim_collisions,
        wall_s=wall_s, dt=dt, setup_s=setup_s,
        accel_threshold=scenario["metrics.accel_threshold"], lat_accel_threshold=scenario["metrics.lat_accel_threshold"],
        ttc_max=scenario["metrics.ttc_max"],
        wheelbase={r.name: r.model.wheelbase for r in robots},
        comfort_decel={r.name: r.model.limits.comfort_decel for r in robots},
    )
    if free_flow_s is not None and rec.completed:
        delay = rec.arrival - free_flow_s
        info.update(delay_jain=jain(np.maximum(delay, 0.0)), delay_max_s=float(delay.max()))
    info.update(deadlock=rec.deadlock, safety_stops=int(periods["safety_stops"].sum()) if "safety_stops" in periods else 0)
    waits = wait_by_robot(scenario, rec.crossings, steps, trajectories, robots, rec.held)
    info.update(pedestrian_wait_s=None if waits is None else float(waits.sum()))
    metrics = compute_metrics(steps, periods, info)
    reasons = []
    if rec.error is not None:
        metrics["error"] = rec.error
    if rec.collisions:
        metrics["completed"], metrics["task_duration_s"] = False, None
        drives = coordinators()[c["coordinator"]].simulator_drives  # SUMO's driver: SUMO drives on
        reasons.append(f"{rec.collisions} collision(s); " + ("SUMO's driver drove on" if drives else "wrecked robots stop where they hit"))
    if rec.deadlock:
        reasons.append(f"deadlock: no unfinished robot got further than {stop * patience:.2f} m, at any time in the last "
                       f"{patience} s, from where it was {patience} s before (t = {len(rec.periods) * dt:.1f} s)")
    elif not rec.completed and rec.error is None:
        reasons.append(f"time limit {duration} s reached")
    if reasons:
        metrics["incomplete_reason"] = "; ".join(reasons)
    return metrics | provenance(scenario.to_toml())


def wait_by_robot(scenario: Scenario, crossings: list[Crossing] | None, steps: pd.DataFrame, trajectories: pd.DataFrame | None,
                  robots: list, held: set[tuple[float, str]] = frozenset()) -> pd.Series | None:
    """Per robot, the seconds it stood before a crossing clear of walkers
    (:func:`~aac_sumo.metrics.pedestrian_waits` with ``metrics.stop_speed`` and
    ``controller.pedestrian_margin``; the walkers from ``trajectories``' ``pedestrian`` rows),
    but while ``held`` by a traffic signal; None without crossings."""
    if not crossings:
        return None
    traj = trajectories if trajectories is not None and len(trajectories) else pd.DataFrame(columns=["t", "kind"])
    walkers = traj[traj["kind"] == "pedestrian"]
    if not len(steps):
        return pd.Series(dtype=float)
    return pedestrian_waits(steps, walkers, crossings, centre_offset={r.name: r.centre_offset for r in robots},
                            length={r.name: r.length for r in robots}, dt=scenario["scenario.dt"],
                            stop_speed=scenario["metrics.stop_speed"], margin=scenario["controller.pedestrian_margin"], held=held)
