"""Table III of the paper (emergency braking): CBF against F-CBF over the initial speed, once per
obstacle prediction (the ``prediction`` column; both barriers get the same one),
``aac-sumo table braking``."""

from __future__ import annotations

from pathlib import Path

from aac_sumo import config, sweep
from aac_sumo.prediction import PREDICTIONS
from aac_sumo.table_common import _fmt, check_table_sets, run_grid, write_csv

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
