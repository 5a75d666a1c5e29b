"""aac-sumo stress: draws are a pure function of the seed and the run index, every draw loads and
builds, outcomes are classified as documented, and a small campaign writes stress.csv and
stress.md whose commands reproduce its runs, and resumes."""

from __future__ import annotations

import csv
import json
import shlex
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.stress import campaign as stress
from aac_sumo.stress.plan import COMMON_KEYS, DESCRIPTIVE, HORIZONS, KINDS, Campaign, draw, plan, prepare
from aac_sumo.stress.roads import ROAD_VARIANTS, road_variants
from aac_sumo.cli.app import main
from aac_sumo.experiments import build
from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.runs.provenance import PROVENANCE_KEYS

ALL = [k for k, v in KINDS.items() if v.baseline is None]  # ours; the baselines' kinds draw the same


def test_draws_are_a_pure_function_of_seed_and_index(tmp_path):
    first = plan(10, ALL, 3, tmp_path)
    assert first == plan(10, ALL, 3, tmp_path)
    assert plan(4, ALL, 3, tmp_path) == first[:4]  # a longer campaign begins with the shorter one
    other = plan(10, ALL, 4, tmp_path)
    assert all(a.sets != b.sets for a, b in zip(first, other))
    assert [d.kind for d in first] == ALL + ALL  # dealt in turn
    assert road_variants(3) == road_variants(3) != road_variants(4)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_every_draw_loads_and_states_its_values(seed):
    for d in plan(10, ALL, seed, Path("out/stress")):  # plan() loads each through the config loader
        spec = KINDS[d.kind]
        assert set(d.values) == {"scenario.duration", *COMMON_KEYS, *spec.keys}
        assert d.sets[-1] == f"scenario.seed={d.seed}"
        scenario = config.load(spec.scenario, list(d.sets))
        assert scenario["controller.horizon"] in HORIZONS
        assert scenario["controller.coordinator"] in ("aac", "lfc") and scenario["controller.barrier"] in ("cbf", "fcbf")
        assert scenario["scenario.duration"] == spec.duration
        for key, value in d.values.items():
            if key not in DESCRIPTIVE:
                assert f"{key}={value}" in d.sets


def test_drawn_worlds_build(tmp_path):
    """The geometric checks of the experiments (overlapping starts, goals in debris, cones on
    cars, a road too short) pass for draws of every kind, on every generated road."""
    draws = plan(8, ["swarm", "circle", "crossing", "braking"], 0, tmp_path)
    one_per_road = {d.values["road"]: d for d in plan(12, ["lane-change"], 0, tmp_path)}
    assert len(one_per_road) == ROAD_VARIANTS and "straight" in one_per_road
    draws += list(one_per_road.values())
    prepare(draws, 0, tmp_path)
    for d in draws:
        setup = build(config.load(d.scenario, list(d.sets)))
        if d.kind == "lane-change":
            assert sum(o.kind == "cone" for o in setup.sim.observe().obstacles) == len(d.values["cones"].split())
            setup.sim.close()


def row(**kw) -> dict:
    return {"status": "ok", "collisions": 0, "sim_collisions": None, "completed": False, "deadlock": False} | kw


@pytest.mark.parametrize("fields, expected", [
    (dict(completed=True), "completed"),
    (dict(deadlock=True), "deadlock"),
    ({}, "timeout"),
    (dict(collisions=2, completed=False), "collision"),
    (dict(sim_collisions=1, completed=True), "collision"),  # SUMO saw a collision our check did not
    (dict(collisions=1, status="error", error="RuntimeError: x"), "collision"),
    (dict(status="error", error="WorkerDied: ...", collisions=None, completed=None, deadlock=None), "error"),
    (dict(status="error", error="RuntimeError: x", completed=False), "error"),
])
def test_outcome(fields, expected):
    assert stress.outcome(row(**fields)) == expected


def read(path: Path) -> tuple[list[str], list[dict]]:
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


