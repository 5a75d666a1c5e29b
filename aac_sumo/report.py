"""Pictures of a run (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_run(result, path: Path) -> None:
    """``trajectories.png`` for the run's scenario kind."""
    if result.scenario.kind == "lane_change":
        from aac_sumo.report_lane_change import plot_lane_change

        return plot_lane_change(result, path)
    if result.scenario.kind == "braking":
        _plot_braking(result, path)
    else:
        _plot_paths(result, path)


def _plot_braking(result, path: Path) -> None:
    """Gap and speeds over time for the ego and the lead."""
    traj = result.trajectories
    ego = traj[traj["kind"] == "controlled"].set_index("t")
    lead = traj[traj["name"] == "lead"].set_index("t")
    gap_centre = np.hypot(lead["x"] - ego["x"], lead["y"] - ego["y"])
    gap_bumper = gap_centre - 0.5 * (lead["length"] + ego["length"])
    fig, (ax_d, ax_v) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    ax_d.plot(gap_centre.index, gap_centre, label="centre-to-centre distance")
    ax_d.plot(gap_bumper.index, gap_bumper, label="bumper gap")
    ax_d.axhline(0.0, color="k", lw=0.8)
    ax_d.set_ylabel("distance [m]")
    ax_d.legend(loc="upper right")
    ax_v.plot(ego.index, ego["v"], label="ego (MPC)")
    ax_v.plot(lead.index, lead["v"], "--", label="lead (braking)")
    ax_v.set_ylabel("speed [m/s]")
    ax_v.set_xlabel("time [s]")
    ax_v.legend(loc="upper right")
    m = result.metrics
    fig.suptitle(f"{m['scenario']}: {m['barrier']}, N={m['horizon']}; min distance "
                 f"{_fmt(m['min_distance_m'])} m, collisions {m['collisions']}, infeasible {m['infeasible_solves']}/{m['solves']}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _plot_paths(result, path: Path) -> None:
    """Every agent's path in the world frame."""
    fig, ax = plt.subplots(figsize=(7, 6))
    for name, group in result.trajectories.groupby("name", sort=False):
        ax.plot(group["x"], group["y"], label=name)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _fmt(x) -> str:
    return "—" if x is None else f"{x:.2f}"
