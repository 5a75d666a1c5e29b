"""What ``aac-sumo tune`` writes: trials.csv, best.toml, tuning.png and summary.md."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Sequence

from aac_sumo import config
from aac_sumo.tune.specs import NUMERIC_METRICS, Constraint, Objective, Param
from aac_sumo.tune.search import Trial, best_trial


def trial_columns(params: Sequence[Param]) -> list[str]:
    return (["trial", "sampler", "proposal"] + [p.key for p in params]
            + ["status", "objective", "score", "best_so_far", "violations", "runs_ok", "runs", "errors"]
            + list(NUMERIC_METRICS))


def trial_row(t: Trial) -> dict:
    row = dict(trial=t.number, sampler=t.sampler, proposal=t.proposal, status=t.status, objective=t.objective,
               score=t.score, best_so_far=t.best_so_far, violations=t.violations, runs_ok=t.runs_ok, runs=t.runs,
               errors=t.errors)
    row |= t.values
    row |= {m: t.metrics.get(m) for m in NUMERIC_METRICS}
    return {k: ("" if v is None or (isinstance(v, float) and math.isnan(v)) else v) for k, v in row.items()}


def write_trials(trials: Sequence[Trial], params: Sequence[Param], path: Path) -> None:
    tmp = path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=trial_columns(params), lineterminator="\n")
        writer.writeheader()
        writer.writerows(trial_row(t) for t in trials)
    tmp.replace(path)


def read_trials(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def best_toml(scenario: config.Scenario, trial: Trial, params: Sequence[Param], objective: Objective,
              constraints: Sequence[Constraint], seeds: int) -> str:
    """The scenario with the best candidate applied, runnable with ``aac-sumo run``."""
    tuned = scenario.with_overrides([p.assignment(trial.values[p.key]) for p in params])
    head = [
        f"# Tuned by aac-sumo tune ({trial.sampler}, trial {trial.number}): {objective} = {trial.objective:.6g}",
        f"# mean over {seeds} seed(s) from scenario.seed; constraints: {', '.join(map(str, constraints)) or 'none'}",
        "# tuned keys: " + ", ".join(f"{p.key} = {trial.values[p.key]!r}" for p in params),
        "",
    ]
    return "\n".join(head) + tuned.to_toml()


def plot_tuning(series: dict[str, Sequence[Trial]], objective: Objective, path: Path, title: str) -> None:
    """Best objective so far against the trial number, one line per sampler; every ok trial as a
    dot, penalised ones as crosses at the bottom/top edge."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    colours = {"bo": "tab:blue", "random": "tab:orange"}
    labels = {"bo": "Bayesian optimization (GP + EI)", "random": "random search"}
    for name, trials in series.items():
        colour = colours.get(name, None)
        xs = [t.number for t in trials]
        best = [t.best_so_far for t in trials]
        ax.step(xs, best, where="post", color=colour, lw=2, label=f"{labels.get(name, name)}: best so far")
        ok = [(t.number, t.objective) for t in trials if t.status == "ok"]
        if ok:
            ax.scatter(*zip(*ok), s=14, color=colour, alpha=0.45)
        bad = [t.number for t in trials if t.status != "ok"]
        if bad:
            ax.scatter(bad, [0.02] * len(bad), transform=ax.get_xaxis_transform(), marker="x", s=20,
                       color=colour, alpha=0.8, label=f"{labels.get(name, name)}: penalised trial")
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_xlabel("trial")
    ax.set_ylabel(f"{objective.metric} ({'higher' if objective.maximise else 'lower'} is better)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def summary(done: dict[str, list[Trial]], best: Trial | None, params: Sequence[Param], objective: Objective,
            constraints: Sequence[Constraint], sampler: str) -> str:
    lines = [f"# Tuning: {objective}" + (f" subject to {', '.join(map(str, constraints))}" if constraints else ""), ""]
    lines += ["| sampler | trials | ok | violated | failed | best " + objective.metric + " | found at trial |",
              "|---|---:|---:|---:|---:|---:|---:|"]
    for name, trials in done.items():
        b = best_trial(trials, objective)
        count = {s: sum(t.status == s for t in trials) for s in ("ok", "violated", "failed")}
        lines.append(f"| {name} | {len(trials)} | {count['ok']} | {count['violated']} | {count['failed']} | "
                     f"{'—' if b is None else f'{b.objective:.6g}'} | {'—' if b is None else b.number} |")
    lines.append("")
    if best is None:
        lines.append("No candidate finished every run and met every constraint; no best.toml was written.")
    else:
        lines.append(f"Best ({best.sampler}, trial {best.number}): "
                     + ", ".join(f"`{p.key} = {best.values[p.key]!r}`" for p in params)
                     + f" → {objective.metric} = {best.objective:.6g}")
    return "\n".join(lines) + "\n"
