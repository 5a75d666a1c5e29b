"""Many runs in parallel: every combination of a grid of scenario keys, K seeds each.

The parent process validates every combination first (a bad key or value stops the sweep
before any run starts), then hands picklable :class:`Task` s (the validated scenario plus the
``--set`` overrides that made it) to an :class:`Executor`: a local process pool (``--workers W``)
or a Dask cluster (``--scheduler tcp://HOST:PORT``), one code path for both. Each run happens in
a separate worker process, never two at once in one process (libsumo holds one simulation per
process; a process-wide lock guards this even on multi-threaded Dask workers).

Finished runs are appended to ``results.csv`` and flushed one by one, so an interrupted sweep
keeps what finished, and ``--resume`` skips the runs already there (``status=ok``); at the end
the file is rewritten in grid order and ``summary.md`` is written. A run that raises in a worker
(or that the runner reports as failed mid-run) becomes a row with ``status=error`` and its
message; a worker process that dies (e.g. a crash in native code) costs only the run it was
running, which becomes an error row as well. The sweep goes on.
"""

from __future__ import annotations

import csv
import hashlib
import itertools
import json
import math
import os
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from aac_sumo import config
from aac_sumo.runs.executor import Executor, SweepError, one_line
from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.runs.provenance import PROVENANCE_KEYS

#: Metrics shown in ``summary.md`` (those that are null in every run are left out).
SUMMARY_METRICS = (
    "completed", "task_duration_s", "compute_ms_mean", "infeasibility_rate", "min_distance_m",
    "min_clearance_m", "collisions", "sim_collisions", "safety_stops", "ttc_mean_s", "tracking_error_m",
    "aggressive_driving_rate", "accel_p95", "jerk_p95", "min_pedestrian_clearance_m", "pedestrian_wait_s", "red_light_violations",
    "right_of_way_violations",
)
@dataclass(frozen=True)
class Task:
    """One run: the scenario file, every override (``--set``, grid, seed), and what it varies.

    ``scenario`` is the validated scenario itself (overrides applied); it travels with the task,
    so a worker on another machine needs aac-sumo installed but not the scenario file. Without
    it the worker loads ``source`` with ``overrides``."""

    index: int
    source: str
    overrides: tuple[str, ...]
    grid: tuple[tuple[str, Any], ...]
    seed: int
    scenario: Any = field(default=None, compare=False, repr=False)


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
    base_scenario = config.load(source, list(sets))  # the --set overrides alone, so their errors name no grid value
    keys = [k for k, _ in grid]
    tasks: list[Task] = []
    for combo in itertools.product(*(values for _, values in grid)):
        combo_sets = [f"{k}={v}" for k, v in zip(keys, combo)]
        loaded = base_scenario.with_overrides(combo_sets, "--grid")
        values = tuple((k, loaded[k]) for k in keys)
        base = loaded["scenario.seed"]
        for i in range(seeds):
            seed_set = f"scenario.seed={base + i}"
            overrides = tuple(sets) + tuple(combo_sets) + (seed_set,)
            tasks.append(Task(len(tasks), source, overrides, values, base + i, loaded.with_overrides([seed_set])))
    return tasks


def columns(grid_keys: list[str]) -> list[str]:
    """``results.csv`` columns: grid keys, seed, every other metric in METRIC_KEYS order, why an
    unfinished run stopped, status, error, and the run's provenance (PROVENANCE_KEYS)."""
    return (list(grid_keys) + ["seed"] + [k for k in METRIC_KEYS if k != "seed"] + ["incomplete_reason", "status", "error"]
            + list(PROVENANCE_KEYS))


#: One simulation at a time per process (libsumo), also on a Dask worker with several threads.
_ONE_RUN_PER_PROCESS = threading.Lock()


def run_task(task: Task) -> dict:
    """Run one task (in a worker); never raises: failures become ``status=error`` rows."""
    row: dict[str, Any] = dict(task.grid) | {"seed": task.seed}
    with _ONE_RUN_PER_PROCESS:
        try:
            from aac_sumo.runs import runner

            scenario = task.scenario if task.scenario is not None else config.load(task.source, list(task.overrides))
            result = runner.run(scenario)
        except Exception as exc:  # the sweep goes on
            return row | {"status": "error", "error": one_line(exc)}
    metrics = result.metrics
    row |= {k: metrics.get(k) for k in METRIC_KEYS + PROVENANCE_KEYS if k != "seed"}
    row["seed"] = task.seed
    row["incomplete_reason"] = metrics.get("incomplete_reason", "")
    error = metrics.get("error")
    return row | {"status": "error" if error else "ok", "error": error or ""}


def error_row(task: Task, exc: BaseException) -> dict:
    """The ``status=error`` row of a task whose call raised outside :func:`run_task`'s guard
    (its worker died, or the cluster lost it)."""
    return dict(task.grid) | {"seed": task.seed, "status": "error", "error": one_line(exc)}








# ---------------------------------------------------------------------------------------------
# results.csv


def run_key(row: dict, grid_keys: list[str]) -> tuple[str, ...]:
    """What identifies a run in ``results.csv``: its grid values and seed, as written there."""
    return tuple(_cell(row.get(k)) for k in list(grid_keys) + ["seed"])


