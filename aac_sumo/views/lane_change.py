"""``trajectories.png`` of a lane-change run: road, lanes, cones, pedestrians' and vehicles' paths,
and every vehicle's speed and lateral acceleration over time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from aac_sumo.views.titles import horizon_and_fleet  # noqa: E402


def _offset(line: np.ndarray, d: float) -> np.ndarray:
    """``line`` (M, 2) shifted by ``d`` [m] to its left (negative: right), vertex by vertex."""
    tangent = np.gradient(line, axis=0)
    tangent /= np.maximum(np.hypot(*tangent.T), 1e-12)[:, None]
    return line + d * np.column_stack([-tangent[:, 1], tangent[:, 0]])


def draw_road(ax, scenario) -> None:
    """The lanes of ``scenario``'s SUMO road (grey, dashed lane edges) on ``ax``: the road the run drives on."""
    from aac_sumo.experiments.lane_change import network_files, scenario_road

    rd = scenario_road(scenario, network_files(scenario)[0])
    for line, width in zip(rd.lanes, rd.widths):
        ax.fill(*np.vstack([_offset(line, 0.5 * width), _offset(line, -0.5 * width)[::-1]]).T, color="0.88", lw=0)
        for side in (-0.5, 0.5):
            ax.plot(*_offset(line, side * width).T, color="0.55", lw=0.6, ls="--")


def plot_lane_change(result, path: Path) -> None:
    """Draw the run's road (from its SUMO network), every controlled vehicle's path (solid) and
    reference (dotted), the pedestrians' paths and the cones, with the headline metrics; below,
    every vehicle's speed and applied lateral acceleration over time, with the scenario's
    aggressive-driving threshold."""
    traj = result.trajectories
    fig, (ax, ax_v, ax_lat) = plt.subplots(3, 1, figsize=(14, 10), gridspec_kw=dict(height_ratios=[2.2, 1, 1]))
    draw_road(ax, result.scenario)
    steps = result.steps
    for name, group in traj[traj["kind"] == "controlled"].groupby("name", sort=False):
        (line,) = ax.plot(group["x"], group["y"], lw=1.2)
        ref = steps[steps["robot"] == name]
        ax.plot(ref["ref_x"], ref["ref_y"], ls=":", lw=0.8, color=line.get_color())
        ax.annotate(name, (group["x"].iloc[0], group["y"].iloc[0]), fontsize=6, ha="right", va="center")
        ax_v.plot(ref["t"], ref["v"], lw=0.9, color=line.get_color())
        ax_lat.plot(ref["t"], ref["lat_accel"], lw=0.9, color=line.get_color())
    for i, (_, group) in enumerate(traj[traj["kind"] == "pedestrian"].groupby("name", sort=False)):
        ax.plot(group["x"], group["y"], color="tab:red", lw=2, label="pedestrians" if i == 0 else None)
        ax.plot(group["x"].iloc[-1], group["y"].iloc[-1], "v", color="tab:red", ms=5)
    cones = traj[traj["kind"] == "cone"].drop_duplicates("name")
    ax.plot(cones["x"], cones["y"], "^", color="tab:orange", ms=7, ls="none", label="cones" if len(cones) else None)
    ax.plot([], [], color="0.3", lw=1.2, label="vehicles (footprint centre)")
    ax.plot([], [], color="0.3", lw=0.8, ls=":", label="references (rear axle)")
    ax.autoscale()
    zoomed = zoom_to_cars(ax, traj[traj["kind"] == "controlled"])
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    stretch = max(1.0, round(0.3 * (x1 - x0) / max(y1 - y0, 1e-9), 1))  # a long straight road stays readable
    ax.set_aspect(stretch)
    ax.set_xlabel("x [m]" + ("; zoomed to the cars, the road goes on" if zoomed else ""))
    ax.set_ylabel("y [m]" if stretch == 1.0 else f"y [m] (stretched x{stretch:g})")
    ax.legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=4)  # below the road, never over a car
    ax_v.set_ylabel("speed [m/s]")
    threshold = result.scenario["metrics.lat_accel_threshold"]
    for sign in (-1, 1):
        ax_lat.axhline(sign * threshold, color="tab:red", lw=0.8, ls="--", label="aggressive threshold" if sign > 0 else None)
    ax_lat.set_ylabel("lateral accel. [m/s²]")
    ax_lat.set_xlabel("t [s]")
    ax_lat.legend(fontsize="small", loc="upper right")
    m = result.metrics
    ax.set_title(f"{m['scenario']}: {m['coordinator']}, {horizon_and_fleet(m, result.scenario.kind)}; task {_fmt(m['task_duration_s'])} s, "
                 f"collisions {m['collisions']} (SUMO {m['sim_collisions']}), min clearance {_fmt(m['min_clearance_m'])} m, "
                 f"tracking error {_fmt(m['tracking_error_m'])} m", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


#: The road panel zooms to the cars when the road spans this many times their extent (either way).
ZOOM = 3.0
#: Room [m] around the cars' extent when zoomed.
ZOOM_MARGIN = 10.0


def zoom_to_cars(ax, cars) -> bool:
    """Limit ``ax`` to the cars' extent (their footprint centres ``x``, ``y``) plus
    ``ZOOM_MARGIN`` when its data span ``ZOOM`` times that much or more along either axis (60 m of
    motion on a 2.75 km road was a blob); whether it zoomed."""
    if not len(cars):
        return False
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    cx0, cx1, cy0, cy1 = cars["x"].min(), cars["x"].max(), cars["y"].min(), cars["y"].max()
    span = max(cx1 - cx0, cy1 - cy0) + 2.0 * ZOOM_MARGIN
    if max(x1 - x0, y1 - y0) < ZOOM * span:
        return False
    ax.set_xlim(max(x0, cx0 - ZOOM_MARGIN), min(x1, cx1 + ZOOM_MARGIN))
    ax.set_ylim(max(y0, cy0 - ZOOM_MARGIN), min(y1, cy1 + ZOOM_MARGIN))
    return True


def _fmt(x) -> str:
    return "—" if x is None else f"{x:.2f}"
