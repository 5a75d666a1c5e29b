"""The bundled highway work zone (sumo_networks/highway_work_zone): a ~2 km four-lane highway with
a sidewalk, cones that close its rightmost car lane for 150 m, one priority crossing, and traffic
that SUMO alone drives through it without teleports or collisions (real netconvert and sumo)."""

from __future__ import annotations

import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from aac_sumo import config, network
from aac_sumo.cli.app import main

NETWORKS = Path(__file__).resolve().parents[1] / "sumo_networks"
HERE = NETWORKS / "highway_work_zone"
NET = HERE / "highway_work_zone.net.xml"
CFG = HERE / "highway_work_zone.sumocfg"
EDGES = ["entry", "approach", "work", "after", "exit"]
CAR_LANES = [1, 2, 3, 4]  # lane 0 of every highway edge is the sidewalk


@pytest.fixture(scope="module")
def net():
    return network.read(NET, "sumo.net", "test", withInternal=True)


def routes(name: str) -> ET.Element:
    return ET.parse(HERE / name).getroot()


def test_the_road_is_five_edges_2_km_long_with_four_car_lanes_and_a_sidewalk(net):
    (road, *_) = network.candidates(net, 2)  # what sumo.edges = "" picks
    assert road.ids == EDGES and road.n_lanes == 4
    assert 1990 < road.length < 2010
    for eid in EDGES:
        lanes = net.getEdge(eid).getLanes()
        assert len(lanes) == 5
        assert lanes[0].allows("pedestrian") and not lanes[0].allows("passenger")
        assert [lane.getIndex() for lane in network.car_lanes(net.getEdge(eid))] == CAR_LANES
        assert not any(lane.allows("pedestrian") for lane in lanes[1:])


def test_one_crossing_over_after_at_1500_m_where_walkers_have_priority(net):
    (crossing,) = [e for e in net.getEdges(withInternal=True) if e.getFunction() == "crossing"]
    assert crossing.getID() == ":X_c0"
    (x0, _), (x1, _) = crossing.getLanes()[0].getShape()
    assert abs(x0 - 1500) < 2 and abs(x1 - 1500) < 2
    onto = [c.get("state") for c in ET.parse(NET).iter("connection") if c.get("to") == crossing.getID()]
    assert onto and set(onto) == {"M"}  # walkers step onto it without waiting


def test_cones_close_lane_1_of_work_for_150_m_behind_a_taper(net):
    root = routes("cones.rou.xml")
    assert {t.get("id") for t in root.iter("vType")} == {"cone"}
    cones = list(root.iter("vehicle"))
    assert {c.get("type") for c in cones} == {"cone"}
    stops = [c.find("stop") for c in cones]
    assert {s.get("lane") for s in stops} == {"work_1"}
    ends = [float(s.get("endPos")) for s in stops]
    assert ends == sorted(ends) and 140 <= ends[-1] - ends[0] <= 160
    assert max(b - a for a, b in zip(ends, ends[1:])) <= 15
    lats = [float(s.get("posLat")) for s in stops]
    half = net.getLane("work_1").getWidth() / 2
    assert lats[0] < 0 < lats[-1] and lats == sorted(lats)  # the taper leads from the lane's right side inwards
    assert all(abs(lat) + 0.2 <= half for lat in lats)  # every cone stands within lane 1


def test_traffic_is_100_aac_cars_the_size_of_the_robot_and_deterministic_background_flows():
    root = routes("traffic.rou.xml")
    types = {t.get("id"): t for t in root.iter("vType")}
    robot = config.load("lane_change")
    assert set(types) == {"aac", "background"}
    assert (float(types["aac"].get("length")), float(types["aac"].get("width"))) == (robot["robot.length"], robot["robot.width"])
    flows = {f.get("id"): f for f in root.iter("flow")}
    assert flows["aac"].get("type") == "aac" and flows["aac"].get("number") == "100"
    assert all(f.get("probability") is None and f.get("number") for f in flows.values())
    assert {f.get("type") for f in flows.values()} == {"aac", "background"}


def sumo(tmp_path: Path, cfg: Path, *args: str) -> None:
    """Run the wheel's sumo on ``cfg`` in ``tmp_path``; it must end without error."""
    done = subprocess.run([network.sumo_binary("sumo"), "-c", str(cfg), "--no-step-log", *args], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0, done.stderr


def test_the_config_runs_in_sumo_alone_without_teleports_or_collisions(tmp_path):
    """Every car and walker arrives by the config's end: the demand fits the road and the work zone."""
    assert ET.parse(CFG).find(".//step-length").get("value") == str(config.load("lane_change")["scenario.dt"])
    sumo(tmp_path, CFG, "--collision.check-junctions", "true", "--tripinfo-output", "trips.xml", "--statistic-output", "stats.xml")
    stats = ET.parse(tmp_path / "stats.xml").getroot()
    assert stats.find("teleports").get("total") == "0"
    assert stats.find("safety").get("collisions") == "0" and stats.find("safety").get("emergencyBraking") == "0"
    assert stats.find("vehicles").get("running") == "15"  # the cones
    assert stats.find("persons").get("loaded") == "5" and stats.find("persons").get("running") == "0"
    trips = [t.get("vType") for t in ET.parse(tmp_path / "trips.xml").iter("tripinfo")]
    assert trips.count("aac") == 100 and trips.count("background") == 40


def test_sumo_puts_the_cones_between_800_and_950_m_in_lane_1(tmp_path, net):
    sumo(tmp_path, CFG, "--end", "1", "--fcd-output", "fcd.xml")
    last = ET.parse(tmp_path / "fcd.xml").getroot().findall("timestep")[-1]
    cones = [v for v in last.iter("vehicle") if v.get("type") == "cone"]
    assert len(cones) == 15 and {c.get("lane") for c in cones} == {"work_1"}
    xs = sorted(float(c.get("x")) for c in cones)
    assert xs[0] == pytest.approx(800, abs=0.5) and xs[-1] == pytest.approx(950, abs=0.5)
    centre, half = net.getLane("work_1").getShape()[0][1], net.getLane("work_1").getWidth() / 2
    assert all(abs(float(c.get("y")) - centre) < half for c in cones)


def net_text(path: Path) -> str:
    """A .net.xml without netconvert's "generated on" line."""
    return "\n".join(ln for ln in path.read_text().splitlines() if "generated on" not in ln)


def test_net_build_rebuilds_the_bundled_net_from_its_plain_xml(tmp_path):
    src = tmp_path / "highway_work_zone"
    shutil.copytree(HERE, src, ignore=shutil.ignore_patterns("*.net.xml"))
    assert main(["net", "build", str(src)]) == 0
    assert net_text(src / NET.name) == net_text(NET)


@pytest.mark.parametrize("folder", sorted(p.name for p in NETWORKS.iterdir() if p.is_dir()))
def test_every_bundled_network_ships_a_config_that_sumo_opens_once_built(folder, tmp_path):
    """Its .sumocfg names files that are there or that aac-sumo net build writes (the OSM example's net)."""
    work = tmp_path / folder
    shutil.copytree(NETWORKS / folder, work, ignore=shutil.ignore_patterns("*.net.xml"))
    assert main(["net", "build", str(work)]) == 0
    (cfg,) = work.glob("*.sumocfg")
    inputs = ET.parse(cfg).find("input")
    named = [inputs.find("net-file").get("value"), *inputs.find("route-files").get("value").split(",")]
    assert all((work / name).is_file() for name in named)
    sumo(tmp_path, cfg, "--end", "5")
