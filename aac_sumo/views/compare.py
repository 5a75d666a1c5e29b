"""Side by side: the metrics of several run directories (``compare.csv``, ``compare.md``) and
their time series and paths overlaid (``compare.png``)."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from aac_sumo.metrics import METRIC_KEYS  # noqa: E402
from aac_sumo.views.titles import CAR_KINDS, horizon_and_fleet  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402


def labels(run_dirs: list[Path]) -> list[str]:
    """A short name per run: its directory name, or its whole path where names repeat."""
    names = [Path(d).name or str(d) for d in run_dirs]
    return [name if names.count(name) == 1 else str(d) for name, d in zip(names, run_dirs)]


def metrics_frame(runs: dict[str, object]) -> pd.DataFrame:
    """One row per run (``run`` = its label): every metric, METRIC_KEYS first."""
    rows = [{"run": label, **run.metrics} for label, run in runs.items()]
    frame = pd.DataFrame(rows)
    first = ["run"] + [k for k in METRIC_KEYS if k in frame]
    return frame[first + [c for c in frame.columns if c not in first]]


def markdown(frame: pd.DataFrame) -> str:
    """The metrics as a Markdown table: one row per metric, one column per run."""
    runs = list(frame["run"])
    lines = ["| metric | " + " | ".join(runs) + " |", "|---|" + "---|" * len(runs)]
    for column in frame.columns[1:]:
        lines.append(f"| {column} | " + " | ".join(_cell(v) for v in frame[column]) + " |")
    return "\n".join(lines) + "\n"


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value).replace("|", "\\|")


#: The paths panel keeps equal axes unless the paths span this many times more one way than the other.
STRETCH = 4.0


def plot(runs: dict[str, object], path: Path) -> None:
    """Overlaid, one colour per run: mean speed, smallest clearance and robots arrived over
    time (counted in whole cars when every run's robots are cars), and every controlled robot's
    path."""
    fig = plt.figure(figsize=(12, 8))
    grid = fig.add_gridspec(3, 2, width_ratios=[1.2, 1])
    speed, clearance, arrived = (fig.add_subplot(grid[i, 0]) for i in range(3))
    paths = fig.add_subplot(grid[:, 1])
    for k, (label, run) in enumerate(runs.items()):
        colour = f"C{k % 10}"
        by_t = run.steps.groupby("t")
        speed.plot(by_t["v"].mean(), color=colour, label=f"{label} ({horizon_and_fleet(run.metrics, run.scenario.kind)})")
        clearance.plot(by_t["clearance_m"].min(), color=colour)
        arrived.plot(arrivals_over_time(run.steps), color=colour, drawstyle="steps-post")
        traj = run.trajectories[run.trajectories["kind"] == "controlled"]
        for j, (_, rows) in enumerate(traj.groupby("name", sort=False)):
            paths.plot(rows["x"], rows["y"], color=colour, lw=1.0, alpha=0.8, label=label if j == 0 else None)
    speed.set_ylabel("mean speed [m/s]")
    clearance.set_ylabel("smallest clearance [m]")
    clearance.axhline(0.0, color="k", lw=0.8)
    cars = all(getattr(run.scenario, "kind", None) in CAR_KINDS for run in runs.values())
    arrived.set_ylabel("cars arrived" if cars else "robots arrived")
    fleet = max([run.steps["robot"].nunique() for run in runs.values()] + [1])
    arrived.set_ylim(-0.02 * fleet, 1.05 * fleet)  # from none to the whole fleet
    arrived.yaxis.set_major_locator(MaxNLocator(integer=True))  # whole robots: no 12.5
    arrived.set_xlabel("time [s]")
    for ax in (speed, clearance, arrived):
        ax.grid(alpha=0.3)
    speed.legend(fontsize="small")
    x0, x1 = paths.dataLim.intervalx
    y0, y1 = paths.dataLim.intervaly
    stretched = max(x1 - x0, y1 - y0) > STRETCH * max(min(x1 - x0, y1 - y0), 1e-9)
    if not stretched:  # a road hundreds of metres long and a few lanes wide stays readable: its axes are not to scale
        paths.set_aspect("equal", adjustable="datalim")
    paths.set_xlabel("x [m]")
    paths.set_ylabel("y [m]" + (f" (stretched x{stretch_of(paths):.0f}, not to scale)" if stretched else ""))
    paths.set_title("paths (footprint centres)" + ("; axes not to scale" if stretched else ""), fontsize="medium")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def arrivals_over_time(steps: pd.DataFrame) -> pd.Series:
    """How many robots have arrived by each time of ``steps`` (a robot counts from its first
    ``arrived`` row on, also once it has left the road and has no rows)."""
    first = steps[steps["arrived"].astype(bool)].groupby("robot")["t"].min()
    times = pd.Index(sorted(steps["t"].unique()))
    return pd.Series([int((first <= t + 1e-9).sum()) for t in times], index=times, dtype=int)


def stretch_of(ax) -> float:
    """How many times more a metre of y than a metre of x takes on ``ax`` as drawn."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    box = ax.get_window_extent()
    return (box.height / max(y1 - y0, 1e-9)) / (box.width / max(x1 - x0, 1e-9))


def compare(run_dirs: list[Path], out: Path) -> str:
    """Read the runs, write compare.csv, compare.md and compare.png into ``out``; return the
    Markdown table."""
    from aac_sumo.runs.files import read_run

    runs = {label: read_run(d) for label, d in zip(labels(run_dirs), run_dirs)}
    frame = metrics_frame(runs)
    out.mkdir(parents=True, exist_ok=True)
    frame.to_csv(out / "compare.csv", index=False)
    sources = "\n".join(f"- `{label}`: {d}" for label, d in zip(runs, run_dirs))
    text = markdown(frame)
    (out / "compare.md").write_text(f"# Comparison of {len(runs)} runs\n\n{sources}\n\n{text}\n![overlaid](compare.png)\n")
    plot(runs, out / "compare.png")
    return text
