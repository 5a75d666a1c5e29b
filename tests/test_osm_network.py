"""A network as netconvert builds it from OpenStreetMap works on the first try: numeric edge ids,
a road split into several edges, single-lane ramps and side roads (real netconvert and libsumo)."""

from __future__ import annotations

import json
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from aac_sumo import config, network
from aac_sumo.cli.app import main
from aac_sumo.experiments.lane_change import MIN_LANES

MAIN = ["264306385#0", "264306385#1", "264306385#2"]  # one OSM way, split at the ramp and the side road
RAMP = ["8008670#0", "8008670#1"]  # a 1-lane on-ramp, longer than the main road's first edge
SIDE = ["153177820", "-153177820"]  # a 1-lane two-way side road with sidewalks


def write_plain_xml(folder: Path, nodes: dict[str, tuple[float, float]], edges: list[str]) -> Path:
    """``folder`` with ``osm.nod.xml`` and ``osm.edg.xml``, built by netconvert; the .net.xml."""
    folder.mkdir()
    (folder / "osm.nod.xml").write_text(
        "<nodes>" + "".join(f'<node id="{n}" x="{x}" y="{y}"/>' for n, (x, y) in nodes.items()) + "</nodes>")
    (folder / "osm.edg.xml").write_text("<edges>" + "".join(edges) + "</edges>")
    return network.build(folder)[0]


def edge(eid: str, a: str, b: str, lanes: int, extra: str = "") -> str:
    return f'<edge id="{eid}" from="{a}" to="{b}" numLanes="{lanes}" speed="27.8" width="3.5" {extra}/>'


@pytest.fixture(scope="module")
def osm(tmp_path_factory) -> tuple[Path, Path]:
    """The OSM-style network, 480 m of 3-lane road along y ~ 0 (x from 0 to 480 m), and a route
    file with five cones in its rightmost lane between x = 190 and 230 m."""
    folder = tmp_path_factory.mktemp("osm") / "osm"
    net = write_plain_xml(
        folder, {"26": (0, 0), "27": (120, 0), "28": (300, 0), "29": (480, 0), "40": (-200, -80), "41": (20, -30), "50": (300, -150)},
        [edge(MAIN[0], "26", "27", 3), edge(MAIN[1], "27", "28", 3), edge(MAIN[2], "28", "29", 3),
         edge(RAMP[0], "40", "41", 1), edge(RAMP[1], "41", "27", 1),
         edge(SIDE[0], "28", "50", 1, 'sidewalkWidth="2"'), edge(SIDE[1], "50", "28", 1, 'sidewalkWidth="2"')])
    start = network.read(net, "sumo.net", "test").getEdge(MAIN[1]).getLanes()[0].getShape()[0][0]  # x of the edge's start
    cones = folder / "cones.rou.xml"
    cones.write_text(
        '<routes><vType id="cone" vClass="passenger" length="0.4" width="0.4" minGap="0" maxSpeed="0.01"/>'
        + "".join(f'<vehicle id="cone{i}" type="cone" depart="0" departLane="0" departPos="{x - start:.1f}" departSpeed="0">'
                  f'<route edges="{MAIN[1]}"/><stop lane="{MAIN[1]}_0" startPos="{x - start - 0.4:.1f}" endPos="{x - start:.1f}" '
                  'duration="100000"/></vehicle>' for i, x in enumerate(range(190, 231, 10)))
        + "</routes>")
    return net, cones


def test_the_road_is_the_three_lane_way_not_the_longer_chain_through_the_ramp(osm):
    net = network.read(osm[0], "sumo.net", "test")
    assert [c.ids for c in network.candidates(net, MIN_LANES)] == [MAIN]
    assert network.candidates(net, 1)[0].ids == RAMP + MAIN[1:]  # the longest chain of all, 1 lane through it
    rd = network.road(net, "", MIN_LANES, "test")
    assert rd.edges == MAIN and rd.n_lanes == 3
    assert all(rd.length(i) > 470 for i in range(3))


def test_edge_ids_with_digits_and_hash_name_the_road(osm):
    scenario = config.load("lane_change", [f"sumo.net={osm[0]}", f"sumo.edges={','.join(MAIN[1:])}"])
    assert scenario["sumo.edges"] == ",".join(MAIN[1:])
    rd = network.road(network.read(osm[0], "sumo.net", "test"), scenario["sumo.edges"], MIN_LANES, "test")
    assert rd.edges == MAIN[1:] and rd.n_lanes == 3


