"""A user's .sumocfg in, the bundled .sumocfg out, and options passed through to SUMO (real
SUMO binaries and libsumo, no mocks)."""

from __future__ import annotations

import shutil
import subprocess
import tomllib
from pathlib import Path

from aac_sumo import config, network
from aac_sumo.runs.files import write_run
from aac_sumo.runs import runner
from aac_sumo.cli.app import main
from aac_sumo.experiments.lane_change import BUNDLED_NET_DIR
from aac_sumo.sim.sumo_options import SumoOptions

BUNDLED_CFG = BUNDLED_NET_DIR / "lane_change.sumocfg"
SHORT = ["controller.coordinator=independent", "controller.horizon=5", "lane_change.vehicles=3", "scenario.duration=1.0"]


def write_config(path: Path, net: str | None = str(BUNDLED_NET_DIR / "lane_change.net.xml"), step: str = "0.1") -> Path:
    net_line = f'<net-file value="{net}"/>' if net else ""
    path.write_text(f'<configuration><input>{net_line}<route-files value="{BUNDLED_NET_DIR / "cones.rou.xml"},'
                    f'{BUNDLED_NET_DIR / "pedestrians.rou.xml"}"/></input><time><step-length value="{step}"/></time></configuration>')
    return path


def test_the_bundled_network_ships_a_config_that_sumo_opens():
    done = subprocess.run([network.sumo_binary("sumo"), "-c", str(BUNDLED_CFG), "--end", "1", "--no-step-log"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_a_run_on_the_bundled_config_is_the_bundled_run():
    """The config names the bundled net and route files: the run is the same, pose for pose."""
    plain = runner.run(config.load("lane_change", SHORT)).trajectories
    configured = runner.run(config.load("lane_change", SHORT + [f"sumo.config={BUNDLED_CFG}"])).trajectories
    assert plain[["x", "y", "heading"]].equals(configured[["x", "y", "heading"]])


def test_the_scenario_overrides_a_config_step_length_and_says_so_in_one_line(tmp_path, capsys):
    cfg = write_config(tmp_path / "my.sumocfg", step="1.0")
    result = runner.run(config.load("lane_change", SHORT + [f"sumo.config={cfg}"]))
    assert len(result.periods) == 10  # 1 s at the scenario's 0.1 s, not SUMO's 1 s
    notes = [line for line in capsys.readouterr().err.splitlines() if "note" in line]
    assert len(notes) == 1 and "step-length=1.0" in notes[0] and str(cfg) in notes[0]


def test_a_config_without_a_network_or_beside_sumo_net_is_one_line(tmp_path, capsys):
    no_net = write_config(tmp_path / "no_net.sumocfg", net=None)
    assert main(["run", "lane_change", "--set", f"sumo.config={no_net}", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sumo.config" in err and "net-file" in err
    both = write_config(tmp_path / "both.sumocfg")
    assert main(["run", "lane_change", "--set", f"sumo.config={both}", "--set", "sumo.net=other.net.xml",
                 "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sumo.net" in err
    bad = tmp_path / "bad.sumocfg"
    bad.write_text("<routes/>")
    assert main(["run", "lane_change", "--set", f"sumo.config={bad}", "--out", str(tmp_path / "c")]) == 2
    assert "SUMO configuration" in capsys.readouterr().err


def test_a_config_whose_network_is_not_built_yet_says_how_to_build_it(tmp_path, capsys):
    """A config naming a net-file that is missing beside its plain-XML sources (the OSM example
    before `aac-sumo net build`): one line naming sumo.config, the missing file and the command
    that builds it. A missing net-file with no sources beside it gets no such hint."""
    shutil.copy(BUNDLED_NET_DIR / "lane_change.edg.xml", tmp_path / "road.edg.xml")
    cfg = write_config(tmp_path / "road.sumocfg", net=str(tmp_path / "road.net.xml"))
    assert main(["run", "lane_change", "--set", f"sumo.config={cfg}", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sumo.config" in err and "road.net.xml" in err
    assert f"aac-sumo net build {tmp_path}" in err
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    cfg = write_config(tmp_path / "other.sumocfg", net=str(elsewhere / "road.net.xml"))
    assert main(["run", "lane_change", "--set", f"sumo.config={cfg}", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "net build" not in err


def test_a_network_that_is_not_built_yet_says_how_to_build_it_wherever_it_is_named(tmp_path, capsys):
    """The same hint when the missing network is named as sumo.net or given to net info: one
    line, exit 2, naming the command that builds it from the sources beside it; none for a
    missing route file there or a missing network with no sources beside it."""
    shutil.copy(BUNDLED_NET_DIR / "lane_change.edg.xml", tmp_path / "road.edg.xml")
    net = tmp_path / "road.net.xml"
    for argv in (["run", "lane_change", "--set", f"sumo.net={net}", "--out", str(tmp_path / "a")], ["net", "info", str(net)]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "road.net.xml" in err and f"aac-sumo net build {tmp_path}" in err, err
    (tmp_path / "elsewhere").mkdir()
    for argv in (["run", "lane_change", "--set", f"sumo.routes={tmp_path / 'cars.rou.xml'}", "--out", str(tmp_path / "b")],
                 ["net", "info", str(tmp_path / "elsewhere" / "road.net.xml")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "net build" not in err, err


def test_extra_arguments_go_through_and_ours_come_after_them():
    cmd = SumoOptions(Path("road.net.xml"), config=Path("my.sumocfg"), extra_args=("--lateral-resolution", "0.8")).command(0.1)
    assert cmd[1:3] == ["-c", "my.sumocfg"]
    assert cmd.index("--lateral-resolution") < cmd.index("--step-length")


def test_the_saved_scenario_reruns_the_same_run_from_another_folder(tmp_path, monkeypatch):
    """Network and route files named relative to the current folder are saved by their resolved
    paths: the saved scenario.toml, run from elsewhere, gives the same run and the same hash."""
    work, elsewhere = tmp_path / "work", tmp_path / "elsewhere"
    work.mkdir()
    elsewhere.mkdir()
    shutil.copy(BUNDLED_NET_DIR / "lane_change.net.xml", work / "my.net.xml")
    shutil.copy(BUNDLED_NET_DIR / "cones.rou.xml", work / "my_cones.rou.xml")
    monkeypatch.chdir(work)
    first = runner.run(config.load("lane_change", SHORT + ["sumo.net=my.net.xml", "sumo.routes=my_cones.rou.xml"]))
    write_run(first, work / "out")
    monkeypatch.chdir(elsewhere)
    again = runner.run(config.load(str(work / "out" / "scenario.toml")))
    assert first.trajectories[["x", "y", "heading"]].equals(again.trajectories[["x", "y", "heading"]])
    assert again.metrics["scenario_hash"] == first.metrics["scenario_hash"]
    assert again.scenario["sumo.net"] == str((work / "my.net.xml").resolve())


def test_metrics_carry_their_provenance():
    m = runner.run(config.load("lane_change", SHORT)).metrics
    assert m["aac_sumo_version"] and m["sumo_version"].startswith("1.") and m["casadi_version"] and m["python_version"]
    assert len(m["scenario_hash"]) == 16
    assert m["git_commit"] is None or len(m["git_commit"].split("-")[0]) == 40


def test_a_saved_scenario_with_quotes_and_backslashes_in_paths_is_valid_toml(tmp_path):
    scenario = config.load("lane_change", ['sumo.output_dir=C:\\\\a"b'])
    again = tomllib.loads(scenario.to_toml())
    assert again["sumo"]["output_dir"] == 'C:\\\\a"b'
