"""Nothing lost: a sweep killed outright and resumed loses only the runs in flight; a Dask worker
that dies costs only its own run, which becomes an error row. (SIGINT and SIGTERM on
``aac-sumo run``: tests/test_cli.py, "interrupted".)"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aac_sumo.runs import sweep

AAC_SUMO = str(Path(sys.executable).parent / "aac-sumo")
SHORT = ["--set", "controller.horizon=5", "--set", "controller.codegen=false", "--set", "scenario.duration=3", "--no-progress"]


def finished_rows(path: Path, grid_keys: list[str]) -> list[dict]:
    """The complete rows of ``results.csv`` as written (text), the way ``--resume`` reads them."""
    if not path.exists():
        return []
    try:
        seeds = {str(r["seed"]) for r in sweep.read_results(path, grid_keys)}
    except sweep.SweepError:  # the header itself is not written yet
        return []
    with open(path, newline="") as fh:
        return [r for r in csv.DictReader(fh) if r["seed"] in seeds]


@pytest.mark.slow
def test_a_sweep_killed_outright_and_resumed_reruns_only_the_runs_in_flight(tmp_path):
    """SIGKILL on the sweep's whole process group once a run has finished; ``--resume`` then keeps
    every row written before the kill as it was (timings and provenance included, so they were
    not run again) and runs the rest: every run appears exactly once."""
    out, seeds = tmp_path / "sweep", 6
    cmd = [AAC_SUMO, "sweep", "braking", "--grid", "braking.speed=5", "--seeds", str(seeds), "--workers", "1",
           "--out", str(out), *SHORT]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        while not finished_rows(out / "results.csv", ["braking.speed"]) and proc.poll() is None:
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the sweep ended before it could be killed"
    before = finished_rows(out / "results.csv", ["braking.speed"])
    assert 1 <= len(before) < seeds

    done = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert f"resuming: {len(before)} of {seeds} runs already in" in done.stderr
    with open(out / "results.csv", newline="") as fh:
        after = list(csv.DictReader(fh))
    assert sorted(int(r["seed"]) for r in after) == list(range(seeds))
    assert all(r["status"] == "ok" for r in after)
    by_seed = {r["seed"]: r for r in after}
    for row in before:
        assert by_seed[row["seed"]] == row


def _kill_worker_on_seed_1(task: sweep.Task) -> dict:
    """A run that kills its worker process (as the kernel's OOM killer would) on seed 1; the
    others return an ok row at once."""
    if task.seed == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return dict(task.grid) | {"seed": task.seed, "status": "ok", "error": ""}


@pytest.mark.slow
def test_a_killed_dask_worker_becomes_an_error_row(tmp_path):
    """On a real Dask cluster, the run whose worker is killed becomes a ``status=error`` row
    naming KilledWorker (the scheduler gives up on it at once: allowed-failures 0); the nanny
    restarts the worker and every other run is ok."""
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    tasks = sweep.plan_tasks("braking", [], [("braking.speed", ["5"])], seeds=4)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0, "distributed.scheduler.worker-saturation": 1.0}):
        with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                      dashboard_address=None) as cluster:
            rows = sweep.run_tasks(tasks, ["braking.speed"], tmp_path, progress=False,
                                   scheduler=cluster.scheduler_address, fn=_kill_worker_on_seed_1)
    assert [(r["seed"], r["status"]) for r in rows] == [(0, "ok"), (1, "error"), (2, "ok"), (3, "ok")]
    assert rows[1]["error"].startswith("KilledWorker")
    with open(tmp_path / "results.csv", newline="") as fh:
        written = list(csv.DictReader(fh))
    assert [(r["seed"], r["status"]) for r in written] == [("0", "ok"), ("1", "error"), ("2", "ok"), ("3", "ok")]
    assert "KilledWorker" in written[1]["error"]


def test_a_sweep_killed_outright_leaves_no_worker_behind(tmp_path):
    """SIGKILL on the sweep process alone (not its process group): its pool's workers notice
    that their parent is gone and end within seconds. (Killed so, or by SIGTERM, a sweep's
    workers used to live on, polling for work that never came.)"""
    out = tmp_path / "sweep"
    cmd = [AAC_SUMO, "sweep", "braking", "--grid", "braking.speed=5", "--seeds", "20", "--workers", "2", "--out", str(out), *SHORT]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        while not finished_rows(out / "results.csv", ["braking.speed"]) and proc.poll() is None:
            time.sleep(0.05)
        children = [int(pid) for pid in Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()]
        workers = [pid for pid in children if "spawn_main" in Path(f"/proc/{pid}/cmdline").read_text()]
        assert workers, "the sweep ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)  # the parent dies at once, without cleaning up
        proc.wait()
        end = time.monotonic() + 30.0
        while time.monotonic() < end and any(Path(f"/proc/{pid}").exists() and "Z" not in _state(pid) for pid in workers):
            time.sleep(0.1)
        assert not [pid for pid in workers if Path(f"/proc/{pid}").exists() and "Z" not in _state(pid)]
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _state(pid: int) -> str:
    try:
        return next(line for line in Path(f"/proc/{pid}/status").read_text().splitlines() if line.startswith("State:"))
    except (FileNotFoundError, StopIteration):
        return "Z"
