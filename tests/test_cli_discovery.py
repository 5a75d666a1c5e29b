"""Finding one's way: --version, the bundled scenarios, every key, did-you-mean, errors naming --set."""

from __future__ import annotations

import pytest

from aac_sumo import __version__
from aac_sumo.cli.app import main


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("aac-sumo: error: "), err
    return err[0]


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"aac-sumo {__version__}"


def test_scenarios_lists_every_bundled_one_with_its_purpose(capsys):
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split()[0] for line in lines]
    assert names == ["braking", "circle_swap", "city", "highway_work_zone", "lane_change", "random_crossing", "swarm_rescue"]
    assert "S2: lane change in SUMO co-simulation (paper Table II)." in lines[4]


def test_keys_of_a_scenario_give_its_values_units_and_meanings(capsys):
    assert main(["keys", "braking"]) == 0
    rows = {line.split()[0]: line.split(None, 3)[1:] for line in capsys.readouterr().out.splitlines()[1:]}
    assert rows["scenario.dt"] == ["0.1", "s", "control period and simulation step"]
    assert rows["braking.speed"][:2] == ["10.0", "m/s"]
    assert rows["controller.coordinator"][0] == '"independent"'  # braking.toml's value, not the schema's "aac"
    assert "sumo.net" not in rows and "swarm_rescue.starts" not in rows


def test_keys_without_a_scenario_cover_every_kind(capsys):
    assert main(["keys"]) == 0
    keys = {line.split()[0] for line in capsys.readouterr().out.splitlines()[1:]}
    assert {"braking.speed", "circle_swap.n_robots", "lane_change.vehicles", "sumo.gui", "aac.keep_right"} <= keys


@pytest.mark.parametrize("argv, expected", [
    (["rn", "braking"], "invalid choice: 'rn'"),
    (["run", "brakin"], "brakin: scenario: expected an existing .toml file or a bundled name (did you mean braking?)"),
    (["run", "braking", "--set", "controller.horizn=5"], "controller.horizn: expected a known key (did you mean controller.horizon?)"),
    (["keys", "circle_swap.toml"], "circle_swap.toml: scenario: expected an existing .toml file"),
])
def test_unknown_names_get_a_suggestion(capsys, argv, expected):
    assert main(argv) == 2
    line = one_error_line(capsys)
    assert expected in line
    if argv[0] == "rn":
        assert line.endswith("did you mean 'run'?")


def test_a_bad_set_value_is_blamed_on_set(capsys):
    assert main(["run", "braking", "--set", "controller.horizon=abc"]) == 2
    line = one_error_line(capsys)
    assert "braking.toml --set: controller.horizon: expected an integer in 1..100, got 'abc'" in line


@pytest.mark.parametrize("command", ["animate", "compare", "scenarios", "keys"])
def test_new_commands_have_help(capsys, command):
    assert main([command, "--help"]) == 0
    assert f"usage: aac-sumo {command}" in capsys.readouterr().out
