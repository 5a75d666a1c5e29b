"""Fuzzing every input path: scenario files, ``--set``, SUMO network, route and configuration files.

Whatever the input, the answer is a scenario that loads and builds, or exit status 2 with one
line on stderr naming the file (or flag) and the key; never a traceback, a hang or a memory
blow-up. Scenarios that load are built (``experiments.build``), not run: building is where every
check on the values' combination happens, and it is fast. A non-finite value reaching a robot's
state during a run ends the run with a clear error, the records so far kept.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aac_sumo import config, experiments
from aac_sumo.runs.files import write_run
from aac_sumo.runs import runner, sweep
from aac_sumo.cli.app import main
from aac_sumo.config import ScenarioError
from aac_sumo.experiments.lane_change import BUNDLED_NET, BUNDLED_ROUTES
from aac_sumo.sim.sumo_options import SumoError
from aac_sumo.runs.sweep import SweepError

#: Examples per fuzz test; AAC_FUZZ_SCALE=20 fuzzes twenty times longer.
SCALE = int(os.environ.get("AAC_FUZZ_SCALE", "1"))
FUZZ = settings(max_examples=40 * SCALE, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
FEW = settings(FUZZ, max_examples=15 * SCALE)
#: Bundled scenarios on the internal simulator (fast to build); lane_change starts SUMO.
INTERNAL = ("braking", "swarm_rescue", "circle_swap", "random_crossing")
ONE_LINE_ERRORS = (ScenarioError, SumoError)


def keys_of(name: str) -> list[str]:
    return [f"{s}.{k}" for s, keys in config.load(name).schema().items() for k in keys]


def one_line(text: str) -> str:
    return " ".join(text.split())


def numbers():
    """Ints and floats, with the edges a user (or a script) may type: huge, negative, NaN, inf."""
    return st.one_of(
        st.integers(min_value=-(2**70), max_value=2**70),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from([0, 1, -1, 2, 10**9, 10**18, 2**31, 2**63 - 1, 1e-300, 1e300, -0.0, 0.5]),
    )


def toml_values():
    """Any value a TOML file may hold under a key."""
    scalars = st.one_of(numbers(), st.booleans(), st.text(max_size=12))
    return st.one_of(scalars, st.lists(scalars, max_size=3), st.lists(st.lists(numbers(), max_size=6), max_size=3),
                     st.dictionaries(st.text(max_size=5), scalars, max_size=2))


def set_texts():
    """The VALUE of ``--set KEY=VALUE``: TOML literals, bare text, unicode."""
    literals = numbers().map(lambda x: repr(x) if isinstance(x, float) else str(x))
    return st.one_of(literals, st.sampled_from(["nan", "inf", "-inf", "+inf", "true", "false", "[]", "[1, 2]", "[[0, 0, 0]]",
                                                '""', "10**9", "1e400", "-0.0", "[nan]", "[[inf, 0, 0]]", "clusters"]),
                     st.text(max_size=16))


def outcome(source: str, sets: list[str]) -> ScenarioError | SumoError | None:
    """None when ``source`` with ``sets`` loads and builds; else the one-line error it raised
    (any other exception fails the test)."""
    try:
        scenario = config.load(source, sets)
        c = scenario.data["controller"]  # the MPC problem's size costs build time alone: load checked it
        setup = experiments.build(scenario.with_overrides(
            ["controller.codegen=false", f"controller.horizon={min(c['horizon'], 5)}",
             f"controller.obstacle_slots={min(c['obstacle_slots'], 8)}", f"controller.ego_discs={min(c['ego_discs'], 2)}"]))
    except ONE_LINE_ERRORS as exc:
        return exc
    setup.sim.close()
    return None


def assert_cli_error(capsys, argv: list[str], error: Exception, *names: str) -> None:
    """``aac-sumo ARGV`` exits 2 with one stderr line, no traceback, naming ``names`` and the key."""
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("aac-sumo: error: "), err
    if isinstance(error, SumoError):  # SUMO refused files it parsed: its message, and its command naming them
        assert lines[0].startswith("aac-sumo: error: SUMO did not start (")
        return
    for name in names + ((error.key,) if isinstance(error, ScenarioError) else ()):
        assert one_line(name) in lines[0], (name, lines[0])


def check(capsys, source: str, sets: list[str], *names: str) -> None:
    error = outcome(source, sets)
    if error is not None:
        with tempfile.TemporaryDirectory() as out:
            argv = ["run", source, "--out", out] + [f"--set={s}" for s in sets]  # --set=-x: a value, not an option
            assert_cli_error(capsys, argv, error, *names)


# --- --set ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", INTERNAL)
@FUZZ
@given(data=st.data())
def test_set_any_value_on_any_key(capsys, name, data):
    """One to three ``--set KEY=VALUE`` on the kind's keys: a scenario that builds, or one line
    naming the file and the key (with ``--set`` when the value itself is wrong)."""
    sets = [f"{data.draw(st.sampled_from(keys_of(name)))}={data.draw(set_texts())}" for _ in range(data.draw(st.integers(1, 3)))]
    check(capsys, name, sets, str(config.resolve(name)))


@FEW
@given(data=st.data())
def test_set_any_value_on_a_lane_change_key(capsys, data):
    key = data.draw(st.sampled_from([k for k in keys_of("lane_change") if k not in ("sumo.gui", "sumo.output_dir")]))
    check(capsys, "lane_change", [f"{key}={data.draw(set_texts())}"], str(config.resolve("lane_change")))


@FUZZ
@given(text=st.text(max_size=30))
def test_set_any_text(capsys, text):
    """Any text after ``--set``: no ``=``, unknown keys, unicode, control characters."""
    check(capsys, "braking", [text], str(config.resolve("braking")))


@FUZZ
@given(grid=st.lists(st.tuples(st.sampled_from(keys_of("braking")), st.lists(set_texts(), min_size=1, max_size=3)), min_size=1, max_size=2))
def test_grid_any_values(capsys, tmp_path, grid):
    """``aac-sumo sweep --grid KEY=V1,V2``: every combination is checked before any run starts."""
    texts = [f"{key}={','.join(values)}" for key, values in grid]
    try:
        sweep.plan_tasks("braking", [], sweep.parse_grid(texts), seeds=2)
    except (ScenarioError, SweepError) as exc:
        argv = ["sweep", "braking", "--out", str(tmp_path / "out")] + [f"--grid={t}" for t in texts]
        assert_cli_error(capsys, argv, exc, "--grid")
        assert not (tmp_path / "out" / "results.csv").exists()


@pytest.mark.parametrize("assignment", [
    "circle_swap.n_robots=1000000000", "random_crossing.n_robots=1000000000", "scenario.duration=1e300", "scenario.dt=1e-300",
    "controller.obstacle_slots=1000000000", "controller.max_iter=1000000000000", "aac.proximity_iterations=1000000000",
    "random_crossing.debris_density=1e300", "random_crossing.area_per_robot=1e300", "scenario.seed=1000000000000",
])
def test_huge_sizes_are_refused_at_once(capsys, assignment):
    """A size that would hang the run or exhaust memory is an exit-2 error, found before any work."""
    name = assignment.split(".")[0] if assignment.startswith(("circle", "random")) else "circle_swap"
    error = outcome(name, [assignment])
    assert error is not None
    assert_cli_error(capsys, ["run", name, "--set", assignment], error, str(config.resolve(name)))


def test_set_scenario_kind_switches_the_sections(capsys):
    """``--set scenario.kind=K`` on another kind's file: K's own section takes its defaults (or
    later ``--set`` s), the other kind's section is dropped."""
    scenario = config.load("braking", ["scenario.kind=circle_swap", "circle_swap.n_robots=3"])
    assert scenario.kind == "circle_swap" and "braking" not in scenario.data and scenario["circle_swap.n_robots"] == 3
    assert outcome("braking", ["scenario.kind=circle_swap"]) is None
    check(capsys, "braking", ["scenario.kind=circle_swap", "braking.speed=3"], "braking.speed")


