"""The paper's tables, ours beside the paper's values: ``aac-sumo table NAME``.

Table I (swarm rescue) and Table II (lane change) compare AAC with LFC at MPC horizons 5, 10 and
15; Table III (emergency braking) compares CBF with F-CBF over the initial speed. The runs go
through the same process pool as ``aac-sumo sweep`` (and leave the same ``results.csv``).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from aac_sumo import config, sweep

TABLES = ("swarm", "lane-change", "braking")

BRAKING_SPEEDS = (5, 10, 15, 20, 25)
BRAKING_BARRIERS = ("cbf", "fcbf")
BRAKING_METRICS = ("infeasibility_rate", "min_distance_m", "ttc_mean_s", "collisions", "min_clearance_m")
PAPER_METRICS = ("infeasibility_rate", "min_distance_m", "ttc_mean_s")
#: Paper Table III: (infeasibility rate, min distance [m], mean TTC [s]); None where it has no value.
PAPER_TABLE_III: dict[tuple[str, int], tuple[float | None, float | None, float | None]] = {
    ("cbf", 5): (0.433, 1.50, 2.04),
    ("fcbf", 5): (0.0, 1.65, 2.10),
    ("cbf", 10): (0.333, 0.87, 2.13),
    ("fcbf", 10): (0.0, 1.05, 3.55),
    ("cbf", 15): (1.0, None, None),
    ("fcbf", 15): (0.0, 4.04, 5.62),
}
BARRIER_LABELS = {"cbf": "CBF", "fcbf": "F-CBF"}


def _speed(value) -> int | float:
    v = float(value)
    return int(v) if v.is_integer() else v


def braking_rows(runs: list[dict], seeds: int) -> list[dict]:
    """One table.csv row per (speed, barrier) from the per-run rows (grid keys
    ``braking.speed`` and ``controller.barrier``); means over the seeds that ran without error."""
    table = []
    for (speed, barrier), group in sweep.groups(runs, ["braking.speed", "controller.barrier"]):
        good = [r for r in group if r.get("status") == "ok"]
        row: dict = {"barrier": barrier, "speed": _speed(speed)}
        for m in BRAKING_METRICS:
            mean, std, _ = sweep.mean_std(r.get(m) for r in good)
            row[m] = mean
            if seeds > 1:
                row[f"{m}_std"] = std
        paper = PAPER_TABLE_III.get((barrier, _speed(speed)), (None,) * len(PAPER_METRICS))
        for m, value in zip(PAPER_METRICS, paper):
            row[f"paper_{m}"] = value
        row["runs"] = len(good)
        row["errors"] = len(group) - len(good)
        table.append(row)
    return table


def braking_columns(seeds: int) -> list[str]:
    cols = ["barrier", "speed"]
    for m in BRAKING_METRICS:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + [f"paper_{m}" for m in PAPER_METRICS] + ["runs", "errors"]


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return repr(value) if isinstance(value, float) else str(value)


def write_csv(rows: list[dict], cols: list[str], path: Path) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(cols)
        writer.writerows([_cell(r.get(c)) for c in cols] for r in rows)


def _num(value) -> float:
    return math.nan if value is None else float(value)


def _fmt(mean, std=None, kind: str = "f2") -> str:
    """``kind``: ``pct`` (rate as %), ``f2`` (two decimals), ``count``."""
    mean, std = _num(mean), _num(std)
    if not math.isfinite(mean):
        return "—"
    if kind == "pct":
        return f"{100 * mean:.1f} ± {100 * std:.1f}%" if math.isfinite(std) else f"{100 * mean:.1f}%"
    if kind == "count" and not math.isfinite(std):
        return f"{mean:.0f}" if float(mean).is_integer() else f"{mean:.2f}"
    return f"{mean:.2f} ± {std:.2f}" if math.isfinite(std) else f"{mean:.2f}"


def braking_markdown(rows: list[dict], scenario: config.Scenario, seeds: int) -> str:
    c, b = scenario.data["controller"], scenario.data["braking"]
    kinds = {"infeasibility_rate": "pct", "collisions": "count"}
    head = ["Barrier", "Speed [m/s]", "Infeasibility (ours)", "Infeasibility (paper)", "Min distance [m] (ours)",
            "Min distance [m] (paper)", "Mean TTC [s] (ours)", "Mean TTC [s] (paper)", "Collisions (ours)",
            "Min clearance [m] (ours)"]
    lines = [
        "# Table III: emergency braking, CBF vs F-CBF",
        "",
        f"Ego (MPC, N = {c['horizon']}, {c['solver']}{' compiled to C' if c['codegen'] else ''}{' + ipopt retry' if c['retry_with_ipopt'] else ''}, "
        f"dt = {scenario['scenario.dt']} s) follows a lead {b['gap']} m ahead (centre to centre) at the same speed; "
        f"the lead brakes at {b['lead_decel']} m/s² from t = {b['t_brake']} s. "
        + (f"Ours: mean ± sample std over {seeds} seeds." if seeds > 1 else "Ours: one seed.")
        + " Min distance is the smallest centre-to-centre distance between ego and lead; min clearance the"
        " smallest footprint gap (negative = overlap); mean TTC is over the steps where the ego closes in;"
        " infeasibility is the share of MPC solves that failed or were infeasible. The paper reports no"
        " values at 20 and 25 m/s, nor collisions or clearance; — marks a missing value.",
        "",
        "| " + " | ".join(head) + " |",
        "|---|---:|" + "---:|" * (len(head) - 2),
    ]
    for r in rows:
        cells = [BARRIER_LABELS.get(r["barrier"], r["barrier"]), str(r["speed"])]
        for m in ("infeasibility_rate", "min_distance_m", "ttc_mean_s"):
            kind = kinds.get(m, "f2")
            cells += [_fmt(r[m], r.get(f"{m}_std"), kind), _fmt(r[f"paper_{m}"], None, kind)]
        cells += [_fmt(r["collisions"], r.get("collisions_std"), "count"), _fmt(r["min_clearance_m"], r.get("min_clearance_m_std"))]
        if r["errors"]:
            cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def braking_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                  progress: bool = True, scheduler: str | None = None, resume: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table III (speeds x barriers x seeds) and write results.csv, table.csv and table.md;
    returns the table rows, the markdown and the per-run rows."""
    sets = list(sets or [])
    grid = [("braking.speed", [str(s) for s in BRAKING_SPEEDS]), ("controller.barrier", list(BRAKING_BARRIERS))]
    runs = run_grid("braking", grid, seeds, workers, out, sets, progress, "table braking", scheduler, resume)
    rows = braking_rows(runs, seeds)
    write_csv(rows, braking_columns(seeds), out / "table.csv")
    text = braking_markdown(rows, config.load("braking", sets), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


# --- Tables I and II: AAC against LFC over the MPC horizon ------------------------------------

HORIZONS = (5, 10, 15)
COORDINATORS = ("aac", "lfc")
COORDINATOR_LABELS = {"aac": "AAC-MPC-FCBF", "lfc": "LFC-MPC-FCBF"}
SWARM_METRICS = ("task_duration_s", "compute_ms_mean", "compute_ms_median", "min_distance_m", "collisions",
                 "authority_jain", "delay_jain", "delay_max_s", "completed", "infeasibility_rate", "safety_stops")
#: Paper Table I: (task duration [s], computation time [ms], minimum distance [m]).
PAPER_TABLE_I: dict[tuple[str, int], tuple[float, float, float]] = {
    ("aac", 5): (18.3, 58.7, 1.19), ("lfc", 5): (22.6, 79.6, 0.47),
    ("aac", 10): (18.1, 68.4, 1.13), ("lfc", 10): (21.2, 125.6, 0.48),
    ("aac", 15): (17.6, 85.6, 1.05), ("lfc", 15): (20.8, 236.5, 0.48),
}
PAPER_I_METRICS = ("task_duration_s", "compute_ms_mean", "min_distance_m")


def horizon_rows(runs: list[dict], seeds: int, metrics, paper: dict, paper_metrics) -> list[dict]:
    """One table.csv row per (coordinator, horizon): means (and stds) over the seeds that ran
    without error; ``completed`` becomes the share of completed runs and task duration is
    averaged over the completed ones (it is null otherwise)."""
    table = []
    for (horizon, coordinator), group in sweep.groups(runs, ["controller.horizon", "controller.coordinator"]):
        good = [r for r in group if r.get("status") == "ok"]
        row: dict = {"coordinator": coordinator, "horizon": int(horizon)}
        for m in metrics:
            values = [float(bool(r.get(m))) if m == "completed" else r.get(m) for r in good]
            mean, std, _ = sweep.mean_std(values)
            row[m] = mean
            if seeds > 1:
                row[f"{m}_std"] = std
        for m, value in zip(paper_metrics, paper.get((coordinator, int(horizon)), (None,) * len(paper_metrics))):
            row[f"paper_{m}"] = value
        row["runs"] = len(good)
        row["errors"] = len(group) - len(good)
        table.append(row)
    return sorted(table, key=lambda r: (r["horizon"], COORDINATORS.index(r["coordinator"]) if r["coordinator"] in COORDINATORS else 9))


def horizon_columns(seeds: int, metrics, paper_metrics) -> list[str]:
    cols = ["coordinator", "horizon"]
    for m in metrics:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + [f"paper_{m}" for m in paper_metrics] + ["runs", "errors"]


def run_grid(scenario: str, grid, seeds: int, workers: int | None, out: Path, sets: list[str] | None,
             progress: bool, desc: str, scheduler: str | None = None, resume: bool = False) -> list[dict]:
    """Every grid combination x seeds run of ``scenario`` through the sweep executor (local
    processes, or the Dask scheduler at ``scheduler``; ``resume`` skips finished runs)."""
    sets = list(sets or [])
    tasks = sweep.plan_tasks(scenario, sets, grid, seeds)
    return sweep.run_tasks(tasks, [k for k, _ in grid], out, workers, progress, desc=desc, scheduler=scheduler,
                           resume=resume, manifest=sweep.sweep_manifest(tasks[0].source, sets))


def run_horizon_table(scenario: str, seeds: int, workers: int | None, out: Path, sets: list[str] | None,
                      progress: bool, desc: str, scheduler: str | None = None, resume: bool = False) -> list[dict]:
    """Every (horizon, coordinator) x seeds run of ``scenario``; the per-run rows."""
    grid = [("controller.horizon", [str(h) for h in HORIZONS]), ("controller.coordinator", list(COORDINATORS))]
    return run_grid(scenario, grid, seeds, workers, out, sets, progress, desc, scheduler, resume)


SWARM_COLUMNS = (
    ("Task duration [s] (ours)", "task_duration_s", "f2"), ("(paper)", "paper_task_duration_s", "f2"),
    ("Compute [ms] mean (ours)", "compute_ms_mean", "f2"), ("median (ours)", "compute_ms_median", "f2"),
    ("(paper)", "paper_compute_ms_mean", "f2"), ("Min distance [m] (ours)", "min_distance_m", "f2"),
    ("(paper)", "paper_min_distance_m", "f2"), ("Collisions", "collisions", "count"), ("Completed", "completed", "pct"),
    ("authority_jain", "authority_jain", "f2"), ("delay_jain", "delay_jain", "f2"), ("delay_max_s [s]", "delay_max_s", "f2"),
    ("Infeasible", "infeasibility_rate", "pct"), ("Safety stops", "safety_stops", "count"),
)


def horizon_markdown(title: str, intro: str, columns, rows: list[dict]) -> str:
    """A markdown table of (coordinator, horizon) rows; ``columns`` are (header, key, kind) with
    kind as in :func:`_fmt`. Ours carry their std (not rates); the paper's never do."""
    lines = [f"# {title}", "", intro, "",
             "| " + " | ".join(["Controller", "N"] + [h for h, _, _ in columns]) + " |",
             "|---|---:|" + "---:|" * len(columns)]
    for r in rows:
        cells = [COORDINATOR_LABELS.get(r["coordinator"], r["coordinator"]), str(r["horizon"])]
        for _, key, kind in columns:
            plain = key.startswith("paper_") or kind == "pct"
            cells.append(_fmt(r[key], None if plain else r.get(f"{key}_std"), kind))
        if r["errors"]:
            cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def swarm_markdown(rows: list[dict], scenario: config.Scenario, seeds: int) -> str:
    c, s = scenario.data["controller"], scenario.data["swarm_rescue"]
    intro = (
        f"{len(s['starts'])} robots with crossing paths among {len(s['debris'])} debris pieces, dt = {scenario['scenario.dt']} s, "
        f"MPC-{c['barrier'].upper()} with {c['solver']}{' compiled to C' if c['codegen'] else ''}; both coordinators use the same "
        f"planner, solver and weights. " + (f"Ours: mean ± sample std over {seeds} seeds." if seeds > 1 else "Ours: one seed.")
        + " Compute is the coordinator's wall time per control period (every MPC solve of the period included). Min distance"
        " is the smallest centre-to-centre distance between two robots. Task duration is averaged over completed runs only."
        " The paper reports only task duration, compute time and minimum distance; — marks a missing value."
    )
    return horizon_markdown("Table I: swarm rescue, AAC vs LFC", intro, SWARM_COLUMNS, rows)


def swarm_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                progress: bool = True, scheduler: str | None = None, resume: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table I (horizons x coordinators x seeds) and write results.csv, table.csv and table.md."""
    runs = run_horizon_table("swarm_rescue", seeds, workers, out, sets, progress, "table swarm", scheduler, resume)
    rows = horizon_rows(runs, seeds, SWARM_METRICS, PAPER_TABLE_I, PAPER_I_METRICS)
    write_csv(rows, horizon_columns(seeds, SWARM_METRICS, PAPER_I_METRICS), out / "table.csv")
    text = swarm_markdown(rows, config.load("swarm_rescue", list(sets or [])), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


LANE_METRICS = ("task_duration_s", "compute_ms_mean", "compute_ms_median", "aggressive_driving_rate", "tracking_error_m",
                "min_pedestrian_clearance_m", "collisions", "sim_collisions", "completed", "infeasibility_rate", "safety_stops")
#: Paper Table II: (task duration [s], computation time [ms], aggressive driving rate, tracking error [m]).
PAPER_TABLE_II: dict[tuple[str, int], tuple[float, float, float, float]] = {
    ("aac", 5): (6.73, 39.4, 0.0909, 0.4899), ("lfc", 5): (7.41, 183.3, 0.1818, 0.4809),
    ("aac", 10): (6.72, 136.3, 0.0909, 0.4765), ("lfc", 10): (7.32, 516.7, 0.1818, 0.4755),
    ("aac", 15): (6.68, 540.8, 0.0909, 0.4586), ("lfc", 15): (7.02, 4025.0, 0.1818, 0.4559),
}
PAPER_II_METRICS = ("task_duration_s", "compute_ms_mean", "aggressive_driving_rate", "tracking_error_m")


LANE_COLUMNS = (
    ("Task duration [s] (ours)", "task_duration_s", "f2"), ("(paper)", "paper_task_duration_s", "f2"),
    ("Compute [ms] mean (ours)", "compute_ms_mean", "f2"), ("median (ours)", "compute_ms_median", "f2"),
    ("(paper)", "paper_compute_ms_mean", "f2"), ("Aggressive driving (ours)", "aggressive_driving_rate", "pct"),
    ("(paper)", "paper_aggressive_driving_rate", "pct"), ("Tracking error [m] (ours)", "tracking_error_m", "f2"),
    ("(paper)", "paper_tracking_error_m", "f2"), ("Min clearance to pedestrians [m]", "min_pedestrian_clearance_m", "f2"),
    ("Collisions", "collisions", "count"), ("SUMO collisions", "sim_collisions", "count"), ("Completed", "completed", "pct"),
    ("Infeasible", "infeasibility_rate", "pct"), ("Safety stops", "safety_stops", "count"),
)


def lane_change_markdown(rows: list[dict], scenario: config.Scenario, seeds: int) -> str:
    c, lc = scenario.data["controller"], scenario.data["lane_change"]
    intro = (
        f"{lc['vehicles']} controlled vehicles at {lc['speed']} m/s in SUMO (libsumo) among cones and crossing pedestrians, "
        f"dt = {scenario['scenario.dt']} s, MPC-{c['barrier'].upper()} with {c['solver']}{' compiled to C' if c['codegen'] else ''}; "
        "both coordinators use the same planner, solver and weights. "
        + (f"Ours: mean ± sample std over {seeds} seeds." if seeds > 1 else "Ours: one seed.")
        + f" Aggressive driving: share of vehicles whose |accel| ever exceeds {scenario['metrics.accel_threshold']} m/s² or whose"
        f" lateral acceleration exceeds {scenario['metrics.lat_accel_threshold']} m/s². Collisions are counted by our footprint"
        " check; SUMO collisions by SUMO itself. The paper reports no clearance or collision figures; — marks a missing value."
    )
    return horizon_markdown("Table II: lane change in SUMO, AAC vs LFC", intro, LANE_COLUMNS, rows)


def lane_change_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                      progress: bool = True, scheduler: str | None = None, resume: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table II (horizons x coordinators x seeds) and write results.csv, table.csv and table.md."""
    runs = run_horizon_table("lane_change", seeds, workers, out, sets, progress, "table lane-change", scheduler, resume)
    rows = horizon_rows(runs, seeds, LANE_METRICS, PAPER_TABLE_II, PAPER_II_METRICS)
    write_csv(rows, horizon_columns(seeds, LANE_METRICS, PAPER_II_METRICS), out / "table.csv")
    text = lane_change_markdown(rows, config.load("lane_change", list(sets or [])), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


BUILDERS = {"swarm": swarm_table, "lane-change": lane_change_table, "braking": braking_table}
