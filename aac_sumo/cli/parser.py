"""The ``aac-sumo`` argument parser: every command and its options."""

from __future__ import annotations

import argparse
from pathlib import Path

from aac_sumo import __version__
from aac_sumo.cli.common import PROG, Parser, int_list, positive_int


def build_parser() -> argparse.ArgumentParser:
    from aac_sumo.cli.views import ANIMATION_FORMATS, add_animation_options, add_commands as add_view_commands

    parser = Parser(prog=PROG, description="AAC + MPC-FCBF experiments: run, sweep, reproduce the paper's tables, benchmark.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{run,animate,compare,sweep,tune,table,bench,stress,net,scenarios,keys}")

    def add_executor(p, resume: bool):
        """Where the runs go (local processes or a Dask cluster), resuming, progress bar."""
        p.add_argument("--workers", type=positive_int, metavar="W", help="worker processes (default: CPU count)")
        p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                       help="run on this Dask scheduler's workers instead of local processes (needs aac-sumo[cluster])")
        if resume:
            p.add_argument("--resume", action="store_true",
                           help="skip the runs that already have a status=ok row in OUT/results.csv")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")

    def add_set(p):
        p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                       help="override a scenario key, e.g. controller.horizon=5 (repeatable)")

    p = sub.add_parser("run", help="one run of a scenario")
    p.add_argument("scenario", metavar="SCENARIO", help="a .toml file or a bundled scenario name (e.g. braking)")
    add_set(p)
    p.add_argument("--seed", type=int, help="the run's seed (same as --set scenario.seed=S)")
    p.add_argument("--out", type=Path, help="output directory (default out/<scenario name>)")
    p.add_argument("--gui", action="store_true", help="show the run in sumo-gui (SUMO scenarios only): the authority car gold, "
                   "cars in a safety stop red; the window stays open at the end until it is closed")
    p.add_argument("--delay", type=float, metavar="MS", help="with --gui: pause per simulation step [ms], to watch")
    p.add_argument("--animate", nargs="?", const="gif", choices=ANIMATION_FORMATS, metavar="{gif,mp4}",
                   help="also write OUT/animation.gif (or .mp4), as aac-sumo animate does")
    add_animation_options(p, positive_int)

    add_view_commands(sub, positive_int)

    p = sub.add_parser("sweep", help="every combination of a grid of keys, K seeds each, in parallel")
    p.add_argument("scenario", metavar="SCENARIO")
    p.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2,...", help="a key and its values (repeatable)")
    add_set(p)
    p.add_argument("--seeds", type=positive_int, default=1, metavar="K", help="seeds per combination: base seed + 0..K-1 (default 1)")
    p.add_argument("--out", type=Path, help="output directory (default out/sweep/<scenario name>)")
    add_executor(p, resume=True)

    p = sub.add_parser("tune", help="Bayesian optimization (GP + Expected Improvement) of scenario keys, beside random search")
    p.add_argument("scenario", metavar="SCENARIO")
    p.add_argument("--param", dest="params", action="append", default=[], metavar="KEY=LO:HI[:log|:int]",
                   help="a tuned key and its range, e.g. controller.q_pos=0.1:100:log (repeatable)")
    p.add_argument("--objective", required=True, metavar="[max:]METRIC",
                   help="metric to minimise (max:METRIC maximises), mean over the seeds")
    p.add_argument("--constraint", dest="constraints", action="append", default=[], metavar="METRIC<op>VALUE",
                   help="must hold on every seed, op one of == <= >= < >, e.g. collisions==0 (repeatable)")
    p.add_argument("--trials", type=positive_int, default=20, metavar="T", help="candidates to evaluate (default 20)")
    p.add_argument("--seeds", type=positive_int, default=1, metavar="K",
                   help="scenario seeds per candidate: scenario.seed + 0..K-1, run in parallel (default 1)")
    p.add_argument("--sampler", choices=("bo", "random"), default="bo", help="bo (default) or random search")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="the tuner's seed: same seed, same trials (default 0)")
    p.add_argument("--init", type=positive_int, metavar="N", help="random trials before the GP takes over (default T//3 within 2..5)")
    p.add_argument("--xi", type=float, default=0.01, metavar="X", help="EI exploration margin, in standard deviations of the objective (default 0.01)")
    p.add_argument("--no-baseline", action="store_true", help="skip the random search of the same budget drawn beside BO in tuning.png")
    add_set(p)
    p.add_argument("--out", type=Path, help="output directory (default out/tune/<scenario name>)")
    add_executor(p, resume=False)

    from aac_sumo.tables.common import LAYER_CHOICES
    from aac_sumo.tables.ablation import CASES as ABLATION_CASES
    from aac_sumo.tables.build import TABLES

    p = sub.add_parser("table", help="one of the paper's tables, ours beside the paper's values; or the circle swap",
                       description="swarm: Table I (AAC vs LFC, horizons 5/10/15); lane-change: Table II (SUMO); "
                       "braking: Table III (CBF vs F-CBF, in the paper's formulation without a terminal condition, then in ours with it; once per "
                       "controller.prediction, the scenario's own first); circle-swap: AAC vs LFC with 8/16/24 robots on radii 4/6/8 m "
                       "(not in the paper); ablation: AAC and LFC as in the paper, with committed plans and with everything, "
                       "beside the baselines, on S1, the circle swaps, the random crossing, S2 and the highway. swarm and circle-swap give AAC and LFC the same emergency layers in every "
                       "run (the safety_layers column): off = neither has the safety stop (the paper), on = both have it.")
    p.add_argument("name", choices=TABLES, metavar="{" + ",".join(TABLES) + "}")
    p.add_argument("--seeds", type=positive_int, default=1, metavar="K", help="seeds per cell (default 1)")
    p.add_argument("--layers", choices=LAYER_CHOICES, metavar="{" + ",".join(LAYER_CHOICES) + "}",
                   help="swarm and circle-swap: aac.safety_stop and lfc.safety_stop, set together: off (the paper), "
                   "on, or both settings (default: both for swarm, off for circle-swap)")
    p.add_argument("--baselines", action="store_true",
                   help="swarm, circle-swap, lane-change: also the baseline coordinators that drive the table's kind "
                   "(ORCA and CBF-QP on the swarms, SUMO's own driver on the road), with the paper's layer setting")
    p.add_argument("--cases", default=None, metavar="C1,C2,...",
                   help="ablation: only these cases (default all: " + ",".join(c[0] for c in ABLATION_CASES) + ")")
    p.add_argument("--sensitivity", action="store_true",
                   help="braking: also each barrier over gamma (and F-CBF over mu1) on the next K seeds, "
                   "into sensitivity.md and sensitivity.csv")
    p.add_argument("--grid", choices=("paired", "full"), default=None,
                   help="circle-swap: paired (8 robots on 4 m, 16 on 6 m, 24 on 8 m; the default) or full "
                   "(8, 16 and 24 robots on each of 4, 6 and 8 m)")
    add_set(p)
    p.add_argument("--out", type=Path, help="output directory (default out/table/<name>)")
    add_executor(p, resume=True)

    p = sub.add_parser("bench", help="speed figures: medians and ratios measured in one process")
    p.add_argument("target", nargs="?", default="all", choices=("mpc", "aac", "tune", "all"), metavar="{mpc,aac,tune,all}")
    p.add_argument("--out", type=Path, default=Path("out/bench"), help="output directory (default out/bench)")
    p.add_argument("--samples", type=positive_int, default=100, metavar="S", help="timed solves per configuration (default 100)")
    p.add_argument("--horizons", type=int_list, default=None, metavar="N1,N2,...", help="MPC horizons (default 5,10,15)")
    p.add_argument("--solvers", default=None, metavar="S1,S2,...", help="solver configurations (default fatrop-c,fatrop,ipopt,sqp)")
    p.add_argument("--repeats", type=positive_int, default=3, metavar="R",
                   help="aac: runs per coordinator, scenario and horizon; medians pool them (default 3)")
    p.add_argument("--scenarios", default=None, metavar="S1,S2,...",
                   help="aac: the scenarios to time (default swarm_rescue,lane_change,random_crossing,highway_work_zone)")

    from aac_sumo.stress.plan import KINDS

    p = sub.add_parser("stress", help="randomized scenario variants; stress.csv and stress.md list every failure with the "
                       "command that reproduces it", description="Run N scenario variants drawn from the distributions of "
                       "docs/reliability.md (a pure function of --seed and the run index) and classify each run: completed, "
                       "deadlock, timeout, collision or error. Exit status 1 when any run of ours collided or any run failed "
                       "(a baseline's collisions are reported, not failures).")
    p.add_argument("--runs", type=positive_int, default=20, metavar="N", help="runs (default 20)")
    ours = ",".join(k for k, v in KINDS.items() if v.baseline is None)
    p.add_argument("--kinds", default=ours, metavar="K1,K2,...",
                   help=f"scenario kinds, dealt to the runs in turn (default {ours}; the baselines as kinds of their own: "
                   f"{','.join(k for k, v in KINDS.items() if v.baseline is not None)})")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="the campaign's seed: same seed, same runs (default 0)")
    p.add_argument("--duration", type=float, metavar="SECONDS", help="cap every run's scenario.duration (default: each kind's cap)")
    p.add_argument("--out", type=Path, default=Path("out/stress"), help="output directory (default out/stress)")
    add_executor(p, resume=True)

    p = sub.add_parser("net", help="SUMO networks: net build DIR runs netconvert on DIR's plain-XML sources; "
                       "net info NET [ROUTES...] lists the roads a scenario can drive on")
    net = p.add_subparsers(dest="action", required=True, metavar="{build,info,trips}")
    q = net.add_parser("build", help="run netconvert on DIR's plain-XML sources")
    q.add_argument("directory", type=Path, metavar="DIR", help="folder with *.netccfg, or *.nod.xml/*.edg.xml/*.con.xml sources")
    q = net.add_parser("info", help="candidate roads (edges, lanes, length, allowed classes), sidewalks and crossings, "
                       "and the vTypes and persons of route files")
    q.add_argument("net", type=Path, metavar="NET", help="a SUMO .net.xml file")
    q.add_argument("routes", type=Path, nargs="*", default=[], metavar="ROUTES", help="SUMO route files (cones, pedestrians, traffic)")
    q = net.add_parser("trips", help="random routes on NET by the wheel's randomTrips.py: controlled cars of a vType of their own "
                       "and SUMO's background cars, for a city run (docs/sumo.md)")
    q.add_argument("net", type=Path, metavar="NET", help="a SUMO .net.xml file")
    q.add_argument("--controlled", type=int, default=30, help="controlled cars, vType --vtype, ids VTYPE.K (default 30)")
    q.add_argument("--background", type=int, default=100, help="SUMO's own cars, ids bg.K (default 100)")
    q.add_argument("--end", type=float, default=300.0, help="the departures spread over [0, END] s (default 300)")
    q.add_argument("--seed", type=int, default=0, help="randomTrips' seed (the background's is SEED + 1)")
    q.add_argument("--vtype", default="aac", help="the controlled cars' vType id (default aac)")
    q.add_argument("--out", type=Path, required=True, help="folder for controlled.rou.xml and background.rou.xml")
    return parser