# --- scenario files ---------------------------------------------------------------------------


def sections():
    """Scenario files as nested tables: known sections and keys mostly, random ones too."""
    schema = config.schema_for("swarm_rescue") | {s: k for kind in config.KIND_SECTIONS for s, k in config.schema_for(kind).items()}
    section = st.one_of(st.sampled_from(sorted(schema)), st.text(max_size=8))

    def keys_for(name):
        known = sorted(schema.get(name, {}))
        key = st.one_of(st.sampled_from(known), st.text(max_size=8)) if known else st.text(max_size=8)
        values = st.one_of(toml_values(), st.sampled_from(list(config.KIND_SECTIONS)))
        return st.dictionaries(key, values, max_size=4)

    return section.flatmap(lambda name: keys_for(name).map(lambda table: (name, table)))


@FUZZ
@given(tables=st.lists(sections(), max_size=4), kind=st.sampled_from(INTERNAL + ("lane_change",)))
def test_any_scenario_file(capsys, tables, kind):
    raw = {"scenario": {"kind": kind}}
    for name, table in tables:
        raw.setdefault(name, {}).update(table) if isinstance(raw.get(name), dict) else raw.__setitem__(name, table)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.toml"
        path.write_text(tomli_w.dumps(raw))
        check(capsys, str(path), [], str(path))


