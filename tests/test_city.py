"""The city (scenario kind ``city``) in real libsumo: controlled cars on SUMO routes that turn through
signalised junctions, among SUMO's own cars and walkers."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import sumo

from aac_sumo import cli

#: aac.3 turns left at D3 and aac.5 right at D2 (sumo_networks/city/traffic.rou.xml); every other
#: car of the route files is SUMO's to drive.
OURS = ["--set", "sumo.controlled_types=[]", "--set", 'sumo.controlled_ids=["aac.3", "aac.5"]']


def turn(steps: pd.DataFrame, robot: str) -> float:
    """The heading change [rad] of ``robot`` from its first to its last step (left positive)."""
    h = steps.loc[steps["robot"] == robot, "heading"].to_numpy()
    return float(np.angle(np.exp(1j * (h[-1] - h[0]))))


@pytest.mark.slow
def test_two_cars_turn_through_signalised_junctions_to_their_routes_ends_without_running_a_red_light(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", "city", *OURS, "--set", "scenario.duration=150", "--set", "sumo.outputs=tripinfo", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["completed"] and metrics["n_robots"] == 2
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0
    assert metrics["red_light_violations"] == 0
    steps = pd.read_csv(out / "steps.csv")
    assert turn(steps, "aac.3") == pytest.approx(np.pi / 2, abs=0.1)  # a left turn
    assert turn(steps, "aac.5") == pytest.approx(-np.pi / 2, abs=0.1)  # a right turn
    assert steps["accel"].abs().max() <= 3.0 + 1e-9  # never beyond the comfort braking


def test_a_city_run_without_controlled_cars_named_is_one_line_exit_2(tmp_path, capsys):
    code = cli.main(["run", "city", "--set", "sumo.controlled_types=[]", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "sumo.controlled_types" in err and "Traceback" not in err


@pytest.mark.slow
def test_a_car_held_at_a_red_light_sets_off_at_green_across_both_crossings_of_its_right_turn(tmp_path, capsys):
    """aac.11 follows a walker on the sidewalk towards C3, stops at the red and turns right at green:
    a commitment that would stand on a crossing is refused, so it goes on across both."""
    out = tmp_path / "out"
    code = cli.main(["run", "city", "--set", "sumo.controlled_types=[]", "--set", 'sumo.controlled_ids=["aac.11"]',
                     "--set", "scenario.duration=160", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["completed"] and not metrics["deadlock"]
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0 and metrics["red_light_violations"] == 0
    steps = pd.read_csv(out / "steps.csv")
    assert turn(steps, "aac.11") == pytest.approx(-np.pi / 2, abs=0.1)
    assert (steps["v"] < 0.05).any()  # it stood at the red


GRID6 = Path(sumo.__file__).parent / "tools" / "game" / "grid6" / "grid6.net.xml"


def test_net_trips_makes_controlled_and_background_routes_with_the_wheels_randomtrips(tmp_path, capsys):
    code = cli.main(["net", "trips", str(GRID6), "--controlled", "6", "--background", "10", "--end", "60", "--out", str(tmp_path)])
    assert code == 0, capsys.readouterr().err
    controlled, background = (ET.parse(tmp_path / f"{name}.rou.xml").getroot() for name in ("controlled", "background"))
    assert [v.get("type") for v in controlled.iter("vehicle")] == ["aac"] * 6
    assert {t.get("id") for t in controlled.iter("vType")} == {"aac"}
    assert all(v.get("id").startswith("aac.") for v in controlled.iter("vehicle"))
    assert len(list(background.iter("vehicle"))) == 10 and all(v.get("type") is None for v in background.iter("vehicle"))
    assert all(float(v.get("depart")) <= 60.0 for v in (*controlled.iter("vehicle"), *background.iter("vehicle")))


def test_net_trips_on_a_missing_network_is_one_line_exit_2(tmp_path, capsys):
    code = cli.main(["net", "trips", str(tmp_path / "none.net.xml"), "--out", str(tmp_path / "routes")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "none.net.xml" in err


@pytest.mark.parametrize("args, key", [(["--end", "0"], "--end"), (["--controlled", "-3"], "--controlled"),
                                       (["--controlled", "0", "--background", "0"], "--controlled/--background")])
def test_net_trips_with_impossible_counts_or_times_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, args, key):
    code = cli.main(["net", "trips", str(GRID6), *args, "--out", str(tmp_path / "routes")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and f"net trips {key}:" in err
    assert not (tmp_path / "routes").exists()


@pytest.mark.slow
def test_cars_of_random_trips_drive_the_wheels_grid6_through_its_signals(tmp_path, capsys):
    """grid6: six signalised junctions 80 m apart, one-lane streets, its fringe joined by unregulated
    and priority junctions; 4 controlled cars and 12 of SUMO's on routes randomTrips.py makes."""
    assert cli.main(["net", "trips", str(GRID6), "--controlled", "4", "--background", "12", "--end", "40", "--seed", "3",
                     "--out", str(tmp_path / "routes")]) == 0
    out = tmp_path / "out"
    routes = ",".join(str(tmp_path / "routes" / f"{name}.rou.xml") for name in ("controlled", "background"))
    code = cli.main(["run", "city", "--set", 'sumo.config=""', "--set", f"sumo.net={GRID6}", "--set", f"sumo.routes={routes}",
                     "--set", "scenario.duration=200", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["n_robots"] == 4 and metrics["completed"]
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0
    assert metrics["red_light_violations"] == 0 and metrics["right_of_way_violations"] == 0


def test_the_bundled_grid6_runs_as_a_city(tmp_path, capsys):
    """sumo_networks/grid6: the wheel's network with net-trips routes, named by its .sumocfg."""
    out = tmp_path / "out"
    code = cli.main(["run", "city", "--set", "sumo.config=../sumo_networks/grid6/grid6.sumocfg", "--set", "scenario.duration=12",
                     "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["n_robots"] >= 1 and metrics["collisions"] == 0 and metrics["right_of_way_violations"] == 0


DRT = Path(sumo.__file__).parent / "tools" / "game" / "DRT" / "osm.net.xml"


@pytest.mark.slow
def test_an_osm_city_of_the_wheel_runs_on_random_trips_and_leaves_undrivable_routes_to_sumo_in_one_line_each(tmp_path, capsys):
    """The wheel's DRT network (from OpenStreetMap) with routes of ``net trips``: routes whose lane
    change for a turn falls on an edge too short for it, or with a corner sharper than the car can
    turn, are SUMO's to drive, each said in one line naming the car and why; the rest are ours and
    the run ends without error or collision."""
    assert cli.main(["net", "trips", str(DRT), "--controlled", "10", "--background", "20", "--end", "60", "--seed", "0",
                     "--vtype", "aac", "--out", str(tmp_path / "routes")]) == 0
    capsys.readouterr()
    routes = ",".join(str(tmp_path / "routes" / f) for f in ("controlled.rou.xml", "background.rou.xml"))
    out = tmp_path / "out"
    code = cli.main(["run", "city", "--set", "sumo.config=", "--set", f"sumo.net={DRT}", "--set", f"sumo.routes={routes}",
                     "--set", "scenario.duration=60", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    left = [line for line in err.splitlines() if "is left to SUMO's driver" in line]
    assert left and all("too short" in line or "tighter than the car" in line or "no car lane" in line for line in left)
    metrics = pd.read_json(out / "metrics.json", typ="series")
    controlled = ET.parse(tmp_path / "routes" / "controlled.rou.xml").getroot().findall("vehicle")
    departing = [v for v in controlled if float(v.get("depart")) <= 60.0]
    assert metrics["n_robots"] == len(departing) - len(left) > 0
    assert metrics["collisions"] == 0
    refused = left[0].split(": ")[1].split()[0]  # one car that no controlled car can drive alone: one line, exit 2
    code = cli.main(["run", "city", "--set", "sumo.config=", "--set", f"sumo.net={DRT}", "--set", f"sumo.routes={routes}",
                     "--set", "sumo.controlled_types=[]", "--set", f'sumo.controlled_ids=["{refused}"]', "--out", str(tmp_path / "none")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "none of 1 is" in err and refused in err


@pytest.mark.parametrize("declared", [False, True])
def test_sumo_inserts_a_controlled_car_no_faster_than_it_can_stop_before_a_junction_where_it_must_wait(tmp_path, capsys, declared):
    """A car of the route files departs at ``departSpeed="max"`` on a 40 m edge into an
    unregulated junction (where a controlled car yields to every crossing way). With
    ``sumo.declared_at_insertion`` SUMO inserts it no faster than it can stop at the declared
    2 m/s^2, after one period of travel, 1.5 m before the edge's end; without, at the lane's
    13.9 m/s times its speed factor."""
    from aac_sumo import network

    folder = tmp_path / "net"
    folder.mkdir()
    nodes = {"C": (0, 0), "W": (-40, 0), "E": (100, 0), "N": (0, 100), "S": (0, -100)}
    (folder / "net.nod.xml").write_text("<nodes>" + "".join(
        f'<node id="{n}" x="{x}" y="{y}"' + (' type="unregulated"/>' if n == "C" else "/>") for n, (x, y) in nodes.items()) + "</nodes>")
    (folder / "net.edg.xml").write_text("<edges>" + "".join(
        f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="1" speed="13.9"/>' for n in "WENS" for a, b in ((n, "C"), ("C", n))) + "</edges>")
    net = network.build(folder)[0]
    routes = tmp_path / "cars.rou.xml"
    routes.write_text("""<routes><vType id="ours" length="4.5" width="1.8" decel="6.0" speedFactor="1.1"/>
        <vehicle id="ours.0" type="ours" depart="0" departSpeed="max"><route edges="WC CE"/></vehicle></routes>""")
    out = tmp_path / "out"
    code = cli.main(["run", "city", "--set", 'sumo.config=""', "--set", f"sumo.net={net}", "--set", f"sumo.routes={routes}",
                     "--set", "sumo.controlled_types=[\"ours\"]", "--set", f"sumo.declared_at_insertion={str(declared).lower()}",
                     "--set", "scenario.duration=0.5", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    speed = pd.read_csv(out / "steps.csv").query("robot == 'ours.0'").v.iloc[0]
    length = network.read(net, "sumo.net", "test").getEdge("WC").getLength()
    room = length - 4.5 - 0.1 - 1.5
    if declared:
        assert speed * 0.1 + speed**2 / (2.0 * 2.0) <= room + 1e-6
        assert speed > 0.9 * 2.0 * (np.sqrt(0.01 + room) - 0.1)  # and no slower than that
    else:
        assert speed > 13.9
