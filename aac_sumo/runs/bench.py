"""Speed figures measured in one process: ``aac-sumo bench``.

``mpc`` times one MPC-FCBF solve (``Plan.solve_ms``) inside a closed loop: an ego robot
(1.0 m x 0.6 m, wheelbase 0.8 m) drives along a straight reference at 8 m/s through a course of
eight real obstacles (three static cones beside its lane, two pedestrians crossing it, three
slower vehicles in the neighbouring lanes), so every obstacle slot is filled and the barrier
constraints are active at some steps. Each step applies ``plan.inputs[0]`` with the bicycle
model and passes the plan back as the warm start. When the ego leaves the course the episode
restarts from the beginning (the first solve of an episode is cold-started).

Every shipped solver configuration is timed on its own (``retry_with_ipopt=False``) and its
failures (status other than ``solved``) are counted: ``fatrop-c`` (the fast path: fatrop with
the problem's functions compiled to C, see ``controller.codegen``), ``fatrop`` (interpreted),
``ipopt`` (the baseline) and ``sqp`` (skipped, with a note, when most of its solves fail). ``ratio`` is the
baseline's median divided by this configuration's median (a speed-up when above 1).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.mpc.plan import Plan
from aac_sumo.references import PathReference
from aac_sumo.world import Obstacle, RobotSpec

HORIZONS = (5, 10, 15)
#: configuration name -> (solver, compiled to C); "fatrop-c" is the shipped fast path
CONFIGS = {"fatrop-c": ("fatrop", True), "fatrop": ("fatrop", False), "ipopt": ("ipopt", False), "sqp": ("sqp", False)}
SOLVERS = tuple(CONFIGS)
BASELINE = "ipopt"
SLOTS = 8
DT = 0.1
SPEED = 8.0
COURSE_END = 95.0  # the episode restarts once the ego's rear axle passes this x [m]
MAX_EPISODE_STEPS = 250  # ... or after this many steps (if it got stuck)
WARMUP = 5


@dataclass
class BenchRecord:
    """One timed configuration, as written to ``bench.json``."""

    name: str
    horizon: int
    samples: int
    median_ms: float
    p95_ms: float
    failures: int
    solver: str
    slots: int = SLOTS
    mean_ms: float = 0.0
    ratio_to: str | None = None
    ratio: float | None = None
    proximity_median_ms: float | None = None
    realtime_factor: float | None = None
    realtime_factor_range: tuple[float, float] | None = None
    runs: int | None = None

    def as_json(self) -> dict:
        out = dict(self.__dict__)
        if self.ratio_to is None:
            del out["ratio_to"], out["ratio"]
        return {k: v for k, v in out.items() if v is not None or k in ("ratio_to", "ratio")}


@dataclass
class BenchReport:
    records: list[BenchRecord] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def ego_spec() -> RobotSpec:
    return RobotSpec("ego", 1.0, 0.6, BicycleModel(0.8, VehicleLimits(-6.0, 3.0, 0.6, 0.0, 20.0)))


# (name, kind, centre at t=0, velocity, length, width)
_COURSE = (
    ("cone1", "cone", (18.0, 0.75), (0.0, 0.0), 0.4, 0.4),
    ("cone2", "cone", (42.0, -0.75), (0.0, 0.0), 0.4, 0.4),
    ("cone3", "cone", (70.0, 0.7), (0.0, 0.0), 0.4, 0.4),
    ("ped1", "pedestrian", (30.0, -4.5), (0.0, 1.3), 0.5, 0.5),
    ("ped2", "pedestrian", (58.0, 5.0), (0.0, -1.2), 0.5, 0.5),
    ("car_left", "robot", (6.0, 1.7), (5.0, 0.0), 1.0, 0.6),
    ("car_right", "robot", (12.0, -1.7), (4.0, 0.0), 1.0, 0.6),
    ("car_left2", "robot", (35.0, 1.8), (3.0, 0.0), 1.0, 0.6),
)


def obstacles_at(t: float) -> list[Obstacle]:
    """The eight course obstacles at time ``t`` [s] of an episode (constant velocities)."""
    out = []
    for name, kind, centre, vel, length, width in _COURSE:
        v = np.array(vel, dtype=float)
        heading = math.atan2(v[1], v[0]) if np.any(v) else 0.0
        out.append(Obstacle(name, kind, np.array(centre, dtype=float) + v * t, v, heading, length, width))
    return out


def closed_loop_times(solver: str, horizon: int, samples: int, warmup: int = WARMUP) -> tuple[np.ndarray, int]:
    """Solve times [ms] of ``samples`` warm-started closed-loop solves after ``warmup`` untimed
    ones, and how many of the timed solves did not end ``solved``."""
    robot = ego_spec()
    name, codegen = CONFIGS[solver]
    planner = MpcPlanner(MpcConfig(horizon=horizon, dt=DT, slots=SLOTS, solver=name, retry_with_ipopt=False, codegen=codegen))
    path = PathReference([[0.0, 0.0], [COURSE_END + 200.0, 0.0]], SPEED, stop_at_end=False)
    times, failures = [], 0
    state, previous, u_prev, t, steps = None, None, np.zeros(2), 0.0, 0
    for i in range(warmup + samples):
        if state is None or state[0] > COURSE_END or steps >= MAX_EPISODE_STEPS:
            state, previous, u_prev, t, steps = np.array([0.0, 0.0, 0.0, SPEED]), None, np.zeros(2), 0.0, 0
        plan: Plan = planner.plan(robot, state, path.horizon(state, horizon, DT), u_prev, obstacles_at(t), previous)
        if i >= warmup:
            times.append(plan.solve_ms)
            failures += plan.status != "solved"
        u_prev = plan.inputs[0]
        state = robot.model.step(state, u_prev, DT)
        previous, t, steps = plan, t + DT, steps + 1
    return np.array(times), failures


def bench_mpc(samples: int = 100, horizons=HORIZONS, solvers=SOLVERS, progress=None) -> BenchReport:
    """Time every solver configuration at every horizon; see the module docstring."""
    report = BenchReport()
    medians: dict[tuple[str, int], float] = {}
    for horizon in horizons:
        for solver in solvers:
            if progress:
                progress(f"mpc/{solver} N={horizon}")
            times, failures = closed_loop_times(solver, horizon, samples)
            if solver == "sqp" and failures > samples / 2:
                report.notes.append(f"mpc/sqp N={horizon} skipped: {failures} of {samples} solves failed")
                continue
            if failures > 0.05 * samples:
                report.notes.append(f"mpc/{solver} N={horizon}: {failures} of {samples} solves failed; "
                                    "its times include the failed solves")
            median = float(np.median(times))
            medians[(solver, horizon)] = median
            report.records.append(BenchRecord(
                name=f"mpc/{solver}", horizon=horizon, samples=len(times), median_ms=median,
                p95_ms=float(np.percentile(times, 95)), failures=int(failures), solver=solver,
                mean_ms=float(np.mean(times)),
            ))
    for rec in report.records:
        base = medians.get((BASELINE, rec.horizon))
        if rec.solver != BASELINE and base is not None and rec.median_ms > 0:
            rec.ratio_to, rec.ratio = f"mpc/{BASELINE}", base / rec.median_ms
    return report


def markdown(report: BenchReport) -> str:
    """The records as a markdown table, plus notes."""
    lines = [
        "| name | N | samples | median [ms] | p95 [ms] | failures | speed-up vs |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for r in report.records:
        ratio = f"{r.ratio:.2f}x {r.ratio_to}" if r.ratio is not None else "(baseline)" if r.solver == BASELINE else ""
        lines.append(f"| {r.name} | {r.horizon} | {r.samples} | {r.median_ms:.2f} | {r.p95_ms:.2f} | {r.failures} | {ratio} |")
    text = "\n".join(lines) + "\n"
    if report.notes:
        text += "\n" + "\n".join(f"- {n}" for n in report.notes) + "\n"
    return text


def write(out: Path, mpc: BenchReport | None = None, aac: BenchReport | None = None) -> str:
    """``bench.json`` (a list of every record) and ``bench.md`` in ``out``; returns the markdown."""
    out.mkdir(parents=True, exist_ok=True)
    records = (mpc.records if mpc else []) + (aac.records if aac else [])
    (out / "bench.json").write_text(json.dumps([r.as_json() for r in records], indent=2) + "\n")
    text = ""
    if mpc is not None:
        text += (
            "# MPC-FCBF solve time\n\n"
            f"One warm-started solve per control period in a closed loop (ego 1.0 m x 0.6 m at {SPEED:g} m/s "
            f"past {len(_COURSE)} obstacles, {SLOTS} slots, dt {DT} s, barrier fcbf); each solver alone "
            f"(no ipopt retry); {WARMUP} untimed warm-up solves. Each configuration drives its own closed loop, "
            "so the problems it solves differ slightly from the others'. Speed-up = baseline median / median.\n\n"
            + markdown(mpc)
        )
    if aac is not None:
        text += ("\n" if text else "") + (
            "# Coordinator time per control period: AAC against LFC\n\n"
            "Full runs of each bundled scenario with its own settings, AAC then LFC, each repeated in this process (the "
            "runs are identical but for their timing). The time is the coordinator's wall time per period: authority "
            "choice, predictions and every MPC solve (LFC solves once per unfinished robot); the medians pool the periods "
            "of all runs. The real-time factor is simulated time over the run's wall time after its set-up (`setup_s`: "
            "building the experiment, loading or compiling its problems; the simulator is included): the median over "
            "the runs, and its range. AAC speed-up = LFC median / AAC median. The "
            f"random_crossing_<n> rows are AAC alone with one authority per cluster (`aac.authorities = \"clusters\"`), "
            f"N = 10, over the first {SCALING_SECONDS:.0f} s of each run ({_scaling_notes()}); growth = that row's median over "
            "the smallest one's; the random_crossing_dense<d> rows are the scenario's AAC on 20 robots at d robots per "
            "100 m^2, whole runs, growth over the sparser row.\n\n"
            + markdown_aac(aac)
        )
    (out / "bench.md").write_text(text)
    return text


# --- coordinators: AAC against LFC per control period ------------------------------------------

AAC_SCENARIOS = ("swarm_rescue", "lane_change", "random_crossing", "highway_work_zone")
#: Robot counts of the random-crossing scaling rows (AAC with one authority per cluster, N = 10,
#: the first SCALING_SECONDS of each run: the crowded part).
SCALING = (15, 100, 1000)
SCALING_SECONDS = 20.0
#: Further settings of a scaling row: at 6 m^2 a robot (the scenario's own) 1,000 robots do not fit
#: (the goals' discs near their packing limit), at 8 m^2 the draw takes about 20 s.
SCALING_SETS = {1000: ["random_crossing.area_per_robot=8"]}
#: Robots per 100 m^2 of the dense random-crossing rows (20 robots, the scenario's AAC, whole runs):
#: the density where AAC first stalled on seeds 0-9 (12.5), and the densest the draw places (20;
#: twice 12.5 does not fit: the goals' reach discs, docs/swarm.md).
DENSE = (12.5, 20.0)
#: The highway work zone's rows (N = 10, whole runs): AAC with one authority per cluster (the
#: scenario's stored plans and safety stop; committed plans are not fit for SUMO's traffic,
#: docs/highway_work_zone.md) with 15 controlled cars (the flow's first 15; SUMO drives the other
#: 85) and with all 100, then the scenario's own AAC (the paper's one authority per period) with all 100.
CLUSTERS = ['aac.authorities="clusters"']
HIGHWAY = (("highway_15", ["sumo.controlled_types=", "sumo.controlled_ids=aac.?,aac.1[0-4]", *CLUSTERS]),
           ("highway_100", CLUSTERS), ("highway_100_one_authority", ["aac.authorities=1"]))


def bench_aac(horizons=HORIZONS, scenarios=AAC_SCENARIOS, repeats=3, progress=None) -> BenchReport:
    """Coordinator wall time per control period, AAC and LFC, in ``repeats`` full runs of each
    bundled scenario at each horizon, one after the other in this process (see
    :func:`_coordinator_record`). ``ratio`` on the AAC record is LFC's median over AAC's (AAC's
    speed-up). The random crossing and the highway work zone give AAC's scaling rows instead
    (:func:`_scaling_records`, :func:`_highway_records`)."""
    from aac_sumo import config

    report = BenchReport()
    for scenario in scenarios:
        try:
            config.resolve(scenario)
        except config.ScenarioError:
            report.notes.append(f"{scenario}: no such bundled scenario; skipped")
            continue
        if scenario == "random_crossing":
            report.records += _scaling_records(repeats, report.notes, progress) + _dense_records(repeats, report.notes, progress)
            continue
        if scenario == "highway_work_zone":
            report.records += _highway_records(repeats, report.notes, progress)
            continue
        for horizon in horizons:
            aac, lfc = (_coordinator_record(name, scenario, horizon, repeats, report.notes, progress) for name in ("aac", "lfc"))
            aac.ratio_to, aac.ratio = lfc.name, lfc.median_ms / aac.median_ms if aac.median_ms > 0 else None
            report.records += [aac, lfc]
    return report


def _scaling_notes() -> str:
    """The scaling rows' settings beyond the robot count, for bench.md."""
    rest = "; ".join(f"{n} robots: {', '.join(sets)}" for n, sets in SCALING_SETS.items() if n in SCALING)
    return "6 m^2 a robot" + (f"; {rest}" if rest else "")


