"""The ``aac-sumo`` command line (see CONTRACT.md): run, sweep, table, bench, plus tune, net build and net info.

Every user mistake (unknown key, bad value, missing or broken scenario file, bad ``--grid`` /
``--set`` syntax, unknown command) ends with exit status 2 and one line on stderr,
``aac-sumo: error: <message>``, never a traceback. A run that fails mid-way (or a sweep/table
with failed runs) still writes its outputs and exits with status 1.
"""

from __future__ import annotations

import json
import math
import signal
import sys
from pathlib import Path

from aac_sumo.cli.interrupt import INTERRUPTED
from aac_sumo.cli.common import PROG, UsageError, check_out
from aac_sumo.cli.parser import build_parser
from aac_sumo.cli.studies import cmd_bench, cmd_stress, cmd_sweep, cmd_table, cmd_tune
from aac_sumo.cli.views import COMMANDS as VIEW_COMMANDS
from aac_sumo.config import ScenarioError
from aac_sumo.runs.files import RunDirError
from aac_sumo.runs.sweep import SweepError
from aac_sumo.sim.sumo_options import SumoError


def main(argv: list[str] | None = None) -> int:
    """Run ``aac-sumo`` with ``argv``; a Ctrl-C while this module loads is
    :func:`aac_sumo.cli.main`'s to answer."""
    args = None
    try:
        args = build_parser().parse_args(argv)
        if INTERRUPTED.is_set():  # a Ctrl-C while the modules loaded, which Python swallowed
            raise KeyboardInterrupt
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
    except KeyboardInterrupt:  # a run interrupted once under way says so itself (cmd_run)
        what = "while starting" if getattr(args, "command", None) in (None, "run") else "(finished runs are kept)"
        print(f"{PROG}: interrupted {what}", file=sys.stderr)
        return 130


def _fail(message) -> int:
    text = " ".join(str(message).split()) or type(message).__name__
    print(f"{PROG}: error: {text}", file=sys.stderr)
    return 2


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


def cmd_run(args) -> int:
    from aac_sumo import config
    from aac_sumo.runs import runner
    from aac_sumo.views.outputs import write_outputs

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
    check_out(out)
    if "output_dir" in scenario.schema().get("sumo", {}):  # SUMO's own files (fcd.xml) go beside ours
        scenario = scenario.with_overrides([f"sumo.output_dir={json.dumps(str(out))}"])
    runner.STOP.clear()
    previous = {sig: signal.signal(sig, lambda signum, frame: runner.STOP.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    if INTERRUPTED.is_set():  # a Ctrl-C since main() began whose KeyboardInterrupt Python swallowed: stop at once
        runner.STOP.set()
    try:  # SIGINT or SIGTERM stops the run between two periods; what it recorded is written
        result = runner.run(scenario)
    except runner.RunInterrupted as stop:
        write_outputs(stop.result, out)
        print(f"{PROG}: {stop.result.metrics['error']}; everything recorded until then is in {out}", file=sys.stderr)
        return 130
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    write_outputs(result, out)
    print(f"{scenario['scenario.name']} ({scenario.source})")
    print(metrics_table(result.metrics))
    print(f"outputs: {out}")
    if args.animate:
        from aac_sumo.cli.views import write_animation

        write_animation(result, out, args.animate, args)
    if result.metrics.get("error"):
        print(f"{PROG}: run failed: {result.metrics['error']}", file=sys.stderr)
        return 1
    return 0


def cmd_net(args) -> int:
    from aac_sumo.cli import net_info
    from aac_sumo import network

    if args.action == "info":
        print(net_info.describe(args.net, args.routes), end="")
        return 0
    if args.action == "trips":
        for path in network.random_trips(args.net, args.out, args.controlled, args.background, args.end, args.seed, args.vtype):
            print(f"wrote {path} ({path.read_text().count('<vehicle ')} vehicles)")
        return 0
    for path in network.build(args.directory):
        print(f"built {path}")
    return 0
