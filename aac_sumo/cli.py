"""The ``aac-sumo`` command line (see CONTRACT.md): run, sweep, table, bench, plus tune, net build and net info.

Every user mistake (unknown key, bad value, missing or broken scenario file, bad ``--grid`` /
``--set`` syntax, unknown command) ends with exit status 2 and one line on stderr,
``aac-sumo: error: <message>``, never a traceback. A run that fails mid-way (or a sweep/table
with failed runs) still writes its outputs and exits with status 1.
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import re
import signal
import sys
from pathlib import Path

from aac_sumo import __version__

PROG = "aac-sumo"


class UsageError(Exception):
    """A command-line mistake; its message is one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line instead of usage + message, still exit status 2
        where = self.prog[len(PROG):].strip()
        raise UsageError((f"{where}: {message}" if where else message) + _did_you_mean(message))


def _did_you_mean(message: str) -> str:
    """``; did you mean 'run'?`` for argparse's "invalid choice: 'rn' (choose from ...)", else nothing."""
    found = re.search(r"invalid choice: '?([^' ]*)'? \(choose from (.*)\)", message)
    if not found:
        return ""
    match = difflib.get_close_matches(found.group(1), [c.strip(" '") for c in found.group(2).split(",")], n=1)
    return f"; did you mean '{match[0]}'?" if match else ""


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return value


def _int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected integers >= 1, got {text!r}")
    return values


def build_parser() -> argparse.ArgumentParser:
    from aac_sumo.cli_views import ANIMATION_FORMATS, add_animation_options, add_commands as add_view_commands

    parser = _Parser(prog=PROG, description="AAC + MPC-FCBF experiments: run, sweep, reproduce the paper's tables, benchmark.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{run,animate,compare,sweep,tune,table,bench,stress,net,scenarios,keys}")

    def add_executor(p, resume: bool):
        """Where the runs go (local processes or a Dask cluster), resuming, progress bar."""
        p.add_argument("--workers", type=_positive_int, metavar="W", help="worker processes (default: CPU count)")
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
    add_animation_options(p, _positive_int)

    add_view_commands(sub, _positive_int)

    p = sub.add_parser("sweep", help="every combination of a grid of keys, K seeds each, in parallel")
    p.add_argument("scenario", metavar="SCENARIO")
    p.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2,...", help="a key and its values (repeatable)")
    add_set(p)
    p.add_argument("--seeds", type=_positive_int, default=1, metavar="K", help="seeds per combination: base seed + 0..K-1 (default 1)")
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
    p.add_argument("--trials", type=_positive_int, default=20, metavar="T", help="candidates to evaluate (default 20)")
    p.add_argument("--seeds", type=_positive_int, default=1, metavar="K",
                   help="scenario seeds per candidate: scenario.seed + 0..K-1, run in parallel (default 1)")
    p.add_argument("--sampler", choices=("bo", "random"), default="bo", help="bo (default) or random search")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="the tuner's seed: same seed, same trials (default 0)")
    p.add_argument("--init", type=_positive_int, metavar="N", help="random trials before the GP takes over (default T//3 within 2..5)")
    p.add_argument("--xi", type=float, default=0.01, metavar="X", help="EI exploration margin, in standard deviations of the objective (default 0.01)")
    p.add_argument("--no-baseline", action="store_true", help="skip the random search of the same budget drawn beside BO in tuning.png")
    add_set(p)
    p.add_argument("--out", type=Path, help="output directory (default out/tune/<scenario name>)")
    add_executor(p, resume=False)

    from aac_sumo.table_common import LAYER_CHOICES
    from aac_sumo.table_ablation import CASES as ABLATION_CASES
    from aac_sumo.tables import TABLES

    p = sub.add_parser("table", help="one of the paper's tables, ours beside the paper's values; or the circle swap",
                       description="swarm: Table I (AAC vs LFC, horizons 5/10/15); lane-change: Table II (SUMO); "
                       "braking: Table III (CBF vs F-CBF, in the paper's formulation without a terminal condition, then in ours with it; once per "
                       "controller.prediction, the scenario's own first); circle-swap: AAC vs LFC with 8/16/24 robots on radii 4/6/8 m "
                       "(not in the paper); ablation: AAC and LFC as in the paper, with committed plans and with everything, "
                       "beside the baselines, on S1, the circle swaps, the random crossing, S2 and the highway. swarm and circle-swap give AAC and LFC the same emergency layers in every "
                       "run (the safety_layers column): off = neither has the safety stop (the paper), on = both have it.")
    p.add_argument("name", choices=TABLES, metavar="{" + ",".join(TABLES) + "}")
    p.add_argument("--seeds", type=_positive_int, default=1, metavar="K", help="seeds per cell (default 1)")
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
    add_set(p)
    p.add_argument("--out", type=Path, help="output directory (default out/table/<name>)")
    add_executor(p, resume=True)

    p = sub.add_parser("bench", help="speed figures: medians and ratios measured in one process")
    p.add_argument("target", nargs="?", default="all", choices=("mpc", "aac", "tune", "all"), metavar="{mpc,aac,tune,all}")
    p.add_argument("--out", type=Path, default=Path("out/bench"), help="output directory (default out/bench)")
    p.add_argument("--samples", type=_positive_int, default=100, metavar="S", help="timed solves per configuration (default 100)")
    p.add_argument("--horizons", type=_int_list, default=None, metavar="N1,N2,...", help="MPC horizons (default 5,10,15)")
    p.add_argument("--solvers", default=None, metavar="S1,S2,...", help="solver configurations (default fatrop-c,fatrop,ipopt,sqp)")
    p.add_argument("--repeats", type=_positive_int, default=3, metavar="R",
                   help="aac: runs per coordinator, scenario and horizon; medians pool them (default 3)")
    p.add_argument("--scenarios", default=None, metavar="S1,S2,...",
                   help="aac: the scenarios to time (default swarm_rescue,lane_change,random_crossing,highway_work_zone)")

    from aac_sumo.stress import KINDS

    p = sub.add_parser("stress", help="randomized scenario variants; stress.csv and stress.md list every failure with the "
                       "command that reproduces it", description="Run N scenario variants drawn from the distributions of "
                       "docs/reliability.md (a pure function of --seed and the run index) and classify each run: completed, "
                       "deadlock, timeout, collision or error. Exit status 1 when any run of ours collided or any run failed "
                       "(a baseline's collisions are reported, not failures).")
    p.add_argument("--runs", type=_positive_int, default=20, metavar="N", help="runs (default 20)")
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
    net = p.add_subparsers(dest="action", required=True, metavar="{build,info}")
    q = net.add_parser("build", help="run netconvert on DIR's plain-XML sources")
    q.add_argument("directory", type=Path, metavar="DIR", help="folder with *.netccfg, or *.nod.xml/*.edg.xml/*.con.xml sources")
    q = net.add_parser("info", help="candidate roads (edges, lanes, length, allowed classes), sidewalks and crossings, "
                       "and the vTypes and persons of route files")
    q.add_argument("net", type=Path, metavar="NET", help="a SUMO .net.xml file")
    q.add_argument("routes", type=Path, nargs="*", default=[], metavar="ROUTES", help="SUMO route files (cones, pedestrians, traffic)")
    return parser


