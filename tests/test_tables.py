"""Fair tables: Table I and the circle swap run AAC and LFC with the same emergency layers in
every run (``safety_layers`` off = the paper, on = both with the safety stop), say which is which,
and put the paper's values beside the ``off`` rows only."""

from __future__ import annotations

import csv
import itertools
from pathlib import Path

import pytest

from aac_sumo import config
from aac_sumo.runs import sweep
from aac_sumo.tables import common as table_common, build as tables
from aac_sumo.cli.app import main


def read_rows(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


@pytest.fixture
def planned(monkeypatch):
    """No simulation: the executor records the tasks it gets and returns one made-up ``ok`` row
    per task, so a table's whole grid is planned, aggregated and written in well under a second."""
    seen: list[tuple[list[sweep.Task], list[str]]] = []

    def run_tasks(tasks, grid_keys, out, workers=None, progress=True, desc="", scheduler=None, resume=False,
                  fn=None, manifest=None):
        seen.append((list(tasks), list(grid_keys)))
        out.mkdir(parents=True, exist_ok=True)
        return [dict(t.grid) | {"seed": t.seed, "status": "ok", "completed": True, "deadlock": False,
                                "task_duration_s": 20.0, "compute_ms_mean": 5.0, "min_distance_m": 1.0, "collisions": 0,
                                "safety_stops": 0} for t in tasks]

    monkeypatch.setattr(sweep, "run_tasks", run_tasks)
    return seen


def _without_coordinator(scenario: config.Scenario) -> dict:
    data = {section: dict(values) for section, values in scenario.data.items()}
    data["controller"].pop("coordinator")
    return data


def _check_equal_layers(tasks: list[sweep.Task]) -> None:
    """Every run has the safety stop of both coordinators as its safety_layers value says."""
    for t in tasks:
        layer = dict(t.grid)["safety_layers"]
        assert t.scenario["aac.safety_stop"] is t.scenario["lfc.safety_stop"] is (layer == "on"), t.overrides
        assert set(table_common.layer_sets(layer)) <= set(t.overrides)


def test_swarm_table_runs_both_settings_with_equal_layers(planned, capsys, tmp_path):
    assert main(["table", "swarm", "--out", str(tmp_path), "--no-progress"]) == 0, capsys.readouterr().err
    ((tasks, keys),) = planned
    assert keys == ["safety_layers", "controller.horizon", "controller.coordinator"]
    assert sorted((dict(t.grid)["safety_layers"], t.scenario["controller.horizon"], t.scenario["controller.coordinator"])
                  for t in tasks) == sorted(itertools.product(("off", "on"), (5, 10, 15), ("aac", "lfc")))
    _check_equal_layers(tasks)
    # within a cell, AAC and LFC differ in the coordinator only: same planner, weights, layers
    cells: dict[tuple, list[dict]] = {}
    for t in tasks:
        cells.setdefault((dict(t.grid)["safety_layers"], t.scenario["controller.horizon"]), []).append(
            _without_coordinator(t.scenario))
    assert len(cells) == 6 and all(len(c) == 2 and c[0] == c[1] for c in cells.values())

    cols, rows = read_rows(tmp_path / "table.csv")
    assert cols[:3] == ["coordinator", "horizon", "safety_layers"]
    assert cols.index("completed") < cols.index("paper_task_duration_s") and not any(c.endswith("_std") for c in cols)
    assert [(r["safety_layers"], r["horizon"], r["coordinator"]) for r in rows] == [
        (layer, str(h), c) for layer in ("off", "on") for h in (5, 10, 15) for c in ("aac", "lfc")]
    for r in rows:
        paper = [r[f"paper_{m}"] for m in tables.PAPER_I_METRICS]
        if r["safety_layers"] == "off":
            assert all(paper), r
        else:
            assert paper == ["", "", ""], r
    assert rows[2]["paper_task_duration_s"] == "18.1"  # AAC at N = 10

    md = (tmp_path / "table.md").read_text()
    off, on = md.split("## " + table_common.LAYER_TITLES["on"])
    assert "## " + table_common.LAYER_TITLES["off"] in off and "`aac.safety_stop = false`, `lfc.safety_stop = false`" in off
    assert "`aac.safety_stop = true`, `lfc.safety_stop = true`" in on
    assert "(paper)" in off and "18.10" in off
    assert "(paper)" not in on and "18.10" not in on
    assert md in capsys.readouterr().out


def test_layers_option_restricts_the_table_to_one_setting(planned, capsys, tmp_path):
    assert main(["table", "swarm", "--layers", "on", "--seeds", "2", "--out", str(tmp_path), "--no-progress"]) == 0
    ((tasks, _),) = planned
    assert len(tasks) == 3 * 2 * 2 and {dict(t.grid)["safety_layers"] for t in tasks} == {"on"}
    _check_equal_layers(tasks)
    cols, rows = read_rows(tmp_path / "table.csv")
    assert "task_duration_s_std" in cols
    assert {r["safety_layers"] for r in rows} == {"on"} and all(r["paper_min_distance_m"] == "" for r in rows)
    assert table_common.LAYER_TITLES["off"] not in (tmp_path / "table.md").read_text()


@pytest.mark.parametrize("argv, words", [
    (["table", "swarm", "--set", "aac.safety_stop=true"], ["aac.safety_stop", "--layers"]),
    (["table", "circle-swap", "--set", "lfc.safety_stop=false"], ["lfc.safety_stop", "--layers"]),
    (["table", "circle-swap", "--set", "circle_swap.n_robots=4"], ["circle_swap.n_robots"]),
    (["table", "braking", "--layers", "off"], ["--layers", "braking"]),
    (["table", "swarm", "--layers", "some"], ["--layers"]),
])
def test_a_table_refuses_to_run_unequal_or_mislabelled_layers(planned, capsys, tmp_path, argv, words):
    assert main(argv + ["--out", str(tmp_path / "t"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert planned == [] and not (tmp_path / "t" / "results.csv").exists()


def test_circle_swap_table_grid(planned, capsys, tmp_path):
    assert main(["table", "circle-swap", "--out", str(tmp_path), "--no-progress"]) == 0, capsys.readouterr().err
    ((tasks, keys),) = planned
    assert keys == ["safety_layers", "circle_swap.n_robots", "circle_swap.radius", "controller.coordinator"]
    assert sorted((t.scenario["circle_swap.n_robots"], t.scenario["circle_swap.radius"], t.scenario["controller.coordinator"])
                  for t in tasks) == [(n, r, c) for n, r in ((8, 4.0), (16, 6.0), (24, 8.0)) for c in ("aac", "lfc")]
    assert {dict(t.grid)["safety_layers"] for t in tasks} == {"off"}  # the default: the paper's setting
    _check_equal_layers(tasks)
    for t in tasks:
        assert (dict(t.grid)["circle_swap.n_robots"], dict(t.grid)["circle_swap.radius"]) == (
            t.scenario["circle_swap.n_robots"], t.scenario["circle_swap.radius"])

    cols, rows = read_rows(tmp_path / "table.csv")
    assert cols[:4] == ["coordinator", "n_robots", "radius", "safety_layers"]
    assert cols[4:10] == ["completed", "task_duration_s", "collisions", "deadlock", "min_distance_m", "min_clearance_m"]
    assert "compute_ms_mean" in cols and not any(c.startswith("paper_") for c in cols)
    assert [(r["coordinator"], r["n_robots"], r["radius"], r["safety_layers"]) for r in rows] == [
        (c, str(n), str(r), "off") for n, r in ((8, 4.0), (16, 6.0), (24, 8.0)) for c in ("aac", "lfc")]
    assert rows[0]["completed"] == "1.0" and rows[0]["deadlock"] == "0.0"
    md = (tmp_path / "table.md").read_text()
    assert table_common.LAYER_TITLES["off"] in md and table_common.LAYER_TITLES["on"] not in md
    assert "| AAC-MPC-FCBF | 24 | 8.0 | 100.0% |" in md

    planned.clear()
    assert main(["table", "circle-swap", "--layers", "both", "--out", str(tmp_path / "both"), "--no-progress"]) == 0
    ((tasks, _),) = planned
    assert len(tasks) == 12
    _check_equal_layers(tasks)

    planned.clear()  # the full grid: every count on every radius, the dense pairings too
    assert main(["table", "circle-swap", "--grid", "full", "--out", str(tmp_path / "full"), "--no-progress"]) == 0
    ((tasks, _),) = planned
    assert sorted((t.scenario["circle_swap.n_robots"], t.scenario["circle_swap.radius"], t.scenario["controller.coordinator"])
                  for t in tasks) == sorted(itertools.product((8, 16, 24), (4.0, 6.0, 8.0), ("aac", "lfc")))
    _, rows = read_rows(tmp_path / "full" / "table.csv")
    assert len(rows) == 18


def test_only_the_circle_swap_table_takes_a_grid(planned, capsys, tmp_path):
    assert main(["table", "swarm", "--grid", "full", "--out", str(tmp_path / "t"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--grid" in err[0] and "circle-swap" in err[0], err
    assert planned == []


def test_table_rows_give_yes_no_metrics_as_shares_and_paper_values_to_off_rows_only():
    base = {"controller.horizon": 5, "controller.coordinator": "lfc", "status": "ok", "collisions": 0}
    runs = [base | {"safety_layers": layer, "completed": done, "deadlock": not done, "task_duration_s": 20.0 if done else None}
            for layer in ("on", "off") for done in (True, False)]
    rows = tables.horizon_rows(runs, 2, ("completed", "deadlock", "task_duration_s"), tables.PAPER_TABLE_I,
                               tables.PAPER_I_METRICS)
    assert [r["safety_layers"] for r in rows] == ["off", "on"]  # off first, whatever ran first
    off, on = rows
    assert off["completed"] == off["deadlock"] == 0.5 and off["task_duration_s"] == 20.0
    assert off["paper_task_duration_s"] == 22.6 and on["paper_task_duration_s"] is None


def test_bundled_scenarios_give_both_coordinators_the_same_layers():
    for name in ("swarm_rescue", "circle_swap"):
        s = config.load(name)
        assert s["aac.safety_stop"] is False and s["lfc.safety_stop"] is False, name


def test_short_layered_table_end_to_end(monkeypatch, capsys, tmp_path):
    """A real (0.3 s) run per cell, one horizon: the results.csv of a layered table."""
    monkeypatch.setattr(tables, "HORIZONS", (5,))
    rc = main(["table", "swarm", "--workers", "1", "--set", "scenario.duration=0.3", "--out", str(tmp_path), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    cols, runs = read_rows(tmp_path / "results.csv")
    assert cols[:4] == ["safety_layers", "controller.horizon", "controller.coordinator", "seed"]
    assert [(r["safety_layers"], r["coordinator"], r["status"]) for r in runs] == [
        ("off", "aac", "ok"), ("off", "lfc", "ok"), ("on", "aac", "ok"), ("on", "lfc", "ok")]
    _, rows = read_rows(tmp_path / "table.csv")
    assert [(r["safety_layers"], r["coordinator"], r["runs"]) for r in rows] == [
        ("off", "aac", "1"), ("off", "lfc", "1"), ("on", "aac", "1"), ("on", "lfc", "1")]
