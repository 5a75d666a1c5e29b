"""The closed loop: observe, decide, step, record; then the metrics (:mod:`aac_sumo.runs.recording`).
A failure mid-run is caught and reported, and everything recorded up to it is kept."""

from __future__ import annotations

import copy
from collections import deque
import sys
import threading
import time

import numba
import numpy as np
import pandas as pd

from aac_sumo import experiments
from aac_sumo.config import Scenario
from aac_sumo.coordination.threads import cores
from aac_sumo.experiments.common import Setup
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.metrics import nearest_robot_distance, pedestrian_clearance, time_to_collision
from aac_sumo.mpc.problem import get_problem
from aac_sumo.references import PathSet, reference_points
from aac_sumo.runs.recording import Recording, RunResult, assemble_metrics
from aac_sumo.world import WorldState


def run(scenario: Scenario) -> RunResult:
    """Run ``scenario`` to completion or its time limit.

    Everything paid once (building the experiment and its compiled problems, loading or
    compiling the numba kernels) happens before the first control period, see :func:`warm_up`,
    and is reported as ``setup_s``, so that ``compute_ms_*`` time only the periods' own work."""
    wall_start = time.perf_counter()
    get_problem.cache_clear()  # solvers keep state between solves: every run starts from fresh ones
    setup = experiments.build(scenario)
    first = setup.sim.observe() if setup.prepare is None else setup.prepare(setup.sim.observe())
    warm_up(setup, first)
    setup_s = time.perf_counter() - wall_start
    rec = Recording(arrival=np.full(len(setup.tasks), np.nan), crossings=setup.sim.crossings())
    interrupted = False
    try:
        loop(setup, rec)
    except Exception as exc:  # keep what was recorded; report the failure in metrics
        rec.error = f"{type(exc).__name__}: {exc}".splitlines()[0]
        print(f"aac-sumo: run stopped at t={len(rec.periods) * scenario['scenario.dt']:.2f} s: {rec.error}", file=sys.stderr)
    except KeyboardInterrupt:  # SIGINT, or STOP set: keep what was recorded, then stop
        rec.error, interrupted = f"interrupted at t={len(rec.periods) * scenario['scenario.dt']:.2f} s", True
    finally:
        setup.sim.close()
    if setup.held is not None:
        rec.held = setup.held()
    steps = with_vehicle_columns(pd.DataFrame(rec.steps, columns=STEP_COLUMNS[:-2]), {r.name: r.model.wheelbase for r in first.robots},
                                 scenario["scenario.dt"])
    periods = pd.DataFrame(rec.periods) if rec.periods else pd.DataFrame(columns=["t", "compute_ms"])
    trajectories = pd.DataFrame(rec.traj)
    metrics = assemble_metrics(setup.scenario, rec, steps, periods, robots=first.robots, free_flow_s=setup.free_flow_s,
                               wall_s=time.perf_counter() - wall_start, setup_s=setup_s, trajectories=trajectories)
    if setup.figures is not None:
        metrics.update(setup.figures())
    goals = np.array([task.points[-1] for task in setup.tasks])
    delays = None if setup.free_flow_s is None else pd.Series(rec.arrival - setup.free_flow_s, index=[r.name for r in first.robots])
    result = RunResult(metrics, steps, periods, trajectories, setup.scenario, goals, delays, rec.crossings)
    if interrupted:
        raise RunInterrupted(result)
    return result


