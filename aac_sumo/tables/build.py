"""The paper's tables, ours beside the paper's values: ``aac-sumo table NAME``.

Table I (swarm rescue) and Table II (lane change) compare AAC with LFC at MPC horizons 5, 10 and
15; Table III (emergency braking) compares CBF with F-CBF over the initial speed, once per
obstacle prediction (see :mod:`aac_sumo.tables.braking`). The circle-swap
table (not in the paper) compares AAC with LFC over the number of robots. The runs go through the
same process pool as ``aac-sumo sweep`` (and leave the same ``results.csv``).

Table I and the circle swap run AAC and LFC with the same emergency layers (the ``safety_layers``
column): ``off`` is the paper's setting (no safety stop for either coordinator), ``on`` gives both
the safety stop. The paper's values stand beside the ``off`` rows only.
"""

from __future__ import annotations

from pathlib import Path

from aac_sumo import config
from aac_sumo.runs import sweep
from aac_sumo.tables.ablation import ablation_table
from aac_sumo.tables.braking import braking_table
from aac_sumo.tables.common import (COORDINATORS, LAYER_KEYS, SAFETY_LAYERS, baselines_for, check_table_sets, fill_metrics,
                                    layer_sets, layered_markdown, layers_of, run_grid, write_csv)


TABLES = ("swarm", "lane-change", "braking", "circle-swap", "ablation")

# --- Tables I and II: AAC against LFC over the MPC horizon ------------------------------------

HORIZONS = (5, 10, 15)

SWARM_METRICS = ("task_duration_s", "compute_ms_mean", "compute_ms_median", "min_distance_m", "collisions",
                 "authority_jain", "delay_jain", "delay_max_s", "completed", "infeasibility_rate", "safety_stops")

#: Paper Table I: (task duration [s], computation time [ms], minimum distance [m]).
PAPER_TABLE_I: dict[tuple[str, int], tuple[float, float, float]] = {
    ("aac", 5): (18.3, 58.7, 1.19), ("lfc", 5): (22.6, 79.6, 0.47),
    ("aac", 10): (18.1, 68.4, 1.13), ("lfc", 10): (21.2, 125.6, 0.48),
    ("aac", 15): (17.6, 85.6, 1.05), ("lfc", 15): (20.8, 236.5, 0.48),
}

PAPER_I_METRICS = ("task_duration_s", "compute_ms_mean", "min_distance_m")


def _layer_rank(row: dict) -> int:
    return SAFETY_LAYERS.index(row["safety_layers"]) if row.get("safety_layers") in SAFETY_LAYERS else -1


def _coordinator_rank(row: dict) -> int:
    return COORDINATORS.index(row["coordinator"]) if row["coordinator"] in COORDINATORS else 9


def horizon_rows(runs: list[dict], seeds: int, metrics, paper: dict, paper_metrics) -> list[dict]:
    """One table.csv row per (coordinator, horizon), and per ``safety_layers`` value when the
    runs carry one: means (and stds) over the seeds that ran without error; ``completed``
    becomes the share of completed runs and task duration is averaged over the completed ones
    (it is null otherwise). The paper's values go to the rows of its setting only: every row
    of a table without ``safety_layers``, the ``off`` rows of one with it."""
    layered = any("safety_layers" in r for r in runs)
    keys = ["controller.horizon", "controller.coordinator"] + (["safety_layers"] if layered else [])
    table = []
    for values, group in sweep.groups(runs, keys):
        horizon, coordinator = values[:2]
        row: dict = {"coordinator": coordinator, "horizon": None if horizon is None else int(horizon)}  # a baseline has no horizon
        if layered:
            row["safety_layers"] = values[2]
        fill_metrics(row, group, seeds, metrics)
        paper_values = paper.get((coordinator, row["horizon"])) if row.get("safety_layers", "off") == "off" else None
        for m, value in zip(paper_metrics, paper_values or (None,) * len(paper_metrics)):
            row[f"paper_{m}"] = value
        table.append(row)
    return sorted(table, key=lambda r: (_layer_rank(r), r["horizon"] is None, r["horizon"] or 0, _coordinator_rank(r)))


def horizon_columns(seeds: int, metrics, paper_metrics, layered: bool = False) -> list[str]:
    cols = ["coordinator", "horizon"] + (["safety_layers"] if layered else [])
    for m in metrics:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + [f"paper_{m}" for m in paper_metrics] + ["runs", "errors"]


