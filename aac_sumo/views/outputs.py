"""Everything ``aac-sumo run --out DIR`` writes: the run's files and its pictures."""

from __future__ import annotations

from pathlib import Path

from aac_sumo.runs.files import write_run
from aac_sumo.runs.recording import RunResult


def write_outputs(result: RunResult, out: Path, plot: bool = True) -> None:
    """Write metrics.json, steps.csv, trajectories.csv, scenario.toml, and with ``plot``
    trajectories.png, timeline.png and fairness.png."""
    write_run(result, out)
    if plot and len(result.trajectories):  # a run stopped before its first period has nothing to draw
        from aac_sumo.views.pictures import plot_run
        from aac_sumo.views.timeline import plot_fairness, plot_timeline

        plot_run(result, out / "trajectories.png")
        if len(result.steps):
            plot_timeline(result, out / "timeline.png")
            plot_fairness(result, out / "fairness.png", result.delays)
