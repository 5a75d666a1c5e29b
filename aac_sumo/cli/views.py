"""The ``aac-sumo`` commands that look at runs and at what is bundled: animate, compare,
scenarios, keys. :mod:`aac_sumo.cli` adds them to its parser and dispatches to them."""

from __future__ import annotations

import argparse
from pathlib import Path

ANIMATION_FORMATS = ("gif", "mp4")


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def _time(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a time >= 0 [s], got {text!r}") from None
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a time >= 0 [s], got {text!r}")
    return value


def add_animation_options(p, positive_int) -> None:
    """``--fps``, ``--every`` and ``--ellipses``, shared by ``animate`` and ``run --animate``."""
    p.add_argument("--fps", type=_positive_float, metavar="F", help="frames per second (default: real time)")
    p.add_argument("--every", type=positive_int, default=1, metavar="K", help="one frame every K control periods (default 1)")
    p.add_argument("--ellipses", action="store_true", help="draw each robot's safety ellipse (controller.barrier's shape)")


def add_commands(sub, positive_int) -> None:
    """The subcommands of this module, on the ``aac-sumo`` subparsers ``sub``."""
    p = sub.add_parser("animate", help="an animation of a run: footprints over time, authority highlighted",
                       description="Writes RUN_DIR/animation.gif (or .mp4): every agent's footprint over time, the authority "
                       "robot in gold, robots in a safety stop outlined in red, cones, debris and pedestrians, and on every "
                       "frame the time and the current authority.")
    p.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a directory written by aac-sumo run --out")
    p.add_argument("--format", choices=ANIMATION_FORMATS, default="gif", help="gif (Pillow, default) or mp4 (ffmpeg from imageio-ffmpeg)")
    add_animation_options(p, positive_int)
    p.add_argument("--still", type=_time, metavar="T", help="write only the frame nearest to time T [s], as RUN_DIR/frame_T.png")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")

    p = sub.add_parser("compare", help="several runs side by side: metrics table and overlaid plots",
                       description="Writes OUT/compare.md and OUT/compare.csv (every metric of every run) and OUT/compare.png "
                       "(mean speed, smallest clearance and robots arrived over time, and the paths, one colour per run).")
    p.add_argument("run_dirs", type=Path, nargs="+", metavar="RUN_DIR", help="directories written by aac-sumo run --out (two or more)")
    p.add_argument("--out", type=Path, required=True, help="output directory")

    sub.add_parser("scenarios", help="the bundled scenarios, each with its one-line purpose",
                   description="Lists the bundled scenarios (names for SCENARIO in run, sweep, tune and keys).")
    p = sub.add_parser("keys", help="every scenario key with its default, unit and meaning",
                       description="Lists every key of SCENARIO (its value in that file as the default), or without "
                       "SCENARIO every key of every scenario kind with the schema's default.")
    p.add_argument("scenario", nargs="?", metavar="SCENARIO", help="a .toml file or a bundled scenario name")


def write_animation(result, out: Path, fmt: str, args) -> Path:
    """Animate ``result`` into ``out/animation.<fmt>``; print and return the path."""
    from aac_sumo.views.animate import animate

    path = out / f"animation.{fmt}"
    frames = animate(result, path, fps=args.fps, every=args.every, ellipses=args.ellipses, progress=not getattr(args, "no_progress", False))
    print(f"animation: {path} ({frames} frames)")
    return path


def cmd_animate(args) -> int:
    from aac_sumo.views.animate import still
    from aac_sumo.runs.files import read_run

    result = read_run(args.run_dir)
    if args.still is None:
        write_animation(result, args.run_dir, args.format, args)
        return 0
    path = args.run_dir / f"frame_{args.still:g}.png"
    t = still(result, path, args.still, ellipses=args.ellipses)
    print(f"frame: {path} (t = {t:g} s)")
    return 0


def cmd_compare(args) -> int:
    from aac_sumo.cli.common import UsageError, check_out
    from aac_sumo.views.compare import compare

    if len(args.run_dirs) < 2:
        raise UsageError(f"compare: expected two or more RUN_DIRs, got {len(args.run_dirs)}")
    check_out(args.out)
    print(compare(args.run_dirs, args.out), end="")
    print(f"outputs: {args.out / 'compare.md'}, {args.out / 'compare.csv'}, {args.out / 'compare.png'}")
    return 0


def cmd_scenarios(args) -> int:
    from aac_sumo import config
    from aac_sumo.cli.catalog import bundled

    rows = bundled()
    if not rows:  # one line from cli.app, exit 2
        raise FileNotFoundError(f"no bundled scenarios in {config.BUNDLED_DIR} (an incomplete installation: reinstall aac-sumo)")
    width = max(len(name) for name, _ in rows)
    for name, purpose in rows:
        print(f"{name:<{width}}  {purpose}")
    return 0


def cmd_keys(args) -> int:
    from aac_sumo import config
    from aac_sumo.cli.catalog import key_rows

    rows = key_rows(config.load(args.scenario) if args.scenario else None)
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    header = ("key", "default", "unit", "meaning")
    for row in [header, *rows]:
        print("  ".join(f"{cell:<{w}}" for cell, w in zip(row[:3], widths)) + "  " + row[3])
    return 0


COMMANDS = {"animate": cmd_animate, "compare": cmd_compare, "scenarios": cmd_scenarios, "keys": cmd_keys}
