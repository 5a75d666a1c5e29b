"""Controlled cars from a SUMO user's own routes (sumo.controlled_types / controlled_ids): the
route files read before the run, the lane plan, and real libsumo runs of a user's .sumocfg with
its own vTypes, a controlled flow and background traffic."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from aac_sumo import cli, network
from aac_sumo.experiments.lane_change import BUNDLED_NET_DIR
from aac_sumo.experiments.lane_plans import closures, lane_plan, planned_path
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
    assert changes == [(1, 130.0, 40.0, 130.0, "closure"), (2, 260.0, 40.0, 445.0, "exit")]  # the first change ends 30 m before the first cone
    assert lane_plan(rd, 0, 10.0, closed, 2, 5.0, 40.0, 30.0, 20.0, window=100.0)[0] == (1, 30.0, 40.0, 130.0, "closure")  # tried from 100 m sooner
    path, s = planned_path(rd, 0, 10.0, changes)
    assert s[0] == 10.0 and s[-1] == 500.0 and np.allclose(path[:, 0], s)
    y = np.interp([100.0, 170.0, 200.0, 240.0, 299.0, 310.0], path[:, 0], path[:, 1])
    assert y[0] == pytest.approx(0.0) and y[1] == pytest.approx(3.2) and y[2] == pytest.approx(3.2)  # beside the cones: lane 1
    assert y[3] == pytest.approx(3.2) and y[4] < 6.4 and y[5] == pytest.approx(6.4)


def test_a_car_on_an_open_lane_keeps_it_and_a_car_past_the_cones_only_takes_its_exit():
    rd = straight_road()
    closed = {0: [(200.0, 240.0)]}
    assert lane_plan(rd, 1, 10.0, closed, None, 5.0, 40.0, 30.0, 20.0) == []
    # right after its start, one lane at a time; the last ends 15 m before the road's end at the latest
    assert lane_plan(rd, 0, 250.0, closed, 2, 5.0, 40.0, 30.0, 20.0) == [(1, 255.0, 40.0, 405.0, "exit"), (2, 295.0, 40.0, 445.0, "exit")]


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
                     "--set", "scenario.duration=60", "--set", "sumo.outputs=collision,tripinfo", "--out", str(out)])
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
    # SUMO's tripinfo.xml has each controlled car's trip, arrived (not vaporized), the last one's
    # included, within two steps of steps.csv's arrival (it leaves SUMO the period after it
    # finished, and SUMO logs a removal at its next step's time)
    arrived = steps[steps["arrived"].astype(bool)].groupby("robot")["t"].min()
    trips = {t.get("id"): t for t in ET.parse(out / "tripinfo.xml").getroot().findall("tripinfo") if t.get("id").startswith("ours.")}
    assert set(trips) == set(arrived.index)
    for name, trip in trips.items():
        assert trip.get("vaporized") in (None, "") and 0.0 < float(trip.get("arrival")) - arrived[name] <= 0.2 + 1e-6, name


@pytest.mark.parametrize("declared", [0.0, 2.0])
def test_sumo_inserts_a_controlled_car_no_faster_than_it_can_stop_at_the_declared_deceleration(tmp_path, capsys, declared):
    """A controlled car of a user's routes departs at ``departSpeed="max"`` with its front at the
    road's start, 30.5 m behind the rear of a car standing in its lane. SUMO picks the fastest
    speed from which the car's vType can stop behind it: with ``sumo.declared_decel`` (2 m/s^2)
    below sqrt(2 * 2 * 30.5) = 11 m/s, as the car will brake once ours; with the vType's own
    6 m/s^2, faster than that."""
    flows = """<vType id="quick" length="4.5" width="1.8" decel="6.0"/>
        <vehicle id="wall" type="bg" route="road" depart="0" departPos="35" departLane="1" departSpeed="0">
            <stop lane="E0_1" endPos="35" duration="1000"/></vehicle>
        <vehicle id="ours.0" type="quick" route="road" depart="0" departPos="0" departLane="1" departSpeed="max"/>"""
    cfg = user_config(tmp_path, flows)
    out = tmp_path / "out"
    code = cli.main(["run", "lane_change", "--set", f"sumo.config={cfg}", "--set", "sumo.controlled_types=quick",
                     "--set", f"sumo.declared_decel={declared}", "--set", "scenario.duration=0.5", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    speed = pd.read_csv(out / "steps.csv").query("robot == 'ours.0'").v.iloc[0]
    assert (speed**2 < 2.0 * 2.0 * 30.5) == bool(declared), speed


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
    """The bundled highway's first 65 s (real libsumo; the 100-car run itself is measured in
    docs/highway_work_zone.md): the flow's cars enter one every 2.4 s, each recorded only from
    its departure; those from the closed lane are out of it before the first cone (x = 800 m)
    and the leaders drive along the work zone; nothing collides, by our check or SUMO's own, whose
    collision output holds exactly the pairs counted."""
    import xml.etree.ElementTree as ET

    out = tmp_path / "out"
    assert cli.main(["run", "highway_work_zone", "--set", "scenario.duration=65", "--set", "sumo.outputs=collision",
                     "--out", str(out)]) in (0, 1)
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["n_robots"] == 28 and not metrics.get("error")  # departures at 0, 2.4, ..., 64.8 s
    assert metrics["collisions"] == 0 and metrics["sim_collisions"] == 0
    assert ET.parse(out / "collision.xml").getroot().findall("collision") == []
    steps = pd.read_csv(out / "steps.csv")
    first = steps.groupby("robot")["t"].min()
    assert len(first) == 28 and np.all(np.diff(np.sort(first.to_numpy())) > 1.5)  # one every 2.4 s, as SUMO inserts them
    closed = steps[(steps.x > 790.0) & (steps.x < 950.0)]
    assert len(closed) and closed.y.min() > -12.25 + 1.75  # nobody's rear axle in the closed lane's half beside the cones
    assert steps.x.max() > 900.0  # the leader drives along the cones (x = 800-950 m; waiting for gaps slows it below 16 m/s)


# --- gap acceptance of the routed cars' lane changes (no SUMO run: the lane plans on synthetic worlds) ---


def routed_cars(*sets: str):
    """RoutedCars for three controlled cars on the bundled 3-lane road (lanes at y = -8, -4.8,
    -1.6 m, x from 0 to 420 m), each changing to lane 1, and an AAC coordinator over them."""
    from aac_sumo import config
    from aac_sumo.experiments.common import coordinator
    from aac_sumo.experiments.routed_cars import RoutedCars
    from aac_sumo.sim.sumo_routes import RoutedVehicle

    scenario = config.load("lane_change", ["sumo.controlled_types=mine", "lane_change.exit_lanes=[1]", "lane_change.speed=16",
                                           "lane_change.finish_margin=0", *sets])
    vehicles = [RoutedVehicle(f"car{k}", "mine", 0.0, 4.0, 1.8, ("E0", "E1")) for k in range(3)]
    from aac_sumo.experiments.common import robot_spec
    robots = [robot_spec(scenario, v.id, v.length, v.width) for v in vehicles]
    cars = RoutedCars(scenario, network.read(NET, "sumo.net", "test"), vehicles, robots, None)
    cars.coordinator = coordinator(scenario, cars.tasks, cars.bands, None, band=True)
    return cars, robots


def highway_world(cars, robots, rows, t=0.0, obstacles=()):
    """The cars ``rows`` ``{k: (x, y, v)}`` (rear axles, heading +x) on the road, the others parked."""
    from aac_sumo.world import WorldState, parking_spot

    states = np.array([parking_spot(k) for k in range(len(robots))])
    present = np.zeros(len(robots), dtype=bool)
    for k, (x, y, v) in rows.items():
        states[k], present[k] = [x, y, 0.0, v], True
    return WorldState(t, states, robots, list(obstacles), present)


def car_at(name, x, y, v):
    from aac_sumo.world import Obstacle

    return Obstacle(name, "scripted", np.array([x, y]), np.array([v, 0.0]), 0.0, 4.5, 1.8)


def test_a_change_waits_for_a_safe_gap_then_begins():
    cars, robots = routed_cars()
    world = highway_world(cars, robots, {0: (20.0, -8.0, 16.0)}, obstacles=[car_at("bg", 21.3, -4.8, 16.0)])
    cars.admit(world, 0)
    cars.judge(world)
    plan = cars.plans[0]
    assert plan.waiting and plan.ahead[0].begin > 20.0 + cars.preview  # beside it: it keeps its lane ...
    ref = cars.tasks[0]
    assert ref.speed_at(ref.project([30.0, -8.0])[0]) == pytest.approx(0.75 * 16.0)  # ... and slows to gap_speed
    assert np.abs(ref.points[ref.points[:, 0] < plan.ahead[0].begin][:, 1] + 8.0).max() < 1e-9
    assert cars.counts["lane_change_waits"] == 1
    clear = highway_world(cars, robots, {0: (40.0, -8.0, 12.0)}, t=2.0, obstacles=[car_at("bg", 120.0, -4.8, 16.0)])
    cars.judge(clear)
    assert plan.accepted and not plan.done  # accepted ahead of its begin ...
    begin = plan.ahead[0].begin
    cars.judge(highway_world(cars, robots, {0: (begin + 0.5, -8.0, 12.0)}, t=4.0, obstacles=[car_at("bg", 200.0, -4.8, 16.0)]))
    assert [c.lane for c in plan.done] == [1] and cars.counts["lane_changes"] == 1  # ... begun once past it
    assert cars.tasks[0].pose_at(cars.tasks[0].project([begin + 45.0, -4.8])[0])[0, 1] == pytest.approx(-4.8, abs=1e-6)


def test_a_controlled_car_behind_lets_the_waiting_car_in_and_one_change_turns_back():
    cars, robots = routed_cars()
    # car 0 at 8 m/s; car 1 in lane 1, 50 m behind at 16 m/s: 46 m bumper gap, the rule needs 2 + 16 + (16^2 - 8^2) / 6 = 50 m;
    # the rule's gap behind car 0 begins at x = 80 - 3.3 - 0.7 - 2 - 8 = 66 m
    world = highway_world(cars, robots, {0: (80.0, -8.0, 8.0), 1: (30.0, -4.8, 16.0)})
    cars.admit(world, 0)
    cars.admit(world, 1)  # car 1 starts in lane 1, its exit: nothing to change
    cars.judge(world)
    assert cars.plans[0].waiting and not cars.plans[0].slow  # held up by car 1 behind it: it keeps its speed ...
    assert cars.plans[1].courtesy_for == 0 and cars.plans[1].courtesy == pytest.approx(66.0)  # ... and car 1 lets it in,
    one = cars.tasks[1]
    for x, v in ((30.0, np.sqrt(8.0**2 + 2 * 1.5 * 36.0)), (66.0, 8.0)):  # slowing to car 0's 8 m/s by 66 m
        assert one.speed_at(one.project([x, -4.8])[0]) == pytest.approx(v, abs=0.05)
    # car 0 stands (at a closed lane, say): car 1, 2 m behind it at 16 m/s, can no longer stop before its gap: it passes
    standing = highway_world(cars, robots, {0: (100.0, -8.0, 0.0), 1: (98.0, -4.8, 16.0)}, t=1.0)
    cars.judge(standing)
    assert cars.plans[0].slow and cars.plans[1].courtesy_for == -1
    # car 0 begins its change into a free lane; a fast car appears close behind before it is across: it turns back
    begin = cars.plans[0].ahead[0].begin
    free = highway_world(cars, robots, {0: (begin - 1.0, -8.0, 16.0), 1: (-200.0, -4.8, 16.0)}, t=3.0)
    cars.judge(free)
    cars.judge(highway_world(cars, robots, {0: (begin + 1.0, -8.0, 16.0), 1: (-200.0, -4.8, 16.0)}, t=3.1))
    assert cars.plans[0].done and not cars.plans[0].crossed and cars.plans[1].courtesy_for == -1
    cut = highway_world(cars, robots, {0: (begin + 5.0, -7.9, 16.0), 1: (begin - 3.0, -4.8, 22.0)}, t=3.4)
    cars.judge(cut)
    plan = cars.plans[0]
    assert [c.kind for c in plan.done] == ["exit", "back"] and plan.ahead[0].lane == 1 and cars.counts["lane_change_aborts"] == 1
    back = cars.tasks[0]
    assert back.pose_at(back.project([begin + 50.0, -8.0])[0])[0, 1] == pytest.approx(-8.0, abs=1e-6)  # back in its lane (until it tries again)


@pytest.mark.slow
def test_on_the_highway_no_lane_change_begins_into_an_unsafe_gap(tmp_path):
    """The bundled highway's first 100 s (real libsumo). Every lane change whose reference leaves
    its lane on the straight road (x < 1400 m: out of the closed lane, onto the exit lanes) is
    found in steps.csv: where the reference's smoothstep begins follows from how far it is off
    its lane (3.5 m apart, 40 m per change), and the change began in the period whose rear axle
    was there first. In the world recorded then (trajectories.csv) every car reaching into the
    target lane left the rule's gaps, checked here by hand: bumper gaps and speeds along x,
    tau = 1 s, b = 3 m/s^2, g0 = 2 m. Some changes had to wait for their gap."""
    from aac_sumo.experiments.lane_gaps import GapRule
    from aac_sumo.experiments.lane_geometry import smooth_road, smoothstep
    from aac_sumo.references import PathReference

    out = tmp_path / "out"
    assert cli.main(["run", "highway_work_zone", "--set", "scenario.duration=100", "--out", str(out)]) in (0, 1)
    metrics = pd.read_json(out / "metrics.json", typ="series")
    assert metrics["collisions"] == 0 and metrics["lane_change_waits"] > 0
    net = network.read(BUNDLED_NET_DIR.parent / "highway_work_zone" / "highway_work_zone.net.xml", "sumo.net", "test")
    road = smooth_road(network.chain_road(network.chain_of(net, ["entry", "approach", "work", "after", "exit"])))
    lines = [PathReference(line, 1.0, stop_at_end=False) for line in road.lanes]  # the lines the references are made of
    centre_y = [-12.25, -8.75, -5.25, -1.75]
    steps = pd.read_csv(out / "steps.csv").sort_values(["robot", "t"])
    off = np.array([line.project_many(steps[["ref_x", "ref_y"]].to_numpy())[1] for line in lines])  # (lanes, rows)
    steps["lane"], steps["off"] = off.argmin(axis=0), off.min(axis=0)
    traj = pd.read_csv(out / "trajectories.csv")
    rule, u = GapRule(1.0, 3.0, 2.0), np.linspace(0.0, 0.5, 5001)
    begins = 0
    for robot, rows in steps.groupby("robot"):
        leaving = (rows["off"].shift() < 1e-3) & (rows["off"] >= 1e-3) & (rows["ref_x"] < 1400.0)
        for k in np.flatnonzero(leaving.to_numpy()):
            row, lane = rows.iloc[k], int(rows.iloc[k - 1].lane)
            pose = lines[lane].pose_at(lines[lane].project([row.ref_x, row.ref_y])[0])[0]
            left = np.cos(pose[2]) * (row.ref_y - pose[1]) - np.sin(pose[2]) * (row.ref_x - pose[0]) > 0.0
            target = lane + (1 if left else -1)
            begin = row.ref_x - 40.0 * np.interp(row.off / 3.5, smoothstep(u), u)
            t = rows[rows.x >= begin].iloc[0].t
            world = traj[np.isclose(traj.t, t)]
            ego = world[world["name"] == robot].iloc[0]
            there = world[(world["name"] != robot) & (np.abs(world.y - centre_y[target]) < 1.75 + 0.5 * world.width)]
            gap = np.abs(there.x - ego.x) - 0.5 * (there.length + ego.length)
            v, v_other = ego.v * np.cos(ego.heading), there.v * np.cos(there.heading)
            need = [rule.ahead(v, w) if x >= ego.x else rule.behind(w, v) for x, w in zip(there.x, v_other)]
            margin = np.min(np.where(gap < 0.0, -np.inf, gap - need), initial=np.inf)
            assert margin >= 0.0, f"{robot} began its change into lane {target} at t = {t} with a gap {margin:.2f} m short"
            begins += 1
    assert begins >= 5  # 9 at ad23cf3: the check above is not vacuous
