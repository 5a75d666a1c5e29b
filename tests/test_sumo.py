"""SUMO co-simulation: real libsumo runs on the bundled and on generated networks (no mock of SUMO)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import sumolib

from aac_sumo import config, network
from aac_sumo.runs import runner
from aac_sumo.cli.app import main
from aac_sumo.experiments import build
from aac_sumo.experiments.common import robot_spec
from aac_sumo.experiments.lane_change import (BAND_SETTLE, BUNDLED_NET, BUNDLED_NET_DIR, lane_change_band, arrivals,
                                              scenario_road, target_lane)
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import PathReference
from aac_sumo.geometry import rect_clearance_rows
from aac_sumo.sim.sumo_options import SumoOptions
from aac_sumo.sim.sumo import SumoSimulator

CONES = BUNDLED_NET_DIR / "cones.rou.xml"
PEDESTRIANS = BUNDLED_NET_DIR / "pedestrians.rou.xml"
LANE_Y = {0: -8.0, 1: -4.8, 2: -1.6}  # bundled road, lane centre lines (x from 0 to 236.5 m)
SMALL = ["controller.coordinator=independent", "controller.horizon=5"]


def cars(*names: str):
    scenario = config.load("lane_change")
    return [robot_spec(scenario, n) for n in names]


def sim_with(states, routes=(), names=None) -> SumoSimulator:
    """A SUMO world on the bundled road with cars at rear-axle ``states`` (n, 4)."""
    robots = cars(*(names or [f"car{i}" for i in range(len(states))]))
    return SumoSimulator(robots, np.array(states, dtype=float), 0.1, ["E0", "E1"], SumoOptions(BUNDLED_NET, list(routes)))


def test_written_poses_read_back_one_step_later():
    """Each step our model's pose goes to SUMO with moveToXY; SUMO's getters (previous step's
    values, so read after the step) return it within 1 cm and 0.1 degree."""
    sim = sim_with([[20.0, LANE_Y[0], 0.0, 10.0], [20.0, LANE_Y[2], 0.05, 8.0]])
    try:
        inputs = np.array([[1.0, 0.05], [-1.0, -0.1]])
        for _ in range(10):
            expected = [r.model.step(s, u, sim.dt) for r, s, u in zip(sim.robots, sim.states.copy(), inputs)]
            sim.step(inputs)
            assert np.abs(sim.states[:, :2] - np.array(expected)[:, :2]).max() < 0.01
            assert np.degrees(np.abs(np.angle(np.exp(1j * (sim.states[:, 2] - np.array(expected)[:, 2]))))).max() < 0.1
    finally:
        sim.close()


@pytest.mark.parametrize("declared", [0.0, 2.0])
def test_sumo_is_told_the_deceleration_declared_for_our_cars(declared):
    """With ``sumo.declared_decel`` SUMO's drivers take our cars to brake at that deceleration
    (their vType's ``decel``, read back through libsumo); without it the vType's own stands."""
    robots = cars("car0")
    options = SumoOptions(BUNDLED_NET, declared_decel=declared)
    sim = SumoSimulator(robots, np.array([[20.0, LANE_Y[0], 0.0, 10.0]]), 0.1, ["E0", "E1"], options)
    try:
        sim.step(np.zeros((1, 2)))
        decel = sim.api.vehicle.getDecel("car0")
        if declared > 0.0:
            assert decel == pytest.approx(declared)
        else:  # SUMO's default passenger type
            assert decel == pytest.approx(sim.api.vehicletype.getDecel(sim.api.vehicle.getTypeID("car0"))) and decel != pytest.approx(2.0)
    finally:
        sim.close()


def test_two_vehicles_twenty_steps_move_without_collision():
    scenario = config.load("lane_change", SMALL + ["lane_change.vehicles=2", "scenario.duration=2.0"])
    result = runner.run(scenario)
    m, steps = result.metrics, result.steps
    assert "error" not in m
    assert len(steps) == 2 * 20
    travelled = steps.groupby("robot")["x"].agg(lambda x: x.iloc[-1] - x.iloc[0])
    assert (travelled > 15.0).all()  # ~10 m/s for 1.9 s
    assert m["collisions"] == 0 and m["sim_collisions"] == 0


def test_same_seed_same_run():
    sets = SMALL + ["lane_change.vehicles=3", "scenario.duration=1.0", "scenario.seed=4"]
    a, b = (runner.run(config.load("lane_change", sets)).trajectories for _ in range(2))
    assert a[["x", "y", "heading"]].equals(b[["x", "y", "heading"]])


def test_rear_end_overlap_is_counted_by_us_and_by_sumo():
    """A car at 10 m/s drives blindly into a stopped one 2 m ahead (bumper to bumper)."""
    sim = sim_with([[20.0, LANE_Y[1], 0.0, 10.0], [26.0, LANE_Y[1], 0.0, 0.0]])
    try:
        reports = [sim.step(np.zeros((2, 2))) for _ in range(5)]
    finally:
        sim.close()
    assert any(("car0", "car1") in r.overlaps for r in reports)
    assert sum(r.sim_collisions for r in reports) >= 1
    assert min(r.clearance.min() for r in reports) < 0


def test_sim_collisions_equal_sumo_collision_output(tmp_path):
    """Asked for SUMO's collision output, the run writes collision.xml beside ours, and the new
    pairs we count as ``sim_collisions`` are the distinct pairs in it; SUMO's messages go to
    sumo.log there. (A car at 10 m/s drives blindly into a stopped one, and into a cone.)"""
    robots = cars("car0", "car1", "car2")
    states = np.array([[20.0, LANE_Y[1], 0.0, 10.0], [26.0, LANE_Y[1], 0.0, 0.0], [181.0, LANE_Y[0], 0.0, 9.0]])
    options = SumoOptions(BUNDLED_NET, [CONES], output_dir=tmp_path, outputs=("collision", "tripinfo"))
    sim = SumoSimulator(robots, states, 0.1, ["E0", "E1"], options)
    try:
        counted = sum(sim.step(np.zeros((3, 2))).sim_collisions for _ in range(20))
    finally:
        sim.close()
    written = ET.parse(tmp_path / "collision.xml").getroot().findall("collision")
    pairs = {tuple(sorted((c.get("collider"), c.get("victim")))) for c in written}
    assert counted == len(pairs) >= 2
    assert (tmp_path / "tripinfo.xml").exists() and (tmp_path / "sumo.log").read_text().strip()


def test_sumos_own_output_shows_each_car_at_its_start_speed_from_the_first_step(tmp_path):
    """fcd.xml's first timestep (t = 0) has every controlled car at the speed it starts with, as
    our state has it (it showed 0.00 for cars starting at 10 m/s), and a standing one at 0."""
    robots = cars("car0", "car1")
    states = np.array([[20.0, LANE_Y[1], 0.0, 10.0], [60.0, LANE_Y[0], 0.0, 0.0]])
    sim = SumoSimulator(robots, states, 0.1, ["E0", "E1"], SumoOptions(BUNDLED_NET, output_dir=tmp_path, outputs=("fcd",)))
    try:
        sim.step(np.zeros((2, 2)))
    finally:
        sim.close()
    first = ET.parse(tmp_path / "fcd.xml").getroot().find("timestep")
    assert float(first.get("time")) == 0.0
    speeds = {v.get("id"): float(v.get("speed")) for v in first.findall("vehicle")}
    assert speeds == {"car0": pytest.approx(10.0), "car1": pytest.approx(0.0)}


def test_a_finished_car_arrives_in_sumo_when_it_finishes_and_leaves_our_road_at_its_end(tmp_path):
    """Two cars at 10 m/s in the middle lane, 60 and 90 m before the road's end; the first
    finishes its task at t = 1 s. SUMO takes it as arrived then (tripinfo.xml lists its trip
    with that arrival, within one step, and fcd.xml ends its track there), while our model drives
    it on, on our road, until its front is within its stopping distance at 4.5 m/s^2 of the end,
    where it leaves our road; it never goes past the lane's end, and SUMO reports no emergency
    stop (finished cars used to drive on up to 60 m past the network's end). The car that has
    not finished drives on in SUMO."""
    road = scenario_road(config.load("lane_change"), BUNDLED_NET)
    end = road.length(1)
    robots = cars("car0", "car1")
    states = np.array([[end - 60.0, LANE_Y[1], 0.0, 10.0], [end - 90.0, LANE_Y[1], 0.0, 10.0]])
    sim = SumoSimulator(robots, states, 0.1, ["E0", "E1"], SumoOptions(BUNDLED_NET, output_dir=tmp_path, outputs=("fcd", "tripinfo")))
    line = PathReference(road.lanes[1], 10.0, stop_at_end=False)
    prepare = arrivals(sim, robots, [line, line], [end, end], lambda w: np.array([w.t >= 1.0 - 1e-9, False]), 0.1)
    front = robots[0].centre_offset + 0.5 * robots[0].length
    on_road, xs_ours = [], []
    try:
        for _ in range(60):
            world = prepare(sim.observe())
            on_road.append((round(world.t, 6), bool(world.on_road[0]), "car0" in sim.arrived))
            if world.on_road[0]:
                xs_ours.append(world.states[0, 0] + front)
            sim.step(np.zeros((2, 2)))
        assert world.on_road[1] and "car1" not in sim.arrived and "car0" in sim.removed
    finally:
        sim.close()
    assert [t for t, _, gone in on_road if gone][0] == pytest.approx(1.0)  # SUMO took it as arrived when it finished
    left = [t for t, here, _ in on_road if not here][0]
    assert 3.0 < left < 6.0  # it drove on on our road, and left it before its front reached the end
    assert max(xs_ours) <= road.lanes[1][-1, 0] + 1e-6
    trips = {t.get("id"): t for t in ET.parse(tmp_path / "tripinfo.xml").getroot().findall("tripinfo")}
    assert set(trips) == {"car0"} and abs(float(trips["car0"].get("arrival")) - 1.0) <= 0.1 + 1e-9
    track = [float(step.get("time")) for step in ET.parse(tmp_path / "fcd.xml").getroot() for v in step.findall("vehicle")
             if v.get("id") == "car0"]
    assert max(track) <= 1.0 + 1e-9
    assert "emergency" not in (tmp_path / "sumo.log").read_text().lower()


def test_outputs_key_takes_only_sumos_outputs(tmp_path, capsys):
    assert main(["run", "lane_change", "--set", "sumo.outputs=fcd,emissions", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sumo.outputs" in err and "fcd, tripinfo, collision, summary, lanechange" in err


def test_cones_are_static_obstacles_sumo_also_collides_with():
    sim = sim_with([[150.0, LANE_Y[0], 0.0, 10.0]], routes=[CONES])
    try:
        cones = [o for o in sim.observe().obstacles if o.kind == "cone"]
        assert len(cones) == 5
        assert all(np.allclose(c.velocity, 0.0) and abs(c.centre[1] - LANE_Y[0]) < 1e-6 for c in cones)
        assert sorted(c.centre[0] for c in cones) == pytest.approx([189.8, 199.8, 209.8, 219.8, 229.8])
        sim.states[0, :2] = [187.0, LANE_Y[0]]  # the next step puts its front bumper at 191.3 m, over cone0
        report = sim.step(np.zeros((1, 2)))
    finally:
        sim.close()
    assert ("car0", "cone0") in report.overlaps
    assert report.sim_collisions == 1


def test_pedestrian_reaches_the_mpc_obstacle_list():
    sim = sim_with([[200.0, LANE_Y[1], 0.0, 0.0]], routes=[PEDESTRIANS])
    try:
        for _ in range(20):
            sim.step(np.zeros((1, 2)))
        world = sim.observe()
        peds = [o for o in world.obstacles if o.kind == "pedestrian"]
        assert {p.name for p in peds} == {"p0", "p1"}
        p1 = next(p for p in peds if p.name == "p1")
        x, y = sim.api.person.getPosition("p1")  # SUMO: front of the walker, walking north
        assert p1.centre == pytest.approx([x, y - 0.5 * p1.length], abs=1e-6)
        assert p1.velocity[1] > 0.5 and abs(p1.velocity[0]) < 1e-6
    finally:
        sim.close()
    cfg = MpcConfig(horizon=5, slots=4)
    params = MpcPlanner(cfg).obstacle_parameters(world.robots[0], world.states[0], world.obstacles)
    active = params[0, params[0, :, 6] == 1.0]
    assert any(np.allclose(row[:2], p1.centre) for row in active)


def test_a_walker_on_a_footpath_knows_how_far_its_ends_are_and_one_on_the_crossing_does_not():
    """p1 starts 3 m along the footpath FS (pedestrians only), walks to the road and onto the zebra
    crossing, an internal lane of the junction: there she is on no walkway of her own."""
    sim = sim_with([[100.0, LANE_Y[1], 0.0, 0.0]], routes=[PEDESTRIANS])
    try:
        sim.step(np.zeros((1, 2)))
        lane = sim.api.person.getLaneID("p1")
        p1 = next(o for o in sim.observe().obstacles if o.name == "p1")
        assert lane.startswith("FS") and p1.walkway is not None
        assert sum(p1.walkway) == pytest.approx(sim.api.lane.getLength(lane))
        assert p1.walkway[0] == pytest.approx(sim.api.person.getLanePosition("p1"))
        for _ in range(300):
            sim.step(np.zeros((1, 2)))
            if sim.api.person.getLaneID("p1").startswith(":"):
                break
        assert sim.api.person.getLaneID("p1").startswith(":")
        assert next(o for o in sim.observe().obstacles if o.name == "p1").walkway is None
    finally:
        sim.close()


def test_a_vehicle_sumo_removes_drives_on_off_the_road_finished_and_the_run_goes_on(capsys):
    """A controlled vehicle SUMO no longer has (it left the network) moves on under our model
    alone, counts as finished, is out of the collision check, and the event is reported."""
    setup = build(config.load("lane_change", SMALL + ["lane_change.vehicles=2", "sumo.isolate=false"]))  # reaches into libsumo
    sim = setup.sim
    try:
        for k in range(10):
            if k == 3:
                sim.api.vehicle.remove("veh1")
            world = sim.observe()
            report = sim.step(setup.coordinator.decide(world).inputs)
        before = sim.states[1].copy()
        sim.step(np.zeros((2, 2)))
        assert "veh1" in sim.removed and before[3] > 0.0
        np.testing.assert_allclose(sim.states[1], sim.robots[1].model.step(before, np.zeros(2), sim.dt))
        assert report.clearance[1] == np.inf
        assert setup.finished(sim.observe()).tolist() == [False, True]
        assert sim.events and "veh1" in sim.events[0]
    finally:
        sim.close()
    assert "SUMO removed controlled vehicle veh1" in capsys.readouterr().err


def test_target_lanes_move_away_from_the_cone_lane():
    assert [target_lane(i, 0, 3) for i in range(3)] == [1, 2, 1]
    assert [target_lane(i, 2, 3) for i in range(3)] == [1, 0, 1]
    assert [target_lane(i, 0, 2) for i in range(2)] == [1, 1]  # nowhere to go but the cone lane: keep lane


@pytest.mark.parametrize("start, target", [(0, 1), (1, 2), (2, 1)])
def test_lane_change_band_spans_both_lanes_then_narrows_to_the_target(start, target):
    """Until its lane change ends a vehicle may be anywhere in its start and target lanes; from
    BAND_SETTLE metres beyond, only in its target lane (margin 1 m inside the lane edges)."""
    radius = [500.0 - 3.2 * (i - 1) for i in range(3)]  # a 3-lane road curving left

    def point(lane: int, s: float) -> np.ndarray:
        """Rear-axle state on lane ``lane``'s centre line at arc length ``s``."""
        angle = s / radius[lane]
        return np.array([radius[lane] * np.sin(angle), 500.0 - radius[lane] * np.cos(angle), angle, 10.0])

    lanes = [np.array([point(i, s)[:2] for s in np.linspace(0.0, 250.0, 251)]) for i in range(3)]
    change_end = 100.0
    band = lane_change_band(network.Road(["E0"], lanes, [3.2, 3.2, 3.2]), start, target, change_end, margin=1.0)

    def inside(lane: int, s: float) -> bool:
        ref = np.array([point(lane, s - 1.0), point(lane, s)])
        nx, ny, lo, hi = band.limits(ref)[0]
        return bool(lo <= nx * ref[1, 0] + ny * ref[1, 1] <= hi)

    for s in (20.0, change_end - 5.0):
        assert inside(start, s) and inside(target, s)
    for s in (change_end + BAND_SETTLE + 5.0, 200.0):
        assert inside(target, s) and not inside(start, s)
    other = 3 - start - target
    assert not any(inside(other, s) for s in (20.0, 200.0))


def test_net_build_reproduces_the_bundled_lanes(tmp_path):
    src = tmp_path / "lane_change"
    shutil.copytree(BUNDLED_NET_DIR, src, ignore=shutil.ignore_patterns("*.net.xml"))
    assert main(["net", "build", str(src)]) == 0
    built, bundled = (sumolib.net.readNet(str(p)) for p in (src / "lane_change.net.xml", BUNDLED_NET))
    lanes = {lane.getID(): lane.getShape() for e in bundled.getEdges() for lane in e.getLanes()}
    assert {lane.getID(): lane.getShape() for e in built.getEdges() for lane in e.getLanes()} == lanes


def write_curved_net(folder: Path, lanes: int, width: float = 3.5, lane_xml: str = "") -> Path:
    """A curved road R (arc of radius 150 m, ~340 m long) with ``lanes`` lanes ``width`` [m]
    wide (``lane_xml``: ``<lane>`` elements that set some lanes apart), built by netconvert."""
    folder.mkdir()
    arc = [(150 * np.sin(t), 150 * (1 - np.cos(t))) for t in np.linspace(0, 2.3, 40)]
    shape = " ".join(f"{x:.2f},{y:.2f}" for x, y in arc)
    (folder / "curve.nod.xml").write_text(
        f'<nodes><node id="A" x="0" y="0"/><node id="B" x="{arc[-1][0]:.2f}" y="{arc[-1][1]:.2f}"/></nodes>')
    (folder / "curve.edg.xml").write_text(
        f'<edges><edge id="R" from="A" to="B" numLanes="{lanes}" speed="13.9" width="{width}" shape="{shape}">{lane_xml}</edge></edges>')
    built = network.build(folder)
    assert built == [folder / f"{folder.name}.net.xml"]
    return built[0]


def test_one_lane_network_is_rejected_with_one_line(tmp_path, capsys):
    net = write_curved_net(tmp_path / "narrow", 1)
    assert main(["run", "lane_change", "--set", f"sumo.net={net}", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "sumo.net" in err and "at least 2 lanes open to passenger" in err
    assert "the best candidate: edges R, 1 lane, " in err and "aac-sumo net info" in err


def test_scenario_runs_to_completion_on_a_curved_four_lane_network(tmp_path):
    net = write_curved_net(tmp_path / "curve", 4)
    cones = tmp_path / "cones.rou.xml"
    cones.write_text(
        '<routes><vType id="cone" length="0.4" width="0.4" minGap="0"/>'
        + "".join(f'<vehicle id="c{i}" type="cone" depart="0" departLane="0" departPos="{p}" departSpeed="0"><route edges="R"/>'
                  f'<stop lane="R_0" startPos="{p - 0.4}" endPos="{p}" duration="1000"/></vehicle>' for i, p in enumerate((120, 130)))
        + "</routes>")
    scenario = config.load("lane_change", SMALL + ["lane_change.vehicles=4", f"sumo.net={net}", f"sumo.routes={cones}",
                                                   "scenario.duration=25.0"])
    m = runner.run(scenario).metrics
    assert "error" not in m
    assert m["completed"] is True and m["collisions"] == 0
    assert m["tracking_error_m"] < 0.5  # the references follow the curved lanes


@pytest.mark.slow
@pytest.mark.parametrize("name", ["aac", "lfc"])
def test_fifteen_vehicles_change_lanes_without_collision(name):
    m = runner.run(config.load("lane_change", [f"controller.coordinator={name}", "controller.horizon=10"])).metrics
    assert "error" not in m
    assert m["n_robots"] == 15
    assert m["collisions"] == 0
    assert m["completed"] is True


def test_sumo_binaries_come_from_the_wheel():
    done = subprocess.run([network.sumo_binary("sumo"), "--version"], capture_output=True, text=True)
    assert done.returncode == 0 and "Eclipse SUMO" in done.stdout


def test_sumo_counts_a_car_changing_lanes_by_its_box_along_the_lane_and_we_see_that_box():
    """With SUMO's continuous lane change (``--lanechange.duration 2``) SUMO checks two cars on a
    lane as boxes along the lane, each behind its front and at its front's lateral position. A
    4.5 m SUMO car pulling out of lane 2 into lane 1 at 24 degrees (its front 1.4 m into lane 1)
    ahead of our car standing in lane 1: their bodies stay 1.3 m apart, yet SUMO reports a
    collision once our front is 0.3 m inside its box, and none 0.2 m behind it. The coordinators
    see that car as its collision cover, which overlaps ours exactly then; the recorded body does
    not."""
    def place(front_x: float):
        sim = SumoSimulator(cars("car0"), np.array([[55.8 - 3.3, LANE_Y[1], 0.0, 0.0]]), 0.1, ["E0", "E1"],
                            SumoOptions(BUNDLED_NET, extra_args=("--lanechange.duration", "2")))
        try:
            api = sim.api
            api.vehicletype.copy("DEFAULT_VEHTYPE", "bg")
            api.vehicletype.setLength("bg", 4.5)
            api.vehicletype.setWidth("bg", 1.8)
            api.vehicle.add("bg", "aac_road", "bg", depart="now", departSpeed="0")
            api.vehicle.setSpeedMode("bg", 0)
            api.vehicle.setLaneChangeMode("bg", 0)
            reports = []
            for _ in range(3):
                api.vehicle.moveToXY("bg", "", -1, front_x, LANE_Y[1] + 1.4, 114.0, keepRoute=2)
                reports.append(sim.step(np.zeros((1, 2))))
            seen = next(o for o in sim.observe().obstacles if o.name == "bg")
            body = next(a for a in sim.agents() if a["name"] == "bg")
            ours = sim.observe().robot_footprints()
        finally:
            sim.close()
        covered = rect_clearance_rows(ours, seen.footprint()[None, :])[0]
        apart = rect_clearance_rows(ours, np.array([[body["x"], body["y"], body["length"], body["width"], body["heading"]]]))[0]
        return sum(r.sim_collisions for r in reports), covered, apart, reports[-1].overlaps

    sumo, covered, apart, overlaps = place(60.0)  # SUMO's box from 55.5 m: our front (55.8 m) is 0.3 m inside
    assert sumo == 1 and covered < 0.0 and apart > 1.0 and not overlaps
    sumo, covered, apart, _ = place(60.5)  # from 56.0 m: 0.2 m ahead of our front
    assert sumo == 0 and covered == pytest.approx(0.2, abs=1e-3) and apart > 1.0


def test_sumo_cars_changing_lanes_reach_the_coordinators_moving_across_and_in_both_lanes():
    """On the bundled highway, SUMO drives every car but ``aac.0`` (ours, driving straight on);
    with its continuous lane change the first SUMO car that changes lanes moves across its lane
    at its lateral speed (a lane per 2 s). The coordinators see it as its collision cover, which
    reaches from where SUMO counts it now to the centre of the lane it moves into, moving along
    the lane; the recorded body keeps its size and moves across as it does."""
    here = Path(__file__).resolve().parents[1] / "sumo_networks" / "highway_work_zone"
    options = SumoOptions(here / "highway_work_zone.net.xml", config=here / "highway_work_zone.sumocfg",
                          extra_args=("--lanechange.duration", "2"))
    robot = robot_spec(config.load("highway_work_zone"), "aac.0", 4.0, 1.8)
    sim = SumoSimulator([robot], np.zeros((1, 4)), 0.1, [], options, routed=frozenset({"aac.0"}))
    try:
        for _ in range(600):
            sim.step(np.zeros((1, 2)))
            moving = [o for o in sim.observe().obstacles if o.kind == "scripted" and abs(sim.api.vehicle.getLateralSpeed(o.name)) > 0.5]
            if moving:
                break
        seen = moving[0]
        v = sim.api.vehicle
        lateral, speed, front_y = v.getLateralSpeed(seen.name), v.getSpeed(seen.name), v.getPosition(seen.name)[1]
        target = min((-12.25, -8.75, -5.25, -1.75), key=lambda c: abs(c - (front_y + np.sign(lateral) * 1.75)))  # car lane centres
        body = next(a for a in sim.agents() if a["name"] == seen.name)
    finally:
        sim.close()
    assert abs(lateral) == pytest.approx(3.5 / 2.0, abs=0.01)
    assert seen.velocity == pytest.approx([speed, 0.0], abs=1e-6)  # the lanes run east (+x) here
    lo, hi = seen.centre[1] - 0.5 * seen.width, seen.centre[1] + 0.5 * seen.width
    assert lo <= min(front_y, target) - 0.9 + 1e-6 and hi >= max(front_y, target) + 0.9 - 1e-6  # from now to the new lane's centre
    assert body["width"] == 1.8 and seen.heading == pytest.approx(0.0, abs=1e-9)


def test_a_car_sumo_took_as_arrived_drives_on_bit_for_bit_as_in_sumo():
    """Once SUMO took a car as arrived (``arrive``) our model drives it on alone; its states are
    the very ones (every bit) it had when SUMO still read its pose back after each move (SUMO
    keeps a moved car's angle in radians, so its read-back heading may differ in the last bit),
    so that a run's decisions do not change with the arrival. It steers, so that its heading
    changes every step."""
    inputs = np.array([[0.5, 0.04], [0.0, 0.0]])
    tracks = []
    for arrive in (False, True):
        sim = sim_with([[20.0, LANE_Y[1], 0.0, 8.0], [20.0, LANE_Y[0], 0.0, 8.0]])
        try:
            track = []
            for k in range(40):
                if arrive and k == 5:
                    sim.arrive(0)
                sim.step(inputs)
                track.append(sim.observe().states.copy())
            assert ("car0" in sim.arrived) == arrive and "car0" not in sim.removed and sim.observe().on_road.all()
            assert ("car0" in set(sim.api.vehicle.getIDList())) != arrive
        finally:
            sim.close()
        tracks.append(np.array(track))
    assert np.array_equal(tracks[0], tracks[1])
    assert len(set(tracks[1][5:, 0, 2].tolist())) > 30  # its heading changed
