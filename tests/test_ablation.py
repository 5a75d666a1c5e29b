"""The ablation table: every variant of a case on the same seeds, each changing only its own keys,
and the baselines that drive the case's kind when they are installed."""

from __future__ import annotations

import csv

import pytest

from aac_sumo import config
from aac_sumo.cli.app import main
from aac_sumo.tables.ablation import AAC_PLAIN, VARIANTS, gains, variants_for


def test_every_variant_is_a_valid_set_of_keys_on_every_case_and_the_paper_rows_have_no_extension():
    for scenario in ("swarm_rescue", "circle_swap", "random_crossing", "lane_change", "highway_work_zone"):
        for name, _, overrides in variants_for(config.load(scenario)["scenario.kind"]):
            loaded = config.load(scenario, list(overrides))
            if name in ("aac_paper", "aac_committed"):
                assert not loaded["aac.safety_stop"] and not loaded["aac.make_room"] and not loaded["aac.detour"]
                assert not loaded["aac.manoeuvre"]
                assert loaded["aac.commit"] is (name == "aac_committed")
            if name == "lfc_paper":
                assert not loaded["lfc.commit"] and not loaded["lfc.safety_stop"]
    assert all(key.split("=")[0].startswith("aac.") for key in AAC_PLAIN)
    assert [v[0] for v in VARIANTS] == ["aac_paper", "aac_committed", "aac_all", "lfc_paper", "lfc_committed"]


def test_gains_compare_each_step_with_the_one_before():
    rows = [{"variant": "aac_paper", "completed": 0.0, "collisions": 6.0, "task_duration_s": float("nan")},
            {"variant": "aac_committed", "completed": 0.5, "collisions": 0.0, "task_duration_s": 20.0},
            {"variant": "aac_all", "completed": 1.0, "collisions": 0.0, "task_duration_s": 12.0}]
    got = gains(rows)
    assert got[0] == "Committed plans (AAC): completed 0 % → 50 %, collisions 6 → 0."
    assert got[1] == "AAC's extensions: completed 50 % → 100 %, collisions 0 → 0, task -8.00 s."


@pytest.mark.slow
def test_the_ablation_of_one_case_runs_every_variant(tmp_path, capsys):
    rc = main(["table", "ablation", "--cases", "circle8", "--seeds", "1", "--workers", "2", "--no-progress",
               "--set", "scenario.duration=4", "--out", str(tmp_path)])
    assert rc == 0, capsys.readouterr().err
    with open(tmp_path / "table.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["variant"] for r in rows][:5] == [v[0] for v in VARIANTS] and {r["case"] for r in rows} == {"circle8"}
    assert all(r["errors"] == "0" for r in rows)
    assert "## circle swap, 8 robots on r = 4 m" in (tmp_path / "table.md").read_text()


def test_cases_belong_to_the_ablation_table(capsys, tmp_path):
    assert main(["table", "swarm", "--cases", "circle8", "--out", str(tmp_path / "t")]) == 2
    assert main(["table", "ablation", "--cases", "nowhere", "--out", str(tmp_path / "u")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--cases" in err[0] and "circle8" in err[1]


@pytest.mark.slow
def test_baselines_add_their_rows_to_table_one_once_without_a_horizon(tmp_path, capsys):
    rc = main(["table", "swarm", "--baselines", "--layers", "off", "--seeds", "1", "--workers", "2", "--no-progress",
               "--set", "scenario.duration=1", "--out", str(tmp_path)])
    assert rc == 0, capsys.readouterr().err
    with open(tmp_path / "table.csv") as fh:
        rows = list(csv.DictReader(fh))
    baseline = [r for r in rows if r["coordinator"] not in ("aac", "lfc")]
    assert {r["coordinator"] for r in baseline} >= {"orca"}
    assert all(r["horizon"] == "" and r["safety_layers"] == "off" and r["errors"] == "0" for r in baseline)
    assert [r["coordinator"] for r in rows][-len(baseline):] == [r["coordinator"] for r in baseline]  # after AAC and LFC
    assert "| ORCA (RVO2) | — |" in (tmp_path / "table.md").read_text()


def test_baselines_belong_to_the_tables_with_baselines(capsys, tmp_path):
    assert main(["table", "braking", "--baselines", "--out", str(tmp_path / "t")]) == 2
    assert "--baselines" in capsys.readouterr().err
