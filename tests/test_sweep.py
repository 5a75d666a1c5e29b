"""Sweeps and tables through the process pool and a Dask cluster: rows, columns, error rows,
crashed workers, --resume, validation first."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import pytest

from aac_sumo import config
from aac_sumo.runs import executor, sweep
from aac_sumo.tables import braking as table_braking
from aac_sumo.cli.app import main
from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.runs.provenance import PROVENANCE_KEYS
from aac_sumo.prediction import PREDICTIONS

SHORT = ["--set", "controller.horizon=5", "--set", "scenario.duration=3", "--no-progress"]


def read_rows(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


def test_grid_sweep_two_workers(capsys, tmp_path):
    rc = main(["sweep", "braking", "--grid", "braking.speed=5,6", "--workers", "2", "--out", str(tmp_path), *SHORT])
    assert rc == 0, capsys.readouterr().err
    cols, rows = read_rows(tmp_path / "results.csv")
    assert cols == (["braking.speed", "seed"] + [k for k in METRIC_KEYS if k != "seed"] + ["incomplete_reason", "status", "error"]
                    + list(PROVENANCE_KEYS))
    assert [(float(r["braking.speed"]), r["seed"], r["status"], r["error"]) for r in rows] == [
        (5.0, "0", "ok", ""), (6.0, "0", "ok", "")]
    assert all(r["horizon"] == "5" and r["scenario"] == "braking" for r in rows)
    summary = (tmp_path / "summary.md").read_text()
    assert "| braking.speed |" in summary and "1/1" in summary
    assert "braking.speed" in capsys.readouterr().out


def test_worker_failure_becomes_error_row(capsys, tmp_path):
    # gap 0.5 passes the schema (> 0) but the braking world rejects the overlapping start while
    # it is built, i.e. inside the worker's run
    rc = main(["sweep", "braking", "--grid", "braking.gap=7,0.5", "--seeds", "2", "--workers", "2",
               "--set", "scenario.seed=4", "--out", str(tmp_path), *SHORT])
    assert rc == 1
    assert "2 of 4 runs failed" in capsys.readouterr().err
    _, rows = read_rows(tmp_path / "results.csv")
    assert [(float(r["braking.gap"]), r["seed"], r["status"]) for r in rows] == [
        (7.0, "4", "ok"), (7.0, "5", "ok"), (0.5, "4", "error"), (0.5, "5", "error")]
    assert all("braking.gap" in r["error"] and r["min_distance_m"] == "" for r in rows[2:])
    assert all(r["min_distance_m"] != "" for r in rows[:2])
    summary = (tmp_path / "summary.md").read_text()
    assert "0/2" in summary and "Errors (2 of 4 runs)" in summary


def test_bad_grid_stops_before_any_run(capsys, tmp_path):
    assert main(["sweep", "braking", "--grid", "braking.speed=5,6", "--grid", "controller.horizon=5,abc",
                 "--out", str(tmp_path), *SHORT]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "braking.toml --grid: controller.horizon: expected an integer" in err
    assert not (tmp_path / "results.csv").exists()
    assert main(["sweep", "braking", "--grid", "controller.nope=1,2", "--out", str(tmp_path), *SHORT]) == 2
    assert "controller.nope" in capsys.readouterr().err


def test_parse_grid():
    assert sweep.parse_grid(["a.b=1, 2", "c.d=x"]) == [("a.b", ["1", "2"]), ("c.d", ["x"])]
    for bad in (["a.b"], ["=1"], ["a.b="], ["a.b=1,"], ["a.b=1", "a.b=2"], ["scenario.seed=1,2"]):
        with pytest.raises(sweep.SweepError):
            sweep.parse_grid(bad)


def test_plan_tasks_seeds_and_overrides():
    tasks = sweep.plan_tasks("braking", ["scenario.seed=10"], [("controller.barrier", ["cbf", "fcbf"])], 3)
    assert [(dict(t.grid)["controller.barrier"], t.seed) for t in tasks] == [
        ("cbf", 10), ("cbf", 11), ("cbf", 12), ("fcbf", 10), ("fcbf", 11), ("fcbf", 12)]
    assert tasks[1].overrides == ("scenario.seed=10", "controller.barrier=cbf", "scenario.seed=11")
    assert [t.index for t in tasks] == list(range(6))


def test_braking_table_short(capsys, tmp_path):
    rc = main(["table", "braking", "--workers", "2", "--out", str(tmp_path), "--set", "scenario.duration=1", *SHORT[:2],
               "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    cols, rows = read_rows(tmp_path / "table.csv")
    assert cols[:4] == ["barrier", "speed", "formulation", "prediction"]
    assert {"infeasibility_rate", "min_distance_m", "ttc_mean_s", "collisions", "min_clearance_m",
            "paper_infeasibility_rate", "paper_min_distance_m", "paper_ttc_mean_s"} <= set(cols)
    assert not any(c.endswith("_std") for c in cols)
    own = config.load("braking")["controller.prediction"]
    order = sorted(PREDICTIONS, key=lambda p: p != own)  # the scenario's own prediction first
    assert [(r["formulation"], r["prediction"], r["barrier"], r["speed"]) for r in rows] == [  # the paper's formulation first
        (f, p, b, str(s)) for f in ("paper", "ours") for p in order for s in (5, 10, 15, 20, 25) for b in ("cbf", "fcbf")]
    paper = {(r["prediction"], r["barrier"], r["speed"]): (r["paper_infeasibility_rate"], r["paper_min_distance_m"]) for r in rows}
    for p in PREDICTIONS:
        assert paper[(p, "cbf", "5")] == ("0.433", "1.5")
        assert paper[(p, "cbf", "15")] == ("1.0", "")
        assert paper[(p, "fcbf", "25")] == ("", "")
    md = (tmp_path / "table.md").read_text()
    assert "| CBF | 5 |" in md and "43.3%" in md and "—" in md
    assert md.index("## The paper's formulation") < md.index("### Prediction: " + own.replace("_", " ") + " (the scenario's default)") \
        < md.index("### Prediction: " + order[1].replace("_", " ")) < md.index("## Ours: with the terminal stopping condition")
    assert md in capsys.readouterr().out
    _, results = read_rows(tmp_path / "results.csv")
    assert len(results) == 40
    assert {r["prediction"] for r in results} == set(PREDICTIONS)
    assert {r["formulation"] for r in results} == {"paper", "ours"}


def test_braking_table_sets_the_prediction_itself(capsys, tmp_path):
    rc = main(["table", "braking", "--out", str(tmp_path), "--set", "controller.prediction=constant_velocity", "--no-progress"])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "controller.prediction" in err


def sensitivity_run(barrier, gamma, mu1, speed, collisions=0, infeasible=0.0, distance=1.0):
    return {"barrier": barrier, "gamma": gamma, "mu1": mu1, "braking.speed": speed, "status": "ok", "collisions": collisions,
            "infeasibility_rate": infeasible, "min_distance_m": distance, "min_clearance_m": distance - 1.0}


def test_the_sensitivity_table_picks_each_barriers_best_setting_and_states_which_claims_hold():
    """Best: the fewest collisions, then the fewest infeasible solves, then the largest smallest
    distance. The claims count the settings at 5-15 m/s only (20 m/s is not the paper's)."""
    runs = [sensitivity_run("cbf", 0.1, None, 5, infeasible=0.2), sensitivity_run("cbf", 0.1, None, 20, collisions=1),
            sensitivity_run("cbf", 0.3, None, 5, collisions=1), sensitivity_run("cbf", 0.3, None, 20),
            sensitivity_run("fcbf", 0.1, 0.2, 5, distance=1.0), sensitivity_run("fcbf", 0.1, 0.2, 20, collisions=1),
            sensitivity_run("fcbf", 0.3, 0.2, 5, distance=2.0), sensitivity_run("fcbf", 0.3, 0.2, 20, collisions=1, distance=2.0)]
    rows = table_braking.sensitivity_rows(runs, seeds=1)
    assert table_braking.best_settings(rows) == {"cbf": ("cbf", 0.3, None), "fcbf": ("fcbf", 0.3, 0.2)}
    claims = "\n".join(table_braking.sensitivity_claims(rows))
    assert "(the paper's claim): 2 of 2 settings." in claims  # F-CBF's collisions are at 20 m/s only
    assert "(the paper's contrast): 2 of 2 settings." in claims
    assert "F-CBF no worse than CBF at the same γ" in claims


def test_only_the_braking_table_has_a_sensitivity_grid(capsys, tmp_path):
    assert main(["table", "swarm", "--sensitivity", "--out", str(tmp_path / "t"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--sensitivity" in err


def test_table_rows_with_seeds():
    runs = [{"braking.speed": 5.0, "controller.barrier": "cbf", "status": "ok", "min_distance_m": d,
             "infeasibility_rate": 0.0, "ttc_mean_s": None, "collisions": 0, "min_clearance_m": 0.1}
            for d in (1.0, 2.0)]
    runs.append({"braking.speed": 5.0, "controller.barrier": "cbf", "status": "error", "min_distance_m": 9.0})
    (row,) = table_braking.braking_rows(runs, seeds=3)
    assert row["min_distance_m"] == 1.5 and row["min_distance_m_std"] == pytest.approx(math.sqrt(0.5))
    assert math.isnan(row["ttc_mean_s"]) and row["runs"] == 2 and row["errors"] == 1
    assert row["paper_min_distance_m"] == 1.50
    assert "min_distance_m_std" in table_braking.braking_columns(3)


# ---------------------------------------------------------------------------------------------
# one executor for a process pool and a Dask cluster; crashes; --resume

#: Metrics that depend only on the scenario and its seed (not on timing or on where it ran).
DETERMINISTIC = ("completed", "task_duration_s", "solves", "infeasible_solves", "infeasibility_rate",
                 "min_distance_m", "min_clearance_m", "collisions", "ttc_mean_s", "tracking_error_m",
                 "aggressive_driving_rate")


def _die_on_seed_1(task: sweep.Task) -> dict:
    """A worker that dies (as a native crash would) on the run of seed 1."""
    if task.seed == 1:
        os._exit(3)
    return sweep.run_task(task)


def test_dask_cluster_gives_the_process_pool_results(capsys, tmp_path):
    distributed = pytest.importorskip("distributed")
    argv = ["sweep", "braking", "--grid", "braking.speed=5,7", "--seeds", "2", *SHORT]
    assert main(argv + ["--workers", "2", "--out", str(tmp_path / "pool")]) == 0, capsys.readouterr().err
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        rc = main(argv + ["--scheduler", cluster.scheduler_address, "--out", str(tmp_path / "dask")])
    assert rc == 0, capsys.readouterr().err
    cols, pool = read_rows(tmp_path / "pool" / "results.csv")
    assert read_rows(tmp_path / "dask" / "results.csv")[0] == cols
    _, dask = read_rows(tmp_path / "dask" / "results.csv")
    assert [(r["braking.speed"], r["seed"], r["status"]) for r in dask] == [
        ("5.0", "0", "ok"), ("5.0", "1", "ok"), ("7.0", "0", "ok"), ("7.0", "1", "ok")]
    for a, b in zip(pool, dask):
        assert {k: a[k] for k in DETERMINISTIC} == {k: b[k] for k in DETERMINISTIC}


def test_unreachable_scheduler_is_a_one_line_error(capsys, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(executor, "CONNECT_TIMEOUT_S", 1.0)
    rc = main(["sweep", "braking", "--grid", "braking.speed=5", "--scheduler", "tcp://127.0.0.1:9",
               "--out", str(tmp_path), *SHORT])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aac-sumo: error: --scheduler tcp://127.0.0.1:9: scheduler: expected")


def test_crashed_worker_costs_only_its_run(tmp_path):
    tasks = sweep.plan_tasks("braking", ["controller.horizon=5", "scenario.duration=2"],
                             [("braking.speed", ["5"])], seeds=3)
    rows = sweep.run_tasks(tasks, ["braking.speed"], tmp_path, workers=2, progress=False, fn=_die_on_seed_1)
    assert [(r["seed"], r["status"]) for r in rows] == [(0, "ok"), (1, "error"), (2, "ok")]
    assert rows[1]["error"].startswith("WorkerDied: the worker process died")
    _, written = read_rows(tmp_path / "results.csv")
    assert [(r["seed"], r["status"]) for r in written] == [("0", "ok"), ("1", "error"), ("2", "ok")]


def _square(x: int) -> int:
    return x * x


def test_a_pool_found_broken_at_submit_loses_no_call(monkeypatch):
    """A worker can die between the wait that returned a finished call and the next submit; the
    pool then refuses the submit itself (BrokenProcessPool). The call goes back to the queue, the
    calls in flight are settled, and every result still comes back once (``make test`` caught
    the race once in test_crashed_worker_costs_only_its_run)."""
    real = executor.Executor._get_pool
    refused = []

    class RefusesOnce:
        def __init__(self, pool):
            self.pool = pool

        def submit(self, fn, item):
            if item == 3 and not refused:
                refused.append(item)
                raise executor.BrokenProcessPool("a child process terminated abruptly")
            return self.pool.submit(fn, item)

    monkeypatch.setattr(executor.Executor, "_get_pool", lambda self: RefusesOnce(real(self)))
    with executor.Executor(workers=2) as ex:
        got = dict(ex.map(_square, list(range(6))))
    assert refused == [3] and got == {i: i * i for i in range(6)}


def test_resume_skips_finished_runs_and_retries_errors(capsys, tmp_path):
    argv = ["sweep", "braking", "--workers", "2", "--out", str(tmp_path), *SHORT]
    assert main(argv + ["--grid", "braking.speed=5,6,7"]) == 0
    path = tmp_path / "results.csv"
    cols, rows = read_rows(path)
    # an interrupted sweep: speed 5 finished (marked so we can tell it is not run again), speed 6
    # failed, speed 7 was cut off while its row was written
    original = [r["min_distance_m"] for r in rows]
    rows[0]["min_distance_m"] = "123.0"
    rows[1].update(status="error", error="RuntimeError: boom", min_distance_m="")
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=cols, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows[:2])
        fh.write("7.0,0,braking,indep")  # the row being written when the sweep was killed
    capsys.readouterr()
    assert main(argv + ["--grid", "braking.speed=5,6,7", "--resume"]) == 0
    assert "resuming: 1 of 3 runs already in" in capsys.readouterr().err
    _, resumed = read_rows(path)
    assert [(r["braking.speed"], r["status"]) for r in resumed] == [("5.0", "ok"), ("6.0", "ok"), ("7.0", "ok")]
    assert resumed[0]["min_distance_m"] == "123.0"  # kept, not run again
    assert [r["min_distance_m"] for r in resumed[1:]] == original[1:]  # run (again)
    assert "| 5.0 | 1/1 |" in (tmp_path / "summary.md").read_text()


def test_resume_refuses_another_sweep(capsys, tmp_path):
    argv = ["sweep", "braking", "--grid", "braking.speed=5", "--out", str(tmp_path), *SHORT]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(argv + ["--resume", "--set", "braking.gap=8"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sweep.json: sets: expected the same --set overrides" in err[0]
    assert main(["sweep", "braking", "--grid", "braking.gap=7", "--out", str(tmp_path), "--resume", *SHORT]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "results.csv: columns: expected the grid keys of this sweep (braking.gap)" in err[0]


def test_executor_map_yields_exceptions_and_results():
    with sweep.Executor(workers=2) as ex:
        got = dict(ex.map(_reciprocal, [1, 0, 4]))
    assert got[0] == 1.0 and got[2] == 0.25 and isinstance(got[1], ZeroDivisionError)


def _reciprocal(x: float) -> float:
    return 1 / x


def test_resumed_rows_keep_their_provenance_as_written(tmp_path):
    """A scenario hash or a commit that reads as a number (5394e80056649392 is 5394 x 10^80056649392)
    comes back as the text it was, so a resumed results.csv is the file it was."""
    keys = ["controller.barrier"]
    row = {c: "" for c in sweep.columns(keys)} | {"controller.barrier": "cbf", "seed": "0", "status": "ok",
                                                   "scenario_hash": "5394e80056649392", "git_commit": "1234567e12"}
    path = tmp_path / "results.csv"
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=sweep.columns(keys), lineterminator="\n")
        writer.writeheader()
        writer.writerow(row)
    (back,) = sweep.read_results(path, keys)
    assert back["scenario_hash"] == "5394e80056649392" and back["git_commit"] == "1234567e12" and back["seed"] == 0
