"""Pictures of a run (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from aac_sumo.views.titles import horizon_and_fleet  # noqa: E402


def plot_run(result, path: Path) -> None:
    """``trajectories.png`` for the run's scenario kind."""
    if result.scenario.kind == "lane_change":
        from aac_sumo.views.lane_change import plot_lane_change

        return plot_lane_change(result, path)
    if result.scenario.kind == "braking":
        _plot_braking(result, path)
    elif result.scenario.kind in ("swarm_rescue", "circle_swap", "random_crossing"):
        _plot_swarm(result, path)
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
    fig.suptitle(f"{m['scenario']}: {m['barrier']}, {horizon_and_fleet(m, result.scenario.kind)}; min distance "
                 f"{_fmt(m['min_distance_m'])} m, collisions {m['collisions']}, infeasible {m['infeasible_solves']}/{m['solves']}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _plot_swarm(result, path: Path) -> None:
    """Robots' paths coloured by robot with starts, goals, debris and final footprints; below,
    a strip of which robot held authority (and where safety stops happened) over time."""
    traj, steps, m = result.trajectories, result.steps, result.metrics
    robots = list(dict.fromkeys(traj.loc[traj["kind"] == "controlled", "name"]))
    colours = plt.get_cmap("tab10")
    fig, (ax, strip) = plt.subplots(2, 1, figsize=(8, 8.5), gridspec_kw=dict(height_ratios=[3.2, 1]))
    for _, row in traj[traj["kind"] != "controlled"].drop_duplicates("name").iterrows():
        _rectangle(ax, row, facecolor="0.6", edgecolor="0.3")
    for i, name in enumerate(robots):
        group = traj[traj["name"] == name]
        colour = colours(i % 10)
        ax.plot(group["x"], group["y"], color=colour, lw=1.5, label=name)
        ax.plot(group["x"].iloc[0], group["y"].iloc[0], "o", color=colour, ms=5)
        _rectangle(ax, group.iloc[-1], facecolor="none", edgecolor=colour)
        if result.goals is not None:
            ax.plot(*result.goals[i], "*", color=colour, ms=13, markeredgecolor="k")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize="small", loc="best")
    done = "completed in " + _fmt(m["task_duration_s"]) + " s" if m["completed"] else m.get("incomplete_reason", "not completed")
    ax.set_title(f"{m['scenario']}: {m['coordinator'].upper()}, {m['barrier']}, {horizon_and_fleet(m, result.scenario.kind)}, seed {m['seed']}; {done}\n"
                 f"min distance {_fmt(m['min_distance_m'])} m, collisions {m['collisions']}, "
                 f"compute median {_fmt(m['compute_ms_median'])} ms/period", fontsize="medium")
    index = {name: i for i, name in enumerate(robots)}
    held = steps[steps["authority"].astype(bool)]
    strip.scatter(held["t"], held["robot"].map(index), c=[colours(index[r] % 10) for r in held["robot"]], marker="|", s=60)
    stops = steps[steps["mode"] == "safety_stop"]
    if len(stops):
        strip.scatter(stops["t"], stops["robot"].map(index), color="red", marker="x", s=18, label="safety stop")
        strip.legend(fontsize="small", loc="upper right")
    strip.set_yticks(range(len(robots)), robots)
    strip.set_ylim(-0.5, len(robots) - 0.5)
    strip.set_xlabel("time [s]")
    strip.set_title("authority (who solved the MPC each period)", fontsize="medium")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _rectangle(ax, row, **style) -> None:
    """Draw the footprint of a trajectories.csv row (centre, heading, length, width)."""
    c, s = np.cos(row["heading"]), np.sin(row["heading"])
    u = 0.5 * row["length"] * np.array([c, s])
    v = 0.5 * row["width"] * np.array([-s, c])
    centre = np.array([row["x"], row["y"]])
    corners = np.array([centre + u + v, centre - u + v, centre - u - v, centre + u - v])
    ax.add_patch(plt.Polygon(corners, closed=True, lw=1.0, **style))


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