def _scaling_records(repeats: int, notes: list[str], progress=None) -> list[BenchRecord]:
    """AAC with ``authorities = "clusters"`` on the random crossing at each robot count of
    SCALING, N = 10, the first SCALING_SECONDS; each record's ratio is its median over the
    smallest count's (the growth of the per-period time)."""
    records = []
    for n in SCALING:
        sets = [f"random_crossing.n_robots={n}", 'aac.authorities="clusters"', f"scenario.duration={SCALING_SECONDS}",
                *SCALING_SETS.get(n, [])]
        record = _coordinator_record("aac", "random_crossing", 10, repeats, notes, progress, sets, f"random_crossing_{n}")
        if records:
            record.ratio_to, record.ratio = records[0].name, record.median_ms / records[0].median_ms
        records.append(record)
    return records


def _dense_records(repeats: int, notes: list[str], progress=None) -> list[BenchRecord]:
    """The scenario's AAC on 20 robots at each density of DENSE, whole runs at N = 10; the second
    record's ratio is its median over the first's."""
    records = []
    for density in DENSE:
        label = f"random_crossing_dense{density:g}"
        record = _coordinator_record("aac", "random_crossing", 10, repeats, notes, progress, [f"random_crossing.density={density}"], label)
        if records:
            record.ratio_to, record.ratio = records[0].name, record.median_ms / records[0].median_ms
        records.append(record)
    return records


