"""sumo-gui plumbing (a window cannot be opened in tests): the command line SUMO gets, the
colours sent for authority and safety stops, and the run options that set them."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from aac_sumo import config
from aac_sumo.cli import _gui_overrides, main
from aac_sumo.sim.sumo import AUTHORITY, PLAIN, SAFETY_STOP, SumoOptions, SumoSimulator


def test_the_gui_starts_at_once_with_its_delay_and_stays_open_at_the_end():
    cmd = SumoOptions(Path("road.net.xml"), gui=True, delay=40).command(0.1)
    assert cmd[0].endswith("sumo-gui") and "--start" in cmd
    assert cmd[cmd.index("--delay") + 1] == "40.0"
    assert "--quit-on-end" not in cmd
    assert "--delay" not in SumoOptions(Path("road.net.xml")).command(0.1)


class RecordingVehicles:
    def __init__(self):
        self.calls = []

    def setColor(self, name, colour):  # noqa: N802 (TraCI's name)
        self.calls.append((name, colour))


def gui_sim(names, gui=True):
    sim = SumoSimulator.__new__(SumoSimulator)  # no SUMO: only the colouring is under test
    sim.robots = [SimpleNamespace(name=n) for n in names]
    sim.options = SumoOptions(Path("road.net.xml"), gui=gui)
    sim.removed = set()
    sim.present = [True] * len(names)
    sim.api = SimpleNamespace(vehicle=RecordingVehicles())
    return sim


def test_authority_is_gold_a_safety_stop_red_and_only_changes_are_sent():
    sim = gui_sim(["veh0", "veh1", "veh2"])
    sim.show({"veh1"}, {"veh2"})
    assert sim.api.vehicle.calls == [("veh1", AUTHORITY), ("veh2", SAFETY_STOP)]
    sim.show({"veh1"}, {"veh2"})
    assert len(sim.api.vehicle.calls) == 2
    sim.show({"veh0"}, set())
    assert sim.api.vehicle.calls[2:] == [("veh0", AUTHORITY), ("veh1", PLAIN), ("veh2", PLAIN)]


def test_without_a_gui_nothing_is_coloured():
    sim = gui_sim(["veh0"], gui=False)
    sim.show({"veh0"}, set())
    assert sim.api.vehicle.calls == []


def test_run_gui_and_delay_set_the_sumo_keys():
    scenario = config.load("lane_change")
    sets = _gui_overrides(scenario, 40.0)
    assert sets == ["sumo.gui=true", "sumo.delay=40.0"]
    assert scenario.with_overrides(sets)["sumo.delay"] == 40.0


def test_delay_without_gui_is_a_one_line_error(capsys):
    assert main(["run", "lane_change", "--delay", "40"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--delay 40: expected a number of milliseconds >= 0, with --gui" in err[0]
