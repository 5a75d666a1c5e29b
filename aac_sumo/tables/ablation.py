"""The ablation table, ``aac-sumo table ablation``: which part of AAC brings which gain.

Every case runs every variant on the same seeds, with the same planner, solver, weights,
prediction and anticipation (the scenario's); a variant changes only the keys it names:

- AAC as in the paper: stored plans, one authority, no extension and no emergency layer;
- AAC with committed plans, still without the extensions (make-room, keep-right, detours,
  cluster authorities, cruise) and without the safety stop;
- AAC with everything: the scenario as bundled (today's default);
- LFC as in the paper: every robot plans every period in index order, no emergency layer;
- LFC with committed plans (``lfc.commit``: prioritized planning under the same exact check and
  deadlock rules as AAC's committed plans);
- the baselines registered for the case's kind: ORCA and CBF-QP on the internal kinds, SUMO's own
  driver on the road (a baseline that is not installed is left out, and the table says so).
"""

from __future__ import annotations

import math
from pathlib import Path

from aac_sumo import config
from aac_sumo.runs import sweep
from aac_sumo.tables.common import COORDINATOR_LABELS, _fmt, _num, baselines_for, fill_metrics, run_grid, write_csv

#: Keys that switch AAC's extensions and emergency layer off (the paper's plain settings).
AAC_PLAIN = ("aac.safety_stop=false", "aac.fallback=brake", "aac.ignore_followers=false", "aac.make_room=false",
             "aac.keep_right=0", "aac.detour=false", "aac.manoeuvre=false", "aac.authorities=1", "aac.cruise=0")
#: ``(name, label, overrides)`` of the AAC and LFC variants, in the table's order.
VARIANTS = (
    ("aac_paper", "AAC as in the paper (stored plans)", ("controller.coordinator=aac", "aac.commit=false") + AAC_PLAIN),
    ("aac_committed", "AAC, committed plans only", ("controller.coordinator=aac", "aac.commit=true") + AAC_PLAIN),
    ("aac_all", "AAC with everything (the scenario)", ("controller.coordinator=aac",)),
    ("lfc_paper", "LFC as in the paper", ("controller.coordinator=lfc", "lfc.commit=false", "lfc.safety_stop=false",
                                          "lfc.fallback=brake", "lfc.ignore_followers=false")),
    ("lfc_committed", "LFC, committed plans (prioritized)", ("controller.coordinator=lfc", "lfc.commit=true")),
)
#: ``(case, scenario, overrides, label)``: S1, the paired circle swaps, the 20-robot crossing, S2, the highway.
CASES = (
    ("swarm", "swarm_rescue", (), "S1 swarm rescue"),
    ("circle8", "circle_swap", ("circle_swap.n_robots=8", "circle_swap.radius=4"), "circle swap, 8 robots on r = 4 m"),
    ("circle16", "circle_swap", ("circle_swap.n_robots=16", "circle_swap.radius=6"), "circle swap, 16 robots on r = 6 m"),
    ("circle24", "circle_swap", ("circle_swap.n_robots=24", "circle_swap.radius=8"), "circle swap, 24 robots on r = 8 m"),
    ("crossing20", "random_crossing", (), "random crossing, 20 robots"),
    ("lane_change", "lane_change", (), "S2 lane change (SUMO)"),
    ("highway", "highway_work_zone", (), "highway work zone (SUMO, 100 cars)"),
)
ABLATION_METRICS = ("completed", "task_duration_s", "collisions", "sim_collisions", "deadlock", "min_clearance_m",
                    "infeasibility_rate", "safety_stops", "compute_ms_median", "aggressive_driving_rate", "jerk_p95")
COLUMNS = (("Completed", "completed", "pct"), ("Task [s]", "task_duration_s", "f2"), ("Collisions", "collisions", "count"),
           ("SUMO collisions", "sim_collisions", "count"), ("Deadlocks", "deadlock", "pct"),
           ("Min clearance [m]", "min_clearance_m", "f2"), ("Infeasible", "infeasibility_rate", "pct"),
           ("Safety stops", "safety_stops", "count"), ("Compute median [ms]", "compute_ms_median", "f2"),
           ("Aggressive", "aggressive_driving_rate", "pct"), ("Jerk p95 [m/s³]", "jerk_p95", "f2"))