def run_horizon_table(scenario: str, seeds: int, workers: int | None, out: Path, sets: list[str] | None,
                      progress: bool, desc: str, scheduler: str | None = None, resume: bool = False,
                      layers: tuple[str, ...] | None = None, baselines: bool = False) -> list[dict]:
    """Every (horizon, coordinator) x seeds run of ``scenario``; the per-run rows. With ``layers``
    (``safety_layers`` values) the grid runs once per setting, AAC and LFC alike in each. With
    ``baselines``, also :func:`baseline_runs`."""
    grid = [("controller.horizon", [str(h) for h in HORIZONS]), ("controller.coordinator", list(COORDINATORS))]
    bundles = [((("safety_layers", layer),), layer_sets(layer)) for layer in layers] if layers else None
    runs = run_grid(scenario, grid, seeds, workers, out, sets, progress, desc, scheduler, resume, bundles)
    if baselines:
        runs += baseline_runs(scenario, seeds, workers, out, sets, progress, desc, scheduler, resume,
                              [((("safety_layers", "off"),), layer_sets("off"))] if layers else None)
    return runs


def baseline_runs(scenario: str, seeds: int, workers: int | None, out: Path, sets: list[str] | None, progress: bool, desc: str,
                  scheduler: str | None, resume: bool, bundles=None) -> list[dict]:
    """Every registered baseline that drives ``scenario``'s kind x seeds (x ``bundles``, the paper's
    layer setting only: a baseline has no emergency layer of ours), into ``out/baselines``; the
    MPC horizon means nothing to them, so their rows have none."""
    names = baselines_for(config.load(scenario)["scenario.kind"])
    if not names:
        return []
    (out / "baselines").mkdir(parents=True, exist_ok=True)
    return run_grid(scenario, [("controller.coordinator", list(names))], seeds, workers, out / "baselines", sets, progress,
                    f"{desc} --baselines", scheduler, resume, bundles)


SWARM_COLUMNS = (
    ("Task duration [s] (ours)", "task_duration_s", "f2"), ("(paper)", "paper_task_duration_s", "f2"),
    ("Compute [ms] mean (ours)", "compute_ms_mean", "f2"), ("median (ours)", "compute_ms_median", "f2"),
    ("(paper)", "paper_compute_ms_mean", "f2"), ("Min distance [m] (ours)", "min_distance_m", "f2"),
    ("(paper)", "paper_min_distance_m", "f2"), ("Collisions", "collisions", "count"), ("Completed", "completed", "pct"),
    ("authority_jain", "authority_jain", "f2"), ("delay_jain", "delay_jain", "f2"), ("delay_max_s [s]", "delay_max_s", "f2"),
    ("Infeasible", "infeasibility_rate", "pct"), ("Safety stops", "safety_stops", "count"),
)


def horizon_markdown(title: str, intro: str, columns, rows: list[dict]) -> str:
    """A markdown table of (coordinator, horizon) rows, one per ``safety_layers`` value if the rows
    carry one; ``columns`` are (header, key, kind) with kind as in :func:`_fmt`."""
    return layered_markdown(title, intro, (("Controller", "coordinator"), ("N", "horizon")), columns, rows)


def swarm_markdown(rows: list[dict], scenario: config.Scenario, seeds: int) -> str:
    c, s = scenario.data["controller"], scenario.data["swarm_rescue"]
    intro = (
        f"{len(s['starts'])} robots with crossing paths among {len(s['debris'])} debris pieces, dt = {scenario['scenario.dt']} s, "
        f"MPC-{c['barrier'].upper()} with {c['solver']}{' compiled to C' if c['codegen'] else ''}; both coordinators use the same "
        f"planner, solver, weights, prediction and emergency layers (each section below states which). "
        + (f"Ours: mean ± sample std over {seeds} seeds." if seeds > 1 else "Ours: one seed.")
        + " Compute is the coordinator's wall time per control period (every MPC solve of the period included). Min distance"
        " is the smallest centre-to-centre distance between two robots. Task duration is averaged over completed runs only."
        " The paper reports only task duration, compute time and minimum distance, with no emergency layer; — marks a"
        " missing value."
    )
    return horizon_markdown("Table I: swarm rescue, AAC vs LFC", intro, SWARM_COLUMNS, rows)


