"""One source for the published figures: ``make results`` (``python -m aac_sumo.tables.results``)
regenerates every table of ``docs/results/`` with the command line, and writes each one's
markdown and CSV there under a line that names the command and the commit that made it.

    python -m aac_sumo.tables.results --list                 # the jobs and their commands
    python -m aac_sumo.tables.results --only ablation_seeds0-4,braking_table3_seeds0-4 --workers 2

The runs go to ``out/results/<job>`` (kept, so that ``--resume`` there is possible by hand);
only the tables are copied into ``docs/results``. All jobs take hours on a 2-core machine: the
highway and the ablation's road cases dominate.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from aac_sumo.runs.provenance import git_commit

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs" / "results"


@dataclass(frozen=True)
class Job:
    """``aac-sumo ARGS --out DIR`` (with ``--workers`` where it runs in parallel; ``python -m
    MODULE ARGS ...`` for another ``module``, a generator whose markdown names its own command and
    commit), then each ``(file in DIR, suffix)`` of ``outputs`` is copied to
    ``docs/results/<name><suffix>``."""

    name: str
    args: tuple[str, ...]
    outputs: tuple[tuple[str, str], ...] = (("table.md", ".md"), ("table.csv", ".csv"))
    parallel: bool = True
    module: str = "aac_sumo.cli"

    @property
    def program(self) -> list[str]:
        """How the command line starts, as a user types it."""
        return ["aac-sumo"] if self.module == "aac_sumo.cli" else ["python", "-m", self.module]


HELD_OUT = ("--set", "scenario.seed=5")
SWEEP_OUTPUTS = (("summary.md", ".md"), ("results.csv", ".csv"))
#: LFC on committed plans with AAC's road settings and no emergency layer: the same layers as AAC in Table II.
LFC_COMMITTED = ("sweep", "lane_change", "--set", "controller.coordinator=lfc", "--set", "lfc.commit=true", "--set",
                 "lfc.safety_stop=false", "--set", "lfc.fallback=brake", "--set", "lfc.ignore_followers=false", "--grid",
                 "controller.horizon=5,10,15", "--seeds", "5")
#: AAC on every circle swap of the full grid (robots x radius), every emergency layer off (the scenario's).
CIRCLE_FULL = ("sweep", "circle_swap", "--grid", "circle_swap.n_robots=8,16,24", "--grid", "circle_swap.radius=4,6,8", "--seeds", "5")
#: AAC on 20 robots of the random crossing over densities (robots per 100 m^2): from sparse to the densest the draw places.
CROSSING_DENSITY = ("sweep", "random_crossing", "--grid", "random_crossing.density=8,10,12.5,16.7,20", "--set",
                    "random_crossing.n_robots=20", "--seeds", "10")
#: AAC on the random crossing as bundled (20 robots), every emergency layer off, 50 seeds a block.
CROSSING_20 = ("sweep", "random_crossing", "--grid", "controller.coordinator=aac", "--seeds", "50")
#: The same with 100 robots, 5 seeds a block (issue 35's blocks start at seeds 0, 20 and 40).
CROSSING_100 = ("sweep", "random_crossing", "--grid", "controller.coordinator=aac", "--set", "random_crossing.n_robots=100", "--seeds", "5")
#: AAC on the highway with committed plans and no emergency layer, held reactively to its strongest braking
#: against SUMO's cars, SUMO told that they brake at 2 m/s^2, their comfort bound: the scenario's own settings since
#: 2026-12-05, spelled out so that the command says what it ran (docs/highway_work_zone.md).
HIGHWAY_COMMITTED = ("sweep", "highway_work_zone", *(a for key in (
    "aac.commit=true", "aac.cruise=4.0", "aac.authorities=clusters", "aac.make_room=false", "aac.commit_margin=1.0",
    "aac.safety_stop=false", "aac.fallback=brake", "aac.ignore_followers=false", "aac.tail_brake=0.3333", "aac.firm_tail=0.3333",
    "aac.traffic_reaction=true", "aac.walker_brake=true", "aac.reaction_brake=1.0", "sumo.declared_decel=2.0") for a in ("--set", key)),
    "--grid", "controller.coordinator=aac", "--seeds", "5")
#: The same with one authority a period among all cars (the paper's AAC) instead of one per cluster.
HIGHWAY_ONE_AUTHORITY = tuple(a.replace("aac.authorities=clusters", "aac.authorities=1") for a in HIGHWAY_COMMITTED)
#: The highway's default before then: the paper's stored plans with the safety stop, one authority a period.
HIGHWAY_STORED = ("sweep", "highway_work_zone", *(a for key in (
    "aac.commit=false", "aac.authorities=1", "aac.safety_stop=true", "aac.fallback=tracking", "aac.ignore_followers=true",
    "sumo.declared_decel=0") for a in ("--set", key)), "--grid", "controller.coordinator=aac", "--seeds", "5")
#: The city's controlled cars under AAC and under SUMO's own driver (the same cars, routes, walkers and traffic).
CITY = ("sweep", "city", "--grid", "controller.coordinator=aac,sumo", "--seeds", "5")

#: Table I's two coordinators on 20 seeds (0-19), every emergency layer off (the scenario's): is AAC's task time
#: no longer than LFC's beyond the seed-to-seed spread?
SWARM_20 = ("sweep", "swarm_rescue", "--grid", "controller.coordinator=aac,lfc", "--grid", "controller.horizon=5,10,15", "--seeds", "20")

JOBS = (
    Job("swarm_table1_seeds0-4", ("table", "swarm", "--seeds", "5", "--baselines")),
    Job("swarm_table1_seeds5-9", ("table", "swarm", "--seeds", "5", "--baselines") + HELD_OUT),
    Job("swarm_table1_sweep_seeds0-19", SWARM_20, SWEEP_OUTPUTS),
    Job("swarm_table1_goal_cruise_seeds0-19", ("sweep", "swarm_rescue", "--grid", "aac.goal_cruise=0,1", "--grid", "controller.horizon=5,10,15",
                                               "--seeds", "20"), SWEEP_OUTPUTS),  # AAC's goal cruise, off and on (ablation)
    Job("lane_change_table2_seeds0-4", ("table", "lane-change", "--seeds", "5", "--baselines")),
    Job("lane_change_table2_seeds5-9", ("table", "lane-change", "--seeds", "5", "--baselines") + HELD_OUT),
    Job("lane_change_lfc_committed_seeds0-4", LFC_COMMITTED, SWEEP_OUTPUTS),
    Job("lane_change_lfc_committed_seeds5-9", LFC_COMMITTED + HELD_OUT, SWEEP_OUTPUTS),
    Job("braking_table3_seeds0-4", ("table", "braking", "--seeds", "5", "--sensitivity"),
        (("table.md", ".md"), ("table.csv", ".csv"), ("sensitivity.md", "_sensitivity.md"), ("sensitivity.csv", "_sensitivity.csv"))),
    Job("circle_swap_seeds0-4", ("table", "circle-swap", "--seeds", "5", "--baselines")),
    Job("circle_swap_full_seeds0-4", CIRCLE_FULL, SWEEP_OUTPUTS),
    Job("circle_swap_full_seeds5-9", CIRCLE_FULL + HELD_OUT, SWEEP_OUTPUTS),
    Job("circle_swap_full_seeds10-14", CIRCLE_FULL + ("--set", "scenario.seed=10"), SWEEP_OUTPUTS),
    Job("random_crossing_seeds0-49", CROSSING_20, SWEEP_OUTPUTS),
    Job("random_crossing_seeds50-99", CROSSING_20 + ("--set", "scenario.seed=50"), SWEEP_OUTPUTS),
    Job("random_crossing_seeds100-149", CROSSING_20 + ("--set", "scenario.seed=100"), SWEEP_OUTPUTS),
    *(Job(f"random_crossing_100_seeds{b}-{b + 4}", CROSSING_100 + ("--set", f"scenario.seed={b}"), SWEEP_OUTPUTS) for b in (0, 20, 40)),
    Job("random_crossing_density_seeds0-9", CROSSING_DENSITY, SWEEP_OUTPUTS),
    Job("random_crossing_density_seeds10-19", CROSSING_DENSITY + ("--set", "scenario.seed=10"), SWEEP_OUTPUTS),
    Job("random_crossing_density_seeds20-29", CROSSING_DENSITY + ("--set", "scenario.seed=20"), SWEEP_OUTPUTS),
    Job("ablation_seeds0-4", ("table", "ablation", "--seeds", "5")),
    Job("highway_work_zone_stored_seeds0-4", HIGHWAY_STORED, SWEEP_OUTPUTS),
    Job("highway_work_zone_committed_seeds0-4", HIGHWAY_COMMITTED, SWEEP_OUTPUTS),
    Job("highway_work_zone_committed_seeds5-9", HIGHWAY_COMMITTED + HELD_OUT, SWEEP_OUTPUTS),
    Job("highway_work_zone_one_authority_seeds0-4", HIGHWAY_ONE_AUTHORITY, SWEEP_OUTPUTS),
    Job("city_seeds0-4", CITY, SWEEP_OUTPUTS),
    Job("city_seeds5-9", CITY + HELD_OUT, SWEEP_OUTPUTS),
    Job("city_grid6_seeds0-4", CITY + ("--set", "sumo.config=../sumo_networks/grid6/grid6.sumocfg"), SWEEP_OUTPUTS),
    Job("bench_mpc", ("bench", "mpc"), (("bench.md", ".md"), ("bench.json", ".json")), parallel=False),
    Job("bench_lane_change_n10", ("bench", "aac", "--scenarios", "lane_change", "--horizons", "10"),
        (("bench.md", ".md"), ("bench.json", ".json")), parallel=False),
    Job("bench_random_crossing", ("bench", "aac", "--scenarios", "random_crossing", "--repeats", "1"),
        (("bench.md", ".md"), ("bench.json", ".json")), parallel=False),
    Job("bench_highway", ("bench", "aac", "--scenarios", "highway_work_zone", "--repeats", "1"),
        (("bench.md", ".md"), ("bench.json", ".json")), parallel=False),
    Job("cbf_qp_seeds0-4", (), (("cbf_qp_seeds0-4.md", ".md"), ("cbf_qp_seeds0-4.csv", ".csv"),
                                ("cbf_qp_seeds0-4_runs.csv", "_runs.csv")), module="aac_sumo.tables.cbf_qp"),
    Job("orca_circle_swap", (), tuple((f"orca_circle_swap_{v}_seeds0-4{ext}", f"_{v}_seeds0-4{ext}")
                                      for v in ("plain", "margin", "noise", "halfplanes") for ext in (".md", ".csv")),
        parallel=False, module="aac_sumo.tables.orca_circle_swap"),
    *(Job(f"orca_rvo2_discs_seeds{b}-{b + 4}", ("--seed", str(b)), ((f"orca_rvo2_discs_seeds{b}-{b + 4}.md", ".md"),
                                                                   (f"orca_rvo2_discs_seeds{b}-{b + 4}.csv", ".csv")),
          parallel=False, module="aac_sumo.tables.orca_discs") for b in (0, 5, 10)),
)


def command(job: Job, out: Path, workers: int | None) -> list[str]:
    """The command line of ``job`` (as the user would type it, ``aac-sumo`` first)."""
    extra = ["--workers", str(workers)] if workers and job.parallel else []
    return [*job.program, *job.args, *extra, "--out", str(out)]


def header(job: Job, cmd: list[str], commit: str | None) -> str:
    """The line that opens each generated markdown file."""
    shown = " ".join(cmd[:-2] + ["--out", "DIR"])
    return f"Generated by `make results` (`{shown}`) at commit {commit or 'unknown'}.\n\n"


def run_job(job: Job, out_root: Path, workers: int | None, docs: Path = DOCS) -> int:
    """Run ``job`` into ``out_root/<name>`` and copy its outputs into ``docs``; the command's exit
    status (its tables are copied when it wrote them, also after failed runs, which they show)."""
    out = out_root / job.name
    if out.exists():
        shutil.rmtree(out)
    cmd = command(job, out, workers)
    status = subprocess.call([sys.executable, "-m", job.module, *cmd[len(job.program):]])
    commit = git_commit()
    docs.mkdir(parents=True, exist_ok=True)
    for source, suffix in job.outputs:
        path = out / source
        if not path.exists():
            continue
        target = docs / f"{job.name}{suffix}"
        text = path.read_text()
        own = job.module != "aac_sumo.cli"  # a generator's markdown names its command and commit itself
        target.write_text(header(job, cmd, commit) + text if suffix.endswith(".md") and not own else text)
    return status


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m aac_sumo.tables.results", description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", default=None, metavar="JOB1,JOB2,...", help="only these jobs (default: all)")
    parser.add_argument("--list", action="store_true", help="print the jobs and their commands, run nothing")
    parser.add_argument("--workers", type=int, default=None, metavar="W", help="worker processes (default: CPU count)")
    parser.add_argument("--out", type=Path, default=Path("out/results"), help="where the runs go (default out/results)")
    args = parser.parse_args(argv)
    names = [j.name for j in JOBS]
    chosen = names if args.only is None else [s.strip() for s in args.only.split(",")]
    unknown = [s for s in chosen if s not in names]
    if unknown:
        print(f"python -m aac_sumo.tables.results: --only {args.only!r}: expected job names among {', '.join(names)}", file=sys.stderr)
        return 2
    jobs = [j for j in JOBS if j.name in chosen]
    if args.list:
        for job in jobs:
            print(f"{job.name}: {' '.join(command(job, args.out / job.name, args.workers))}")
        return 0
    failed = [job.name for job in jobs if run_job(job, args.out, args.workers) != 0]
    if failed:
        print(f"python -m aac_sumo.tables.results: runs failed in {', '.join(failed)} (their tables show them)", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
