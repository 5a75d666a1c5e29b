"""What a tuning candidate is scored on: runs of a scenario on K seeds through the sweep
executor (:class:`ScenarioEvaluator`, after :func:`check_params`), or an analytic function
(:func:`analytic_evaluator`: the tests and the sampler benchmark ``aac-sumo bench tune``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from aac_sumo import config
from aac_sumo.runs.executor import Executor
from aac_sumo.runs.sweep import Task, error_row, run_task
from aac_sumo.tune.search import SAMPLERS, Evaluate, Search
from aac_sumo.tune.specs import Objective, Param, TuneError


def check_params(source: str, sets: list[str], params: Sequence[Param]) -> config.Scenario:
    """Load the scenario and check that every tuned key exists, is numeric, fits its scale
    (an integer key needs ``:int``) and accepts both ends of its range (ScenarioError/TuneError)."""
    base = config.load(source, list(sets))
    schema = base.schema()
    for p in params:
        section, _, name = p.key.partition(".")
        if section not in schema or name not in schema[section]:
            base.with_overrides([f"{p.key}=0"], "--param")  # raises the standard unknown-key error
        kind = schema[section][name].type
        if kind not in (int, float):
            raise TuneError(f"--param {p.key}: expected a numeric key, this one takes "
                            f"{schema[section][name].expected()}")
        if kind is int and p.scale != "int":
            raise TuneError(f"--param {p}: scale: expected :int for the integer key {p.key}")
        for end in (p.lo, p.hi):
            base.with_overrides([p.assignment(p.value(p.coordinate(end)) if p.scale != "int" else int(end))], "--param")
    return base


class ScenarioEvaluator:
    """Runs candidates on ``seeds`` seeds (base seed + 0..seeds-1) of a scenario through an
    :class:`~aac_sumo.runs.executor.Executor`, all runs of a batch at once."""

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
