"""Tuning: Bayesian optimization (GP + Expected Improvement) of scenario keys, beside random search.

``aac-sumo tune SCENARIO --param KEY=LO:HI[:log|:int] ... --objective [max:]METRIC
[--constraint METRIC<op>VALUE ...] --trials T --seeds K`` proposes T candidates one after the
other. Each candidate (a value for every ``--param``) is run on K scenario seeds in parallel
through the same :class:`~aac_sumo.sweep.Executor` as sweeps (local processes or a Dask cluster),
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

import csv
import math
import operator
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from aac_sumo import config
from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.sweep import Executor, SweepError, Task, error_row, run_task

#: Metrics an objective or a constraint may name (the numeric metrics.json keys).
NUMERIC_METRICS = tuple(k for k in METRIC_KEYS if k not in ("scenario", "coordinator", "barrier", "seed"))
SCALES = ("linear", "log", "int")
SAMPLERS = ("bo", "random")
OPS: dict[str, Callable[[float, float], bool]] = {
    "==": operator.eq, "<=": operator.le, ">=": operator.ge, "<": operator.lt, ">": operator.gt,
}
#: Significant digits of proposed float values (what trials.csv and best.toml show).
DIGITS = 6


class TuneError(SweepError):
    """A command-line mistake in a tuning specification (one line)."""


# ---------------------------------------------------------------------------------------------
# specifications


@dataclass(frozen=True)
class Param:
    """A tuned key and its range. ``scale``: ``linear`` (uniform), ``log`` (uniform in log10,
    lo > 0) or ``int`` (integers lo..hi, both included)."""

    key: str
    lo: float
    hi: float
    scale: str = "linear"

    def bounds(self) -> tuple:
        """The range in the optimiser's space (log10 for ``log``; ``(lo, hi, int)`` for ``int``)."""
        if self.scale == "log":
            return (math.log10(self.lo), math.log10(self.hi))
        if self.scale == "int":
            return (int(self.lo), int(self.hi), int)
        return (self.lo, self.hi)

    def value(self, u: float) -> float | int:
        """The key's value at optimiser coordinate ``u`` (clipped into the range; floats rounded
        to DIGITS significant digits)."""
        if self.scale == "int":
            return int(min(max(round(float(u)), self.lo), self.hi))
        x = 10.0 ** float(u) if self.scale == "log" else float(u)
        return min(max(float(f"{x:.{DIGITS}g}"), self.lo), self.hi)

    def coordinate(self, value: float) -> float:
        return math.log10(value) if self.scale == "log" else float(value)

    def sample(self, rng: np.random.RandomState) -> float | int:
        if self.scale == "int":
            return int(rng.randint(int(self.lo), int(self.hi) + 1))
        lo, hi = self.bounds()[:2]
        return self.value(rng.uniform(lo, hi))

    def assignment(self, value) -> str:
        """``KEY=VALUE`` for ``--set`` (a TOML literal)."""
        return f"{self.key}={value!r}" if isinstance(value, float) else f"{self.key}={value}"

    def __str__(self) -> str:
        tail = "" if self.scale == "linear" else f":{self.scale}"
        return f"{self.key}={_num_text(self.lo)}:{_num_text(self.hi)}{tail}"


