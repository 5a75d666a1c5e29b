"""The search of ``aac-sumo tune`` (:mod:`aac_sumo.tune`): trials and their penalised scores, and
the samplers (Bayesian optimization with GP + Expected Improvement, and random search). The tuned
parameters, objective and constraints are :mod:`aac_sumo.tune.specs`.

``aac-sumo tune SCENARIO --param KEY=LO:HI[:log|:int] ... --objective [max:]METRIC
[--constraint METRIC<op>VALUE ...] --trials T --seeds K`` proposes T candidates one after the
other. Each candidate (a value for every ``--param``) is run on K scenario seeds in parallel
through the same :class:`~aac_sumo.runs.executor.Executor` as sweeps (local processes or a Dask cluster),
and scored by the mean of the objective metric over the seeds.

How a candidate is proposed (``--sampler``):

- ``random``: uniformly in each parameter's range (log-uniform for ``:log``, uniform integers for
  ``:int``), from a generator seeded by ``--seed``.
- ``bo`` (default): the first ``--init`` candidates are exactly random search's first ones (same
  generator), then each next one maximises Expected Improvement under a Gaussian process
  (Matern 5/2 kernel) fitted to every trial so far. GP and EI are the ``bayesian-optimization``
  package's (``bayes_opt.BayesianOptimization`` and ``bayes_opt.acquisition.ExpectedImprovement``);
  the objective is standardised before fitting, so ``--xi`` is in standard deviations. ``:log``
  parameters are modelled in log10 space and ``:int`` ones as integers. The optimiser is rebuilt
  from the trial history at every step with a generator seeded by (``--seed``, trial number), so
  the same ``--seed`` gives the same trials. When EI proposes a candidate that was already
  evaluated, a random candidate is evaluated instead (its ``proposal`` says so).

Penalties: a candidate whose runs all finished and met every ``--constraint`` on every seed is
``ok``. One whose constraint fails on some seed is ``violated``; one with a failed run (an error,
or a null objective such as ``task_duration_s`` of a run that did not complete) is ``failed``.
Neither is dropped: both are kept in ``trials.csv``, and the optimiser sees them with the
penalised score ``worst + margin``, where ``worst`` is the worst objective of the ``ok`` trials
so far and ``margin`` their spread (or 10 % of ``|worst|`` when they are all equal, or 1 when
that is 0); with no ``ok`` trial yet, every trial scores the same. ``best.toml`` is only ever an
``ok`` candidate.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from aac_sumo.tune.specs import NUMERIC_METRICS, Constraint, Objective, Param, TuneError, to_float

SAMPLERS = ("bo", "random")


# ---------------------------------------------------------------------------------------------
# trials and their scores


@dataclass
class Trial:
    """One evaluated candidate."""

    number: int  # 1, 2, ... within its sampler
    sampler: str
    proposal: str
    values: dict[str, Any]
    status: str  # ok | violated | failed
    objective: float  # mean over seeds (NaN when a run failed)
    violations: str = ""
    metrics: dict[str, float] = field(default_factory=dict)  # means over the seeds' ok runs
    runs_ok: int = 0
    runs: int = 0
    errors: str = ""
    score: float = math.nan  # the penalised value to minimise, as of the end
    best_so_far: float = math.nan  # best ok objective among trials 1..number of this sampler


def judge(rows: list[dict], objective: Objective, constraints: Sequence[Constraint]) -> dict:
    """Status, objective (mean over seeds), violations, metric means and errors of one
    candidate's runs (one row per seed, each with ``status`` and the metrics)."""
    failed = [r for r in rows if r.get("status") != "ok"]
    ok = [r for r in rows if r.get("status") == "ok"]
    errors = "; ".join(f"seed {r.get('seed')}: {r.get('error')}" for r in failed)
    missing = [r for r in ok if not math.isfinite(to_float(r.get(objective.metric)))]
    if missing:
        seeds = ", ".join(str(r.get("seed")) for r in missing)
        errors = "; ".join(filter(None, [errors, f"{objective.metric} is null on seed(s) {seeds}"]))
    violations = []
    for c in constraints:
        bad = sum(not c.holds(r.get(c.metric)) for r in ok)
        if bad:
            violations.append(f"{c} fails on {bad}/{len(rows)} seeds")
    means = {}
    for m in dict.fromkeys(list(NUMERIC_METRICS) + [objective.metric] + [c.metric for c in constraints]):
        xs = [to_float(r.get(m)) for r in ok]
        xs = [x for x in xs if math.isfinite(x)]
        if xs:
            means[m] = sum(xs) / len(xs)
    value = means.get(objective.metric, math.nan) if not failed and not missing else math.nan
    status = "failed" if failed or missing else ("violated" if violations else "ok")
    return dict(status=status, objective=value, violations="; ".join(violations), metrics=means,
                runs_ok=len(ok), runs=len(rows), errors=errors)


def penalised(trials: Sequence[Trial], objective: Objective) -> list[float]:
    """Each trial's value to minimise: the objective's score for ``ok`` trials, and
    ``worst + margin`` for the others (see the module docstring)."""
    good = [objective.score(t.objective) for t in trials if t.status == "ok"]
    if good:
        worst, spread = max(good), max(good) - min(good)
        margin = spread if spread > 0 else (0.1 * abs(worst) if worst != 0 else 1.0)
        penalty = worst + margin
    else:
        penalty = 0.0
    return [objective.score(t.objective) if t.status == "ok" else penalty for t in trials]


