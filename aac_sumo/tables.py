"""The paper's tables, ours beside the paper's values: ``aac-sumo table NAME``.

Table I (swarm rescue) and Table II (lane change) compare AAC with LFC at MPC horizons 5, 10 and
15; Table III (emergency braking) compares CBF with F-CBF over the initial speed, once per
obstacle prediction (the ``prediction`` column; both barriers get the same one). The circle-swap
table (not in the paper) compares AAC with LFC over the number of robots. The runs go through the
same process pool as ``aac-sumo sweep`` (and leave the same ``results.csv``).

Table I and the circle swap run AAC and LFC with the same emergency layers (the ``safety_layers``
column): ``off`` is the paper's setting (no safety stop for either coordinator), ``on`` gives both
the safety stop. The paper's values stand beside the ``off`` rows only.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

from aac_sumo import config, sweep
from aac_sumo.prediction import PREDICTIONS

TABLES = ("swarm", "lane-change", "braking", "circle-swap")

# --- Emergency layers: the same setting for both coordinators ----------------------------------

#: ``safety_layers`` values: ``off`` = neither coordinator has an emergency layer (the paper),
#: ``on`` = both brake through the safety stop (the safer variant).
SAFETY_LAYERS = ("off", "on")
#: What ``--layers`` accepts: one setting, or both (``off`` rows first).
LAYER_CHOICES = ("off", "on", "both")
#: The keys each setting fixes, for AAC and LFC together, in every run of a layered table.
LAYER_KEYS = ("aac.safety_stop", "lfc.safety_stop")
LAYER_TITLES = {
    "off": "Safety layers off: neither coordinator has an emergency layer (the paper's setting)",
    "on": "Safety layers on: both coordinators brake through the safety stop (the safer variant)",
}


def layer_sets(layer: str) -> list[str]:
    """The ``--set`` overrides of one ``safety_layers`` value, the same for AAC and LFC."""
    value = {"off": "false", "on": "true"}[layer]
    return [f"{key}={value}" for key in LAYER_KEYS]


def layers_of(choice: str) -> tuple[str, ...]:
    """``--layers off|on|both`` as the settings to run, ``off`` first."""
    if choice not in LAYER_CHOICES:
        raise sweep.SweepError(f"--layers {choice}: expected one of {', '.join(LAYER_CHOICES)}")
    return SAFETY_LAYERS if choice == "both" else (choice,)


def check_table_sets(sets: list[str], fixed: tuple[str, ...], name: str) -> None:
    """Refuse a ``--set`` of a key the table itself sets in every run (it would be overridden)."""
    for text in sets:
        key = text.split("=", 1)[0].strip()
        if key in fixed:
            hint = " (choose with --layers off|on|both)" if key in LAYER_KEYS else ""
            raise sweep.SweepError(f"--set {text}: {key}: expected a key that table {name} does not set itself; "
                                   f"it sets {', '.join(fixed)} in every run{hint}")


def plan_bundled_tasks(scenario: str, sets: list[str], bundles, grid, seeds: int) -> tuple[list[sweep.Task], list[str]]:
    """Tasks for keys that vary together: each bundle is ``(values, bundle_sets)``, with
    ``values`` the ``(column, value)`` pairs it records in ``results.csv`` and ``bundle_sets``
    the overrides it applies after ``sets``; every bundle runs the whole ``grid`` x ``seeds``.
    Returns the tasks (indexed in order) and the grid keys (bundle columns, then ``grid``'s)."""
    tasks: list[sweep.Task] = []
    for values, bundle_sets in bundles:
        for t in sweep.plan_tasks(scenario, list(sets) + list(bundle_sets), grid, seeds):
            tasks.append(dataclasses.replace(t, index=len(tasks), grid=tuple(values) + t.grid))
    return tasks, [k for k, _ in bundles[0][0]] + [k for k, _ in grid]

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
    """One table.csv row per (speed, barrier), and per ``prediction`` when the runs carry one,
    from the per-run rows (grid keys ``braking.speed`` and ``controller.barrier``); means over the
    seeds that ran without error. The paper does not state its prediction: its values stand
    beside every prediction's rows."""
    keyed = any("prediction" in r for r in runs)
    keys = (["prediction"] if keyed else []) + ["braking.speed", "controller.barrier"]
    table = []
    for values, group in sweep.groups(runs, keys):
        speed, barrier = values[-2:]
        good = [r for r in group if r.get("status") == "ok"]
        row: dict = {"barrier": barrier, "speed": _speed(speed)} | ({"prediction": values[0]} if keyed else {})
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


def braking_columns(seeds: int, keyed: bool = False) -> list[str]:
    """table.csv columns; ``keyed``: with the ``prediction`` column after barrier and speed."""
    cols = ["barrier", "speed"] + (["prediction"] if keyed else [])
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
    """Table III as markdown: one table per prediction (the scenario's own first), or one
    table when the rows carry no prediction."""
    c, b = scenario.data["controller"], scenario.data["braking"]
    lines = [
        "# Table III: emergency braking, CBF vs F-CBF",
        "",
        f"Ego (MPC, N = {c['horizon']}, {c['solver']}{' compiled to C' if c['codegen'] else ''}{' + ipopt retry' if c['retry_with_ipopt'] else ''}, "
        f"dt = {scenario['scenario.dt']} s, gamma = {c['gamma']}) follows a lead {b['gap']} m ahead (centre to centre) at the same speed; "
        f"the lead brakes at {b['lead_decel']} m/s² from t = {b['t_brake']} s. "
        + (f"Ours: mean ± sample std over {seeds} seeds." if seeds > 1 else "Ours: one seed.")
        + " Min distance is the smallest centre-to-centre distance between ego and lead; min clearance the"
        " smallest footprint gap (negative = overlap); mean TTC is over the steps where the ego closes in;"
        " infeasibility is the share of MPC solves that failed or were infeasible. The paper reports no"
        " values at 20 and 25 m/s, nor collisions or clearance, and does not state its prediction; — marks a missing value.",
    ]
    for prediction, group in sweep.groups(rows, ["prediction"]):
        if prediction[0] is not None:
            default = " (the scenario's default)" if prediction[0] == c["prediction"] else ""
            lines += ["", f"## Prediction: {prediction[0].replace('_', ' ')}{default}"]
        lines += ["", *braking_block(group)]
    return "\n".join(lines) + "\n"


def braking_block(rows: list[dict]) -> list[str]:
    """The markdown table lines of ``rows`` (one prediction)."""
    kinds = {"infeasibility_rate": "pct", "collisions": "count"}
    head = ["Barrier", "Speed [m/s]", "Infeasibility (ours)", "Infeasibility (paper)", "Min distance [m] (ours)",
            "Min distance [m] (paper)", "Mean TTC [s] (ours)", "Mean TTC [s] (paper)", "Collisions (ours)",
            "Min clearance [m] (ours)"]
    lines = ["| " + " | ".join(head) + " |", "|---|---:|" + "---:|" * (len(head) - 2)]
    for r in rows:
        cells = [BARRIER_LABELS.get(r["barrier"], r["barrier"]), str(r["speed"])]
        for m in ("infeasibility_rate", "min_distance_m", "ttc_mean_s"):
            kind = kinds.get(m, "f2")
            cells += [_fmt(r[m], r.get(f"{m}_std"), kind), _fmt(r[f"paper_{m}"], None, kind)]
        cells += [_fmt(r["collisions"], r.get("collisions_std"), "count"), _fmt(r["min_clearance_m"], r.get("min_clearance_m_std"))]
        if r["errors"]:
            cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def braking_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                  progress: bool = True, scheduler: str | None = None, resume: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table III (predictions x speeds x barriers x seeds; the scenario's own prediction
    first) and write results.csv, table.csv and table.md; returns the table rows, the markdown
    and the per-run rows."""
    sets = list(sets or [])
    check_table_sets(sets, ("controller.prediction",), "braking")
    scenario = config.load("braking", sets)
    own = scenario["controller.prediction"]
    bundles = [((("prediction", p),), [f"controller.prediction={p}"]) for p in sorted(PREDICTIONS, key=lambda p: p != own)]
    grid = [("braking.speed", [str(s) for s in BRAKING_SPEEDS]), ("controller.barrier", list(BRAKING_BARRIERS))]
    runs = run_grid("braking", grid, seeds, workers, out, sets, progress, "table braking", scheduler, resume, bundles)
    rows = braking_rows(runs, seeds)
    write_csv(rows, braking_columns(seeds, keyed=True), out / "table.csv")
    text = braking_markdown(rows, scenario, seeds)
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


#: Yes/no metrics that a table row gives as the share of runs (``completed``: completed rate).
SHARE_METRICS = ("completed", "deadlock")


def fill_metrics(row: dict, group: list[dict], seeds: int, metrics) -> dict:
    """Means (and stds when ``seeds`` > 1) over the runs of ``group`` that ran without error, plus
    ``runs`` and ``errors``; yes/no metrics become shares, and a metric that is null in a run
    (task duration of an incomplete run) is averaged over the others."""
    good = [r for r in group if r.get("status") == "ok"]
    for m in metrics:
        values = [float(bool(r.get(m))) if m in SHARE_METRICS else r.get(m) for r in good]
        mean, std, _ = sweep.mean_std(values)
        row[m] = mean
        if seeds > 1:
            row[f"{m}_std"] = std
    row["runs"] = len(good)
    row["errors"] = len(group) - len(good)
    return row


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
        row: dict = {"coordinator": coordinator, "horizon": int(horizon)}
        if layered:
            row["safety_layers"] = values[2]
        fill_metrics(row, group, seeds, metrics)
        paper_values = paper.get((coordinator, int(horizon))) if row.get("safety_layers", "off") == "off" else None
        for m, value in zip(paper_metrics, paper_values or (None,) * len(paper_metrics)):
            row[f"paper_{m}"] = value
        table.append(row)
    return sorted(table, key=lambda r: (_layer_rank(r), r["horizon"], _coordinator_rank(r)))


def horizon_columns(seeds: int, metrics, paper_metrics, layered: bool = False) -> list[str]:
    cols = ["coordinator", "horizon"] + (["safety_layers"] if layered else [])
    for m in metrics:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + [f"paper_{m}" for m in paper_metrics] + ["runs", "errors"]


def run_grid(scenario: str, grid, seeds: int, workers: int | None, out: Path, sets: list[str] | None,
             progress: bool, desc: str, scheduler: str | None = None, resume: bool = False, bundles=None) -> list[dict]:
    """Every grid combination x seeds run of ``scenario`` through the sweep executor (local
    processes, or the Dask scheduler at ``scheduler``; ``resume`` skips finished runs); with
    ``bundles`` (see :func:`plan_bundled_tasks`) the grid runs once per bundle."""
    sets = list(sets or [])
    if bundles:
        tasks, keys = plan_bundled_tasks(scenario, sets, bundles, grid, seeds)
    else:
        tasks, keys = sweep.plan_tasks(scenario, sets, grid, seeds), [k for k, _ in grid]
    return sweep.run_tasks(tasks, keys, out, workers, progress, desc=desc, scheduler=scheduler,
                           resume=resume, manifest=sweep.sweep_manifest(tasks[0].source, sets))


def run_horizon_table(scenario: str, seeds: int, workers: int | None, out: Path, sets: list[str] | None,
                      progress: bool, desc: str, scheduler: str | None = None, resume: bool = False,
                      layers: tuple[str, ...] | None = None) -> list[dict]:
    """Every (horizon, coordinator) x seeds run of ``scenario``; the per-run rows. With ``layers``
    (``safety_layers`` values) the grid runs once per setting, AAC and LFC alike in each."""
    grid = [("controller.horizon", [str(h) for h in HORIZONS]), ("controller.coordinator", list(COORDINATORS))]
    bundles = [((("safety_layers", layer),), layer_sets(layer)) for layer in layers] if layers else None
    return run_grid(scenario, grid, seeds, workers, out, sets, progress, desc, scheduler, resume, bundles)


SWARM_COLUMNS = (
    ("Task duration [s] (ours)", "task_duration_s", "f2"), ("(paper)", "paper_task_duration_s", "f2"),
    ("Compute [ms] mean (ours)", "compute_ms_mean", "f2"), ("median (ours)", "compute_ms_median", "f2"),
    ("(paper)", "paper_compute_ms_mean", "f2"), ("Min distance [m] (ours)", "min_distance_m", "f2"),
    ("(paper)", "paper_min_distance_m", "f2"), ("Collisions", "collisions", "count"), ("Completed", "completed", "pct"),
    ("authority_jain", "authority_jain", "f2"), ("delay_jain", "delay_jain", "f2"), ("delay_max_s [s]", "delay_max_s", "f2"),
    ("Infeasible", "infeasibility_rate", "pct"), ("Safety stops", "safety_stops", "count"),
)


def markdown_table(rows: list[dict], first, columns) -> list[str]:
    """The lines of a markdown table: ``first`` are (header, key) columns shown as they are (the
    coordinator by its label), ``columns`` (header, key, kind) with kind as in :func:`_fmt`. Ours
    carry their std (not rates); the paper's never do."""
    lines = ["| " + " | ".join([h for h, _ in first] + [h for h, _, _ in columns]) + " |",
             "|---|" + "---:|" * (len(first) - 1 + len(columns))]
    for r in rows:
        cells = [COORDINATOR_LABELS.get(r[key], r[key]) if key == "coordinator" else str(r[key]) for _, key in first]
        for _, key, kind in columns:
            plain = key.startswith("paper_") or kind == "pct"
            cells.append(_fmt(r[key], None if plain else r.get(f"{key}_std"), kind))
        if r["errors"]:
            cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def layered_markdown(title: str, intro: str, first, columns, rows: list[dict]) -> str:
    """A markdown table per ``safety_layers`` value under its own heading (one table when the
    rows carry none); the paper's columns only where the paper's setting ran (``off``)."""
    lines = [f"# {title}", "", intro]
    layers = [layer for layer in SAFETY_LAYERS if any(r.get("safety_layers") == layer for r in rows)]
    if not layers:
        return "\n".join(lines + [""] + markdown_table(rows, first, columns)) + "\n"
    for layer in layers:
        part = [r for r in rows if r.get("safety_layers") == layer]
        shown = columns if layer == "off" else [c for c in columns if not c[1].startswith("paper_")]
        lines += ["", f"## {LAYER_TITLES[layer]}", "",
                  f"`safety_layers = {layer}`: " + ", ".join(f"`{k} = {layer == 'on'}`".lower() for k in LAYER_KEYS)
                  + " in every run of this table" + ("" if layer == "off" else "; the paper has no such rows") + ".", ""]
        lines += markdown_table(part, first, shown)
    return "\n".join(lines) + "\n"


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
                layers: str = "both") -> tuple[list[dict], str, list[dict]]:
    """Run Table I (safety layers x horizons x coordinators x seeds) and write results.csv,
    table.csv and table.md. ``layers`` (``off``, ``on`` or ``both``) sets ``aac.safety_stop``
    and ``lfc.safety_stop`` together in every run."""
    sets = list(sets or [])
    check_table_sets(sets, LAYER_KEYS, "swarm")
    runs = run_horizon_table("swarm_rescue", seeds, workers, out, sets, progress, "table swarm", scheduler, resume,
                             layers=layers_of(layers))
    rows = horizon_rows(runs, seeds, SWARM_METRICS, PAPER_TABLE_I, PAPER_I_METRICS)
    write_csv(rows, horizon_columns(seeds, SWARM_METRICS, PAPER_I_METRICS, layered=True), out / "table.csv")
    text = swarm_markdown(rows, config.load("swarm_rescue", sets), seeds)
    (out / "table.md").write_text(text)
    return rows, text, runs