def _num_text(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise TuneError(f"{where}: expected a finite number, got {text!r}")
    return value


def parse_param(text: str) -> Param:
    """``KEY=LO:HI[:log|:int]`` as a :class:`Param`; syntax and range errors raise :class:`TuneError`
    (whether KEY exists is checked against the scenario by :func:`check_params`)."""
    key, sep, spec = text.partition("=")
    key = key.strip()
    parts = [p.strip() for p in spec.split(":")]
    if not sep or not key or "." not in key or len(parts) not in (2, 3) or "" in parts[:2]:
        raise TuneError(f"--param {text!r}: expected KEY=LO:HI[:log|:int], e.g. controller.gamma=0.05:0.9")
    where = f"--param {key}"
    lo, hi = _number(parts[0], f"{where}: LO"), _number(parts[1], f"{where}: HI")
    scale = parts[2] if len(parts) == 3 else "linear"
    if scale not in SCALES:
        raise TuneError(f"{where}: scale: expected log or int (or nothing for linear), got {scale!r}")
    if lo >= hi:
        raise TuneError(f"{where}: range: expected LO < HI, got {parts[0]}:{parts[1]}")
    if scale == "log" and lo <= 0:
        raise TuneError(f"{where}: range: expected LO > 0 for a log scale, got {parts[0]}")
    if scale == "int" and not (lo.is_integer() and hi.is_integer()):
        raise TuneError(f"{where}: range: expected integer bounds for an int scale, got {parts[0]}:{parts[1]}")
    if key == "scenario.seed":
        raise TuneError(f"{where}: expected a scenario key other than the seed (use --seeds K)")
    return Param(key, lo, hi, scale)


def parse_params(texts: Iterable[str]) -> list[Param]:
    params = [parse_param(t) for t in texts]
    if not params:
        raise TuneError("tune: --param: expected at least one KEY=LO:HI[:log|:int]")
    seen: set[str] = set()
    for p in params:
        if p.key in seen:
            raise TuneError(f"--param {p.key}: expected each key once, given twice")
        seen.add(p.key)
    return params


@dataclass(frozen=True)
class Objective:
    """The metric to optimise; ``score`` turns it into a value to minimise."""

    metric: str
    maximise: bool = False

    def score(self, value: float) -> float:
        return -value if self.maximise else value

    def better(self, a: float, b: float) -> bool:
        return self.score(a) < self.score(b)

    def __str__(self) -> str:
        return f"max:{self.metric}" if self.maximise else self.metric


def _check_metric(metric: str, where: str, known: Sequence[str] | None) -> None:
    if known is not None and metric not in known:
        raise TuneError(f"{where}: {metric}: expected a numeric metric ({', '.join(known)})")


def parse_objective(text: str, known: Sequence[str] | None = NUMERIC_METRICS) -> Objective:
    """``METRIC`` (minimise), ``min:METRIC`` or ``max:METRIC`` (maximise)."""
    text = text.strip()
    maximise = text.startswith("max:")
    metric = text[4:] if maximise else text.removeprefix("min:")
    _check_metric(metric.strip(), "--objective", known)
    return Objective(metric.strip(), maximise)


@dataclass(frozen=True)
class Constraint:
    """``metric op bound``, checked on every seed's run."""

    metric: str
    op: str
    bound: float

    def holds(self, value: Any) -> bool:
        x = _float(value)
        return math.isfinite(x) and OPS[self.op](x, self.bound)

    def __str__(self) -> str:
        return f"{self.metric}{self.op}{_num_text(self.bound)}"


_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(==|<=|>=|<|>)\s*(\S+)\s*$")


def parse_constraint(text: str, known: Sequence[str] | None = NUMERIC_METRICS) -> Constraint:
    """``METRIC==V``, ``<=``, ``>=``, ``<`` or ``>`` (``true``/``false`` count as 1/0)."""
    m = _CONSTRAINT.match(text)
    if not m:
        raise TuneError(f"--constraint {text!r}: expected METRIC<op>VALUE with op one of ==, <=, >=, <, > "
                        "(e.g. collisions==0)")
    metric, op, raw = m.groups()
    _check_metric(metric, "--constraint", known)
    bound = {"true": 1.0, "false": 0.0}.get(raw.lower())
    return Constraint(metric, op, bound if bound is not None else _number(raw, f"--constraint {metric}: VALUE"))


def _float(value: Any) -> float:
    if value is None or value == "":
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


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
    missing = [r for r in ok if not math.isfinite(_float(r.get(objective.metric)))]
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
        xs = [_float(r.get(m)) for r in ok]
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


# ---------------------------------------------------------------------------------------------
# scenarios: validation and evaluation through the executor


def check_params(source: str, sets: list[str], params: Sequence[Param]) -> config.Scenario:
    """Load the scenario and check that every tuned key exists, is numeric, fits its scale
    (an integer key needs ``:int``) and accepts both ends of its range (ScenarioError/TuneError)."""
    base = config.load(source, list(sets))
    schema = base.schema()
    for p in params:
        section, _, name = p.key.partition(".")
        if section not in schema or name not in schema[section]:
            config.load(source, list(sets) + [f"{p.key}=0"])  # raises the standard unknown-key error
        kind = schema[section][name].type
        if kind not in (int, float):
            raise TuneError(f"--param {p.key}: expected a numeric key, this one takes "
                            f"{schema[section][name].expected()}")
        if kind is int and p.scale != "int":
            raise TuneError(f"--param {p}: scale: expected :int for the integer key {p.key}")
        for end in (p.lo, p.hi):
            base.with_overrides([p.assignment(p.value(p.coordinate(end)) if p.scale != "int" else int(end))])
    return base


class ScenarioEvaluator:
    """Runs candidates on ``seeds`` seeds (base seed + 0..seeds-1) of a scenario through an
    :class:`~aac_sumo.sweep.Executor`, all runs of a batch at once."""

    def __init__(self, source: str, sets: list[str], params: Sequence[Param], seeds: int, executor: Executor):
        self.source, self.sets, self.params, self.seeds, self.executor = source, list(sets), list(params), seeds, executor
        self.base_seed = config.load(source, self.sets)["scenario.seed"]
        self.runs = 0

    def tasks(self, values: dict[str, Any], first_index: int = 0) -> list[Task]:
        assignments = [p.assignment(values[p.key]) for p in self.params]
        scenario = config.load(self.source, self.sets + assignments)
        out = []
        for i in range(self.seeds):
            seed = self.base_seed + i
            seed_set = f"scenario.seed={seed}"
            out.append(Task(first_index + i, self.source, tuple(self.sets + assignments + [seed_set]),
                            tuple((p.key, values[p.key]) for p in self.params), seed,
                            scenario.with_overrides([seed_set])))
        return out

    def __call__(self, candidates: list[dict[str, Any]]) -> list[list[dict]]:
        tasks = [t for n, c in enumerate(candidates) for t in self.tasks(c, n * self.seeds)]
        rows: list[dict | None] = [None] * len(tasks)
        for i, result in self.executor.map(run_task, tasks):
            rows[i] = error_row(tasks[i], result) if isinstance(result, BaseException) else result
        self.runs += len(tasks)
        return [rows[n * self.seeds:(n + 1) * self.seeds] for n in range(len(candidates))]


# ---------------------------------------------------------------------------------------------
# outputs


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


# ---------------------------------------------------------------------------------------------
# the command


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


# ---------------------------------------------------------------------------------------------
# analytic objectives (tests and the sampler benchmark)


def branin(x1: float, x2: float) -> float:
    """The Branin-Hoo function on [-5, 10] x [0, 15]; global minimum 0.397887 at three points."""
    b, c, t = 5.1 / (4 * math.pi ** 2), 5 / math.pi, 1 / (8 * math.pi)
    return (x2 - b * x1 ** 2 + c * x1 - 6) ** 2 + 10 * (1 - t) * math.cos(x1) + 10


def hartmann3(x1: float, x2: float, x3: float) -> float:
    """The 3-D Hartmann function on [0, 1]^3; global minimum -3.86278."""
    alpha = np.array([1.0, 1.2, 3.0, 3.2])
    a = np.array([[3.0, 10, 30], [0.1, 10, 35], [3.0, 10, 30], [0.1, 10, 35]])
    p = 1e-4 * np.array([[3689, 1170, 2673], [4699, 4387, 7470], [1091, 8732, 5547], [381, 5743, 8828]])
    x = np.array([x1, x2, x3])
    return float(-np.sum(alpha * np.exp(-np.sum(a * (x - p) ** 2, axis=1))))


def analytic_evaluator(fn: Callable[..., float], keys: Sequence[str], metric: str = "f") -> Evaluate:
    """An :data:`Evaluate` that scores each candidate with ``fn`` (one ok row, in process)."""

    def evaluate(candidates):
        return [[{"status": "ok", "seed": 0, metric: fn(*(c[k] for k in keys))}] for c in candidates]

    return evaluate


# ---------------------------------------------------------------------------------------------
# the sampler benchmark: ``aac-sumo bench tune``

#: Analytic problems of the benchmark: function, parameters, known optimum.
BENCH_PROBLEMS: dict[str, tuple[Callable[..., float], list[Param], float]] = {
    "branin": (branin, [Param("x.x1", -5, 10), Param("x.x2", 0, 15)], 0.397887),
    "hartmann3": (hartmann3, [Param("x.x1", 0, 1), Param("x.x2", 0, 1), Param("x.x3", 0, 1)], -3.86278),
}
BENCH_TRIALS = 30


def _bench_job(job: tuple[str, str, int, int]) -> list[float]:
    """Best-so-far curve of one sampler on one problem with one tuner seed (runs in a worker)."""
    name, sampler, seed, trials = job
    fn, params, _ = BENCH_PROBLEMS[name]
    search = Search(params, Objective("f"), sampler=sampler, seed=seed)
    return [t.best_so_far for t in search.run(trials, analytic_evaluator(fn, [p.key for p in params]))]


def benchmark(samples: int, out: Path, trials: int = BENCH_TRIALS, workers: int | None = None,
              progress: bool = True) -> str:
    """BO against random search with the same budget of ``trials`` evaluations, on each analytic
    problem, with tuner seeds 0..samples-1; writes tune_bench.json, tune_bench.md and
    tune_bench.png into ``out`` and returns the markdown."""
    import json

    from tqdm import tqdm

    jobs = [(name, sampler, seed, trials) for name in BENCH_PROBLEMS for sampler in SAMPLERS for seed in range(samples)]
    curves: dict[tuple[str, str], list[list[float]]] = {(n, s): [None] * samples for n in BENCH_PROBLEMS for s in SAMPLERS}
    with Executor(workers) as ex, tqdm(total=len(jobs), desc="bench tune", unit="search", disable=not progress,
                                       dynamic_ncols=True) as bar:
        for i, result in ex.map(_bench_job, jobs):
            if isinstance(result, BaseException):
                raise result
            name, sampler, seed, _ = jobs[i]
            curves[(name, sampler)][seed] = result
            bar.update()
    records = []
    for name, (_, params, optimum) in BENCH_PROBLEMS.items():
        finals = {s: np.array([c[-1] for c in curves[(name, s)]]) for s in SAMPLERS}
        for sampler in SAMPLERS:
            x = finals[sampler]
            rec = dict(name=f"tune/{sampler}/{name}", dims=len(params), trials=trials, samples=samples,
                       optimum=optimum, median_best=float(np.median(x)), mean_best=float(np.mean(x)),
                       p25_best=float(np.percentile(x, 25)), p75_best=float(np.percentile(x, 75)),
                       median_gap=float(np.median(x - optimum)))
            if sampler == "bo":
                rec |= dict(ratio_to=f"tune/random/{name}", wins=int(np.sum(finals["bo"] < finals["random"])),
                            ties=int(np.sum(finals["bo"] == finals["random"])),
                            gap_ratio=float(np.median(finals["random"] - optimum) / max(np.median(x - optimum), 1e-12)))
            records.append(rec)
    out.mkdir(parents=True, exist_ok=True)
    (out / "tune_bench.json").write_text(json.dumps(records, indent=2) + "\n")
    _plot_bench(curves, trials, out / "tune_bench.png")
    lines = [f"# Tuner benchmark: best value after {trials} evaluations, BO (GP + EI) against random search", "",
             f"{samples} tuner seeds per sampler; lower is better; gap = best - known optimum.", "",
             "| problem | dims | optimum | sampler | median best | mean best | p25 – p75 | median gap | BO better in |",
             "|---|---:|---:|---|---:|---:|---|---:|---|"]
    for r in records:
        problem = r["name"].split("/")[2]
        wins = f"{r['wins']}/{samples} seeds (median gap {r['gap_ratio']:.3g}x smaller)" if "wins" in r else ""
        lines.append(f"| {problem} | {r['dims']} | {r['optimum']:.6g} | {r['name'].split('/')[1]} | {r['median_best']:.4g} | "
                     f"{r['mean_best']:.4g} | {r['p25_best']:.4g} – {r['p75_best']:.4g} | {r['median_gap']:.3g} | {wins} |")
    text = "\n".join(lines) + "\n"
    (out / "tune_bench.md").write_text(text)
    return text


def _plot_bench(curves: dict, trials: int, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(BENCH_PROBLEMS)
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 3.8))
    xs = np.arange(1, trials + 1)
    for ax, name in zip(np.atleast_1d(axes), names):
        optimum = BENCH_PROBLEMS[name][2]
        for sampler, colour, label in (("bo", "tab:blue", "BO (GP + EI)"), ("random", "tab:orange", "random search")):
            gap = np.array(curves[(name, sampler)]) - optimum
            gap = np.maximum(gap, 1e-6)
            ax.plot(xs, np.median(gap, axis=0), color=colour, lw=2, label=f"{label}: median")
            ax.fill_between(xs, np.percentile(gap, 25, axis=0), np.percentile(gap, 75, axis=0), color=colour,
                            alpha=0.2, label=f"{label}: 25–75 %")
        ax.set_yscale("log")
        ax.set_xlabel("trial")
        ax.set_ylabel("best so far − optimum")
        ax.set_title(f"{name} ({len(BENCH_PROBLEMS[name][1])}-D), {len(curves[(name, 'bo')])} tuner seeds", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