def _highway_records(repeats: int, notes: list[str], progress=None) -> list[BenchRecord]:
    """The HIGHWAY rows, whole runs at N = 10; the second and third records' ratio is their
    median over the first's (the growth of the per-period time from 15 to 100 cars)."""
    records = []
    for label, sets in HIGHWAY:
        record = _coordinator_record("aac", "highway_work_zone", 10, repeats, notes, progress, sets, label)
        if records:
            record.ratio_to, record.ratio = records[0].name, record.median_ms / records[0].median_ms
        records.append(record)
    return records


def _coordinator_record(name: str, scenario: str, horizon: int, repeats: int, notes: list[str], progress=None,
                        sets: list[str] = (), label_as: str | None = None) -> BenchRecord:
    """``repeats`` runs of ``scenario`` with coordinator ``name`` at ``horizon``; the runs are
    identical but for their timing (a note says so otherwise). ``samples`` counts the periods of
    all runs and the medians pool them; ``failures`` counts the infeasible or failed MPC solves
    of one run; ``proximity_median_ms`` is the median time of the proximity decision over the
    periods that ran one; ``realtime_factor`` is the median over the runs of simulated time over
    the run's wall time after its set-up (the metric of that name; simulator included),
    ``realtime_factor_range`` its least and greatest.
    ``sets`` are further ``--set`` assignments, and ``label_as`` names the record instead of the
    scenario."""
    from aac_sumo import config
    from aac_sumo.runs import runner

    label = f"{name}/{label_as or scenario} N={horizon}"
    times, prox, rtf, metrics = [], [], [], []
    for run in range(repeats):
        if progress:
            progress(label + (f" (run {run + 1} of {repeats})" if repeats > 1 else ""))
        result = runner.run(config.load(scenario, [f"controller.coordinator={name}", f"controller.horizon={horizon}", *sets]))
        metrics.append(result.metrics)
        times.append(result.periods["compute_ms"].to_numpy())
        p = result.periods.get("proximity_ms")
        prox.append(p[p > 0].to_numpy() if p is not None else np.array([]))
        if result.metrics["realtime_factor"] is not None:
            rtf.append(result.metrics["realtime_factor"])
    first = metrics[0]
    if first.get("error"):
        notes.append(f"{label}: run failed: {first['error']}")
    elif not first["completed"] and not any(a.startswith("scenario.duration=") for a in sets):
        notes.append(f"{label}: {first.get('incomplete_reason', 'not completed')}")
    if any(m["infeasible_solves"] != first["infeasible_solves"] or len(t) != len(times[0]) for m, t in zip(metrics, times)):
        notes.append(f"{label}: the runs differ (infeasible solves {[m['infeasible_solves'] for m in metrics]})")
    times, prox = np.concatenate(times), np.concatenate(prox)
    return BenchRecord(
        name=f"{name}/{label_as or scenario}", horizon=horizon, samples=len(times), median_ms=float(np.median(times)),
        p95_ms=float(np.percentile(times, 95)), failures=int(first["infeasible_solves"]),
        solver=result.scenario["controller.solver"] + ("-c" if result.scenario["controller.codegen"] else ""),
        slots=result.scenario["controller.obstacle_slots"], mean_ms=float(np.mean(times)),
        proximity_median_ms=float(np.median(prox)) if prox.size else None,
        realtime_factor=float(np.median(rtf)) if rtf else None,
        realtime_factor_range=(min(rtf), max(rtf)) if rtf else None, runs=repeats,
    )