def main(argv: list[str] | None = None) -> int:
    from aac_sumo.config import ScenarioError
    from aac_sumo.sim.sumo import SumoError
    from aac_sumo.cli_views import COMMANDS as VIEW_COMMANDS
    from aac_sumo.run_files import RunDirError
    from aac_sumo.sweep import SweepError

    args = None
    try:
        args = build_parser().parse_args(argv)
        return {"run": cmd_run, "sweep": cmd_sweep, "tune": cmd_tune, "table": cmd_table, "bench": cmd_bench,
                "net": cmd_net, "stress": cmd_stress, **VIEW_COMMANDS}[args.command](args)
    except SystemExit as exc:  # --help
        return exc.code if isinstance(exc.code, int) else 0
    except (UsageError, ScenarioError, SweepError, SumoError, RunDirError, FileNotFoundError) as exc:
        return _fail(exc)
    except UnicodeDecodeError as exc:  # a scenario file that is not UTF-8 text
        name = getattr(args, "scenario", None) or "scenario file"
        return _fail(f"{name}: (encoding): expected UTF-8 text ({exc.reason} at byte {exc.start})")
    except OSError as exc:  # e.g. --out names a file
        return _fail(f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": "))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted (finished runs are kept)", file=sys.stderr)
        return 130


def _fail(message) -> int:
    text = " ".join(str(message).split()) or type(message).__name__
    print(f"{PROG}: error: {text}", file=sys.stderr)
    return 2


# ---------------------------------------------------------------------------------------------


def _fmt_value(value) -> str:
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "—" if not math.isfinite(value) else f"{value:.4g}"
    return str(value)