@FUZZ
@given(data=st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_any_bytes_as_scenario_file(capsys, data):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.toml"
        path.write_bytes(data)
        try:
            error = outcome(str(path), [])
        except UnicodeDecodeError:
            assert_cli_error(capsys, ["run", str(path), "--out", folder + "/out"], None, str(path), "UTF-8")
            return
        if error is not None:
            assert_cli_error(capsys, ["run", str(path), "--out", folder + "/out"], error, str(path))


@pytest.mark.parametrize("suffix", ["", ".toml"])
def test_a_directory_given_as_scenario_file(capsys, tmp_path, suffix):
    folder = tmp_path / f"scenario{suffix}"
    folder.mkdir()
    with pytest.raises(ScenarioError) as error:
        config.load(str(folder))
    assert_cli_error(capsys, ["run", str(folder)], error.value, str(folder))
    assert_cli_error(capsys, ["sweep", str(folder), "--grid", "controller.horizon=5,10", "--out", str(tmp_path / "o")],
                     error.value, str(folder))


def test_an_empty_scenario_file_is_the_defaults(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text("")
    assert outcome(str(path), []) is None


# --- SUMO network, route and configuration files ----------------------------------------------


def broken_xml():
    """Truncated copies of real SUMO files, empty files, random bytes and text that is not XML."""
    net, routes = BUNDLED_NET.read_bytes(), BUNDLED_ROUTES[0].read_bytes()
    return st.one_of(
        st.integers(0, len(net) - 1).map(lambda n: net[:n]),
        st.integers(0, len(routes) - 1).map(lambda n: routes[:n]),
        st.binary(max_size=100),
        st.text(max_size=100).map(str.encode),
        st.sampled_from([b"", b"<net/>", b"<routes/>", b"<configuration/>", b"<routes><vehicle id='x'/></routes>",
                         b"<configuration><input><net-file value='nowhere.net.xml'/></input></configuration>",
                         b"<?xml version='1.0'?>\n<!DOCTYPE x [<!ENTITY a 'aaaaaaaa'>]><routes>&a;</routes>"]),
    )


@FEW
@given(key=st.sampled_from(["sumo.net", "sumo.routes", "sumo.config"]), data=broken_xml())
def test_broken_sumo_files(capsys, key, data):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "broken.xml"
        path.write_bytes(data)
        check(capsys, "lane_change", [f"{key}={json.dumps(str(path))}"], "lane_change.toml", key)
        if isinstance(outcome("lane_change", [f"{key}={json.dumps(str(path))}"]), SumoError):
            assert key == "sumo.routes", "a net or configuration SUMO refuses is found before SUMO starts"


@pytest.mark.parametrize("key", ["sumo.net", "sumo.routes", "sumo.config"])
def test_a_directory_given_as_sumo_file(capsys, tmp_path, key):
    error = outcome("lane_change", [f"{key}={tmp_path}"])
    assert isinstance(error, ScenarioError) and error.key == key
    check(capsys, "lane_change", [f"{key}={tmp_path}"], "lane_change.toml", key)


@FEW
@given(data=broken_xml())
def test_net_info_on_broken_files(capsys, data):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "broken.net.xml"
        path.write_bytes(data)
        capsys.readouterr()
        status = main(["net", "info", str(path)])
        err = capsys.readouterr().err
        assert "Traceback" not in err
        if status != 0:
            assert status == 2 and len(err.splitlines()) == 1 and str(path) in err, err


# --- a non-finite state during a run -----------------------------------------------------------


def test_a_nan_state_ends_the_run_with_a_clear_error_and_keeps_the_records(tmp_path, monkeypatch):
    """The internal simulator is real; only the fault is injected: robot1's speed turns NaN
    after the fifth step. The run stops there, says which robot and when, and keeps the five
    periods recorded before."""
    from aac_sumo.sim.internal import InternalSimulator

    real_step = InternalSimulator.step

    def faulty_step(self, inputs):
        report = real_step(self, inputs)
        if self.t > 0.45:
            self.states[1, 3] = math.nan
        return report

    monkeypatch.setattr(InternalSimulator, "step", faulty_step)
    result = runner.run(config.load("swarm_rescue", ["controller.horizon=5", "controller.codegen=false", "scenario.duration=1"]))
    error = result.metrics["error"]
    assert "non-finite state of robot1 at t=0.50 s" in error
    assert result.metrics["completed"] is False
    assert len(result.periods) == 5 and np.isfinite(result.steps[["x", "y", "heading", "v"]].to_numpy()).all()
    write_run(result, tmp_path)
    assert "non-finite state of robot1" in json.loads((tmp_path / "metrics.json").read_text())["error"]