def swarm_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                progress: bool = True, scheduler: str | None = None, resume: bool = False,
                layers: str = "both", baselines: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table I (safety layers x horizons x coordinators x seeds) and write results.csv,
    table.csv and table.md. ``layers`` (``off``, ``on`` or ``both``) sets ``aac.safety_stop``
    and ``lfc.safety_stop`` together in every run; ``baselines`` adds their rows."""
    sets = list(sets or [])
    check_table_sets(sets, LAYER_KEYS, "swarm")
    runs = run_horizon_table("swarm_rescue", seeds, workers, out, sets, progress, "table swarm", scheduler, resume,
                             layers=layers_of(layers), baselines=baselines)
    rows = horizon_rows(runs, seeds, SWARM_METRICS, PAPER_TABLE_I, PAPER_I_METRICS)
    write_csv(rows, horizon_columns(seeds, SWARM_METRICS, PAPER_I_METRICS, layered=True), out / "table.csv")
    text = swarm_markdown(rows, config.load("swarm_rescue", sets), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


# --- Circle swap: AAC against LFC over the number of robots ------------------------------------

#: (robots, circle radius [m]) of the circle-swap table: ``paired`` (each count on the radius that
#: keeps its crowd as dense as the 8 robots on 4 m, the default) or ``full`` (every count on every radius).
CIRCLE_GRIDS = {"paired": ((8, 4.0), (16, 6.0), (24, 8.0)),
                "full": tuple((n, r) for n in (8, 16, 24) for r in (4.0, 6.0, 8.0))}

CIRCLE_KEYS = ("circle_swap.n_robots", "circle_swap.radius")

CIRCLE_METRICS = ("completed", "task_duration_s", "collisions", "deadlock", "min_distance_m", "min_clearance_m",
                  "compute_ms_mean", "compute_ms_median", "infeasibility_rate", "safety_stops", "authority_jain",
                  "delay_max_s")

CIRCLE_COLUMNS = (
    ("Completed", "completed", "pct"), ("Task duration [s]", "task_duration_s", "f2"), ("Collisions", "collisions", "count"),
    ("Deadlock", "deadlock", "pct"), ("Min distance [m]", "min_distance_m", "f2"), ("Min clearance [m]", "min_clearance_m", "f2"),
    ("Compute [ms] mean", "compute_ms_mean", "f2"), ("median", "compute_ms_median", "f2"),
    ("Infeasible", "infeasibility_rate", "pct"), ("Safety stops", "safety_stops", "count"),
    ("authority_jain", "authority_jain", "f2"), ("delay_max_s [s]", "delay_max_s", "f2"),
)


def circle_rows(runs: list[dict], seeds: int) -> list[dict]:
    """One table.csv row per (coordinator, robots, radius, safety layers): means (and stds) over the
    seeds that ran without error; ``completed`` and ``deadlock`` are shares of the runs. The paper
    has no circle swap, so there are no ``paper_`` values."""
    table = []
    keys = ["controller.coordinator", *CIRCLE_KEYS, "safety_layers"]
    for (coordinator, n, radius, layer), group in sweep.groups(runs, keys):
        row = {"coordinator": coordinator, "n_robots": int(n), "radius": float(radius), "safety_layers": layer}
        table.append(fill_metrics(row, group, seeds, CIRCLE_METRICS))
    return sorted(table, key=lambda r: (_layer_rank(r), r["n_robots"], _coordinator_rank(r)))


def circle_columns(seeds: int) -> list[str]:
    cols = ["coordinator", "n_robots", "radius", "safety_layers"]
    for m in CIRCLE_METRICS:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + ["runs", "errors"]


def circle_markdown(rows: list[dict], scenario: config.Scenario, seeds: int) -> str:
    c, cs = scenario.data["controller"], scenario.data["circle_swap"]
    intro = (
        f"n robots evenly spaced on a circle of the given radius drive to the antipodal points at {cs['cruise_speed']} m/s: "
        f"every straight path meets at the centre. dt = {scenario['scenario.dt']} s, time limit {scenario['scenario.duration']} s, "
        f"MPC-{c['barrier'].upper()} with {c['solver']}{' compiled to C' if c['codegen'] else ''}, N = {c['horizon']}; "
        "both coordinators use the same planner, solver, weights, prediction and emergency layers (each section below states "
        "which). " + (f"Mean ± sample std over {seeds} seeds" if seeds > 1 else "One seed")
        + f" (the seed moves the starts by up to ±{cs['start_jitter']} m and seeds AAC's proximity decision)."
        " Completed and deadlock are shares of the runs; task duration is averaged over completed runs only. Compute is"
        " the coordinator's wall time per control period. The paper has no circle swap; — marks a missing value."
    )
    first = (("Controller", "coordinator"), ("Robots", "n_robots"), ("Radius [m]", "radius"))
    return layered_markdown("Circle swap: AAC vs LFC over the number of robots", intro, first, CIRCLE_COLUMNS, rows)


def circle_swap_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                      progress: bool = True, scheduler: str | None = None, resume: bool = False,
                      layers: str = "off", baselines: bool = False, grid: str = "paired") -> tuple[list[dict], str, list[dict]]:
    """Run the circle-swap table (safety layers x (robots, radius) of ``CIRCLE_GRIDS[grid]`` x
    coordinators x seeds) and write results.csv, table.csv and table.md. ``layers`` (``off``
    by default, ``on`` or ``both``) sets ``aac.safety_stop`` and ``lfc.safety_stop`` together."""
    sets = list(sets or [])
    check_table_sets(sets, LAYER_KEYS + CIRCLE_KEYS, "circle-swap")
    bundles = [((("safety_layers", layer), ("circle_swap.n_robots", n), ("circle_swap.radius", radius)),
                layer_sets(layer) + [f"circle_swap.n_robots={n}", f"circle_swap.radius={radius}"])
               for layer in layers_of(layers) for n, radius in CIRCLE_GRIDS[grid]]
    grid = [("controller.coordinator", list(COORDINATORS))]
    runs = run_grid("circle_swap", grid, seeds, workers, out, sets, progress, "table circle-swap", scheduler, resume, bundles)
    if baselines:
        runs += baseline_runs("circle_swap", seeds, workers, out, sets, progress, "table circle-swap", scheduler, resume,
                              [b for b in bundles if dict(b[0])["safety_layers"] == "off"] or None)
    rows = circle_rows(runs, seeds)
    write_csv(rows, circle_columns(seeds), out / "table.csv")
    text = circle_markdown(rows, config.load("circle_swap", sets), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


LANE_METRICS = ("task_duration_s", "compute_ms_mean", "compute_ms_median", "aggressive_driving_rate", "tracking_error_m",
                "min_pedestrian_clearance_m", "collisions", "sim_collisions", "completed", "infeasibility_rate", "safety_stops",
                "accel_p95", "lat_accel_p95", "jerk_p95", "pedestrian_wait_s")

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
    ("accel p95 [m/s²]", "accel_p95", "f2"), ("lat. accel p95 [m/s²]", "lat_accel_p95", "f2"),
    ("jerk p95 [m/s³]", "jerk_p95", "f2"), ("Waiting at clear crossings [car·s]", "pedestrian_wait_s", "f2"),
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
        " check; SUMO collisions by SUMO itself. The p95 columns are the 95th percentiles of |accel|, |lateral acceleration|"
        " and |jerk| over every car's every step; waiting at clear crossings (pedestrian_wait_s) sums the seconds cars stood"
        f" within 30 m before the crossing while no walker was within {scenario['controller.pedestrian_margin']} m of their"
        " lane's part of it. The paper reports no clearance, collision, smoothness or waiting figures; — marks a missing value."
    )
    return horizon_markdown("Table II: lane change in SUMO, AAC vs LFC", intro, LANE_COLUMNS, rows)


def lane_change_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                      progress: bool = True, scheduler: str | None = None, resume: bool = False,
                      baselines: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table II (horizons x coordinators x seeds) and write results.csv, table.csv and table.md;
    ``baselines`` adds their rows."""
    runs = run_horizon_table("lane_change", seeds, workers, out, sets, progress, "table lane-change", scheduler, resume,
                             baselines=baselines)
    rows = horizon_rows(runs, seeds, LANE_METRICS, PAPER_TABLE_II, PAPER_II_METRICS)
    write_csv(rows, horizon_columns(seeds, LANE_METRICS, PAPER_II_METRICS), out / "table.csv")
    text = lane_change_markdown(rows, config.load("lane_change", list(sets or [])), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


BUILDERS = {"swarm": swarm_table, "lane-change": lane_change_table, "braking": braking_table, "ablation": ablation_table,
            "circle-swap": circle_swap_table}

#: The tables that run AAC and LFC with switchable emergency layers, and their ``--layers`` default.
LAYERED = {"swarm": "both", "circle-swap": "off"}