def metrics_table(metrics: dict) -> str:
    """Metrics as ``key  value`` lines, aligned, in METRIC_KEYS order then any extra keys."""
    from aac_sumo.metrics import METRIC_KEYS

    keys = [k for k in METRIC_KEYS if k in metrics] + [k for k in metrics if k not in METRIC_KEYS]
    width = max(map(len, keys), default=0)
    return "\n".join(f"  {k:<{width}}  {_fmt_value(metrics[k])}" for k in keys)


def _gui_overrides(scenario, delay: float | None) -> list[str] | None:
    """``--set <section>.gui=true`` (and ``<section>.delay=MS``) when the scenario's schema has a
    GUI switch, else None."""
    for section, keys in scenario.schema().items():
        if "gui" in keys:
            return [f"{section}.gui=true"] + ([f"{section}.delay={delay!r}"] if delay is not None else [])
    return None


def _check_out(out: Path) -> None:
    """Fail before any work when ``--out`` exists but is not a directory."""
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: expected a directory, found a file")


def cmd_run(args) -> int:
    from aac_sumo import config, runner

    sets = list(args.sets) + ([f"scenario.seed={args.seed}"] if args.seed is not None else [])
    scenario = config.load(args.scenario, sets)
    if args.delay is not None and (not args.gui or not 0 <= args.delay < float("inf")):
        raise UsageError(f"run: --delay {args.delay:g}: expected a number of milliseconds >= 0, with --gui")
    if args.gui:
        gui = _gui_overrides(scenario, args.delay)
        if gui is None:
            print(f"note: scenario kind '{scenario.kind}' runs on the internal simulator, which has no GUI; continuing without one")
        else:
            scenario = scenario.with_overrides(gui)
    out = args.out if args.out is not None else Path("out") / scenario["scenario.name"]
    _check_out(out)
    if "output_dir" in scenario.schema().get("sumo", {}):  # SUMO's own files (fcd.xml) go beside ours
        scenario = scenario.with_overrides([f"sumo.output_dir={json.dumps(str(out))}"])
    runner.STOP.clear()
    previous = {sig: signal.signal(sig, lambda signum, frame: runner.STOP.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:  # SIGINT or SIGTERM stops the run between two periods; what it recorded is written
        result = runner.run(scenario)
    except runner.RunInterrupted as stop:
        runner.write_outputs(stop.result, out)
        print(f"{PROG}: {stop.result.metrics['error']}; everything recorded until then is in {out}", file=sys.stderr)
        return 130
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    runner.write_outputs(result, out)
    print(f"{scenario['scenario.name']} ({scenario.source})")
    print(metrics_table(result.metrics))
    print(f"outputs: {out}")
    if args.animate:
        from aac_sumo.cli_views import write_animation

        write_animation(result, out, args.animate, args)
    if result.metrics.get("error"):
        print(f"{PROG}: run failed: {result.metrics['error']}", file=sys.stderr)
        return 1
    return 0


def cmd_net(args) -> int:
    from aac_sumo import net_info, network

    if args.action == "info":
        print(net_info.describe(args.net, args.routes), end="")
        return 0
    for path in network.build(args.directory):
        print(f"built {path}")
    return 0


def _out_dir(args, folder: str) -> Path:
    """``--out``, or ``out/<folder>/<scenario name>`` (which loads, so validates, the scenario)."""
    from aac_sumo import config

    out = args.out if args.out is not None else Path("out") / folder / config.load(args.scenario, list(args.sets))["scenario.name"]
    _check_out(out)
    return out


def cmd_sweep(args) -> int:
    from aac_sumo import sweep

    out = _out_dir(args, "sweep")
    rows, text = sweep.sweep(args.scenario, args.grid, list(args.sets), args.seeds, args.workers, out,
                             progress=not args.no_progress, scheduler=args.scheduler, resume=args.resume)
    print(text, end="")
    print(f"outputs: {out / 'results.csv'}, {out / 'summary.md'}")
    return _report_failures(rows)


def cmd_tune(args) -> int:
    from aac_sumo import tune

    out = _out_dir(args, "tune")
    result = tune.tune(args.scenario, args.params, args.objective, args.constraints, args.trials, out,
                       sets=list(args.sets), seeds=args.seeds, sampler=args.sampler, seed=args.seed, init=args.init,
                       xi=args.xi, baseline=not args.no_baseline, workers=args.workers, scheduler=args.scheduler,
                       progress=not args.no_progress)
    print(result.text, end="")
    files = ["trials.csv"] + (["best.toml"] if result.best is not None else []) + ["tuning.png", "summary.md"]
    print("outputs: " + ", ".join(str(out / f) for f in files))
    if result.best is None:
        print(f"{PROG}: no candidate met the constraints in every run; nothing to write into best.toml", file=sys.stderr)
        return 1
    return 0


def _report_failures(rows: list[dict]) -> int:
    failed = sum(r.get("status") != "ok" for r in rows)
    if failed:
        print(f"{PROG}: {failed} of {len(rows)} runs failed (status=error in results.csv)", file=sys.stderr)
        return 1
    return 0


def cmd_stress(args) -> int:
    from aac_sumo import stress

    _check_out(args.out)
    rows, text = stress.stress(args.runs, stress.parse_kinds(args.kinds), args.seed, args.out, args.workers, args.scheduler,
                               args.resume, progress=not args.no_progress, duration=args.duration)
    print(text, end="")
    print(f"outputs: {args.out / 'stress.csv'}, {args.out / 'stress.md'}")
    ours = [r for r in rows if not stress.is_baseline(r)]  # a baseline's collisions are reported (stress.md), not failures
    bad = {"collision": sum(r["outcome"] == "collision" for r in ours), "error": sum(r["outcome"] == "error" for r in rows)}
    if any(bad.values()):
        print(f"{PROG}: {bad['collision']} collision(s) and {bad['error']} error(s) in {len(rows)} runs (see stress.md)", file=sys.stderr)
        return 1
    return 0


def cmd_table(args) -> int:
    from aac_sumo import tables

    out = args.out if args.out is not None else Path("out") / "table" / args.name
    extra = {}
    if args.layers is not None:
        if args.name not in tables.LAYERED:
            raise UsageError(f"table {args.name}: --layers: expected one of the tables {', '.join(tables.LAYERED)} "
                             f"(table {args.name} does not switch emergency layers)")
        extra["layers"] = args.layers
    if args.baselines:
        if args.name not in ("swarm", "circle-swap", "lane-change"):
            raise UsageError(f"table {args.name}: --baselines: expected table swarm, circle-swap or lane-change")
        extra["baselines"] = True
    if args.cases is not None:
        if args.name != "ablation":
            raise UsageError(f"table {args.name}: --cases: expected table ablation (the only table with cases)")
        from aac_sumo.table_ablation import CASES

        extra["cases"] = _names(args.cases, "--cases", tuple(c[0] for c in CASES))
    if args.sensitivity:
        if args.name != "braking":
            raise UsageError(f"table {args.name}: --sensitivity: expected table braking (the only table with a sensitivity grid)")
        extra["sensitivity"] = True
    _check_out(out)
    _, text, runs = tables.BUILDERS[args.name](args.seeds, args.workers, out, list(args.sets), progress=not args.no_progress,
                                                scheduler=args.scheduler, resume=args.resume, **extra)
    print(text, end="")
    runs_file = out / "CASE" / "results.csv" if args.name == "ablation" else out / "results.csv"
    print(f"outputs: {out / 'table.csv'}, {out / 'table.md'}, {runs_file}")
    return _report_failures(runs)


def _names(text: str | None, flag: str, known: tuple[str, ...]) -> tuple[str, ...]:
    """The comma-separated names of a ``flag`` (all of ``known`` without it); a one-line usage
    error for a name not among them."""
    if text is None:
        return known
    names = tuple(s.strip() for s in text.split(","))
    if not names or any(s not in known for s in names):
        raise UsageError(f"{flag} {text!r}: expected names among {', '.join(known)}")
    return names


def cmd_bench(args) -> int:
    from aac_sumo import bench

    if args.target == "tune":  # BO against random search; --samples = tuner seeds per sampler
        from aac_sumo import tune

        _check_out(args.out)
        print(tune.benchmark(args.samples, args.out), end="")
        print(f"outputs: {args.out / 'tune_bench.json'}, {args.out / 'tune_bench.md'}, {args.out / 'tune_bench.png'}")
        return 0
    solvers = _names(args.solvers, "--solvers", bench.SOLVERS)
    horizons = tuple(args.horizons) if args.horizons else bench.HORIZONS
    _check_out(args.out)
    progress = lambda what: print(f"timing {what} ...", file=sys.stderr, flush=True)  # noqa: E731
    mpc = bench.bench_mpc(args.samples, horizons, solvers, progress=progress) if args.target in ("mpc", "all") else None
    scenarios = _names(args.scenarios, "--scenarios", bench.AAC_SCENARIOS)
    aac = bench.bench_aac(horizons, scenarios, repeats=args.repeats, progress=progress) if args.target in ("aac", "all") else None
    print(bench.write(args.out, mpc, aac), end="")
    print(f"outputs: {args.out / 'bench.json'}, {args.out / 'bench.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
