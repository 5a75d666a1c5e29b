"""The command line: one-line exit-2 errors, a real run's outputs, determinism, bench records."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aac_sumo import config
from aac_sumo.cli.app import main
from aac_sumo.metrics import METRIC_KEYS

ROOT = Path(__file__).resolve().parents[1]
FAST = ["--set", "controller.horizon=5", "--set", "braking.speed=5"]


def error_line(capsys) -> str:
    """The single stderr line of a failed command (asserts there is exactly one)."""
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("aac-sumo: error: ")
    assert "Traceback" not in err
    return lines[0]


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_unknown_set_key(capsys, tmp_path):
    assert main(["run", "braking", "--set", "controller.horizn=5", "--out", str(tmp_path)]) == 2
    line = error_line(capsys)
    assert "controller.horizn" in line and "braking.toml" in line
    assert not (tmp_path / "metrics.json").exists()


def test_wrong_type(capsys):
    assert main(["run", "braking", "--set", "controller.horizon=abc"]) == 2
    line = error_line(capsys)
    assert "controller.horizon" in line and "integer" in line


LANE_CHANGE = config.load("lane_change")
STRING_KEYS = [f"{section}.{name}" for section, keys in LANE_CHANGE.schema().items() for name, key in keys.items() if key.type is str]


@settings(max_examples=60, deadline=None)
@given(key=st.sampled_from(STRING_KEYS), text=st.text(alphabet="0123456789#", min_size=1, max_size=14))
def test_a_string_key_takes_ids_of_digits_and_hash_as_text(key, text):
    """OSM edge ids such as 153177820 or 264306385#2 are text, not a number cut at a TOML comment."""
    assert LANE_CHANGE.with_overrides([f"{key}={text}"])[key] == text


@pytest.mark.parametrize("text", [":J0_0", "-153177820", "-153177820#1", "2026-12-01", "1e5", "true"])
def test_a_string_key_takes_colons_dashes_and_number_like_text_as_text(text):
    assert LANE_CHANGE.with_overrides([f"sumo.edges={text}"])["sumo.edges"] == text
    assert LANE_CHANGE.with_overrides([f'sumo.edges="{text}"'])["sumo.edges"] == text  # quoted, as before


@pytest.mark.parametrize("text, rows", [("[1, 2], [3, 4.5]", [[1, 2], [3, 4.5]]), ("[[1, 2]]", [[1, 2]]), ("", [])])
def test_a_list_key_takes_comma_separated_items(text, rows):
    assert config.load("swarm_rescue", [f"swarm_rescue.goals={text}"])["swarm_rescue.goals"] == rows


def test_a_list_key_with_wrong_items_is_one_line(capsys):
    assert main(["run", "swarm_rescue", "--set", "swarm_rescue.goals=1,2"]) == 2
    assert "swarm_rescue.goals" in (line := error_line(capsys)) and "[x, y] rows" in line


def test_set_without_value(capsys):
    assert main(["run", "braking", "--set", "controller.horizon"]) == 2
    assert "KEY=VALUE" in error_line(capsys)


def test_bad_toml_names_file(capsys, tmp_path):
    path = write(tmp_path, "broken.toml", "[scenario\nname = 'x'\n")
    assert main(["run", str(path)]) == 2
    assert str(path) in error_line(capsys)


def test_missing_file(capsys, tmp_path):
    path = tmp_path / "nope.toml"
    assert main(["run", str(path)]) == 2
    assert "nope.toml" in error_line(capsys)
    assert main(["run", "no_such_bundled_scenario"]) == 2
    assert "no_such_bundled_scenario" in error_line(capsys)


@pytest.mark.parametrize("text, key", [
    ('[scenario]\nkind = "braking"\n[controller]\nhorizn = 5\n', "controller.horizn"),
    ('[scenario]\nkind = "braking"\n[bogus]\nx = 1\n', "bogus"),
    ('[scenario]\nkind = "braking"\n[braking]\nspeed = "fast"\n', "braking.speed"),
])
def test_unknown_or_bad_key_in_file(capsys, tmp_path, text, key):
    path = write(tmp_path, "mine.toml", text)
    assert main(["run", str(path)]) == 2
    line = error_line(capsys)
    assert str(path) in line and key in line


def test_overlapping_start(capsys):
    assert main(["run", "braking", "--set", "braking.gap=0.5"]) == 2
    line = error_line(capsys)
    assert "braking.gap" in line and "overlap" in line