# --- Circle swap: AAC against LFC over the number of robots ------------------------------------

#: (robots, circle radius [m]) of the circle-swap table.
CIRCLE_SIZES = ((8, 4.0), (16, 6.0), (24, 8.0))
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
                      layers: str = "off") -> tuple[list[dict], str, list[dict]]:
    """Run the circle-swap table (safety layers x (robots, radius) of :data:`CIRCLE_SIZES` x
    coordinators x seeds) and write results.csv, table.csv and table.md. ``layers`` (``off``
    by default, ``on`` or ``both``) sets ``aac.safety_stop`` and ``lfc.safety_stop`` together."""
    sets = list(sets or [])
    check_table_sets(sets, LAYER_KEYS + CIRCLE_KEYS, "circle-swap")
    bundles = [((("safety_layers", layer), ("circle_swap.n_robots", n), ("circle_swap.radius", radius)),
                layer_sets(layer) + [f"circle_swap.n_robots={n}", f"circle_swap.radius={radius}"])
               for layer in layers_of(layers) for n, radius in CIRCLE_SIZES]
    grid = [("controller.coordinator", list(COORDINATORS))]
    runs = run_grid("circle_swap", grid, seeds, workers, out, sets, progress, "table circle-swap", scheduler, resume, bundles)
    rows = circle_rows(runs, seeds)
    write_csv(rows, circle_columns(seeds), out / "table.csv")
    text = circle_markdown(rows, config.load("circle_swap", sets), seeds)
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


BUILDERS = {"swarm": swarm_table, "lane-change": lane_change_table, "braking": braking_table,
            "circle-swap": circle_swap_table}
#: The tables that run AAC and LFC with switchable emergency layers, and their ``--layers`` default.
LAYERED = {"swarm": "both", "circle-swap": "off"}
