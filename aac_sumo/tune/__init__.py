"""Tuning: Bayesian optimization (GP + Expected Improvement) of scenario keys, beside random search.

``aac-sumo tune SCENARIO --param KEY=LO:HI[:log|:int] ... --objective [max:]METRIC
[--constraint METRIC<op>VALUE ...] --trials T --seeds K`` proposes T candidates one after the
other. Each candidate (a value for every ``--param``) is run on K scenario seeds in parallel
through the same :class:`~aac_sumo.runs.executor.Executor` as sweeps (local processes or a Dask cluster),
and scored by the mean of the objective metric over the seeds.

The parts: :mod:`aac_sumo.tune.specs` (the tuned parameters, objective and constraints),
:mod:`aac_sumo.tune.search` (trials, penalties and the samplers: how a candidate is proposed and
scored), :mod:`aac_sumo.tune.objectives` (scenario runs and analytic
functions as objectives; the sampler benchmark) and :mod:`aac_sumo.tune.outputs` (the files).
This package's own module runs the command and offers the names of those parts that callers use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from aac_sumo import config
from aac_sumo.runs.executor import Executor
from aac_sumo.tune.objectives import ScenarioEvaluator, analytic_evaluator, benchmark, branin, check_params, hartmann3
from aac_sumo.tune.outputs import best_toml, plot_tuning, read_trials, summary, write_trials
from aac_sumo.tune.specs import (Constraint, Objective, Param, TuneError, parse_constraint, parse_objective, parse_param,
                                 parse_params)
from aac_sumo.tune.search import Search, Trial, best_trial, default_init, judge

__all__ = ["tune", "TuneResult", "benchmark", "branin", "hartmann3", "analytic_evaluator", "read_trials", "Constraint",
           "Objective", "Param", "Search", "Trial", "TuneError", "best_trial", "default_init", "judge", "parse_constraint",
           "parse_objective", "parse_param"]


@dataclass
class TuneResult:
    trials: list[Trial]
    baseline: list[Trial]
    best: Trial | None
    text: str
    runs: int


def tune(scenario: str, param_texts: list[str], objective_text: str, constraint_texts: list[str], trials: int,
         out: Path, sets: list[str] | None = None, seeds: int = 1, sampler: str = "bo", seed: int = 0,
         init: int | None = None, xi: float = 0.01, baseline: bool = True, workers: int | None = None,
         scheduler: str | None = None, progress: bool = True) -> TuneResult:
    """The whole ``aac-sumo tune`` command: validate everything, search, write trials.csv,
    best.toml and tuning.png (with random search of the same budget beside it unless
    ``baseline`` is off or the sampler is random)."""
    sets = list(sets or [])
    params = parse_params(param_texts)
    objective = parse_objective(objective_text)
    constraints = [parse_constraint(c) for c in constraint_texts]
    if trials < 1:
        raise TuneError(f"--trials {trials}: expected an integer >= 1")
    if init is not None and init < 1:
        raise TuneError(f"--init {init}: expected an integer >= 1")
    if not (xi >= 0 and math.isfinite(xi)):
        raise TuneError(f"--xi {xi}: expected a number >= 0")
    source = str(config.resolve(scenario).resolve())
    base = check_params(source, sets, params)
    out.mkdir(parents=True, exist_ok=True)
    from tqdm import tqdm

    cache: dict = {}
    samplers = [sampler] + (["random"] if baseline and sampler != "random" else [])
    done: dict[str, list[Trial]] = {}
    with Executor(workers, scheduler) as ex:
        evaluator = ScenarioEvaluator(source, sets, params, seeds, ex)
        for name in samplers:
            search = Search(params, objective, constraints, name, seed, init, xi, cache)
            bar = tqdm(total=trials, desc=f"tune {name}", unit="trial", disable=not progress, dynamic_ncols=True)

            def on_trial(t: Trial, bar=bar) -> None:
                write_trials([x for s in done.values() for x in s] + search.trials, params, out / "trials.csv")
                bar.set_postfix(best=f"{t.best_so_far:.4g}", refresh=False)
                bar.update()

            try:
                done[name] = search.run(trials, evaluator, on_trial)
            finally:
                bar.close()
    main = done[sampler]
    all_trials = [t for s in done.values() for t in s]
    write_trials(all_trials, params, out / "trials.csv")
    best = best_trial(all_trials, objective)
    (out / "best.toml").unlink(missing_ok=True)
    if best is not None:
        (out / "best.toml").write_text(best_toml(base, best, params, objective, constraints, seeds))
    plot_tuning(done, objective, out / "tuning.png",
                f"{base['scenario.name']}: {objective}, {seeds} seed(s) per trial, tuner seed {seed}")
    text = summary(done, best, params, objective, constraints, sampler)
    (out / "summary.md").write_text(text)
    return TuneResult(main, done.get("random", []) if sampler != "random" else [], best, text, evaluator.runs)
