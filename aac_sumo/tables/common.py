"""What the tables share: the emergency-layer settings (the same for AAC and LFC in every run),
the runs of a grid through the sweep executor, per-row means over seeds, and CSV and Markdown
formatting (:mod:`aac_sumo.tables.build`)."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

from aac_sumo import registry
from aac_sumo.runs import sweep

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


#: Our coordinators, compared in the paper's tables.
COORDINATORS = ("aac", "lfc")
#: The registered baseline coordinators (``controller.coordinator``) and the scenario kinds each drives.
BASELINES = {name: entry.kinds or registry.kinds() for name, entry in registry.coordinators().items() if entry.baseline}
#: Every registered coordinator's name in the tables.
COORDINATOR_LABELS = {name: entry.label for name, entry in registry.coordinators().items()}


def baselines_for(kind: str) -> tuple[str, ...]:
    """The registered baseline coordinators that drive scenarios of ``kind``."""
    return tuple(name for name, kinds in BASELINES.items() if kind in kinds)


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


def markdown_table(rows: list[dict], first, columns) -> list[str]:
    """The lines of a markdown table: ``first`` are (header, key) columns shown as they are (the
    coordinator by its label), ``columns`` (header, key, kind) with kind as in :func:`_fmt`. Ours
    carry their std (not rates); the paper's never do."""
    lines = ["| " + " | ".join([h for h, _ in first] + [h for h, _, _ in columns]) + " |",
             "|---|" + "---:|" * (len(first) - 1 + len(columns))]
    for r in rows:
        cells = [COORDINATOR_LABELS.get(r[key], r[key]) if key == "coordinator" else "—" if r[key] is None else str(r[key])
                 for _, key in first]
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