def read_results(path: Path, grid_keys: list[str]) -> list[dict]:
    """The rows of an earlier ``results.csv`` of the same grid keys, values parsed back
    (numbers, booleans, ``None`` for empty cells); a file of other columns raises :class:`SweepError`."""
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        found = list(reader.fieldnames or [])
        rows = list(reader)
    if found != columns(grid_keys):
        got = ", ".join(c for c in found if c not in columns([])) or "none"
        raise SweepError(f"--resume {path}: columns: expected the grid keys of this sweep "
                         f"({', '.join(grid_keys)}) and the metric columns, got grid keys {got}")
    # a row cut short by a hard kill while it was written is not a finished run
    rows = [r for r in rows if None not in r and None not in r.values() and r.get("status") in ("ok", "error")]
    text = ("status", "error", *PROVENANCE_KEYS)  # as written: a hash such as 5394e80056649392 is no number
    return [{k: (v if k in text else _parse_cell(v)) for k, v in r.items()} for r in rows]


def _parse_cell(text: str) -> Any:
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _cell(value: Any) -> str:
    return "" if value is None else str(value)


def _manifest_check(out: Path, manifest: dict, resume: bool) -> None:
    """Refuse to resume a sweep made of another scenario or other ``--set`` overrides."""
    path = out / "sweep.json"
    if resume and path.exists():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError):
            old = {}
        for key in ("scenario", "scenario_sha256", "sets"):
            if key in old and old[key] != manifest.get(key):
                what = {"scenario": "the same scenario file", "scenario_sha256": "an unchanged scenario file",
                        "sets": "the same --set overrides"}[key]
                raise SweepError(f"--resume {path}: {key}: expected {what} as the interrupted sweep "
                                 f"({old[key]}), got {manifest.get(key)}")
    path.write_text(json.dumps(manifest, indent=2) + "\n")


def sweep_manifest(source: str, sets: list[str]) -> dict:
    """What a resumed sweep must share with the one it continues."""
    return {"scenario": source, "scenario_sha256": hashlib.sha256(Path(source).read_bytes()).hexdigest(),
            "sets": list(sets)}


def run_tasks(tasks: list[Task], grid_keys: list[str], out: Path, workers: int | None = None,
              progress: bool = True, desc: str = "sweep", scheduler: str | None = None,
              resume: bool = False, fn: Callable[[Task], dict] = run_task,
              manifest: dict | None = None) -> list[dict]:
    """Run ``tasks`` (locally on ``workers`` processes, or on the Dask cluster at ``scheduler``),
    appending each finished row to ``out/results.csv``; returns the rows in task order (the file
    is rewritten in that order at the end, followed by any earlier rows of runs not planned now).

    With ``resume``, runs whose grid values and seed already have a ``status=ok`` row in
    ``out/results.csv`` are not run again (error rows are retried). ``fn`` runs one task."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    fields = columns(grid_keys)
    if manifest is not None:
        _manifest_check(out, manifest, resume)
    earlier: dict[tuple, dict] = {}
    if resume and path.exists():
        for r in read_results(path, grid_keys):
            if r.get("status") == "ok":
                earlier[run_key(r, grid_keys)] = r
    rows: dict[int, dict] = {}
    todo = []
    for t in tasks:
        key = run_key(dict(t.grid) | {"seed": t.seed}, grid_keys)
        if key in earlier:
            rows[t.index] = earlier.pop(key) | dict(t.grid) | {"seed": t.seed}
        else:
            todo.append(t)
    if resume and rows:
        print(f"aac-sumo: resuming: {len(rows)} of {len(tasks)} runs already in {path}", file=sys.stderr)
    from tqdm import tqdm

    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows(_csv_row(r) for r in list(rows.values()) + list(earlier.values()))
        fh.flush()
        bar = tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc=desc, unit="run",
                   disable=not progress, dynamic_ncols=True)
        errors = 0
        try:
            with Executor(min(workers or os.cpu_count() or 1, len(todo) or 1), scheduler) as ex:
                for i, result in ex.map(fn, todo):
                    task = todo[i]
                    row = error_row(task, result) if isinstance(result, BaseException) else result
                    rows[task.index] = row
                    writer.writerow(_csv_row(row))
                    fh.flush()
                    errors += row["status"] != "ok"
                    bar.set_postfix(errors=errors, refresh=False)
                    bar.update()
        finally:
            bar.close()
    ordered = [rows[t.index] for t in tasks]
    tmp = path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows(_csv_row(r) for r in ordered + list(earlier.values()))
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
          out: Path, progress: bool = True, scheduler: str | None = None,
          resume: bool = False) -> tuple[list[dict], str]:
    """The whole ``aac-sumo sweep`` command: validate, run (locally or on the Dask cluster at
    ``scheduler``; with ``resume``, only the runs not yet in results.csv), write results.csv and
    summary.md."""
    grid = parse_grid(grid_texts)
    if not grid:
        raise SweepError("sweep: expected at least one --grid KEY=V1,V2,...")
    tasks = plan_tasks(scenario, sets, grid, seeds)
    keys = [k for k, _ in grid]
    rows = run_tasks(tasks, keys, out, workers, progress, scheduler=scheduler, resume=resume,
                     manifest=sweep_manifest(tasks[0].source, sets))
    name = config.load(tasks[0].source, list(sets))["scenario.name"]
    text = summary_markdown(rows, keys, f"Sweep of {name}: {len(rows)} runs ({seeds} seed{'s' if seeds > 1 else ''} each)")
    (out / "summary.md").write_text(text)
    return rows, text