def best_trial(trials: Sequence[Trial], objective: Objective) -> Trial | None:
    """The ``ok`` trial with the best objective (the first one on ties)."""
    best = None
    for t in trials:
        if t.status == "ok" and (best is None or objective.better(t.objective, best.objective)):
            best = t
    return best


# ---------------------------------------------------------------------------------------------
# the search

#: Evaluates candidates: a list of ``{key: value}`` to a list (per candidate) of per-seed rows.
Evaluate = Callable[[list[dict[str, Any]]], list[list[dict]]]


def default_init(trials: int) -> int:
    """Random trials before the GP takes over: ``trials // 3`` clipped to 2..5."""
    return max(2, min(5, trials // 3))


def _candidate_key(values: dict[str, Any]) -> tuple:
    return tuple(sorted((k, repr(v)) for k, v in values.items()))


class Search:
    """One sampler's sequence of trials over ``params``; :meth:`run` evaluates ``trials``
    candidates through ``evaluate`` (sharing ``cache``: evaluations are deterministic, so a
    candidate already evaluated, e.g. by the other sampler, is not run again)."""

    def __init__(self, params: Sequence[Param], objective: Objective, constraints: Sequence[Constraint] = (),
                 sampler: str = "bo", seed: int = 0, init: int | None = None, xi: float = 0.01,
                 cache: dict | None = None):
        if sampler not in SAMPLERS:
            raise TuneError(f"--sampler {sampler}: expected one of {', '.join(SAMPLERS)}")
        self.params, self.objective, self.constraints = list(params), objective, list(constraints)
        self.sampler, self.seed, self.init, self.xi = sampler, seed, init, xi
        self.cache: dict = {} if cache is None else cache
        self.trials: list[Trial] = []
        self._rng = np.random.RandomState(_seed(seed, 0))  # candidates of random search / BO's initial ones
        self._fallback = np.random.RandomState(_seed(seed, 1))  # BO: replaces a repeated EI proposal

    def random_candidate(self, rng: np.random.RandomState | None = None) -> dict[str, Any]:
        rng = self._rng if rng is None else rng
        return {p.key: p.sample(rng) for p in self.params}

    def run(self, trials: int, evaluate: Evaluate, on_trial: Callable[[Trial], None] | None = None) -> list[Trial]:
        init = default_init(trials) if self.init is None else self.init
        if self.sampler == "random":  # independent candidates: evaluate them all at once
            candidates = [self.random_candidate() for _ in range(trials)]
            self._evaluate(candidates, evaluate)
            for values in candidates:
                self._record(values, "random", on_trial)
            return self.trials
        for n in range(trials):
            if n < init:
                values, proposal = self.random_candidate(), "initial random"
            else:
                values, proposal = self.suggest(n), "expected improvement"
                if _candidate_key(values) in {_candidate_key(t.values) for t in self.trials}:
                    values, proposal = self.random_candidate(self._fallback), "random (EI repeated a trial)"
            self._evaluate([values], evaluate)
            self._record(values, proposal, on_trial)
        return self.trials

    def suggest(self, n: int) -> dict[str, Any]:
        """The candidate maximising Expected Improvement under a GP fitted to the trials so far."""
        from bayes_opt import BayesianOptimization, acquisition

        names = [f"p{i:03d}" for i in range(len(self.params))]
        scores = np.array(penalised(self.trials, self.objective))
        std = scores.std()
        target = -(scores - scores.mean()) / (std if std > 0 else 1.0)  # bayes_opt maximises
        rng = np.random.RandomState(_seed(self.seed, 2, n))
        # one BLAS thread: the matrices are tiny, and threads only fight the simulations for cores
        with warnings.catch_warnings(), _one_blas_thread():
            # bayes_opt calls integer parameters experimental; sklearn notes GP fits that hit a bound
            warnings.simplefilter("ignore")
            opt = BayesianOptimization(
                f=None, pbounds={name: p.bounds() for name, p in zip(names, self.params)},
                acquisition_function=acquisition.ExpectedImprovement(xi=self.xi),
                random_state=rng, verbose=0, allow_duplicate_points=True)
            for t, y in zip(self.trials, target):
                opt.register(params={name: p.coordinate(t.values[p.key]) for name, p in zip(names, self.params)},
                             target=float(y))
            point = opt.suggest()
        return {p.key: p.value(point[name]) for name, p in zip(names, self.params)}

    def _evaluate(self, candidates: list[dict], evaluate: Evaluate) -> None:
        todo, seen = [], set()
        for c in candidates:
            key = _candidate_key(c)
            if key not in self.cache and key not in seen:
                todo.append(c)
                seen.add(key)
        if todo:
            for c, rows in zip(todo, evaluate(todo)):
                self.cache[_candidate_key(c)] = rows

    def _record(self, values: dict, proposal: str, on_trial) -> Trial:
        verdict = judge(self.cache[_candidate_key(values)], self.objective, self.constraints)
        trial = Trial(len(self.trials) + 1, self.sampler, proposal, dict(values), **verdict)
        self.trials.append(trial)
        for t, s in zip(self.trials, penalised(self.trials, self.objective)):
            t.score = s
        best = best_trial(self.trials, self.objective)
        trial.best_so_far = best.objective if best is not None else math.nan
        if on_trial is not None:
            on_trial(trial)
        return trial


def _one_blas_thread():
    try:
        from threadpoolctl import threadpool_limits  # comes with scikit-learn, bayes_opt's GP
    except ImportError:  # pragma: no cover
        import contextlib

        return contextlib.nullcontext()
    return threadpool_limits(1)


def _seed(*parts: int) -> int:
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(1)[0])