@pytest.mark.slow  # three worker processes and three runs: ~25 s on a loaded 2-core machine
def test_small_campaign_reproduces_and_resumes(capsys, tmp_path):
    out = tmp_path / "stress"
    args = ["stress", "--kinds", "braking,circle", "--seed", "27", "--duration", "1", "--workers", "1", "--no-progress",
            "--out", str(out)]  # seed 27: horizon 5 in both runs, 5 robots in the circle
    assert main(args + ["--runs", "1"]) == 0, capsys.readouterr().err
    cols, rows = read(out / "stress.csv")
    assert cols[:3] == ["run", "kind", "outcome"] and cols[-1] == "command"
    assert set(METRIC_KEYS) | set(PROVENANCE_KEYS) | {"status", "error", "scenario.duration", "braking.speed"} <= set(cols)
    assert [(r["run"], r["kind"], r["status"], r["outcome"]) for r in rows] == [("0", "braking", "ok", "timeout")]
    text = (out / "stress.md").read_text()
    assert "| braking | 1 | 0 | 0 | 0 | 1 | 0 |" in text and "## Per coordinator and barrier" in text
    assert f"**timeout**: time limit 1.0 s reached  \n  `{rows[0]['command']}`" in text

    # the command reproduces the run
    command = shlex.split(rows[0]["command"])
    assert command[:3] == ["aac-sumo", "run", "braking"]
    assert main(command[1:] + ["--out", str(tmp_path / "again")]) == 0
    again = json.loads((tmp_path / "again" / "metrics.json").read_text())
    assert float(rows[0]["min_clearance_m"]) == pytest.approx(again["min_clearance_m"], abs=1e-9)
    assert str(again["seed"]) == rows[0]["seed"]

    # a longer campaign resumed: the finished run is kept (its wall-time figures too), one new run
    capsys.readouterr()
    assert main(args + ["--runs", "2", "--resume"]) == 0
    assert "resuming: 1 of 2 runs already" in capsys.readouterr().err
    _, resumed = read(out / "stress.csv")
    assert resumed[0]["realtime_factor"] == rows[0]["realtime_factor"]
    assert [(r["run"], r["kind"]) for r in resumed] == [("0", "braking"), ("1", "circle")]

    assert main(args + ["--runs", "2", "--resume", "--seed", "8"]) == 2  # another campaign's folder
    assert "seed: expected the interrupted campaign's 27, got 8" in capsys.readouterr().err


@pytest.mark.parametrize("flags, message", [
    (["--kinds", "swarm,flying"], "--kinds 'swarm,flying': expected comma-separated names among swarm, circle"),
    (["--runs", "0"], "--runs: expected an integer >= 1"),
    (["--seed", "-1"], "--seed -1: expected an integer >= 0"),
    (["--duration", "0"], "--duration 0.0: expected a number of seconds > 0"),
])
def test_bad_flags_exit_2_with_one_line(capsys, tmp_path, flags, message):
    assert main(["stress", "--out", str(tmp_path), *flags]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.slow
def test_ci_subset_has_no_collision_and_no_error(capsys, tmp_path):
    """The CI subset: 20 seeded runs of the goal-reaching kinds, each at most 10 s of simulated
    time (wall time in docs/reliability.md). Braking is left out: at horizon 5 it collides
    (docs/reliability.md, "Collisions the CI subset leaves out")."""
    rc = main(["stress", "--runs", "20", "--kinds", "swarm,circle,crossing", "--seed", "0", "--duration", "10",
               "--workers", "2", "--no-progress", "--out", str(tmp_path)])
    _, rows = read(tmp_path / "stress.csv")
    assert len(rows) == 20
    assert rc == 0, (tmp_path / "stress.md").read_text()


def test_baselines_are_kinds_of_their_own_whose_collisions_are_not_failures_of_ours():
    """``orca-circle`` draws as ``circle`` does and runs ORCA; a collision there is reported in its
    row but does not count against our coordinators; the default kinds are ours alone."""
    from aac_sumo.cli.app import build_parser

    drawn = draw(Campaign(7, Path("/tmp/unused")), 0, ["orca-circle"])
    assert drawn.values["controller.coordinator"] == "orca" and "circle_swap.n_robots" in drawn.values
    assert stress.is_baseline({"kind": "orca-circle"}) and not stress.is_baseline({"kind": "circle"})
    default = build_parser().parse_args(["stress"]).kinds.split(",")
    assert default == ["swarm", "circle", "crossing", "lane-change", "braking"]