def error_line(capsys) -> str:
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("aac-sumo: error: ")
    return lines[0]


def test_a_named_one_lane_ramp_is_rejected_with_one_line_that_says_what_to_do(osm, capsys, tmp_path):
    assert main(["run", "lane_change", "--set", f"sumo.net={osm[0]}", "--set", f"sumo.edges={RAMP[0]}", "--out", str(tmp_path)]) == 2
    line = error_line(capsys)
    length = network.read(osm[0], "sumo.net", "test").getEdge(RAMP[0]).getLength()
    assert "sumo.edges" in line and f"edges {RAMP[0]}, 1 lane, {length:.0f} m" in line and "at least 2 lanes" in line
    assert "aac-sumo net info" in line


def test_an_unknown_or_disconnected_edge_is_one_line(osm, capsys, tmp_path):
    assert main(["run", "lane_change", "--set", f"sumo.net={osm[0]}", "--set", "sumo.edges=153177821"]) == 2
    assert "sumo.edges" in (line := error_line(capsys)) and "'153177821'" in line
    assert main(["run", "lane_change", "--set", f"sumo.net={osm[0]}", "--set", f"sumo.edges={MAIN[0]} {MAIN[2]}"]) == 2
    assert f"{MAIN[0]} does not lead to {MAIN[2]}" in error_line(capsys)


def test_lane_counts_may_differ_where_the_lanes_connect(tmp_path):
    """3 lanes, then 4 where an on-ramp adds an acceleration lane on the right, then 3 again: the
    road's lanes follow the connections (lane 0 continues into lane 1 of the 4-lane edge)."""
    net_path = write_plain_xml(
        tmp_path / "merge", {"a": (0, 0), "b": (150, 0), "c": (300, 0), "d": (450, 0), "r": (0, -40)},
        [edge("1#0", "a", "b", 3), edge("1#1", "b", "c", 4), edge("1#2", "c", "d", 3), edge("2", "r", "b", 1)])
    net = network.read(net_path, "sumo.net", "test")
    assert [len(network.car_lanes(net.getEdge(e))) for e in ("1#0", "1#1", "1#2")] == [3, 4, 3]
    (chain,) = network.candidates(net, MIN_LANES)
    assert chain.ids == ["1#0", "1#1", "1#2"] and chain.tracks == ((0, 1, 0), (1, 2, 1), (2, 3, 2))
    rd = network.road(net, "", MIN_LANES, "test")
    for line in rd.lanes:  # each lane stays straight across both junctions: no jump to a neighbour
        assert np.ptp(line[:, 1]) < 0.5


def test_net_info_lists_roads_sidewalks_and_route_contents(osm, capsys):
    net, cones = osm
    assert main(["net", "info", str(net), str(cones)]) == 0
    out = capsys.readouterr().out
    length = {tuple(c.ids): c.length for c in network.candidates(network.read(net, "sumo.net", "test"), 1)}
    roads = [ln.split() for ln in out.splitlines() if ln.strip().endswith("<- lane_change")]
    assert roads == [["3", f"{length[tuple(MAIN)]:.0f}", "m", *MAIN, "[all]", "<-", "lane_change"]]
    assert f"1   {length[tuple(RAMP + MAIN[1:])]:.0f} m  {' '.join(RAMP + MAIN[1:])}  [all]" in out
    assert f"sidewalks or footpaths on 2 edges ({SIDE[1]} {SIDE[0]})" in out
    assert "crossings: 0" in out and "--crossings.guess" in out
    assert "vType cone (vClass passenger, 0.4 m length, 0.4 m width): 5 vehicles, 0 persons" in out


def test_net_info_of_a_missing_file_is_one_line(capsys, tmp_path):
    assert main(["net", "info", str(tmp_path / "their.net.xml")]) == 2
    assert "NET" in error_line(capsys)


@pytest.mark.slow
def test_lane_change_runs_on_the_osm_network_with_only_net_and_routes_set(osm, tmp_path):
    net, cones = osm
    assert main(["run", "lane_change", "--set", f"sumo.net={net}", "--set", f"sumo.routes={cones}", "--out", str(tmp_path)]) == 0
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["n_robots"] == 15
    assert m["completed"] is True and m["collisions"] == 0


