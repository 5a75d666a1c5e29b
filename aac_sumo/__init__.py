"""aac-sumo: Alternative Authority Control with MPC-FCBF, in SUMO and an internal simulator.

The Python API (docs/api.md)::

    from aac_sumo import load_scenario, run
    result = run(load_scenario("swarm_rescue", ["controller.horizon=5"]))
    result.metrics, result.steps, result.trajectories

The names below load their modules on first use, so that ``import aac_sumo`` stays cheap.
"""

from __future__ import annotations

import os

# One run, one result on any x86-64 machine with AVX2: numpy's AVX-512 kernels and OpenBLAS's
# per-CPU kernels round differently in the last bit, and a committed-plan run turns such a bit
# into other decisions (docs/reliability.md, "Reproducible runs"). Set before numpy is imported;
# a value already in the environment wins.
os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", "X86_V4 AVX512_ICL AVX512_SPR")
os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")

import importlib  # noqa: E402
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("aac-sumo")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "unknown"

#: Public name -> (module, attribute).
_API = {
    "load_scenario": ("aac_sumo.config", "load"),
    "Scenario": ("aac_sumo.config", "Scenario"),
    "ScenarioError": ("aac_sumo.config", "ScenarioError"),
    "Key": ("aac_sumo.config", "Key"),
    "run": ("aac_sumo.runs.runner", "run"),
    "write_outputs": ("aac_sumo.views.outputs", "write_outputs"),
    "RunResult": ("aac_sumo.runs.recording", "RunResult"),
    "read_run": ("aac_sumo.runs.files", "read_run"),
    "register_experiment": ("aac_sumo.registry", "register_experiment"),
    "register_coordinator": ("aac_sumo.registry", "register_coordinator"),
}
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name not in _API:
        raise AttributeError(f"module 'aac_sumo' has no attribute {name!r}")
    module, attribute = _API[name]
    return getattr(importlib.import_module(module), attribute)
