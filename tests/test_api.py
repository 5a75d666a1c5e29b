"""The documented Python API: docs/api.md's example runs exactly as written."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def documented_example() -> str:
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def test_the_documented_example_runs_as_written(tmp_path):
    """In a fresh process (registering changes the schema for the rest of the process)."""
    done = subprocess.run([sys.executable, "-c", documented_example()], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    selfish = next(line for line in lines if line.startswith("selfish:"))
    aac = next(line for line in lines if line.startswith("aac:"))
    assert "collisions 0" not in selfish and "collisions 0," in aac
    status, speed = re.search(r"^exit status (\d+), top speed ([\d.]+) m/s$", done.stdout, flags=re.M).groups()
    assert status == "0" and 0.3 < float(speed) <= 0.4 + 3.0 * 0.1  # the key's cap, plus one period at robot.a_max
    assert "head_on.toml --set: selfish.max_sped: expected a known key (did you mean selfish.max_speed?)" in lines


def test_the_package_exports_the_api_lazily():
    code = ("import sys, aac_sumo; assert 'aac_sumo.runs.runner' not in sys.modules; "
            "from aac_sumo import load_scenario, run, Scenario, register_experiment, register_coordinator; "
            "print(aac_sumo.__version__)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip()


def _imported_env(env: dict) -> list[str]:
    """What ``import aac_sumo`` leaves of the CPU-dispatch pins, and whether numpy came with it."""
    code = ("import os, sys, aac_sumo; print('numpy' in sys.modules); "
            "print(os.environ['NPY_DISABLE_CPU_FEATURES']); print(os.environ['OPENBLAS_CORETYPE'])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def test_importing_the_package_pins_numpy_and_openblas_kernels_before_numpy_loads():
    clean = {k: v for k, v in os.environ.items() if k not in ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")}
    assert _imported_env(clean) == ["False", "X86_V4 AVX512_ICL AVX512_SPR", "Haswell"]


def test_a_users_own_cpu_dispatch_settings_win():
    env = dict(os.environ, NPY_DISABLE_CPU_FEATURES="X86_V3", OPENBLAS_CORETYPE="Prescott")
    assert _imported_env(env) == ["False", "X86_V3", "Prescott"]
