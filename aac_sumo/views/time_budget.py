"""Where a road run's time goes: per car, the seconds lost against driving at its cruise speed,
split by what it was slowed by.

Run it on a run directory (``aac-sumo run lane_change --out DIR``)::

    python -m aac_sumo.views.time_budget DIR [DIR ...]

Each recorded step of a car until it finished loses ``dt (1 - v / v_cruise)`` seconds [s]
(none above the cruise speed). The loss goes to the first cause that holds at that step, in
this order:

- ``yielding``: a walker lies ahead of the car's front within ``YIELD_AHEAD`` [m] along its
  heading and within ``YIELD_ACROSS`` [m] of its centre line across it, nearer than any car
  ahead in its lane;
- ``following``: another car slower than ``SLOW_SHARE`` of the cruise speed lies ahead in its
  lane (centres less than a car width apart across its heading) within ``FOLLOW_AHEAD`` [m]
  (the anticipation's look-ahead): the car is in or behind a slow queue;
- ``lane change``: the car is more than ``lane_change.lane_tolerance`` [m] across its heading
  from where it ends the run (straight roads: its target lane; not before it has finished);
- ``committed``: with committed plans, it drives its stopping tail or holds at its end;
- ``other``: anything else (a merge, its MPC's own choice).

The attribution looks at geometry only, not at the coordinator's reasons, so it is a rough
budget: a car that follows a car that yields counts as following.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd

from aac_sumo.runs.files import RunDirError, read_run
from aac_sumo.views.titles import horizon_and_fleet

#: How far ahead of a car's front [m], and how far beside its centre line [m], a walker it yields to may be.
YIELD_AHEAD = 30.0
YIELD_ACROSS = 12.0
#: A car ahead in the lane within this [m], slower than SLOW_SHARE of the cruise speed, is a queue it follows.
FOLLOW_AHEAD = 80.0
SLOW_SHARE = 0.9
CAUSES = ("yielding", "following", "lane change", "committed", "other")


def step_causes(steps: pd.DataFrame, trajectories: pd.DataFrame, tolerance: float, cruise: float) -> pd.Series:
    """The cause (one of CAUSES) of every row of ``steps`` (columns ``t, robot, x, y, heading, v,
    mode``; rear axle, world frame), from everything's footprint centres in ``trajectories``."""
    steps = steps.assign(t=steps["t"].round(6))
    trajectories = trajectories.assign(t=trajectories["t"].round(6))
    cars = trajectories[trajectories["kind"] == "controlled"]
    walkers = trajectories[trajectories["kind"] == "pedestrian"]
    final_y = steps.groupby("robot")["y"].last()
    finish_t = steps[steps["arrived"].astype(bool)].groupby("robot")["t"].min() if "arrived" in steps else pd.Series(dtype=float)
    centres = cars.set_index(["t", "name"])[["x", "y", "length"]]
    ego = centres.reindex(pd.MultiIndex.from_arrays([steps["t"], steps["robot"]])).to_numpy()
    cause = pd.Series("other", index=steps.index, dtype=object)
    by_t_cars = {t: g for t, g in cars.groupby("t")}
    by_t_walkers = {t: g for t, g in walkers.groupby("t")}
    for t, rows in steps.groupby("t"):
        others = by_t_cars.get(t)
        people = by_t_walkers.get(t)
        for idx, row in rows.iterrows():
            c, s = np.cos(row["heading"]), np.sin(row["heading"])
            position = steps.index.get_loc(idx)
            centre, front = ego[position, :2], 0.5 * ego[position, 2]
            near_car = np.inf
            if others is not None:
                mine = others[others["name"] != row["robot"]]
                rel = mine[["x", "y"]].to_numpy() - centre
                along, across = rel @ np.array([c, s]), rel @ np.array([-s, c])
                ahead = (along > 0.0) & (along < FOLLOW_AHEAD) & (np.abs(across) < 1.8) & (mine["v"].to_numpy() < SLOW_SHARE * cruise)
                if ahead.any():
                    near_car = float(along[ahead].min())
            near_walker = np.inf
            if people is not None and len(people):
                rel = people[["x", "y"]].to_numpy() - centre
                along, across = rel @ np.array([c, s]), rel @ np.array([-s, c])
                ahead = (along > 0.0) & (along < YIELD_AHEAD + front) & (np.abs(across) < YIELD_ACROSS)
                if ahead.any():
                    near_walker = float(along[ahead].min())
            if near_walker < near_car:
                cause[idx] = "yielding"
            elif np.isfinite(near_car):
                cause[idx] = "following"
            elif abs(row["y"] - final_y[row["robot"]]) > tolerance and not (row["robot"] in finish_t and t >= finish_t[row["robot"]]):
                cause[idx] = "lane change"
            elif row.get("mode") in ("tail", "hold"):
                cause[idx] = "committed"
    return cause


def time_budget(steps: pd.DataFrame, trajectories: pd.DataFrame, cruise: float, dt: float, tolerance: float) -> pd.DataFrame:
    """Per car (rows) the seconds [s] lost against ``cruise`` [m/s] to each of CAUSES, their sum
    ``lost``, and the time it took (``time``: until it arrived, or the run's end)."""
    steps = steps.copy()
    if "arrived" in steps:
        first = steps[steps["arrived"].astype(bool)].groupby("robot")["t"].min()
        steps = steps[steps["t"] <= steps["robot"].map(first).fillna(np.inf)]
    steps["loss"] = dt * np.clip(1.0 - steps["v"] / cruise, 0.0, 1.0)
    steps["cause"] = step_causes(steps, trajectories, tolerance, cruise)
    table = steps.pivot_table(index="robot", columns="cause", values="loss", aggfunc="sum", fill_value=0.0)
    table = table.reindex(columns=list(CAUSES), fill_value=0.0)
    table["lost"] = table.sum(axis=1)
    table["time"] = steps.groupby("robot")["t"].max() + dt
    order = sorted(table.index, key=lambda name: (len(name), name))
    return table.loc[order]


def budget_markdown(run_dir: str) -> str:
    """The time budget of the run in ``run_dir`` as a Markdown table, with its mean row."""
    run = read_run(run_dir)
    sc = run.scenario
    if sc["scenario.kind"] != "lane_change":
        raise RunDirError(f"{run_dir}: expected a run of a road scenario (kind lane_change), got kind {sc['scenario.kind']}")
    table = time_budget(run.steps, run.trajectories, sc["lane_change.speed"], sc["scenario.dt"], sc["lane_change.lane_tolerance"])
    m = run.metrics
    task = m.get("task_duration_s")
    lines = [f"{run_dir}: {m.get('coordinator')}, {horizon_and_fleet(m, sc.kind)}, seed {m.get('seed')}, "
             f"task {'not completed' if task is None else f'{task:.1f} s'}; "
             f"seconds lost against {sc['lane_change.speed']:g} m/s per car", "",
             "| car | " + " | ".join(CAUSES) + " | lost | time |", "|---" * (len(CAUSES) + 3) + "|"]
    for name, row in list(table.iterrows()) + [("mean", table.mean())]:
        lines.append(f"| {name} | " + " | ".join(f"{row[c]:.1f}" for c in CAUSES) + f" | {row['lost']:.1f} | {row['time']:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m aac_sumo.views.time_budget", description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", help="run directories of a road scenario (aac-sumo run ... --out DIR)")
    args = parser.parse_args(argv)
    for run_dir in args.runs:
        try:
            print(budget_markdown(run_dir) + "\n")
        except RunDirError as exc:
            print(f"python -m aac_sumo.views.time_budget: error: {exc}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
