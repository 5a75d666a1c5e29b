"""aac-sumo net info on a city: the road lane_change takes is named in one line of its own, and
long id lists are cut to their first ids and how many more there are."""

from __future__ import annotations

from pathlib import Path

from aac_sumo import network
from aac_sumo.cli.app import main


def test_net_info_names_the_chosen_road_and_counts_what_it_leaves_out(capsys):
    import sumo

    net = Path(sumo.SUMO_HOME) / "tools" / "game" / "DRT" / "osm.net.xml"
    assert main(["net", "info", str(net)]) == 0
    out = capsys.readouterr().out
    chosen = network.road(network.read(net, "sumo.net", "test"), "", 2, "test")
    takes = [ln.strip() for ln in out.splitlines() if ln.strip().startswith("lane_change takes the road marked <- lane_change")]
    marked = next(ln.split() for ln in out.splitlines() if ln.strip().endswith("<- lane_change"))
    assert marked[3:3 + len(chosen.edges)] == list(chosen.edges)
    assert takes == [f"lane_change takes the road marked <- lane_change: 2 lanes, {marked[1]} m, "
                     f"edges {chosen.edges[0]} to {chosen.edges[-1]} ({len(chosen.edges)} edges)"]
    sidewalks = next(ln for ln in out.splitlines() if ln.startswith("pedestrians: sidewalks or footpaths on 1180 edges ("))
    assert " ... and 1174 more)" in sidewalks  # six ids of 1180
    assert max(len(ln) for ln in out.splitlines() if "<- lane_change" not in ln) < 400
