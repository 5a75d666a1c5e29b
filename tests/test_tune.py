"""Tuning: parameter specs, Bayesian optimization against random search, penalties, determinism,
and the ``aac-sumo tune`` command end to end on the braking scenario."""

from __future__ import annotations

import math
import statistics

import pytest

from aac_sumo import config, tune
from aac_sumo.runs import runner
from aac_sumo.cli.app import main

BRANIN = [tune.Param("x.a", -5, 10), tune.Param("x.b", 0, 15)]
QUICK = ["--set", "controller.horizon=5", "--set", "scenario.duration=2", "--set", "braking.speed=5", "--no-progress"]


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("aac-sumo: error: ") and "Traceback" not in err
    return lines[0]


def branin_search(sampler: str, seed: int, trials: int = 25, **kw) -> list[tune.Trial]:
    search = tune.Search(BRANIN, tune.Objective("f"), sampler=sampler, seed=seed, **kw)
    return search.run(trials, tune.analytic_evaluator(tune.branin, ["x.a", "x.b"]))


# ---------------------------------------------------------------------------------------------
# specifications


@pytest.mark.parametrize("text, expected", [
    ("controller.gamma=0.05:0.9", tune.Param("controller.gamma", 0.05, 0.9, "linear")),
    ("controller.q_pos=0.1:100:log", tune.Param("controller.q_pos", 0.1, 100, "log")),
    ("controller.horizon=5:20:int", tune.Param("controller.horizon", 5, 20, "int")),
    (" braking.gap = 6 : 9 ", tune.Param("braking.gap", 6, 9, "linear")),
])
def test_parse_param(text, expected):
    assert tune.parse_param(text) == expected


def test_param_scales_map_to_values_in_range():
    log, integer = tune.Param("a.b", 0.1, 100, "log"), tune.Param("a.c", 5, 20, "int")
    assert log.bounds() == (-1.0, 2.0) and log.value(1.0) == 10.0 and log.coordinate(10.0) == 1.0
    assert integer.bounds() == (5, 20, int) and integer.value(7.4) == 7 and integer.value(99) == 20
    import numpy as np

    rng = np.random.RandomState(0)
    logs = [log.sample(rng) for _ in range(400)]
    ints = [integer.sample(rng) for _ in range(400)]
    assert all(0.1 <= x <= 100 for x in logs) and sum(x < 1 for x in logs) > 80  # log-uniform: 1/3 below 1
    assert set(ints) == set(range(5, 21)) and all(isinstance(x, int) for x in ints)


@pytest.mark.parametrize("param, says", [
    ("controller.gamma=0.9:0.05", "--param controller.gamma: range: expected LO < HI"),
    ("controller.gamma=0.5:0.5", "--param controller.gamma: range: expected LO < HI"),
    ("controller.gamma=low:0.9", "--param controller.gamma: LO: expected a finite number"),
    ("controller.q_pos=0:100:log", "--param controller.q_pos: range: expected LO > 0 for a log scale"),
    ("controller.q_pos=0.1:100:cubic", "--param controller.q_pos: scale: expected log or int"),
    ("controller.horizon=5.5:20:int", "--param controller.horizon: range: expected integer bounds"),
    ("controller.gamma", "expected KEY=LO:HI[:log|:int]"),
    ("controller.gamma=0.1", "expected KEY=LO:HI[:log|:int]"),
    ("controller.horizn=5:20:int", "braking.toml --param: controller.horizn: expected a known key (did you mean controller.horizon?)"),
    ("controller.horizon=5:20", "--param controller.horizon=5:20: scale: expected :int for the integer key"),
    ("controller.barrier=0:1", "--param controller.barrier: expected a numeric key"),
    ("controller.gamma=0.05:1.5", "braking.toml --param: controller.gamma: expected a number in (0, 1]"),
    ("scenario.seed=0:9:int", "--param scenario.seed: expected a scenario key other than the seed"),
])
def test_bad_param_is_exit_2_and_one_line(capsys, tmp_path, param, says):
    rc = main(["tune", "braking", "--param", param, "--objective", "min_clearance_m", "--out", str(tmp_path), *QUICK])
    assert rc == 2
    assert says in error_line(capsys)
    assert not (tmp_path / "trials.csv").exists()


@pytest.mark.parametrize("argv, says", [
    (["--objective", "speediness"], "--objective: speediness: expected a numeric metric"),
    (["--objective", "max:barrier"], "--objective: barrier: expected a numeric metric"),
    (["--objective", "min_clearance_m", "--constraint", "collisions=0"], "--constraint 'collisions=0': expected METRIC<op>VALUE"),
    (["--objective", "min_clearance_m", "--constraint", "crashes==0"], "--constraint: crashes: expected a numeric metric"),
    (["--objective", "min_clearance_m", "--constraint", "collisions<=many"], "--constraint collisions: VALUE: expected a finite number"),
    (["--objective", "min_clearance_m", "--param", "controller.gamma=0.1:0.2"], "--param controller.gamma: expected each key once"),
    (["--objective", "min_clearance_m", "--sampler", "grid"], "tune: argument --sampler: invalid choice"),
    (["--objective", "min_clearance_m", "--trials", "0"], "tune: argument --trials: expected an integer >= 1"),
    ([], "tune: the following arguments are required: --objective"),
])
def test_bad_objective_or_constraint_is_exit_2_and_one_line(capsys, tmp_path, argv, says):
    rc = main(["tune", "braking", "--param", "controller.gamma=0.05:0.9", *argv, "--out", str(tmp_path), *QUICK])
    assert rc == 2
    assert says in error_line(capsys)


