"""Controlled cars from a SUMO user's own routes (sumo.controlled_types / controlled_ids): the
route files read before the run, the lane plan, and real libsumo runs of a user's .sumocfg with
its own vTypes, a controlled flow and background traffic."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aac_sumo import cli, network
from aac_sumo.experiments.lane_change import BUNDLED_NET_DIR
from aac_sumo.experiments.routed_cars import closures, lane_plan, planned_path
from aac_sumo.sim.sumo_routes import RoutesError, controlled, read_routes

NET = BUNDLED_NET_DIR / "lane_change.net.xml"
CONES = BUNDLED_NET_DIR / "cones.rou.xml"


def write(path, text):
    path.write_text(text)
    return path


def test_flows_expand_as_sumo_names_and_times_them(tmp_path):
    f = write(tmp_path / "r.rou.xml", """<routes>
        <vType id="mine" length="4.5" width="1.9"/>
        <route id="road" edges="E0 E1"/>
        <flow id="a" type="mine" route="road" begin="2" period="3" number="4"/>
        <flow id="b" type="mine" begin="0" end="10" vehsPerHour="720" from="E0" to="E1"/>
        <flow id="c" begin="0" end="10" number="2"><route edges="E0"/></flow>
        <vehicle id="v" type="mine" depart="5.5" route="road"/>
    </routes>""")
    vs = read_routes([f], until=9.0)
    by = {v.id: v for v in vs}
    assert [by[f"a.{k}"].depart for k in range(3)] == [2.0, 5.0, 8.0] and "a.3" not in by  # 11 s is after the run
    assert [by[f"b.{k}"].depart for k in range(2)] == [0.0, 5.0] and by["b.0"].trip and by["b.0"].edges == ("E0", "E1")
    assert [by[f"c.{k}"].depart for k in range(2)] == [0.0, 5.0] and by["c.0"].vtype == "DEFAULT_VEHTYPE"
    assert (by["v"].length, by["v"].width, by["v"].edges) == (4.5, 1.9, ("E0", "E1"))
    assert [v.depart for v in vs] == sorted(v.depart for v in vs)
    assert {v.id for v in controlled(vs, ["mine"], [])} == {"a.0", "a.1", "a.2", "b.0", "b.1", "v"}
    assert {v.id for v in controlled(vs, [], ["c.*"])} == {"c.0", "c.1"}


@pytest.mark.parametrize("flow", ['<flow id="p" begin="0" end="9" probability="0.1" route="road"/>',
                                  '<flow id="p" begin="0" end="9" period="exp(0.2)" route="road"/>',
                                  '<flow id="p" begin="0" route="road"/>'])
def test_a_flow_whose_vehicles_cannot_be_known_is_refused(tmp_path, flow):
    f = write(tmp_path / "r.rou.xml", f'<routes><route id="road" edges="E0"/>{flow}</routes>')
    with pytest.raises(RoutesError, match="flow id='p'"):
        read_routes([f], until=60.0)


def straight_road(lanes=3, length=500.0, width=3.2) -> network.Road:
    return network.Road(["E"], [np.array([[0.0, j * width], [length, j * width]]) for j in range(lanes)], [width] * lanes)


def test_a_car_leaves_a_closed_lane_before_the_cones_then_takes_its_exit_lane():
    rd = straight_road()
    closed = closures(rd, [np.array([s, 0.0]) for s in (200.0, 215.0, 240.0)])
    assert closed == {0: [(200.0, 240.0)]}
    changes = lane_plan(rd, 0, 10.0, closed, 2, change_start=5.0, change_length=40.0, lead=30.0, margin=20.0)
    assert changes == [(1, 130.0, 40.0), (2, 260.0, 40.0)]  # the first change ends 30 m before the first cone
    path = planned_path(rd, 0, 10.0, changes)
    y = np.interp([100.0, 170.0, 200.0, 240.0, 299.0, 310.0], path[:, 0], path[:, 1])
    assert y[0] == pytest.approx(0.0) and y[1] == pytest.approx(3.2) and y[2] == pytest.approx(3.2)  # beside the cones: lane 1
    assert y[3] == pytest.approx(3.2) and y[4] < 6.4 and y[5] == pytest.approx(6.4)


def test_a_car_on_an_open_lane_keeps_it_and_a_car_past_the_cones_only_takes_its_exit():
    rd = straight_road()
    closed = {0: [(200.0, 240.0)]}
    assert lane_plan(rd, 1, 10.0, closed, None, 5.0, 40.0, 30.0, 20.0) == []
    assert lane_plan(rd, 0, 250.0, closed, 2, 5.0, 40.0, 30.0, 20.0) == [(2, 255.0, 80.0)]  # right after its start; two lanes: twice the length


def user_config(tmp_path, flows: str, net=NET) -> str:
    write(tmp_path / "traffic.rou.xml", f"""<routes>
        <vType id="mine" length="4.5" width="1.8" color="0,0,255"/>
        <vType id="bg" length="4.5" width="1.8" maxSpeed="12"/>
        <route id="road" edges="E0 E1"/>
        {flows}
    </routes>""")
    cfg = write(tmp_path / "my.sumocfg", f"""<configuration><input>
        <net-file value="{net}"/><route-files value="{CONES},traffic.rou.xml"/>
    </input></configuration>""")
    return str(cfg)


FLOWS = """<flow id="ours" type="mine" route="road" begin="0" period="3" number="4" departLane="0" departSpeed="8"/>
           <flow id="bgf" type="bg" route="road" begin="1.5" period="3" number="3" departLane="2" departSpeed="8"/>"""


@pytest.mark.slow
def test_a_users_sumocfg_runs_unchanged_with_its_controlled_flow_among_background_traffic(tmp_path, capsys):
    cfg = user_config(tmp_path, FLOWS)
    out = tmp_path / "out"
    code = cli.main(["run", "lane_change", "--set", f"sumo.config={cfg}", "--set", "sumo.controlled_types=mine",
                     "--set", "scenario.duration=60", "--set", "sumo.outputs=collision", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    steps = pd.read_csv(out / "steps.csv")
    first = steps.groupby("robot")["t"].min()
    assert sorted(first.index) == [f"ours.{k}" for k in range(4)]
    assert np.allclose(first.sort_index().to_numpy(), [0.0, 3.0, 6.0, 9.0], atol=0.25)  # each from its departure on
    # departLane 0 is the cone lane: every car has left it beside the cones (y = -8 m there; lane 1 is at -4.8 m)
    beside = steps[(steps.x > 185.0) & (steps.x < 235.0)]
    assert len(beside) and beside.y.min() > -6.5
    traj = pd.read_csv(out / "trajectories.csv")
    assert {"bgf.0", "bgf.1", "bgf.2"} <= set(traj[traj.kind == "scripted"].name)  # SUMO drove them: obstacles to us
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["completed"] and metrics["n_robots"] == 4 and metrics["collisions"] == 0 and metrics["sim_collisions"] == 0


@pytest.mark.parametrize("sets, key", [
    (["sumo.controlled_types=nosuch"], "sumo.controlled_types"),
    (["sumo.controlled_ids=bgf.*", "lane_change.exit_lanes=5"], "lane_change.exit_lanes"),
])
def test_a_missing_piece_of_a_users_config_is_one_line_exit_2(tmp_path, capsys, sets, key):
    cfg = user_config(tmp_path, FLOWS)
    code = cli.main(["run", "lane_change", "--set", f"sumo.config={cfg}", *sum((["--set", s] for s in sets), []),
                     "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and key in err and "Traceback" not in err


def test_a_route_without_room_for_a_lane_change_is_one_line_exit_2(tmp_path, capsys):
    nod = write(tmp_path / "one.nod.xml", '<nodes><node id="A" x="0" y="0"/><node id="B" x="300" y="0"/></nodes>')
    edg = write(tmp_path / "one.edg.xml", '<edges><edge id="E0" from="A" to="B" numLanes="1" speed="13.9"/></edges>')
    net = tmp_path / "one.net.xml"
    import subprocess

    subprocess.run([network.sumo_binary("netconvert"), "-n", str(nod), "-e", str(edg), "-o", str(net)], check=True, capture_output=True)
    cfg = user_config(tmp_path, '<flow id="ours" type="mine" begin="0" period="3" number="2"><route edges="E0"/></flow>', net)
    (tmp_path / "my.sumocfg").write_text((tmp_path / "my.sumocfg").read_text().replace(f"{CONES},", ""))
    code = cli.main(["run", "lane_change", "--set", f"sumo.config={cfg}", "--set", "sumo.controlled_types=mine"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "sumo.controlled_types" in err and "2 car lanes" in err


@pytest.mark.slow
def test_the_highway_work_zone_first_minute(tmp_path):
    """The bundled highway's first 60 s (real libsumo; the 100-car run itself is measured in
    docs/highway_work_zone.md): the flow's cars enter one every 2.4 s, each recorded only from
    its departure; those from the closed lane are out of it before the first cone (x = 800 m)
    and the leaders pass the work zone; nothing collides, by our check or SUMO's own, whose
    collision output holds exactly the pairs counted."""
    import xml.etree.ElementTree as ET

    out = tmp_path / "out"
    assert cli.main(["run", "highway_work_zone", "--set", "scenario.duration=60", "--set", "sumo.outputs=collision",
                     "--out", str(out)]) in (0, 1)
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["n_robots"] == 25 and not metrics.get("error")
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0
    assert ET.parse(out / "collision.xml").getroot().findall("collision") == []
    steps = pd.read_csv(out / "steps.csv")
    first = steps.groupby("robot")["t"].min()
    assert len(first) == 25 and np.all(np.diff(np.sort(first.to_numpy())) > 1.5)  # one every 2.4 s, as SUMO inserts them
    closed = steps[(steps.x > 790.0) & (steps.x < 950.0)]
    assert len(closed) and closed.y.min() > -12.25 + 1.75  # nobody's rear axle in the closed lane's half beside the cones
    assert steps.x.max() > 955.0  # the leader is past the last cone (x = 950 m)
