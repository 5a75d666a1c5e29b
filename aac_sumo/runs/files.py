"""A run directory (``aac-sumo run --out DIR``): writing its files and reading a run back."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from aac_sumo.config import load
from aac_sumo.runs.recording import RunResult

#: The files of a run directory that the pictures and comparisons read.
RUN_FILES = ("metrics.json", "steps.csv", "trajectories.csv", "scenario.toml")


class RunDirError(Exception):
    """A directory that is not a run's output; ``str()`` is one line naming it and the file."""


def read_run(run_dir: str | Path) -> RunResult:
    """The run written into ``run_dir`` (its per-period table is not written, so it is empty)."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: expected a run directory (written by aac-sumo run --out DIR)")
    missing = [name for name in RUN_FILES if not (run_dir / name).is_file()]
    if missing:
        raise RunDirError(f"{run_dir}: expected a run directory with {', '.join(RUN_FILES)}; missing {', '.join(missing)}")
    try:
        metrics = json.loads((run_dir / "metrics.json").read_text())
        steps = pd.read_csv(run_dir / "steps.csv")
        trajectories = pd.read_csv(run_dir / "trajectories.csv")
    except (ValueError, pd.errors.ParserError) as exc:
        raise RunDirError(f"{run_dir}: unreadable run file ({type(exc).__name__}: {exc})".splitlines()[0]) from None
    scenario = load(str(run_dir / "scenario.toml"))
    return RunResult(metrics, steps, pd.DataFrame(columns=["t", "compute_ms"]), trajectories, scenario)


def write_run(result: RunResult, out: Path) -> None:
    """Write metrics.json, steps.csv, trajectories.csv and scenario.toml into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text(json.dumps(result.metrics, indent=2) + "\n")
    result.steps.to_csv(out / "steps.csv", index=False)
    result.trajectories.to_csv(out / "trajectories.csv", index=False)
    (out / "scenario.toml").write_text(result.scenario.to_toml())