def test_parse_objective_and_constraint():
    assert tune.parse_objective("task_duration_s") == tune.Objective("task_duration_s", False)
    assert tune.parse_objective("max:min_clearance_m") == tune.Objective("min_clearance_m", True)
    c = tune.parse_constraint("collisions==0")
    assert (c.metric, c.op, c.bound) == ("collisions", "==", 0.0)
    assert c.holds(0) and not c.holds(1) and not c.holds(None)
    assert tune.parse_constraint("min_clearance_m >= 0.25").holds(0.3)
    assert not tune.parse_constraint("infeasibility_rate<0.1").holds(0.1)
    assert tune.parse_constraint("completed==true").holds(True)


# ---------------------------------------------------------------------------------------------
# the search


def test_bo_beats_random_search_on_branin_with_the_same_budget():
    # Branin on [-5, 10] x [0, 15], global minimum 0.398; 25 evaluations each, five tuner seeds
    bo = [branin_search("bo", s)[-1].best_so_far for s in range(5)]
    rnd = [branin_search("random", s)[-1].best_so_far for s in range(5)]
    assert statistics.median(bo) < 0.8 * statistics.median(rnd)
    assert sum(b < r for b, r in zip(bo, rnd)) >= 4
    assert min(bo) >= 0.397887 - 1e-6


def test_same_seed_same_trials_and_bo_starts_from_random_search():
    a, b, c = branin_search("bo", 3, 10), branin_search("bo", 3, 10), branin_search("bo", 4, 10)
    assert [t.values for t in a] == [t.values for t in b]
    assert [t.values for t in a] != [t.values for t in c]
    rnd = branin_search("random", 3, 10)
    init = tune.default_init(10)
    assert [t.values for t in a[:init]] == [t.values for t in rnd[:init]]
    assert [t.proposal for t in a] == ["initial random"] * init + ["expected improvement"] * (10 - init)


def test_best_so_far_is_monotone_and_matches_the_trials():
    trials = branin_search("bo", 0, 12)
    assert [t.number for t in trials] == list(range(1, 13))
    for i, t in enumerate(trials):
        assert t.best_so_far == min(x.objective for x in trials[:i + 1])


def test_maximising_and_integer_parameters():
    # maximise -(x - 7)^2 - (y - 0.3)^2 over x in 1..12 (int) and y in [0.01, 10] (log)
    params = [tune.Param("a.x", 1, 12, "int"), tune.Param("a.y", 0.01, 10, "log")]
    search = tune.Search(params, tune.Objective("g", maximise=True), sampler="bo", seed=1)
    trials = search.run(20, tune.analytic_evaluator(lambda x, y: -(x - 7) ** 2 - (y - 0.3) ** 2, ["a.x", "a.y"], "g"))
    assert all(isinstance(t.values["a.x"], int) and 0.01 <= t.values["a.y"] <= 10 for t in trials)
    best = tune.best_trial(trials, search.objective)
    assert best.values["a.x"] == 7 and best.objective > -0.1


def test_violations_and_failures_are_kept_and_penalised():
    # f = branin, but candidates with a > 5 violate "g<=5" and those with b > 12 fail
    def evaluate(candidates):
        out = []
        for c in candidates:
            if c["x.b"] > 12:
                out.append([{"status": "error", "seed": 0, "error": "RuntimeError: boom"}])
            else:
                out.append([{"status": "ok", "seed": 0, "f": tune.branin(c["x.a"], c["x.b"]), "g": c["x.a"]}])
        return out

    objective, constraint = tune.Objective("f"), tune.parse_constraint("g<=5", known=None)
    trials = tune.Search(BRANIN, objective, [constraint], sampler="random", seed=2).run(30, evaluate)
    status = {t.status for t in trials}
    assert status == {"ok", "violated", "failed"}
    ok = [t for t in trials if t.status == "ok"]
    worst, best = max(t.objective for t in ok), min(t.objective for t in ok)
    for t in trials:
        if t.status == "ok":
            assert t.score == t.objective and t.values["x.a"] <= 5 and t.values["x.b"] <= 12
        else:
            assert t.score == pytest.approx(worst + (worst - best))
        if t.status == "violated":
            assert t.violations == "g<=5 fails on 1/1 seeds" and t.values["x.a"] > 5
            assert not math.isnan(t.metrics["f"])  # its metrics are still recorded
        if t.status == "failed":
            assert math.isnan(t.objective) and "seed 0: RuntimeError: boom" in t.errors
    assert tune.best_trial(trials, objective).objective == best


