"""Many runs in parallel: every combination of a grid of scenario keys, K seeds each.

The parent process validates every combination first (a bad key or value stops the sweep
before any run starts), then hands picklable :class:`Task` s (scenario path plus ``--set``
overrides) to a process pool; each worker loads its scenario itself. Finished runs are appended
to ``results.csv`` and flushed one by one, so an interrupted sweep keeps what finished; at the
end the file is rewritten in grid order and ``summary.md`` is written. A run that raises in a
worker (or that the runner reports as failed mid-run) becomes a row with ``status=error`` and its
message; the sweep goes on.
"""

from __future__ import annotations

import csv
import itertools
import math
import multiprocessing
import os
import signal
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

from aac_sumo import config
from aac_sumo.metrics import METRIC_KEYS

#: Metrics shown in ``summary.md`` (those that are null in every run are left out).
SUMMARY_METRICS = (
    "completed", "task_duration_s", "compute_ms_mean", "infeasibility_rate", "min_distance_m",
    "min_clearance_m", "collisions", "ttc_mean_s", "tracking_error_m", "aggressive_driving_rate",
)


class SweepError(ValueError):
    """A command-line mistake in a sweep specification (one line)."""


@dataclass(frozen=True)
class Task:
    """One run: the scenario file, every override (``--set``, grid, seed), and what it varies."""

    index: int
    source: str
    overrides: tuple[str, ...]
    grid: tuple[tuple[str, Any], ...]
    seed: int


def parse_grid(texts: Iterable[str]) -> list[tuple[str, list[str]]]:
    """``["KEY=V1,V2", ...]`` as ``[(KEY, ["V1", "V2"]), ...]``; syntax errors raise :class:`SweepError`."""
    grid: list[tuple[str, list[str]]] = []
    for text in texts:
        key, sep, raw = text.partition("=")
        key = key.strip()
        values = [v.strip() for v in raw.split(",")]
        if not sep or not key or not raw.strip() or any(v == "" for v in values):
            raise SweepError(f"--grid {text!r}: expected KEY=V1,V2,... (a dotted key and comma-separated values)")
        if key == "scenario.seed":
            raise SweepError("--grid scenario.seed: use --seeds K (and --set scenario.seed=S for the base seed) instead")
        if any(key == k for k, _ in grid):
            raise SweepError(f"--grid {key}: given more than once")
        grid.append((key, values))
    return grid


def plan_tasks(scenario: str, sets: list[str], grid: list[tuple[str, list[str]]], seeds: int) -> list[Task]:
    """Every grid combination x ``seeds`` seeds (base seed + 0..seeds-1), each combination loaded
    once here so a bad key or value raises :class:`~aac_sumo.config.ScenarioError` before any run."""
    if seeds < 1:
        raise SweepError(f"--seeds {seeds}: expected an integer >= 1")
    source = str(config.resolve(scenario).resolve())
    config.load(source, list(sets))  # the --set overrides alone, so their errors name no grid value
    keys = [k for k, _ in grid]
    tasks: list[Task] = []
    for combo in itertools.product(*(values for _, values in grid)):
        combo_sets = [f"{k}={v}" for k, v in zip(keys, combo)]
        loaded = config.load(source, list(sets) + combo_sets)
        values = tuple((k, loaded[k]) for k in keys)
        base = loaded["scenario.seed"]
        for i in range(seeds):
            overrides = tuple(sets) + tuple(combo_sets) + (f"scenario.seed={base + i}",)
            tasks.append(Task(len(tasks), source, overrides, values, base + i))
    return tasks


def columns(grid_keys: list[str]) -> list[str]:
    """``results.csv`` columns: grid keys, seed, every other metric in METRIC_KEYS order, status, error."""
    return list(grid_keys) + ["seed"] + [k for k in METRIC_KEYS if k != "seed"] + ["status", "error"]


def run_task(task: Task) -> dict:
    """Run one task (in a worker); never raises: failures become ``status=error`` rows."""
    row: dict[str, Any] = dict(task.grid) | {"seed": task.seed}
    try:
        from aac_sumo import runner

        result = runner.run(config.load(task.source, list(task.overrides)))
    except Exception as exc:  # the sweep goes on
        return row | {"status": "error", "error": _one_line(exc)}
    metrics = result.metrics
    row |= {k: metrics.get(k) for k in METRIC_KEYS if k != "seed"}
    row["seed"] = task.seed
    error = metrics.get("error")
    return row | {"status": "error" if error else "ok", "error": error or ""}


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}".rstrip(": ")


def _init_worker() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is handled by the parent alone


