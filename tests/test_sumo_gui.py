"""sumo-gui plumbing (a window cannot be opened in tests): the command line SUMO gets, the
colours a real SUMO gets for authority and safety stops, and the run options that set them."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from aac_sumo import config
from aac_sumo.cli.app import _gui_overrides, main
from aac_sumo.experiments.common import robot_spec
from aac_sumo.experiments.lane_change import BUNDLED_NET
from aac_sumo.sim.sumo import AUTHORITY, PLAIN, SAFETY_STOP, SumoSimulator
from aac_sumo.sim.sumo_options import SumoOptions


def test_the_gui_starts_at_once_with_its_delay_and_stays_open_at_the_end():
    cmd = SumoOptions(Path("road.net.xml"), gui=True, delay=40).command(0.1)
    assert cmd[0].endswith("sumo-gui") and "--start" in cmd
    assert cmd[cmd.index("--delay") + 1] == "40.0"
    assert "--quit-on-end" not in cmd
    assert "--delay" not in SumoOptions(Path("road.net.xml")).command(0.1)


NAMES = ("veh0", "veh1", "veh2")


@pytest.fixture
def shown_in_sumo():
    """A real SUMO (libsumo) with three cars on the bundled road, started by the public
    constructor, and a function that says whether the simulator shows a GUI. libsumo keeps every
    vehicle's colour and reports it (``vehicle.getColor``) as sumo-gui would draw it; a window
    cannot be opened in tests, so the GUI is said after the start (``options`` is public)."""
    scenario = config.load("lane_change")
    robots = [robot_spec(scenario, n) for n in NAMES]
    states = np.array([[20.0, -8.0, 0.0, 0.0], [40.0, -4.8, 0.0, 0.0], [60.0, -1.6, 0.0, 0.0]])
    sim = SumoSimulator(robots, states, 0.1, ["E0", "E1"], SumoOptions(BUNDLED_NET))

    def with_gui(gui: bool) -> SumoSimulator:
        sim.options = dataclasses.replace(sim.options, gui=gui)
        return sim

    try:
        yield with_gui
    finally:
        with_gui(False).close()


def colours(sim) -> dict[str, tuple]:
    return {n: tuple(sim.api.vehicle.getColor(n)) for n in NAMES}


def test_authority_is_gold_a_safety_stop_red_and_only_changes_are_sent(shown_in_sumo):
    sim = shown_in_sumo(True)
    own = colours(sim)  # SUMO's colour before we show anything
    assert AUTHORITY not in own.values() and SAFETY_STOP not in own.values()
    sim.show({"veh1"}, {"veh2"})
    assert colours(sim) == {"veh0": own["veh0"], "veh1": AUTHORITY, "veh2": SAFETY_STOP}  # veh0 was plain: nothing sent
    marked = (1, 2, 3, 255)
    sim.api.vehicle.setColor("veh1", marked)  # had show sent veh1's unchanged colour again, this would be gone
    sim.show({"veh1"}, {"veh2"})
    assert colours(sim) == {"veh0": own["veh0"], "veh1": marked, "veh2": SAFETY_STOP}
    sim.show({"veh0"}, set())
    assert colours(sim) == {"veh0": AUTHORITY, "veh1": PLAIN, "veh2": PLAIN}


def test_without_a_gui_nothing_is_coloured(shown_in_sumo):
    sim = shown_in_sumo(False)
    own = colours(sim)
    sim.show({"veh0"}, {"veh1"})
    assert colours(sim) == own


def test_run_gui_and_delay_set_the_sumo_keys():
    scenario = config.load("lane_change")
    sets = _gui_overrides(scenario, 40.0)
    assert sets == ["sumo.gui=true", "sumo.delay=40.0"]
    assert scenario.with_overrides(sets)["sumo.delay"] == 40.0


def test_delay_without_gui_is_a_one_line_error(capsys):
    assert main(["run", "lane_change", "--delay", "40"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--delay 40: expected a number of milliseconds >= 0, with --gui" in err[0]


def test_the_gui_without_a_display_is_one_line_at_once(tmp_path, monkeypatch, capsys):
    """On Linux with neither DISPLAY nor WAYLAND_DISPLAY set, `run --gui` stops before SUMO
    starts with exit status 2 and one line naming sumo.gui and what to do (sumo-gui retried for
    a minute and printed 240 lines first)."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert main(["run", "lane_change", "--gui", "--out", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sumo.gui" in err and "display" in err and "without --gui" in err


def test_a_display_sumo_gui_cannot_open_is_one_line_at_once(tmp_path, monkeypatch, capfd):
    """With DISPLAY naming a display that does not exist, sumo-gui exits at once: the run stops
    with exit status 2 and one line carrying sumo-gui's own message, not a minute of traci
    starting sumo-gui again on 60 ports and 240 lines of retries."""
    monkeypatch.setenv("DISPLAY", ":97")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["run", "lane_change", "--gui", "--out", str(tmp_path / "g")]) == 2
    captured = capfd.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "SUMO did not start (FXApp::openDisplay: unable to open display :97)" in err[0], err
    assert "Retrying" not in captured.out