def test_judge_uses_every_seed():
    objective, c = tune.Objective("task_duration_s"), tune.parse_constraint("collisions==0")
    rows = [{"status": "ok", "seed": 0, "task_duration_s": 4.0, "collisions": 0},
            {"status": "ok", "seed": 1, "task_duration_s": 6.0, "collisions": 0}]
    assert tune.judge(rows, objective, [c])["objective"] == 5.0
    rows[1]["collisions"] = 1
    verdict = tune.judge(rows, objective, [c])
    assert verdict["status"] == "violated" and verdict["violations"] == "collisions==0 fails on 1/2 seeds"
    rows[1]["task_duration_s"] = None  # did not complete
    verdict = tune.judge(rows, objective, [c])
    assert verdict["status"] == "failed" and "task_duration_s is null on seed(s) 1" in verdict["errors"]


# ---------------------------------------------------------------------------------------------
# the command on a real scenario


def test_tune_braking_end_to_end_and_best_toml_runs(capsys, tmp_path):
    out = tmp_path / "tune"
    rc = main(["tune", "braking", "--trials", "4", "--param", "controller.gamma=0.05:0.9",
               "--param", "controller.q_pos=0.1:100:log", "--objective", "max:min_clearance_m",
               "--constraint", "collisions==0", "--seeds", "2", "--workers", "2", "--out", str(out), *QUICK])
    assert rc == 0, capsys.readouterr().err
    assert "best.toml" in capsys.readouterr().out
    rows = tune.read_trials(out / "trials.csv")
    assert [(r["sampler"], r["trial"]) for r in rows] == [("bo", str(i)) for i in range(1, 5)] + [
        ("random", str(i)) for i in range(1, 5)]
    assert all(r["status"] == "ok" and r["runs_ok"] == "2" and r["min_clearance_m"] != "" for r in rows)
    assert [r["controller.gamma"] for r in rows[:2]] == [r["controller.gamma"] for r in rows[4:6]]
    assert (out / "tuning.png").stat().st_size > 0
    best = max(rows, key=lambda r: float(r["objective"]))
    scenario = config.load(str(out / "best.toml"))
    assert scenario["controller.gamma"] == float(best["controller.gamma"])
    assert scenario["controller.q_pos"] == float(best["controller.q_pos"])
    assert scenario["controller.horizon"] == 5 and scenario["scenario.duration"] == 2
    assert runner.run(scenario).metrics["collisions"] == 0


def test_tune_is_reproducible_on_a_scenario(tmp_path):
    argv = ["tune", "braking", "--trials", "3", "--init", "2", "--param", "controller.gamma=0.05:0.9",
            "--objective", "infeasibility_rate", "--seed", "7", "--no-baseline", "--workers", "2", *QUICK]
    assert main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert main(argv + ["--out", str(tmp_path / "b")]) == 0
    keep = ("trial", "proposal", "controller.gamma", "status", "objective", "infeasible_solves", "min_clearance_m")
    a, b = (tune.read_trials(tmp_path / d / "trials.csv") for d in "ab")
    assert [{k: r[k] for k in keep} for r in a] == [{k: r[k] for k in keep} for r in b]
    assert {r["sampler"] for r in a} == {"bo"}


def test_no_feasible_candidate_writes_no_best_toml(capsys, tmp_path):
    # a gap below the robots' length makes every start overlap: every run fails, inside the worker
    rc = main(["tune", "braking", "--trials", "2", "--param", "braking.gap=0.3:0.6", "--objective", "min_clearance_m",
               "--no-baseline", "--workers", "2", "--out", str(tmp_path), *QUICK])
    assert rc == 1
    assert "no candidate met the constraints" in capsys.readouterr().err
    rows = tune.read_trials(tmp_path / "trials.csv")
    assert [r["status"] for r in rows] == ["failed", "failed"]
    assert all("braking.gap" in r["errors"] and r["runs_ok"] == "0" for r in rows)
    assert not (tmp_path / "best.toml").exists()


def test_sampler_benchmark_writes_paired_records(tmp_path):
    text = tune.benchmark(samples=2, out=tmp_path, trials=8, workers=2, progress=False)
    import json

    records = json.loads((tmp_path / "tune_bench.json").read_text())
    assert [r["name"] for r in records] == ["tune/bo/branin", "tune/random/branin", "tune/bo/hartmann3",
                                            "tune/random/hartmann3"]
    for r in records:
        assert r["trials"] == 8 and r["samples"] == 2 and r["median_best"] >= r["optimum"] - 1e-6
    bo = records[0]
    assert bo["ratio_to"] == "tune/random/branin" and 0 <= bo["wins"] + bo["ties"] <= 2
    # the same tuner seeds give the same figures, run in any order on any worker
    assert records[1]["median_best"] == pytest.approx(
        statistics.median(branin_search("random", s, 8)[-1].best_so_far for s in range(2)))
    assert (tmp_path / "tune_bench.png").stat().st_size > 0 and "| branin | 2 |" in text
