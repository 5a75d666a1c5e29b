"""A user's install: the bundled scenarios and networks are package data (aac_sumo.config.package_data),
`python -m build` gives a wheel and an sdist without warnings, and the wheel installed into a
fresh venv runs from another folder (issue 36)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

from aac_sumo import config
from aac_sumo.config import package_data
from aac_sumo.cli.app import main

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
#: docs/lane_change.md's netconvert output, written beside the OSM example and not bundled.
NOT_BUNDLED = {"osm_example/example.net.xml"}


def wheel_files(clone: Path) -> set[str]:
    """Every file the wheel of ``clone`` must carry, as its path inside the wheel: each module,
    scenario and network file."""
    modules = {p.relative_to(clone).as_posix() for p in (clone / "aac_sumo").rglob("*.py")}
    scenarios = {f"aac_sumo/_bundled/scenarios/{p.name}" for p in (clone / "scenarios").glob("*.toml")}
    networks = {p.relative_to(clone / "sumo_networks").as_posix() for p in (clone / "sumo_networks").rglob("*") if p.is_file()}
    return modules | scenarios | {f"aac_sumo/_bundled/sumo_networks/{n}" for n in networks - NOT_BUNDLED}


def test_a_checkout_finds_its_own_scenarios_and_networks():
    assert package_data.scenarios_dir() == ROOT / "scenarios" == config.BUNDLED_DIR
    assert package_data.networks_dir() == ROOT / "sumo_networks"
    assert (package_data.networks_dir() / "lane_change" / "lane_change.net.xml").is_file()


def test_a_bundled_name_is_found_from_any_folder_even_beside_a_folder_of_that_name(tmp_path, monkeypatch):
    (tmp_path / "braking").mkdir()  # e.g. an earlier run's --out braking
    monkeypatch.chdir(tmp_path)
    assert config.resolve("braking") == ROOT / "scenarios" / "braking.toml"


def test_with_nothing_bundled_scenarios_and_run_say_so_in_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(config, "BUNDLED_DIR", tmp_path / "scenarios")
    monkeypatch.chdir(tmp_path)
    assert main(["scenarios"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("aac-sumo: error: no bundled scenarios in "), err
    assert main(["run", "braking"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "a bundled name (none is bundled in " in err[0], err


def _run(args, cwd, env, timeout=600) -> str:
    done = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(map(str, args))}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout + done.stderr


def _copy_checkout(dest: Path) -> Path:
    """The checkout as a user's clone would build it: without the venv, outputs or build leftovers."""
    ignore = shutil.ignore_patterns(".git", ".venv", "out", "build", "dist", "*.egg-info", "__pycache__",
                                    ".pytest_cache", ".hypothesis", "example.net.xml")
    return Path(shutil.copytree(ROOT, dest, ignore=ignore))


def _documented_example() -> str:
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


@pytest.mark.slow
def test_the_wheel_installed_in_a_fresh_venv_runs_from_another_folder(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE", "VIRTUAL_ENV")}
    dist, venv, elsewhere = tmp_path / "dist", tmp_path / "venv", tmp_path / "elsewhere"
    elsewhere.mkdir()
    try:
        # A wheel and an sdist (the wheel is built from the sdist), without a warning.
        clone = _copy_checkout(tmp_path / "clone")
        out = _run([sys.executable, "-m", "build", "--outdir", dist, clone], tmp_path, env)
        warnings = [line for line in out.splitlines() if re.search(r"warn|deprecat", line, re.I)]
        assert not warnings, "\n".join(warnings)
        wheel, = dist.glob("aac_sumo-*.whl")
        assert len(list(dist.glob("aac_sumo-*.tar.gz"))) == 1
        missing = wheel_files(clone) - set(zipfile.ZipFile(wheel).namelist())
        assert not missing, sorted(missing)

        # A fresh venv with the wheel; every command from a folder that is not the checkout.
        _run([sys.executable, "-m", "venv", venv], tmp_path, env)
        _run([venv / "bin" / "python", "-m", "pip", "install", "--quiet", "--no-compile", wheel], tmp_path, env, timeout=900)
        tool, python = venv / "bin" / "aac-sumo", venv / "bin" / "python"
        version = PYPROJECT["project"]["version"]
        assert _run([tool, "--version"], elsewhere, env).strip() == f"aac-sumo {version}"
        listed = [line.split()[0] for line in _run([tool, "scenarios"], elsewhere, env).splitlines()]
        assert listed == sorted(p.stem for p in (ROOT / "scenarios").glob("*.toml"))

        # The installed package, not the checkout; the bundled highway's ../sumo_networks/ config
        # and the lane change's default network resolve inside it.
        where = _run([python, "-c", (
            "import aac_sumo, aac_sumo.config.package_data as d; from aac_sumo import load_scenario\n"
            "from aac_sumo.experiments.lane_change import network_files\n"
            "print(aac_sumo.__file__); print(d.root())\n"
            "for name in ('highway_work_zone', 'lane_change'):\n"
            "    net, routes = network_files(load_scenario(name)); print(net.resolve()); [print(r.resolve()) for r in routes]\n"
        )], elsewhere, env).splitlines()
        site = (venv / "lib").resolve()
        assert all(Path(line).resolve().is_relative_to(site) and Path(line).exists() for line in where), where
        assert any(line.endswith("highway_work_zone.net.xml") for line in where) and any(line.endswith("lane_change.net.xml") for line in where)

        _run([tool, "run", "braking", "--set", "scenario.duration=6", "--out", "braking"], elsewhere, env)
        braking = json.loads((elsewhere / "braking" / "metrics.json").read_text())
        assert braking["completed"] and braking["collisions"] == 0 and braking["git_commit"] is None

        _run([tool, "run", "lane_change", "--set", "scenario.duration=5", "--out", "lane_change"], elsewhere, env)
        lane_change = json.loads((elsewhere / "lane_change" / "metrics.json").read_text())
        assert lane_change["collisions"] == 0 and lane_change["sumo_version"]

        (elsewhere / "api_example.py").write_text(_documented_example())
        lines = _run([python, "api_example.py"], elsewhere, env).splitlines()
        assert any(line.startswith("aac: collisions 0,") for line in lines), lines
    finally:
        shutil.rmtree(venv, ignore_errors=True)  # 1.7 GB; pytest keeps its last three temporary folders