def run_tasks(tasks: list[Task], grid_keys: list[str], out: Path, workers: int | None = None,
              progress: bool = True, desc: str = "sweep") -> list[dict]:
    """Run ``tasks`` in a process pool, appending each finished row to ``out/results.csv``;
    returns the rows in task order (the file is rewritten in that order at the end)."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    fields = columns(grid_keys)
    workers = max(1, min(workers or os.cpu_count() or 1, len(tasks) or 1))
    rows: dict[int, dict] = {}
    from tqdm import tqdm

    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        fh.flush()
        ctx = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker)
        bar = tqdm(total=len(tasks), desc=desc, unit="run", disable=not progress, dynamic_ncols=True)
        errors = 0
        try:
            futures = {pool.submit(run_task, t): t for t in tasks}
            for fut in as_completed(futures):
                task = futures[fut]
                try:
                    row = fut.result()
                except Exception as exc:  # the worker process itself died
                    row = dict(task.grid) | {"seed": task.seed, "status": "error", "error": _one_line(exc)}
                rows[task.index] = row
                writer.writerow(_csv_row(row))
                fh.flush()
                errors += row["status"] != "ok"
                bar.set_postfix(errors=errors, refresh=False)
                bar.update()
        except BaseException:  # Ctrl-C: running tasks are lost, finished ones are in results.csv
            procs = list((getattr(pool, "_processes", None) or {}).values())
            for proc in procs:
                proc.terminate()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        finally:
            bar.close()
        pool.shutdown()
    ordered = [rows[t.index] for t in tasks]
    tmp = path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows(_csv_row(r) for r in ordered)
    os.replace(tmp, path)
    return ordered


def _csv_row(row: dict) -> dict:
    return {k: ("" if v is None else v) for k, v in row.items()}


# ---------------------------------------------------------------------------------------------
# aggregation


def _number(v: Any) -> float:
    if v is None or v == "":
        return math.nan
    if isinstance(v, bool):
        return float(v)
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def mean_std(values: Iterable[Any]) -> tuple[float, float, int]:
    """Mean, sample standard deviation (NaN for fewer than two) and count of the finite values."""
    xs = [x for x in map(_number, values) if math.isfinite(x)]
    if not xs:
        return math.nan, math.nan, 0
    mean = sum(xs) / len(xs)
    std = math.sqrt(sum((x - mean) ** 2 for x in xs) / (len(xs) - 1)) if len(xs) > 1 else math.nan
    return mean, std, len(xs)


def groups(rows: list[dict], grid_keys: list[str]) -> list[tuple[tuple, list[dict]]]:
    """Rows grouped by their grid values, in first-seen (grid) order."""
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        out.setdefault(tuple(r.get(k) for k in grid_keys), []).append(r)
    return list(out.items())


def fmt(mean: float, std: float = math.nan, digits: int = 3) -> str:
    """``mean ± std`` (or ``mean``; ``—`` when missing), ``digits`` significant digits."""
    if not math.isfinite(mean):
        return "—"
    text = f"{mean:.{digits}g}"
    return f"{text} ± {std:.2g}" if math.isfinite(std) else text


def summary_markdown(rows: list[dict], grid_keys: list[str], title: str) -> str:
    """Mean ± std over seeds of the main metrics per grid combination (successful runs only)."""
    ok_rows = [r for r in rows if r.get("status") == "ok"]
    metrics = [m for m in SUMMARY_METRICS if any(math.isfinite(_number(r.get(m))) for r in ok_rows)]
    head = list(grid_keys) + ["runs ok"] + metrics
    lines = [f"# {title}", "", "Mean ± sample standard deviation over seeds of the runs that finished "
             "without error (`completed` is the share of completed runs).", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for values, group in groups(rows, grid_keys):
        good = [r for r in group if r.get("status") == "ok"]
        cells = [str(v) for v in values] + [f"{len(good)}/{len(group)}"]
        cells += [fmt(*mean_std(r.get(m) for r in good)[:2]) for m in metrics]
        lines.append("| " + " | ".join(cells) + " |")
    failed = [r for r in rows if r.get("status") != "ok"]
    if failed:
        lines += ["", f"## Errors ({len(failed)} of {len(rows)} runs)", ""]
        for r in failed:
            where = ", ".join(f"{k}={r.get(k)}" for k in grid_keys + ["seed"])
            lines.append(f"- {where}: {r.get('error')}")
    return "\n".join(lines) + "\n"


def sweep(scenario: str, grid_texts: list[str], sets: list[str], seeds: int, workers: int | None,
          out: Path, progress: bool = True) -> tuple[list[dict], str]:
    """The whole ``aac-sumo sweep`` command: validate, run, write results.csv and summary.md."""
    grid = parse_grid(grid_texts)
    if not grid:
        raise SweepError("sweep: expected at least one --grid KEY=V1,V2,...")
    tasks = plan_tasks(scenario, sets, grid, seeds)
    keys = [k for k, _ in grid]
    rows = run_tasks(tasks, keys, out, workers, progress)
    name = config.load(tasks[0].source, list(sets))["scenario.name"]
    text = summary_markdown(rows, keys, f"Sweep of {name}: {len(rows)} runs ({seeds} seed{'s' if seeds > 1 else ''} each)")
    (out / "summary.md").write_text(text)
    return rows, text
