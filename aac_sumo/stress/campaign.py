"""Randomized stress campaigns: ``aac-sumo stress``.

Run ``i`` of a campaign of seed ``S`` has the kind ``kinds[i mod len(kinds)]`` and draws every
value from ``numpy.random.default_rng([S, 0, i])`` (:func:`~aac_sumo.stress.plan.draw`), so the plan is a pure
function of the seed and the run index: a resumed or longer campaign plans the same runs. Each
run is a bundled scenario plus ``--set KEY=VALUE`` overrides (``scenario.seed`` last), which
``aac-sumo run KIND --set ...`` reproduces. Lane-change runs also name files the campaign writes
into its output folder: a few generated roads (plain XML built with netconvert,
:func:`~aac_sumo.stress.roads.road_variants`, drawn from ``[S, 1]``) and one route file per run with its cones and
pedestrians.

The distributions (``docs/reliability.md`` has the table) are chosen so that no draw is
impossible: starts are spaced wider than two footprints plus their jitter, debris stays clear of
starts and goals, cones stand beyond every car's lane change and within the first edge. Every
draw is checked by the config loader when planned (a rejection is a bug and stops the
campaign). ``random_crossing`` draws its own geometry from the scenario seed by rejection
sampling; a scenario seed whose geometry fails is replaced by the next one from the run's
generator (deterministic, at most ``CROSSING_TRIES`` times).

The runs go through the sweep executor (:func:`aac_sumo.runs.sweep.run_tasks`: local processes or
Dask, ``--resume``). ``results.csv`` is its progress file; at the end ``stress.csv`` (one row
per run, with its outcome and reproducing command) and ``stress.md`` are written.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Callable

from aac_sumo import config
from aac_sumo.runs import sweep
from aac_sumo.runs.executor import SweepError
from aac_sumo.stress.plan import DRAWN_KEYS, KINDS, plan, prepare

#: Outcomes of a run, most severe first (see :func:`outcome`).
OUTCOMES = ("collision", "error", "deadlock", "timeout", "completed")


# --- outcomes and reports ------------------------------------------------------------------------


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0


def is_baseline(row: dict) -> bool:
    """Whether a stress row ran one of the baselines (its collisions are not failures of ours)."""
    return KINDS[row["kind"]].baseline is not None if row.get("kind") in KINDS else False


def outcome(row: dict) -> str:
    """A run's outcome: ``collision`` when ``collisions`` or ``sim_collisions`` > 0; else ``error``
    when its status is error (it raised, or its worker died); else ``completed`` when every robot
    finished, ``deadlock`` when the runner's deadlock rule ended it, ``timeout`` otherwise (the
    time limit ``scenario.duration`` came first)."""
    if _positive(row.get("collisions")) or _positive(row.get("sim_collisions")):
        return "collision"
    if row.get("status") != "ok":
        return "error"
    if row.get("completed") is True:
        return "completed"
    return "deadlock" if row.get("deadlock") is True else "timeout"


def stress_columns() -> list[str]:
    """``stress.csv`` columns: run, kind, outcome, the drawn values, then results.csv's (seed,
    metrics, status, error, provenance), then the reproducing command."""
    rest = sweep.columns([])
    return ["run", "kind", "outcome", *DRAWN_KEYS] + rest + ["command"]


def _split(rows: list[dict], key: Callable[[dict], str]) -> list[str]:
    groups: dict[str, list[str]] = {}
    for r in rows:
        groups.setdefault(key(r), []).append(r["outcome"])
    lines = []
    for name, outs in groups.items():
        lines.append(f"| {name} | {len(outs)} | " + " | ".join(str(outs.count(o)) for o in OUTCOMES) + " |")
    return lines


def _worst(rows: list[dict], metric: str) -> str:
    known = [r for r in rows if isinstance(r.get(metric), (int, float)) and math.isfinite(r[metric])]
    if not known:
        return f"- `{metric}`: no run measured it"
    r = min(known, key=lambda r: r[metric])
    return f"- `{metric}` = {r[metric]:.3g} m in run {r['run']} ({r['kind']}, {r['outcome']}): `{r['command']}`"


def markdown(rows: list[dict], title: str) -> str:
    """``stress.md``: the outcome split per kind and per (coordinator, barrier), the worst
    clearance and distance, and every failure with the command that reproduces it."""
    head = ["| | runs | " + " | ".join(OUTCOMES) + " |", "|---|---|" + "---|" * len(OUTCOMES)]
    lines = [f"# {title}", "", "Outcomes (docs/reliability.md defines them): collision (footprint overlap or a "
             "SUMO-reported collision), error (the run raised or its worker died), deadlock, timeout (the time "
             "limit `scenario.duration` came first), completed.", "", "## Per kind", "", *head]
    lines += _split(rows, lambda r: r["kind"])
    lines += ["", "## Per coordinator and barrier", "", *head]
    lines += _split(sorted(rows, key=lambda r: (str(r.get("controller.coordinator")), str(r.get("controller.barrier")))),
                    lambda r: f"{r.get('controller.coordinator')} / {r.get('controller.barrier')}")
    lines += ["", "## Closest approach", "", _worst(rows, "min_clearance_m"), _worst(rows, "min_distance_m")]
    failed = [r for r in rows if r["outcome"] != "completed"]
    lines += ["", f"## Failures ({len(failed)} of {len(rows)} runs)", ""]
    for r in sorted(failed, key=lambda r: (OUTCOMES.index(r["outcome"]), r["run"])):
        why = r.get("error") or r.get("incomplete_reason") or ""
        lines.append(f"- run {r['run']} ({r['kind']}): **{r['outcome']}**{': ' + why if why else ''}  \n  `{r['command']}`")
    if not failed:
        lines.append("None.")
    return "\n".join(lines) + "\n"


def _manifest(out: Path, mine: dict, resume: bool) -> None:
    """Refuse to resume a campaign of another seed, kinds or duration cap (``OUT/stress.json``)."""
    path = out / "stress.json"
    if resume and path.is_file():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError):
            old = {}
        for key in mine:
            if key in old and old[key] != mine[key]:
                raise SweepError(f"--resume {path}: {key}: expected the interrupted campaign's {old[key]}, got {mine[key]}")
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(mine, indent=2) + "\n")


def stress(runs: int, kinds: list[str], seed: int, out: Path, workers: int | None = None, scheduler: str | None = None,
           resume: bool = False, progress: bool = True, duration: float | None = None) -> tuple[list[dict], str]:
    """The whole ``aac-sumo stress`` command: plan, write the generated files, run (``resume``:
    only the runs without a ``status=ok`` row in ``OUT/results.csv``), write stress.csv and
    stress.md. Returns the stress.csv rows and the markdown."""
    if seed < 0:
        raise SweepError(f"stress: --seed {seed}: expected an integer >= 0")
    if duration is not None and not 0 < duration < math.inf:
        raise SweepError(f"stress: --duration {duration}: expected a number of seconds > 0")
    _manifest(out, {"seed": seed, "kinds": kinds, "duration": duration}, resume)
    draws = plan(runs, kinds, seed, out, duration)
    prepare(draws, seed, out)
    tasks = [sweep.Task(d.index, str(config.resolve(d.scenario).resolve()), d.sets,
                        (("run", d.index), ("kind", d.kind), *d.values.items()), d.seed,
                        config.load(d.scenario, list(d.sets), "stress --set")) for d in draws]
    results = sweep.run_tasks(tasks, ["run", "kind", *DRAWN_KEYS], out, workers, progress, desc="stress",
                              scheduler=scheduler, resume=resume)
    rows = [r | {"outcome": outcome(r), "command": d.command()} for r, d in zip(results, draws)]
    with open(out / "stress.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=stress_columns(), extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in rows)
    text = markdown(rows, f"Stress campaign: {runs} runs of {', '.join(kinds)}, seed {seed}")
    (out / "stress.md").write_text(text)
    return rows, text
