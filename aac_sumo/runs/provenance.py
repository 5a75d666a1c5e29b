"""Where a run's figures come from: the package, SUMO, casadi and Python versions, the git commit
of the checkout it ran from, and a hash of the full scenario that ran."""

from __future__ import annotations

import hashlib
import platform
import subprocess
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import casadi

#: The provenance keys, in the order metrics.json and results.csv carry them.
PROVENANCE_KEYS = ("aac_sumo_version", "git_commit", "sumo_version", "casadi_version", "python_version", "scenario_hash")


def _version(dist: str) -> str | None:
    try:
        return version(dist)
    except PackageNotFoundError:
        return None


@lru_cache(maxsize=None)
def git_commit() -> str | None:
    """The commit of the git checkout the package is imported from (:func:`commit_of`)."""
    return commit_of(Path(__file__).resolve().parent)


def commit_of(folder: Path) -> str | None:
    """The commit of the git checkout holding ``folder``, with ``-dirty`` when it has uncommitted
    changes to tracked files outside its ``docs/`` (where ``make results`` writes the figures it
    generates, which make no run differ); None outside a checkout (an installed wheel)."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=folder, capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ":(top)", ":(top,exclude)docs"],
                               cwd=folder, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("-dirty" if dirty else "")


def provenance(scenario_toml: str) -> dict:
    """The provenance keys of a run of the scenario whose full TOML text is ``scenario_toml``;
    ``scenario_hash`` is the first 16 hex digits of its SHA-256."""
    return dict(
        aac_sumo_version=_version("aac-sumo"),
        git_commit=git_commit(),
        sumo_version=_version("eclipse-sumo"),
        casadi_version=casadi.__version__,
        python_version=platform.python_version(),
        scenario_hash=hashlib.sha256(scenario_toml.encode()).hexdigest()[:16],
    )