@pytest.mark.parametrize("argv", [
    ["frobnicate"],
    [],
    ["table", "nonsense"],
    ["table", "swarm", "--seeds", "0"],
    ["bench", "aac", "--horizons", "0"],
    ["sweep", "braking", "--grid", "braking.speed"],
    ["sweep", "braking", "--grid", "braking.speed=5,,6"],
    ["sweep", "braking", "--seeds", "0", "--grid", "braking.speed=5"],
    ["run"],
    ["net", "info"],
    ["net", "frobnicate", "x"],
])
def test_usage_errors_are_one_line(capsys, argv):
    assert main(argv) == 2
    error_line(capsys)


def test_out_is_a_file(capsys, tmp_path):
    path = write(tmp_path, "file", "")
    assert main(["run", "braking", "--out", str(path)]) == 2
    assert str(path) in error_line(capsys)


def test_subprocess_error_has_no_traceback(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-m", "aac_sumo.cli", "run", "braking", "--set", "controller.nope=1"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [proc.stderr.strip()] and "controller.nope" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_help_exits_zero(capsys):
    assert main(["--help"]) == 0
    assert "run" in capsys.readouterr().out


def test_run_writes_outputs(capsys, tmp_path):
    out = tmp_path / "run"
    assert main(["run", "braking", *FAST, "--gui", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "no GUI" in stdout and str(out) in stdout and "infeasibility_rate" in stdout
    for name in ("metrics.json", "steps.csv", "trajectories.csv", "trajectories.png"):
        assert (out / name).stat().st_size > 0, name
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(METRIC_KEYS) <= set(metrics)
    assert metrics["horizon"] == 5 and metrics["scenario"] == "braking"


def test_same_seed_same_trajectories(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["run", "braking", *FAST, "--seed", "3", "--out", str(out)]) == 0
    assert (a / "trajectories.csv").read_bytes() == (b / "trajectories.csv").read_bytes()
    assert json.loads((a / "metrics.json").read_text())["seed"] == 3


def test_bench_records(capsys, tmp_path):
    assert main(["bench", "mpc", "--samples", "3", "--horizons", "5", "--solvers", "fatrop,ipopt", "--out", str(tmp_path)]) == 0
    records = json.loads((tmp_path / "bench.json").read_text())
    assert [r["name"] for r in records] == ["mpc/fatrop", "mpc/ipopt"]
    for r in records:
        assert {"name", "horizon", "samples", "median_ms", "p95_ms", "failures"} <= set(r)
        assert r["horizon"] == 5 and r["samples"] == 3 and 0 <= r["failures"] <= 3
    fast, base = records
    assert fast["ratio_to"] == "mpc/ipopt"
    assert fast["ratio"] == pytest.approx(base["median_ms"] / fast["median_ms"])
    assert "ratio" not in base
    assert (tmp_path / "bench.md").read_text().count("mpc/") >= 2


def test_table_resumes_from_its_results(capsys, tmp_path):
    argv = ["table", "braking", "--seeds", "1", "--workers", "1", "--set", "scenario.duration=0.3", "--no-progress",
            "--out", str(tmp_path)]
    assert main(argv) == 0
    first = (tmp_path / "results.csv").read_text()
    assert main(argv + ["--resume"]) == 0
    assert (tmp_path / "results.csv").read_text() == first
    assert main(argv[:-2] + ["--set", "scenario.duration=0.4", "--out", str(tmp_path), "--resume"]) == 2  # another sweep


def test_bench_aac_pools_repeated_runs(tmp_path):
    """Each coordinator runs ``repeats`` times: the periods of all runs are pooled, the failures
    are one run's, and the real-time factor is the runs' median within their range."""
    from aac_sumo.runs import bench

    report = bench.bench_aac((5,), ("braking",), repeats=2)
    aac, lfc = report.records
    assert (aac.name, lfc.name) == ("aac/braking", "lfc/braking")
    singles = bench.bench_aac((5,), ("braking",), repeats=1).records
    for r, single in zip((aac, lfc), singles):
        assert r.runs == 2 and r.samples == 2 * single.samples
        lo, hi = r.realtime_factor_range
        assert lo <= r.realtime_factor <= hi
    assert aac.failures == singles[0].failures
    assert aac.ratio == pytest.approx(lfc.median_ms / aac.median_ms)
    assert "| aac/braking | 5 | 2 |" in bench.markdown_aac(report)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_run_keeps_what_it_recorded_and_exits_non_zero(tmp_path, sig):
    """SIGINT or SIGTERM in the middle of ``aac-sumo run``: the outputs up to that moment are
    written, metrics.json says the run was interrupted, and the command exits with 130."""
    out = tmp_path / "out"
    cmd = [str(Path(sys.executable).parent / "aac-sumo"), "run", "random_crossing", "--set", "random_crossing.n_robots=300",
           "--out", str(out)]
    # a short run first fills numba's on-disk cache, which the child then loads instead of compiling: on a fresh clone
    # compiling took longer than the 10 s below, and the signal came during start-up
    start = time.perf_counter()
    assert main(["run", "random_crossing", "--set", "random_crossing.n_robots=3", "--set", "scenario.duration=0.3",
                 "--out", str(tmp_path / "warm")]) == 0
    slowness = time.perf_counter() - start  # grows with the machine's load, as the child's start-up does
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # past start-up and warm-up (10 s idle; longer on a loaded machine, which once sent the signal during start-up),
    # long before the 300-robot crossing ends (about 200 s simulated at 1.7 times real time idle; the 100-robot one,
    # used before, had become fast enough to complete before a loaded machine's signal)
    time.sleep(min(10.0 + 3.0 * slowness, 40.0))
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["error"].startswith("interrupted at t=") and metrics["completed"] is False
    steps = (out / "steps.csv").read_text().splitlines()
    assert len(steps) > 1 + 100  # a header and at least one period of 100 robots
    assert "everything recorded until then" in err


def test_a_run_stopped_before_its_first_period_still_writes_its_files(tmp_path):
    """A stop that comes during start-up (a loaded machine) leaves metrics, empty tables and
    no pictures, rather than a traceback from drawing nothing."""
    from aac_sumo.runs import runner
    from aac_sumo.views.outputs import write_outputs

    runner.STOP.set()
    try:
        with pytest.raises(runner.RunInterrupted) as stop:
            runner.run(config.load("circle_swap", ["circle_swap.n_robots=2"]))
    finally:
        runner.STOP.clear()
    write_outputs(stop.value.result, tmp_path)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["error"] == "interrupted at t=0.00 s" and metrics["completed"] is False
    assert (tmp_path / "steps.csv").exists() and not list(tmp_path.glob("*.png"))


@pytest.mark.parametrize("command, said", [("run", "aac-sumo: interrupted while starting"),
                                           ("sweep", "aac-sumo: interrupted (finished runs are kept)")])
def test_a_ctrl_c_before_a_run_begins_says_it_was_starting(monkeypatch, capsys, command, said):
    """Ctrl-C while ``run`` loads its scenario: exit 130 and one line that says the run was
    starting (it said "finished runs are kept", a sweep's words, of a single run); a sweep
    keeps its own words."""
    from aac_sumo.cli import app

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(app, f"cmd_{command}", interrupted)
    argv = ["run", "lane_change"] if command == "run" else ["sweep", "lane_change", "--grid", "controller.horizon=5"]
    assert app.main(argv) == 130
    assert capsys.readouterr().err.splitlines() == [said]


def test_a_ctrl_c_that_python_swallowed_while_loading_still_ends_the_command_with_130(monkeypatch, capsys, tmp_path):
    """A KeyboardInterrupt raised inside a callback of the import machinery is only reported as
    "Exception ignored" and the program goes on (a fresh clone's CI saw a run that Ctrl-C hit so
    finish with 0). The hook notes it without a traceback, and the command stops with 130 and one line."""
    import types

    import aac_sumo.cli as cli
    from aac_sumo.cli import app, interrupt

    parser = app.build_parser()

    def parse_args(argv):
        sys.unraisablehook(types.SimpleNamespace(exc_type=KeyboardInterrupt))  # as Python reports a swallowed one
        return parser.parse_args(argv)

    monkeypatch.setattr(app, "build_parser", lambda: types.SimpleNamespace(parse_args=parse_args))
    assert cli.main(["run", "swarm_rescue", "--out", str(tmp_path / "out")]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "interrupted" in err[0]
    assert not (tmp_path / "out").exists()
    assert not interrupt.INTERRUPTED.is_set() and sys.unraisablehook is not interrupt._unraisable  # left as before