#: Set to stop the running loop at the start of its next period (a signal handler sets it).
STOP = threading.Event()


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by SIGINT or SIGTERM; ``result`` holds everything recorded up to then (its
    metrics say ``error``). Being a KeyboardInterrupt, it stops sweeps as before."""

    def __init__(self, result: RunResult):
        super().__init__(result.metrics.get("error", "interrupted"))
        self.result = result


def stuck(history, unfinished: np.ndarray, limit: float) -> bool:
    """The deadlock rule: whether some robot is ``unfinished`` (n,) and none of them got further
    than ``limit`` [m], at any entry of ``history`` (positions (n, 2) per period, oldest
    first), from where it was at the first. A robot that drove off and came back within the
    window is not stuck."""
    if not unfinished.any():
        return False
    moved = np.hypot(*(np.asarray(history) - history[0]).transpose(2, 0, 1)).max(axis=0)[unfinished]
    return bool(moved.max() <= limit)


def loop(setup: Setup, rec: Recording) -> None:
    """The closed loop, one control period per step until every task is finished, the time
    limit, or a deadlock: observe, decide, step, and record into ``rec``. A non-finite robot
    state ends it with ``FloatingPointError`` (:func:`check_finite`)."""
    scenario, sim, coord = setup.scenario, setup.sim, setup.coordinator
    dt, duration = scenario["scenario.dt"], scenario["scenario.duration"]
    stop, patience = scenario["metrics.stop_speed"], scenario["metrics.deadlock_time"]
    window = int(round(patience / dt))
    crossings = tuple(rec.crossings or ())  # the map's, static: every period's world holds them
    history: deque[np.ndarray] = deque(maxlen=window + 1)  # rear-axle positions, for the deadlock rule
    references = References(setup)
    workers = scenario["controller.workers"]  # the metrics' compiled loops share the coordinator's threads
    numba.set_num_threads(min(workers if workers > 0 else cores(), numba.config.NUMBA_NUM_THREADS))
    active_overlaps: set = set()
    for k in range(int(round(duration / dt)) + 1):
        if STOP.is_set():  # asked to stop (aac-sumo run's SIGINT/SIGTERM handler), between two periods
            raise KeyboardInterrupt
        world = sim.observe() if setup.prepare is None else setup.prepare(sim.observe())
        world.crossings = crossings
        check_finite(world)
        rec.traj += [dict(t=round(world.t, 9), **a) for a in sim.agents()]
        done = np.asarray(setup.finished(world), dtype=bool)
        here = world.on_road
        arriving = done & np.isnan(rec.arrival)
        rec.arrival[arriving] = world.t
        if done.all():
            rec.completed, rec.task_duration = True, world.t
            rec.steps += arrival_rows(world, arriving & here, rec.steps, references)
            return
        if k * dt >= duration - 1e-9:
            return
        history.append(world.states[:, :2].copy())
        if len(history) > window and stuck(history, ~done & here, stop * patience):
            rec.deadlock = True
            return
        decision = coord.decide(world)
        ttc = time_to_collision(world)
        nearest = nearest_robot_distance(world)
        to_pedestrians = pedestrian_clearance(world)
        sim.show({robot.name for robot, r in zip(world.robots, decision.robots) if r.authority},
                 {robot.name for robot, r in zip(world.robots, decision.robots) if r.mode == "safety_stop"})
        contacts = sim.step(decision.inputs)
        rec.collisions += len(contacts.overlaps - active_overlaps)
        active_overlaps = contacts.overlaps
        if contacts.sim_collisions is not None:
            rec.sim_collisions = (rec.sim_collisions or 0) + contacts.sim_collisions
        rec.periods.append(dict(t=world.t, compute_ms=decision.compute_ms, **decision.notes))
        inputs = decision.inputs if contacts.applied is None else contacts.applied  # what the robots did (SUMO's driver)
        refs = references(world.states)
        for i, (robot, r) in enumerate(zip(world.robots, decision.robots)):
            if not here[i]:
                continue
            x, ref = world.states[i], refs[i]
            rec.steps.append(dict(
                t=world.t, robot=robot.name, x=x[0], y=x[1], heading=x[2], v=x[3],
                accel=inputs[i, 0], steer=inputs[i, 1],
                ref_x=ref[0], ref_y=ref[1], ref_heading=ref[2], ref_v=ref[3],
                status=r.status, solver=r.solver, solve_ms=r.solve_ms, iterations=r.iterations, capped=r.capped,
                authority=r.authority,
                reason=r.reason, mode=r.mode, proximity_score=r.score, proximity_progress=r.progress,
                arrived=bool(done[i]), clearance_m=contacts.clearance[i], nearest_robot_m=nearest[i], ttc_s=ttc[i],
                pedestrian_clearance_m=to_pedestrians[i],
            ))


def arrival_rows(world: WorldState, arriving: np.ndarray, steps: list[dict], references: References) -> list[dict]:
    """``steps.csv`` rows of the robots ``arriving`` (n,) at the run's last observation, the one
    that completes it: their state and reference point, ``arrived`` true, no solve (``status``
    empty), and the inputs and mode of their last row in ``steps`` held (no decision is taken
    then; the last inputs are the ones in effect). Without them the last robot to arrive was
    never marked arrived."""
    last = {row["robot"]: row for row in steps}
    rows, refs = [], references(world.states)
    for i in np.flatnonzero(arriving):
        name, x, ref = world.robots[i].name, world.states[i], refs[i]
        held = last.get(name, {})
        rows.append(dict(t=world.t, robot=name, x=x[0], y=x[1], heading=x[2], v=x[3], accel=held.get("accel", 0.0),
                         steer=held.get("steer", 0.0), ref_x=ref[0], ref_y=ref[1], ref_heading=ref[2], ref_v=ref[3], status="",
                         solver="", capped=False, authority=False, mode=held.get("mode", ""), arrived=True))
    return rows


def check_finite(world: WorldState) -> None:
    """``FloatingPointError`` naming the first robot whose state holds a NaN or an infinity: the
    run stops there (its records so far kept) instead of feeding it to the controller."""
    finite = np.isfinite(world.states).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise FloatingPointError(f"non-finite state of {world.robots[i].name} at t={world.t:.2f} s "
                                 f"([x, y, heading, v] = {world.states[i].tolist()})")


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


class References:
    """Every robot's reference ``[x, y, heading, v]`` where it is (n, 4): the projection of its
    rear axle onto its task's path, as stage 0 of the MPC's reference
    (:func:`~aac_sumo.references.reference_points`; the tasks' arrays kept while the tasks stay
    the same objects). The runner computes them for every robot at every step, whatever the
    coordinator did, so that ``tracking_error_m`` measures every coordinator on the same samples."""

    def __init__(self, setup: Setup):
        self.setup, self.paths = setup, None

    def __call__(self, states: np.ndarray) -> np.ndarray:
        tasks = self.setup.tasks
        if self.paths is None or not self.paths.holds(tasks):
            self.paths = PathSet(tasks)
        return reference_points(tasks, states, self.setup.scenario["scenario.dt"], self.paths)


def warm_up(setup: Setup, world: WorldState) -> None:
    """Pay the one-off costs of the first control period before the loop, without changing the
    run: the numba kernels load from their cache (or compile, the first time on a machine)
    when first called, and so does whatever else a decision touches for the first time.

    A copy of the coordinator warms up what it declares (:meth:`Coordinator.warm_up`), decides
    once on ``world``, runs the safety stop's checks and is thrown away. Copying gives it fresh
    solvers (see ``MpcProblem.__deepcopy__``: solvers keep state between solves) and its own
    random generator and memory, so the run's coordinator is untouched. The per-step
    measurements and the reference projection are pure and run on ``world`` as well.
    """
    time_to_collision(world)
    nearest_robot_distance(world)
    pedestrian_clearance(world)
    footprints = world.robot_footprints()
    pairwise_rect_clearance(footprints, footprints)
    References(setup)(world.states)
    try:
        shadow = copy.deepcopy(setup.coordinator)
        shadow.warm_up(world)
        shadow.decide(world)
        everyone, coasting = np.arange(len(world.robots)), np.zeros((len(world.robots), 2))
        shadow.safety_check(world).unsafe(everyone, coasting, 0.1)
        shadow.safety_check(world).safe_inputs(everyone, coasting, 0.1)
    except Exception as exc:  # a warm-up is no reason to stop a run: the first period then pays
        print(f"aac-sumo: warm-up decision skipped: {type(exc).__name__}: {exc}".splitlines()[0], file=sys.stderr)

