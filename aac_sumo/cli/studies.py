"""The ``aac-sumo`` commands that run many runs: sweep, tune, stress, table and bench."""

from __future__ import annotations

import sys
from pathlib import Path

from aac_sumo.cli.common import PROG, UsageError, check_out


def _out_dir(args, folder: str) -> Path:
    """``--out``, or ``out/<folder>/<scenario name>`` (which loads, so validates, the scenario)."""
    from aac_sumo import config

    out = args.out if args.out is not None else Path("out") / folder / config.load(args.scenario, list(args.sets))["scenario.name"]
    check_out(out)
    return out


def cmd_sweep(args) -> int:
    from aac_sumo.runs import sweep

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
    from aac_sumo.stress import campaign as stress
    from aac_sumo.stress.plan import parse_kinds

    check_out(args.out)
    rows, text = stress.stress(args.runs, parse_kinds(args.kinds), args.seed, args.out, args.workers, args.scheduler,
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
    from aac_sumo.tables import build as tables

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
        from aac_sumo.tables.ablation import CASES

        extra["cases"] = _names(args.cases, "--cases", tuple(c[0] for c in CASES))
    if args.sensitivity:
        if args.name != "braking":
            raise UsageError(f"table {args.name}: --sensitivity: expected table braking (the only table with a sensitivity grid)")
        extra["sensitivity"] = True
    if args.grid is not None:
        if args.name != "circle-swap":
            raise UsageError(f"table {args.name}: --grid: expected table circle-swap (the only table with a choice of grid)")
        extra["grid"] = args.grid
    check_out(out)
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
    from aac_sumo.runs import bench

    if args.target == "tune":  # BO against random search; --samples = tuner seeds per sampler
        from aac_sumo import tune

        check_out(args.out)
        print(tune.benchmark(args.samples, args.out), end="")
        print(f"outputs: {args.out / 'tune_bench.json'}, {args.out / 'tune_bench.md'}, {args.out / 'tune_bench.png'}")
        return 0
    solvers = _names(args.solvers, "--solvers", bench.SOLVERS)
    horizons = tuple(args.horizons) if args.horizons else bench.HORIZONS
    check_out(args.out)
    progress = lambda what: print(f"timing {what} ...", file=sys.stderr, flush=True)  # noqa: E731
    mpc = bench.bench_mpc(args.samples, horizons, solvers, progress=progress) if args.target in ("mpc", "all") else None
    scenarios = _names(args.scenarios, "--scenarios", bench.AAC_SCENARIOS)
    aac = bench.bench_aac(horizons, scenarios, repeats=args.repeats, progress=progress) if args.target in ("aac", "all") else None
    print(bench.write(args.out, mpc, aac), end="")
    print(f"outputs: {args.out / 'bench.json'}, {args.out / 'bench.md'}")
    return 0