EXAMPLE = Path(__file__).resolve().parents[1] / "sumo_networks" / "osm_example"
OSM_OPTIONS = ["--geometry.remove", "--ramps.guess", "--junctions.join", "--osm.sidewalks", "--crossings.guess"]


@pytest.fixture(scope="module")
def example_net(tmp_path_factory) -> Path:
    """docs/lane_change.md's OSM path: netconvert --osm-files on the bundled example."""
    out = tmp_path_factory.mktemp("osm_example") / "example.net.xml"
    done = subprocess.run([network.sumo_binary("netconvert"), "--osm-files", str(EXAMPLE / "example.osm"), "--connection-files",
                           str(EXAMPLE / "crossing.con.xml"), *OSM_OPTIONS, "-o", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return out


def test_the_osm_example_converts_to_a_road_with_sidewalk_cones_and_a_priority_crossing(example_net, capsys):
    net = network.read(example_net, "sumo.net", "test", withInternal=True)
    (chain, *_) = network.candidates(net, MIN_LANES)
    assert chain.ids == [f"264306385#{i}" for i in range(4)] and chain.n_lanes == 3
    assert [lane.getIndex() for lane in chain.lanes(0)] == [1, 1, 1, 1]  # lane 0 of every edge is the sidewalk
    assert main(["net", "info", str(example_net), str(EXAMPLE / "cones.rou.xml"), str(EXAMPLE / "walkers.rou.xml")]) == 0
    out = capsys.readouterr().out
    assert "264306385#1_1" in out and "crossings: 2" in out and "person p2: walks 264306385#0 -> 264306385#3" in out
    onto = [c.get("state") for c in ET.parse(example_net).iter("connection") if c.get("to") == ":3_c0"]  # the zebra at node 3
    assert onto == ["M"]  # walkers step onto it with priority


@pytest.mark.slow
def test_lane_change_runs_on_the_osm_example_with_cones_and_walkers(example_net, tmp_path):
    routes = f"{EXAMPLE / 'cones.rou.xml'},{EXAMPLE / 'walkers.rou.xml'}"
    assert main(["run", "lane_change", "--set", f"sumo.net={example_net}", "--set", f"sumo.routes={routes}", "--out", str(tmp_path)]) == 0
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["completed"] is True and m["collisions"] == 0
    assert m["min_pedestrian_clearance_m"] > 1.0


def test_net_build_of_the_osm_example_writes_the_net_of_the_docs_command_that_its_sumocfg_names(example_net, tmp_path):
    work = tmp_path / "osm_example"
    shutil.copytree(EXAMPLE, work, ignore=shutil.ignore_patterns("*.net.xml"))
    assert network.build(work) == [work / "example.net.xml"]
    assert ET.parse(work / "osm_example.sumocfg").find(".//net-file").get("value") == "example.net.xml"
    built, documented = (network.read(p, "sumo.net", "test", withInternal=True) for p in (work / "example.net.xml", example_net))
    assert {lane.getID(): lane.getShape() for e in built.getEdges() for lane in e.getLanes()} == \
        {lane.getID(): lane.getShape() for e in documented.getEdges() for lane in e.getLanes()}


def test_net_info_of_a_city_marks_the_road_it_takes_and_keeps_the_crossings_short(capsys):
    """The eclipse-sumo wheel's DRT city network (OSM): lane_change takes a long 2-lane road that
    the table of the widest chains does not reach; it is listed after them with its mark. Its 503
    crossings over 673 edges are counted, with the first six edge ids only."""
    import sumo

    net = Path(sumo.SUMO_HOME) / "tools" / "game" / "DRT" / "osm.net.xml"
    assert main(["net", "info", str(net)]) == 0
    out = capsys.readouterr().out
    chosen = network.road(network.read(net, "sumo.net", "test"), "", 2, "test")
    marked = [ln.split() for ln in out.splitlines() if ln.strip().endswith("<- lane_change")]
    assert len(marked) == 1 and marked[0][0] == "2" and marked[0][3:3 + len(chosen.edges)] == list(chosen.edges)
    crossings = next(ln for ln in out.splitlines() if ln.strip().startswith("crossings:"))
    assert crossings.strip().startswith("crossings: 503 (over 673 edges: ") and crossings.endswith(" ... and 667 more)")
    assert len(crossings) < 200
