"""Pictures of a run over time: ``timeline.png`` (per robot: speed, acceleration, lateral
acceleration, clearance; the authority strip) and ``fairness.png`` (authority share and delay
per robot)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from aac_sumo.metrics import authority_share  # noqa: E402
from aac_sumo.views.titles import horizon_and_fleet  # noqa: E402

#: Above this many robots the per-robot lines share one colour and the legend is left out.
LEGEND_MAX = 10


def lateral_acceleration(steps: pd.DataFrame, wheelbase: float) -> pd.Series:
    """Applied lateral acceleration [m/s^2] of every row: the ``lat_accel`` column where the
    run recorded one, else ``v^2 tan(steer) / L`` of the bicycle model."""
    if "lat_accel" in steps:
        return steps["lat_accel"]
    return steps["v"] ** 2 * np.tan(steps["steer"]) / wheelbase


def plot_timeline(result, path: Path) -> None:
    """Speed, applied acceleration, lateral acceleration and clearance to the nearest thing of
    every robot over time, above a strip of who held authority, where safety stops happened
    and which solves failed."""
    steps, m = result.steps, result.metrics
    robots = list(dict.fromkeys(steps["robot"]))
    index = {name: i for i, name in enumerate(robots)}
    colours = plt.get_cmap("tab10" if len(robots) <= 10 else "tab20")
    fig, axes = plt.subplots(5, 1, figsize=(9, 11), sharex=True, gridspec_kw=dict(height_ratios=[1, 1, 1, 1, 1.2]))
    lat = lateral_acceleration(steps, result.scenario["robot.wheelbase"])
    panels = [("v", "speed [m/s]"), ("accel", "acceleration [m/s²]"), (lat, "lateral accel. [m/s²]"),
              ("clearance_m", "clearance [m]")]
    for ax, (column, label) in zip(axes, panels):
        values = steps[column] if isinstance(column, str) else column
        for name, rows in steps.groupby("robot", sort=False):
            ax.plot(rows["t"], values[rows.index], lw=1.0, color=colours(index[name] % colours.N), label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax, key in ((axes[1], "accel_threshold"), (axes[2], "lat_accel_threshold")):
        for sign in (-1, 1):
            ax.axhline(sign * result.scenario[f"metrics.{key}"], color="0.4", ls=":", lw=0.8)
    axes[3].axhline(0.0, color="k", lw=0.8)
    finite = steps["clearance_m"].replace([np.inf, -np.inf], np.nan).dropna()
    if len(finite):
        axes[3].set_ylim(min(finite.min(), 0.0) - 0.1, min(finite.max(), 5.0 * max(finite.median(), 0.5)) + 0.1)
    if len(robots) <= LEGEND_MAX:
        axes[0].legend(fontsize="x-small", ncol=min(len(robots), 5), loc="upper right")
    authority_strip(axes[4], steps, robots, colours)
    done = f"completed in {m['task_duration_s']:.2f} s" if m.get("completed") else m.get("incomplete_reason", "not completed")
    fig.suptitle(f"{m['scenario']}: {str(m['coordinator']).upper()}, {m['barrier']}, {horizon_and_fleet(m, result.scenario.kind)}, seed {m['seed']}; {done}",
                 fontsize="medium")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def authority_strip(ax, steps: pd.DataFrame, robots: list[str], colours) -> None:
    """One row per robot: a tick where it held authority, a red cross at a safety stop, a black
    dot at a failed (infeasible or failed) solve."""
    index = {name: i for i, name in enumerate(robots)}
    held = steps[steps["authority"].astype(bool)]
    ax.scatter(held["t"], held["robot"].map(index), c=[colours(index[r] % colours.N) for r in held["robot"]], marker="|", s=40)
    for mask, style in ((steps["mode"] == "safety_stop", dict(color="red", marker="x", s=16, label="safety stop")),
                        (steps["status"].isin(("infeasible", "failed")), dict(color="k", marker="o", s=10, label="failed solve"))):
        if mask.any():
            ax.scatter(steps.loc[mask, "t"], steps.loc[mask, "robot"].map(index), **style)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="x-small", loc="upper right")
    ax.set_yticks(range(len(robots)), robots, fontsize="x-small" if len(robots) > LEGEND_MAX else "small")
    ax.set_ylim(-0.5, len(robots) - 0.5)
    ax.set_xlabel("time [s]")
    ax.set_title("authority (who solved its MPC each period)", fontsize="small")


def plot_fairness(result, path: Path, delays: np.ndarray | None = None) -> None:
    """Write :func:`fairness_figure` of ``result`` and ``delays`` to ``path`` (PNG, 100 dpi)."""
    fig = fairness_figure(result, delays)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def fairness_figure(result, delays: np.ndarray | None = None) -> plt.Figure:
    """The fairness picture as a matplotlib figure of two axes: on top, bars per robot of the
    authority received over its fair share (:func:`~aac_sumo.metrics.authority_share`) with the
    fair share dashed; below, its delay [s] (arrival time minus free-flow time; ``delays`` by
    robot name, NaN for a robot that did not arrive, drawn as a grey bar of height 0). Only
    robots with recorded steps are shown (a run stopped early misses those not yet departed).
    The caller closes it."""
    steps, m = result.steps, result.metrics
    order = list(dict.fromkeys(steps["robot"]))
    share = authority_share(steps).reindex(order)
    robots = list(share.index)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(max(6.0, 0.45 * len(robots) + 2), 6.5), sharex=True)
    top.bar(robots, share.to_numpy(), color="tab:blue")
    top.axhline(1.0, color="k", lw=0.8, ls="--", label="fair share")
    top.set_ylabel("authority / fair share")
    top.legend(fontsize="small", loc="upper right")
    top.set_title(f"authority_jain {_fmt(m.get('authority_jain'))}", fontsize="small")
    if delays is None:
        bottom.text(0.5, 0.5, "delays unknown: this scenario has no free-flow times", ha="center", va="center",
                    transform=bottom.transAxes)
    else:
        delays = pd.Series(delays).reindex(robots).to_numpy(dtype=float)
        bottom.bar(robots, np.nan_to_num(delays, nan=0.0), color=["tab:orange" if np.isfinite(d) else "0.8" for d in delays])
        bottom.set_title(f"delay_jain {_fmt(m.get('delay_jain'))}, delay_max_s {_fmt(m.get('delay_max_s'))}"
                         + ("; grey: did not arrive" if np.isnan(delays).any() else ""), fontsize="small")
    bottom.set_ylabel("delay [s]")
    bottom.tick_params(axis="x", labelrotation=90 if len(robots) > LEGEND_MAX else 0)
    fig.suptitle(f"{m['scenario']}: {str(m['coordinator']).upper()}, {horizon_and_fleet(m, result.scenario.kind)}, seed {m['seed']}: fairness per robot",
                 fontsize="medium")
    fig.tight_layout()
    return fig


def _fmt(x) -> str:
    return "—" if x is None else f"{x:.2f}"