def variants_for(kind: str) -> list[tuple[str, str, tuple[str, ...]]]:
    """The AAC and LFC variants, then every registered baseline that drives ``kind``."""
    return list(VARIANTS) + [(name, COORDINATOR_LABELS[name], (f"controller.coordinator={name}",)) for name in baselines_for(kind)]


def ablation_rows(runs: list[dict], seeds: int, case: str) -> list[dict]:
    """One row per variant of ``case``: means (and stds) over its seeds that ran without error."""
    return [fill_metrics({"case": case, "variant": values[0]}, group, seeds, ABLATION_METRICS)
            for values, group in sweep.groups(runs, ["variant"])]


def ablation_columns(seeds: int) -> list[str]:
    cols = ["case", "variant"]
    for m in ABLATION_METRICS:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + ["runs", "errors"]


def gains(rows: list[dict]) -> list[str]:
    """What each step of the ablation changes on one case, as sentences (completion, task time of
    the completed runs, collisions)."""
    by = {r["variant"]: r for r in rows}
    steps = (("aac_paper", "aac_committed", "Committed plans (AAC)"), ("aac_committed", "aac_all", "AAC's extensions"),
             ("lfc_paper", "lfc_committed", "Committed plans (LFC)"), ("lfc_committed", "aac_all", "Authority rotation with everything, against prioritized planning"))
    out = []
    for a, b, what in steps:
        if a in by and b in by:
            ra, rb = by[a], by[b]
            task = _num(rb["task_duration_s"]) - _num(ra["task_duration_s"])
            out.append(f"{what}: completed {100 * _num(ra['completed']):.0f} % → {100 * _num(rb['completed']):.0f} %, "
                       f"collisions {_num(ra['collisions']):.2g} → {_num(rb['collisions']):.2g}"
                       + (f", task {task:+.2f} s" if math.isfinite(task) else "") + ".")
    return out


def ablation_markdown(tables: list[tuple[str, str, list[dict], list[tuple]]], seeds: int) -> str:
    """One table per case, then what each step brings there."""
    lines = ["# Ablation: which part brings which gain", "",
             "Every variant runs on the same seeds with the same planner, solver, weights, prediction and anticipation "
             "(the scenario's); a variant changes only its own keys (`aac_sumo/tables/ablation.py`). "
             + (f"Mean ± sample std over {seeds} seeds" if seeds > 1 else "One seed")
             + "; task time over the completed runs; a deadlock or a time-out is an incomplete run."]
    for label, kind, rows, variants in tables:
        names = {v[0]: v[1] for v in variants}
        lines += ["", f"## {label}", "", "| Variant | " + " | ".join(h for h, _, _ in COLUMNS) + " |",
                  "|---|" + "---:|" * len(COLUMNS)]
        for r in rows:
            cells = [names.get(r["variant"], r["variant"])]
            cells += [_fmt(r[k], None if kind_ == "pct" else r.get(f"{k}_std"), kind_) for _, k, kind_ in COLUMNS]
            if r["errors"]:
                cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
            lines.append("| " + " | ".join(cells) + " |")
        lines += [""] + [f"- {g}" for g in gains(rows)]
    return "\n".join(lines) + "\n"


def ablation_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None, progress: bool = True,
                   scheduler: str | None = None, resume: bool = False, cases: tuple[str, ...] | None = None
                   ) -> tuple[list[dict], str, list[dict]]:
    """Run every variant of every case (``cases``: a subset of :data:`CASES` by name) x seeds, each
    case's runs into ``out/<case>``; write table.csv and table.md into ``out``."""
    sets = list(sets or [])
    chosen = [c for c in CASES if cases is None or c[0] in cases]
    all_rows, all_runs, tables = [], [], []
    for case, scenario, case_sets, label in chosen:
        kind = config.load(scenario)["scenario.kind"]
        variants = variants_for(kind)
        bundles = [((("variant", name),), list(case_sets) + list(overrides)) for name, _, overrides in variants]
        runs = run_grid(scenario, [], seeds, workers, out / case, sets, progress, f"table ablation {case}", scheduler, resume, bundles)
        rows = ablation_rows(runs, seeds, case)
        all_rows += rows
        all_runs += runs
        tables.append((label, kind, rows, variants))
    write_csv(all_rows, ablation_columns(seeds), out / "table.csv")
    text = ablation_markdown(tables, seeds)
    (out / "table.md").write_text(text)
    return all_rows, text, all_runs
