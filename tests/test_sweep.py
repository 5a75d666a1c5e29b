"""Sweeps and tables through the process pool: rows, columns, error rows, validation first."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from aac_sumo import sweep, tables
from aac_sumo.cli import main
from aac_sumo.metrics import METRIC_KEYS

SHORT = ["--set", "controller.horizon=5", "--set", "scenario.duration=3", "--no-progress"]


def read_rows(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


def test_grid_sweep_two_workers(capsys, tmp_path):
    rc = main(["sweep", "braking", "--grid", "braking.speed=5,6", "--workers", "2", "--out", str(tmp_path), *SHORT])
    assert rc == 0, capsys.readouterr().err
    cols, rows = read_rows(tmp_path / "results.csv")
    assert cols == ["braking.speed", "seed"] + [k for k in METRIC_KEYS if k != "seed"] + ["status", "error"]
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
    assert len(err.splitlines()) == 1 and "controller.horizon" in err
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
    assert cols[:2] == ["barrier", "speed"]
    assert {"infeasibility_rate", "min_distance_m", "ttc_mean_s", "collisions", "min_clearance_m",
            "paper_infeasibility_rate", "paper_min_distance_m", "paper_ttc_mean_s"} <= set(cols)
    assert not any(c.endswith("_std") for c in cols)
    assert [(r["barrier"], r["speed"]) for r in rows] == [(b, str(s)) for s in (5, 10, 15, 20, 25) for b in ("cbf", "fcbf")]
    paper = {(r["barrier"], r["speed"]): (r["paper_infeasibility_rate"], r["paper_min_distance_m"]) for r in rows}
    assert paper[("cbf", "5")] == ("0.433", "1.5")
    assert paper[("cbf", "15")] == ("1.0", "")
    assert paper[("fcbf", "25")] == ("", "")
    md = (tmp_path / "table.md").read_text()
    assert "| CBF | 5 |" in md and "43.3%" in md and "—" in md
    assert md in capsys.readouterr().out
    assert len(read_rows(tmp_path / "results.csv")[1]) == 10


def test_table_rows_with_seeds():
    runs = [{"braking.speed": 5.0, "controller.barrier": "cbf", "status": "ok", "min_distance_m": d,
             "infeasibility_rate": 0.0, "ttc_mean_s": None, "collisions": 0, "min_clearance_m": 0.1}
            for d in (1.0, 2.0)]
    runs.append({"braking.speed": 5.0, "controller.barrier": "cbf", "status": "error", "min_distance_m": 9.0})
    (row,) = tables.braking_rows(runs, seeds=3)
    assert row["min_distance_m"] == 1.5 and row["min_distance_m_std"] == pytest.approx(math.sqrt(0.5))
    assert math.isnan(row["ttc_mean_s"]) and row["runs"] == 2 and row["errors"] == 1
    assert row["paper_min_distance_m"] == 1.50
    assert "min_distance_m_std" in tables.braking_columns(3)
