"""RVO2 on its own, with holonomic discs that take their ORCA velocity instantly (as in the
anchor, ../shared/ANCHORS.md), on the same 45 circle swaps as :mod:`aac_sumo.tables.orca_circle_swap`:
DIR/orca_rvo2_discs_seeds0-4.md and .csv (`make results` copies them into docs/results/, job
orca_rvo2_discs_seeds0-4; `--seed 5` and `--seed 10` give the blocks of seeds 5-9 and 10-14, as
the circle swap's held-out blocks). It separates what ORCA does from what our bicycles and their
tracking law do.

    python -m aac_sumo.tables.orca_discs --out DIR [--seed S] [--seeds N]

Each robot's disc starts at its footprint centre, as our scenario places it (same seed, same
jitter), and drives to its goal. The radius is the covering disc's 0.36 m. The preferred velocity
is RVO2's example rule: towards the goal at 1 m/s, or the whole remaining gap when that is less
than 1 m. The most speed is 1 m/s, with neighbour distance 3 m, time horizon 2 s, 10 neighbours
and dt 0.1 s. A robot has arrived when its centre is within 0.3 m of its goal. A run completes when
all robots have arrived at once, within 60 s. It is a deadlock when no unfinished disc moves more
than 0.16 m in 8 s. Overlaps are disc overlaps deeper than 1 mm (RVO2 computes in single
precision), and discs that overlap are not stopped.
"""

from __future__ import annotations

import argparse
import sys
from collections import deque
from pathlib import Path

import numpy as np
import pandas as pd
import pyrvo

from aac_sumo import config
from aac_sumo.experiments import build
from aac_sumo.runs.provenance import commit_of

DT, LIMIT, TOL, SPEED, RADIUS = 0.1, 60.0, 0.3, 1.0, float(np.hypot(0.6, 0.4) / 2)
WINDOW, PROGRESS = 8.0, 0.16
#: Disc overlaps shallower than this [m] are RVO2's single-precision touching, not counted as overlaps.
TOUCH = 1e-3


def run(n: int, r: float, seed: int) -> dict:
    setup = build(config.load("circle_swap", ["controller.coordinator=orca", f"circle_swap.n_robots={n}",
                                              f"circle_swap.radius={r}", f"scenario.seed={seed}"]))
    world = setup.sim.observe()
    starts = world.robot_centres()
    goals = np.array([task.points[-1] for task in setup.tasks])
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(DT)
    for p in starts:
        sim.add_agent((float(p[0]), float(p[1])), 3.0, 10, 2.0, 2.0, RADIUS, SPEED, (0.0, 0.0))
    history: deque = deque(maxlen=int(round(WINDOW / DT)) + 1)
    min_gap, overlapping, episodes = np.inf, set(), 0
    for k in range(int(round(LIMIT / DT)) + 1):
        pos = np.array([sim.get_agent_position(i).to_tuple() for i in range(n)])
        gap = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1)) - 2 * RADIUS
        gap[np.arange(n), np.arange(n)] = np.inf
        min_gap = min(min_gap, float(gap.min()))
        now = {(i, j) for i, j in zip(*np.nonzero(gap < -TOUCH)) if i < j}
        episodes += len(now - overlapping)
        overlapping = now
        done = np.hypot(*(pos - goals).T) <= TOL
        if done.all():
            return dict(completed=True, deadlock=False, task_duration_s=round(k * DT, 9), min_gap_m=min_gap, overlaps=episodes)
        history.append(pos)
        if len(history) == history.maxlen:
            moved = np.hypot(*(np.array(history) - history[0]).transpose(2, 0, 1)).max(axis=0)[~done]
            if moved.max() <= PROGRESS:
                return dict(completed=False, deadlock=True, task_duration_s=None, min_gap_m=min_gap, overlaps=episodes)
        for i in range(n):
            gap_i = goals[i] - pos[i]
            dist = float(np.hypot(*gap_i))
            pref = gap_i / dist * min(SPEED, dist) if dist > 1e-9 else np.zeros(2)
            sim.set_agent_pref_velocity(i, (float(pref[0]), float(pref[1])))
        sim.do_step()
    return dict(completed=False, deadlock=False, task_duration_s=None, min_gap_m=min_gap, overlaps=episodes)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/orca_rvo2_discs"), help="where the table and its runs go")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="first seed (default 0)")
    parser.add_argument("--seeds", type=int, default=5, metavar="N", help="seeds per cell, S to S+N-1 (default 5)")
    args = parser.parse_args(argv)
    if args.seed < 0 or args.seeds < 1:
        flag, value, least = ("--seed", args.seed, 0) if args.seed < 0 else ("--seeds", args.seeds, 1)
        print(f"python -m aac_sumo.tables.orca_discs: {flag}: expected an integer >= {least}, got {value}", file=sys.stderr)
        return 2
    seeds = range(args.seed, args.seed + args.seeds)
    name = f"orca_rvo2_discs_seeds{seeds[0]}-{seeds[-1]}"
    args.out.mkdir(parents=True, exist_ok=True)
    commit = commit_of(Path(__file__).resolve().parent) or "unknown"
    rows = [dict(n_robots=n, radius=r, seed=seed, **run(n, r, seed)) for n in (8, 16, 24) for r in (4.0, 6.0, 8.0) for seed in seeds]
    results = pd.DataFrame(rows).assign(git_commit=commit)
    results.to_csv(args.out / f"{name}.csv", index=False)
    g = results.groupby(["n_robots", "radius"])
    done, total = int(results["completed"].sum()), len(results)
    lines = [
        "# RVO2 alone (holonomic discs) on the circle swaps",
        "",
        f"Generated by `python -m aac_sumo.tables.orca_discs --seed {seeds[0]} --seeds {len(seeds)}` at commit {commit[:7]}, seeds "
        f"{seeds[0]}-{seeds[-1]}: the module docstring gives the rules. "
        "The discs take their velocity instantly and are never stopped by contact.",
        "",
        f"**{done} of {total} runs complete ({100.0 * done / total:.0f} %)**; deadlocks in {int(results['deadlock'].sum())}; "
        f"a disc overlap deeper than 1 mm in {int((results['min_gap_m'] < -TOUCH).sum())} runs (deepest {-min(0.0, results['min_gap_m'].min()) * 100:.1f} cm).",
        "",
        "| n | r [m] | completed | deadlocks | runs with an overlap > 1 mm | min gap [m] | task duration [s] (completed) |",
        "|---|---|---|---|---|---|---|",
    ]
    for (n, r), cell in g:
        duration = cell["task_duration_s"].dropna()
        lines.append(f"| {n} | {r:g} | {int(cell['completed'].sum())}/{len(cell)} | {int(cell['deadlock'].sum())}/{len(cell)} | "
                     f"{int((cell['min_gap_m'] < -TOUCH).sum())}/{len(cell)} | {cell['min_gap_m'].min():.4f} | "
                     f"{'—' if duration.empty else f'{duration.mean():.1f}'} |")
    (args.out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
