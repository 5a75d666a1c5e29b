"""The closed loop: observe, decide, step, record; then metrics. A failure mid-run is caught and
reported, and everything recorded up to it is kept."""

from __future__ import annotations

import json
from collections import deque
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from aac_sumo import experiments
from aac_sumo.config import Scenario
from aac_sumo.metrics import compute_metrics, jain, nearest_robot_distance, pedestrian_clearance, time_to_collision
from aac_sumo.mpc.problem import get_problem


@dataclass
class RunResult:
    """Metrics, the per-robot step table, the per-period table, every agent's trajectory, and
    each robot's goal (the end of its reference path, rear axle [m])."""

    metrics: dict
    steps: pd.DataFrame
    periods: pd.DataFrame
    trajectories: pd.DataFrame
    scenario: Scenario
    goals: np.ndarray | None = None


def run(scenario: Scenario) -> RunResult:
    """Run ``scenario`` to completion or its time limit."""
    wall_start = time.perf_counter()
    get_problem.cache_clear()  # solvers keep state between solves: every run starts from fresh ones
    setup = experiments.build(scenario)
    sim, coord = setup.sim, setup.coordinator
    robots = sim.observe().robots
    dt, duration = scenario["scenario.dt"], scenario["scenario.duration"]
    steps, periods, traj = [], [], []
    active_overlaps: set = set()
    collisions, sim_collisions = 0, None
    completed, task_duration, error, deadlock = False, None, None, False
    arrival = np.full(len(setup.tasks), np.nan)
    stop, patience = scenario["metrics.stop_speed"], scenario["metrics.deadlock_time"]
    window = int(round(patience / dt))
    history: deque[np.ndarray] = deque(maxlen=window + 1)  # rear-axle positions, for the deadlock rule
    try:
        for k in range(int(round(duration / dt)) + 1):
            world = sim.observe()
            traj += [dict(t=round(world.t, 9), **a) for a in sim.agents()]
            done = np.asarray(setup.finished(world), dtype=bool)
            arrival[done & np.isnan(arrival)] = world.t
            if done.all():
                completed, task_duration = True, world.t
                break
            if k * dt >= duration - 1e-9:
                break
            history.append(world.states[:, :2].copy())
            if len(history) > window:
                moved = np.hypot(*(history[-1] - history[0]).T)[~done]
                if moved.size and moved.max() <= stop * patience:
                    deadlock = True
                    break
            decision = coord.decide(world)
            ttc = time_to_collision(world)
            nearest = nearest_robot_distance(world)
            to_pedestrians = pedestrian_clearance(world)
            contacts = sim.step(decision.inputs)
            collisions += len(contacts.overlaps - active_overlaps)
            active_overlaps = contacts.overlaps
            if contacts.sim_collisions is not None:
                sim_collisions = (sim_collisions or 0) + contacts.sim_collisions
            periods.append(dict(t=world.t, compute_ms=decision.compute_ms, **decision.notes))
            for i, (robot, rec) in enumerate(zip(world.robots, decision.robots)):
                ref = rec.reference[0] if rec.reference is not None else np.full(4, np.nan)
                x = world.states[i]
                steps.append(dict(
                    t=world.t, robot=robot.name, x=x[0], y=x[1], heading=x[2], v=x[3],
                    accel=decision.inputs[i, 0], steer=decision.inputs[i, 1],
                    ref_x=ref[0], ref_y=ref[1], ref_heading=ref[2], ref_v=ref[3],
                    status=rec.status, solver=rec.solver, solve_ms=rec.solve_ms, authority=rec.authority,
                    reason=rec.reason, mode=rec.mode, proximity_score=rec.score, proximity_progress=rec.progress,
                    arrived=bool(done[i]), clearance_m=contacts.clearance[i], nearest_robot_m=nearest[i], ttc_s=ttc[i],
                    pedestrian_clearance_m=to_pedestrians[i],
                ))
    except Exception as exc:  # keep what was recorded; report the failure in metrics
        error = f"{type(exc).__name__}: {exc}".splitlines()[0]
        print(f"aac-sumo: run stopped at t={len(periods) * dt:.2f} s: {error}", file=sys.stderr)
    finally:
        sim.close()

    steps_df = pd.DataFrame(steps, columns=STEP_COLUMNS)
    periods_df = pd.DataFrame(periods) if periods else pd.DataFrame(columns=["t", "compute_ms"])
    c = scenario.data["controller"]
    info = dict(
        scenario=scenario["scenario.name"], coordinator=c["coordinator"], barrier=c["barrier"], horizon=c["horizon"],
        seed=scenario["scenario.seed"], n_robots=len(setup.tasks), completed=completed, task_duration_s=task_duration,
        collisions=collisions, sim_collisions=sim_collisions, wall_s=time.perf_counter() - wall_start, dt=dt,
        accel_threshold=scenario["metrics.accel_threshold"], lat_accel_threshold=scenario["metrics.lat_accel_threshold"],
        ttc_max=scenario["metrics.ttc_max"],
        wheelbase={r.name: r.model.wheelbase for r in robots},
    )
    if setup.free_flow_s is not None and completed:
        delay = arrival - setup.free_flow_s
        info.update(delay_jain=jain(np.maximum(delay, 0.0)), delay_max_s=float(delay.max()))
    info.update(deadlock=deadlock, safety_stops=int(periods_df["safety_stops"].sum()) if "safety_stops" in periods_df else 0)
    metrics = compute_metrics(steps_df, periods_df, info)
    reasons = []
    if error is not None:
        metrics["error"] = error
    if collisions:
        metrics["completed"], metrics["task_duration_s"] = False, None
        reasons.append(f"{collisions} collision(s); wrecked robots stop where they hit")
    if deadlock:
        reasons.append(f"deadlock: no unfinished robot got further than {stop * patience:.2f} m from where it was "
                       f"{patience} s before (t = {len(periods) * dt:.1f} s)")
    elif not completed and error is None:
        reasons.append(f"time limit {duration} s reached")
    if reasons:
        metrics["incomplete_reason"] = "; ".join(reasons)
    goals = np.array([task.points[-1] for task in setup.tasks])
    return RunResult(metrics, steps_df, periods_df, pd.DataFrame(traj), scenario, goals)


STEP_COLUMNS = [
    "t", "robot", "x", "y", "heading", "v", "accel", "steer", "ref_x", "ref_y", "ref_heading", "ref_v",
    "status", "solver", "solve_ms", "authority", "reason", "mode", "proximity_score", "proximity_progress",
    "arrived", "clearance_m", "nearest_robot_m", "ttc_s", "pedestrian_clearance_m",
]


def write_outputs(result: RunResult, out: Path, plot: bool = True) -> None:
    """Write metrics.json, steps.csv, trajectories.csv, scenario.toml and trajectories.png."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text(json.dumps(result.metrics, indent=2) + "\n")
    result.steps.to_csv(out / "steps.csv", index=False)
    result.trajectories.to_csv(out / "trajectories.csv", index=False)
    (out / "scenario.toml").write_text(result.scenario.to_toml())
    if plot:
        from aac_sumo.report import plot_run

        plot_run(result, out / "trajectories.png")
