"""The closed loop: observe, decide, step, record; then metrics. A failure mid-run is caught and
reported, and everything recorded up to it is kept."""

from __future__ import annotations

import copy
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
from aac_sumo.coordination.proximity import ProximityParams, proximity_decision
from aac_sumo.experiments.common import Setup
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.metrics import compute_metrics, jain, nearest_robot_distance, pedestrian_clearance, time_to_collision
from aac_sumo.mpc.problem import get_problem
from aac_sumo.world import WorldState


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
    """Run ``scenario`` to completion or its time limit.

    Everything paid once (building the experiment and its compiled problems, loading or
    compiling the numba kernels) happens before the first control period, see :func:`warm_up`,
    and is reported as ``setup_s``, so that ``compute_ms_*`` time only the periods' own work."""
    wall_start = time.perf_counter()
    get_problem.cache_clear()  # solvers keep state between solves: every run starts from fresh ones
    setup = experiments.build(scenario)
    sim, coord = setup.sim, setup.coordinator
    first = sim.observe()
    robots = first.robots
    dt, duration = scenario["scenario.dt"], scenario["scenario.duration"]
    warm_up(setup, first)
    setup_s = time.perf_counter() - wall_start
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
                x = world.states[i]
                ref = reference_point(setup, i, x)
                steps.append(dict(
                    t=world.t, robot=robot.name, x=x[0], y=x[1], heading=x[2], v=x[3],
                    accel=decision.inputs[i, 0], steer=decision.inputs[i, 1],
                    ref_x=ref[0], ref_y=ref[1], ref_heading=ref[2], ref_v=ref[3],
                    status=rec.status, solver=rec.solver, solve_ms=rec.solve_ms, iterations=rec.iterations, capped=rec.capped,
                    authority=rec.authority,
                    reason=rec.reason, mode=rec.mode, proximity_score=rec.score, proximity_progress=rec.progress,
                    arrived=bool(done[i]), clearance_m=contacts.clearance[i], nearest_robot_m=nearest[i], ttc_s=ttc[i],
                    pedestrian_clearance_m=to_pedestrians[i],
                ))
    except Exception as exc:  # keep what was recorded; report the failure in metrics
        error = f"{type(exc).__name__}: {exc}".splitlines()[0]
        print(f"aac-sumo: run stopped at t={len(periods) * dt:.2f} s: {error}", file=sys.stderr)
    finally:
        sim.close()

    steps_df = with_vehicle_columns(pd.DataFrame(steps, columns=STEP_COLUMNS[:-2]), {r.name: r.model.wheelbase for r in robots}, dt)
    periods_df = pd.DataFrame(periods) if periods else pd.DataFrame(columns=["t", "compute_ms"])
    c = scenario.data["controller"]
    info = dict(
        scenario=scenario["scenario.name"], coordinator=c["coordinator"], barrier=c["barrier"], horizon=c["horizon"],
        seed=scenario["scenario.seed"], n_robots=len(setup.tasks), completed=completed, task_duration_s=task_duration,
        collisions=collisions, sim_collisions=sim_collisions, wall_s=time.perf_counter() - wall_start, dt=dt, setup_s=setup_s,
        accel_threshold=scenario["metrics.accel_threshold"], lat_accel_threshold=scenario["metrics.lat_accel_threshold"],
        ttc_max=scenario["metrics.ttc_max"],
        wheelbase={r.name: r.model.wheelbase for r in robots},
        comfort_decel={r.name: r.model.limits.comfort_decel for r in robots},
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
    "status", "solver", "solve_ms", "iterations", "capped", "authority", "reason", "mode", "proximity_score",
    "proximity_progress", "arrived", "clearance_m", "nearest_robot_m", "ttc_s", "pedestrian_clearance_m", "lat_accel", "jerk",
]


def with_vehicle_columns(steps: pd.DataFrame, wheelbase: dict, dt: float) -> pd.DataFrame:
    """``steps`` with ``lat_accel``, the applied lateral acceleration ``v^2 tan(steer) / L``
    [m/s^2] (positive to the left), and ``jerk``, the change of the applied acceleration since
    the robot's previous step over the period ``dt`` [m/s^3] (NaN at its first step)."""
    steps["lat_accel"] = steps["v"] ** 2 * np.tan(steps["steer"]) / steps["robot"].map(wheelbase)
    steps["jerk"] = steps.groupby("robot")["accel"].diff() / dt
    return steps


def reference_point(setup: Setup, i: int, state: np.ndarray) -> np.ndarray:
    """Robot ``i``'s reference ``[x, y, heading, v]`` where it is: the projection of its
    rear axle ``state`` onto its task's path, as stage 0 of the MPC's reference. The runner
    computes it for every robot at every step, whatever the coordinator did, so that
    ``tracking_error_m`` measures every coordinator on the same samples."""
    return setup.tasks[i].horizon(state, 0, setup.scenario["scenario.dt"])[0]


def warm_up(setup: Setup, world: WorldState) -> None:
    """Pay the one-off costs of the first control period before the loop, without changing the
    run: the numba kernels load from their cache (or compile, the first time on a machine)
    when first called, and so does whatever else a decision touches for the first time.

    A copy of the coordinator decides once on ``world``, runs the safety stop's checks and is
    thrown away. Copying gives it fresh solvers (see ``MpcProblem.__deepcopy__``: solvers keep
    state between solves) and its own random generator and memory, so the run's coordinator is
    untouched. The proximity decision, which the first period may not need, runs on a tiny
    instance with its own generator; the per-step measurements and the reference projection
    are pure and run on ``world`` as well.
    """
    time_to_collision(world)
    nearest_robot_distance(world)
    pedestrian_clearance(world)
    footprints = world.robot_footprints()
    pairwise_rect_clearance(footprints, footprints)
    for i in range(len(world.robots)):
        reference_point(setup, i, world.states[i])
    proximity_decision(np.zeros((2, 2)), np.ones((2, 2)), np.zeros((1, 2)), np.ones(1), np.array([-1]),
                       ProximityParams(iterations=2), np.random.default_rng(0))
    try:
        shadow = copy.deepcopy(setup.coordinator)
        shadow.decide(world)
        everyone, coasting = np.arange(len(world.robots)), np.zeros((len(world.robots), 2))
        shadow.safety_check(world).unsafe(everyone, coasting, 0.1)
        shadow.safety_check(world).safe_inputs(everyone, coasting, 0.1)
    except Exception as exc:  # a warm-up is no reason to stop a run: the first period then pays
        print(f"aac-sumo: warm-up decision skipped: {type(exc).__name__}: {exc}".splitlines()[0], file=sys.stderr)


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