def markdown_aac(report: BenchReport) -> str:
    """The coordinator records as a markdown table, plus notes."""
    lines = [
        "| name | N | runs | periods | median [ms] | p95 [ms] | mean [ms] | proximity median [ms] | infeasible solves per run | real-time factor: median (range) | AAC speed-up |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in report.records:
        prox = f"{r.proximity_median_ms:.2f}" if r.proximity_median_ms is not None else "—"
        ratio = f"{r.ratio:.2f}x vs {r.ratio_to}" if r.ratio is not None else ""
        if r.ratio is not None and r.ratio_to.startswith("aac/"):
            ratio = f"(growth: {r.ratio:.2f}x the time of {r.ratio_to})"
        rtf = f"{r.realtime_factor:.1f}" if r.realtime_factor is not None else "—"
        if r.realtime_factor_range is not None and r.runs and r.runs > 1:
            rtf += f" ({r.realtime_factor_range[0]:.1f}–{r.realtime_factor_range[1]:.1f})"
        lines.append(f"| {r.name} | {r.horizon} | {r.runs} | {r.samples} | {r.median_ms:.2f} | {r.p95_ms:.2f} | {r.mean_ms:.2f} | {prox} | "
                     f"{r.failures} | {rtf} | {ratio} |")
    text = "\n".join(lines) + "\n"
    if report.notes:
        text += "\n" + "\n".join(f"- {n}" for n in report.notes) + "\n"
    return text
