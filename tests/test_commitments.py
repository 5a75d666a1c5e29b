"""Committed plans: AAC is collision-free by construction, clusters are independent.

Every check uses the simulator's own footprint geometry or exact rectangle clearance, never
what the coordinator says about itself."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from aac_sumo import config, experiments
from aac_sumo.coordination.base import RobotDecision
from aac_sumo.coordination.commitments import CommitmentBook, clusters, reach_radii, stopping_commitment
from aac_sumo.coordination.traffic_courses import braking_courses, standing_points, stop_lines, traffic_clearances
from aac_sumo.coordination.make_room import MakeRoom
from aac_sumo.coordination.regions import Fleet
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.geometry import pairwise_rect_clearance
from aac_sumo.kernels.commitments import course_boxes, course_clearance, ragged_nearest
from aac_sumo.kernels.motion import footprint_rows
from aac_sumo.world import Obstacle, RobotSpec

#: Every emergency layer off: safety comes from the commitments alone.
PLAIN = ["aac.safety_stop=false", "lfc.safety_stop=false", "controller.coordinator=aac"]


def small_robot(i: int, reverse: bool = True) -> RobotSpec:
    limits = VehicleLimits(-2.0, 1.0, 0.6, -1.5 if reverse else 0.0, 1.5)
    return RobotSpec(f"robot{i}", 0.6, 0.4, BicycleModel(0.45, limits))


def drive(scenario, periods: int, check=None):
    """Run ``scenario``'s closed loop for ``periods``; call ``check(coordinator, world, period)``
    after every decision. Returns the inputs (periods, n, 2) and the simulator's contacts."""
    setup = experiments.build(scenario)
    sim, coord = setup.sim, setup.coordinator
    inputs, overlaps = [], set()
    for period in range(periods):
        world = sim.observe()
        decision = coord.decide(world)
        if check is not None:
            check(coord, world, period)
        inputs.append(decision.inputs.copy())
        overlaps |= sim.step(decision.inputs).overlaps
    return np.array(inputs), overlaps


def commitments_apart(coord, world, period):
    """The invariant: every two commitments keep the margin at every period from now on, and
    to the debris; and every robot is where its commitment says."""
    book = coord.book
    statics = np.array([o.footprint() for o in world.obstacles if o.kind in ("static", "cone")]).reshape(-1, 5)
    gaps = book.pairwise_clearance(period, statics)
    assert gaps.min() >= book.margin - 1e-9, f"period {period}: commitments {np.unravel_index(gaps.argmin(), gaps.shape)} at {gaps.min():.4f} m"
    expected = np.array([c.course(period, 0)[0] for c in book.items])
    # the simulator's steps and the commitment's compiled course round differently (seed 4063 of the
    # spread test: 8e-9 m/s apart after a few dozen periods)
    np.testing.assert_allclose(world.states, expected, rtol=0.0, atol=1e-7)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(3, 6), seed=st.integers(0, 10_000), clustered=st.booleans())
def test_random_small_crossings_never_collide_and_commitments_stay_apart(n, seed, clustered):
    authorities = '"clusters"' if clustered else "1"
    scenario = config.load("random_crossing", PLAIN + [f"random_crossing.n_robots={n}", f"scenario.seed={seed}",
                                                       f"aac.authorities={authorities}", "aac.keep_right=1.0"])
    _, overlaps = drive(scenario, 50, commitments_apart)
    assert not overlaps


def test_circle_swap_commitments_stay_apart_in_the_crowded_centre():
    scenario = config.load("circle_swap", PLAIN + ["circle_swap.n_robots=8"])
    _, overlaps = drive(scenario, 80, commitments_apart)
    assert not overlaps


def group(x0: float, y0: float) -> tuple[list, list]:
    """Three robots whose straight paths cross near (x0 + 3, y0)."""
    starts = [[x0, y0 - 1.5, 0.46], [x0, y0 + 1.5, -0.46], [x0 + 6.0, y0, np.pi]]
    goals = [[x0 + 6.0, y0 + 1.5], [x0 + 6.0, y0 - 1.5], [x0, y0]]
    return starts, goals


def swarm(starts, goals, commit: bool = True) -> list[str]:
    return PLAIN + ['aac.authorities="clusters"', f"aac.commit={str(commit).lower()}", "aac.make_room=false", "swarm_rescue.start_jitter=0.0", "swarm_rescue.debris=[]",
                    f"swarm_rescue.starts={starts}", f"swarm_rescue.goals={goals}"]


@pytest.mark.parametrize("commit,safety", [(True, False), (False, False), (False, True)],
                         ids=["committed", "stored_plans", "stored_plans_safety_stop"])
def test_far_apart_clusters_get_exactly_the_inputs_each_gets_alone(commit, safety):
    (sa, ga), (sb, gb) = group(0.0, 0.0), group(100.0, 40.0)
    layer = [f"aac.safety_stop={str(safety).lower()}"]
    together, _ = drive(config.load("swarm_rescue", swarm(sa + sb, ga + gb, commit) + layer), 40)
    alone_a, _ = drive(config.load("swarm_rescue", swarm(sa, ga, commit) + layer), 40)
    alone_b, _ = drive(config.load("swarm_rescue", swarm(sb, gb, commit) + layer), 40)
    np.testing.assert_array_equal(together[:, :3], alone_a)
    np.testing.assert_array_equal(together[:, 3:], alone_b)
    assert np.abs(alone_a).sum() > 0  # they did drive


@pytest.mark.parametrize("commit", [True, False], ids=["committed", "stored_plans"])
def test_one_authority_in_each_cluster_per_period(commit):
    (sa, ga), (sb, gb) = group(0.0, 0.0), group(100.0, 40.0)
    setup = experiments.build(config.load("swarm_rescue", swarm(sa + sb, ga + gb, commit)))
    world = setup.sim.observe()
    decision = setup.coordinator.decide(world)
    held = np.flatnonzero([r.authority for r in decision.robots])
    coord = setup.coordinator
    groups = clusters(world.robot_centres(), reach_radii(coord.fleet, world.states, coord.planner.config.horizon, 0.1), 0.05)
    assert len(held) == len(groups) == decision.notes["authorities"]
    assert all(len(set(held) & set(g)) == 1 for g in groups)  # exactly one in each
    assert all(set(g) <= {0, 1, 2} or set(g) <= {3, 4, 5} for g in groups)  # no cluster spans the two far groups


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), crowd=st.sampled_from([0, 4]))
@example(seed=4063, crowd=0)
def test_spread_authorities_keep_every_commitment_apart(seed, crowd):
    """Several authorities in one cluster plan in the same period (with ``crowd_authorities``, also
    robots whose reach discs meet); each commits only against the commitments made before it, so
    the invariant holds as with one."""
    scenario = config.load("random_crossing", PLAIN + ["random_crossing.n_robots=12", f"scenario.seed={seed}", 'aac.authorities="spread"',
                                                       f"aac.crowd_authorities={crowd}"])
    _, overlaps = drive(scenario, 40, commitments_apart)
    assert not overlaps


@pytest.mark.parametrize("crowd", [1, 3, 100])
def test_crowd_authorities_add_robots_in_no_close_pair_with_the_periods_authorities(crowd):
    """A packed 4 x 4 block, 0.9 m apart, all one cluster: "spread" alone gives the authorities
    whose reach discs cannot meet; ``crowd_authorities`` adds at most that many more, the
    longest-waiting first, each at least ``close_distance`` from every authority before it;
    with enough of them, every robot left out is in a close pair with one that plans."""
    starts = [[0.9 * (k % 4), 0.9 * (k // 4), 0.0] for k in range(16)]
    goals = [[0.9 * (k % 4) + 20.0, 0.9 * (k // 4)] for k in range(16)]
    sets = swarm(starts, goals) + ['aac.authorities="spread"', "controller.obstacle_slots=16"]
    spread = experiments.build(config.load("swarm_rescue", sets))
    crowded = experiments.build(config.load("swarm_rescue", sets + [f"aac.crowd_authorities={crowd}"]))
    world = crowded.sim.observe()
    members = np.arange(16)
    for setup in (spread, crowded):
        setup.coordinator.decide(world)  # builds its fleet
        assert len(setup.coordinator.groups(world, np.zeros(16, dtype=bool))) == 1  # one cluster (and this period's reach discs)
        setup.coordinator.last_turn[:] = 0
    before = [i for i, _ in spread.coordinator.turns_in_group(world, members, members, [RobotDecision(False)] * 16, 1)]
    turns = [(i, why) for i, why in crowded.coordinator.turns_in_group(world, members, members, [RobotDecision(False)] * 16, 1)]
    held = [i for i, _ in turns]
    assert held[: len(before)] == before  # the same first authorities
    extra = held[len(before):]
    assert 1 <= len(extra) <= crowd and all(why == "round_robin" for _, why in turns[len(before):])
    centres = world.robot_centres()
    close = crowded.coordinator.params.close_distance
    for k, i in enumerate(extra):
        earlier = held[: len(before) + k]
        assert np.hypot(*(centres[earlier] - centres[i]).T).min() >= close
    if crowd == 100:
        left = np.setdiff1d(members, held)
        assert all(np.hypot(*(centres[held] - centres[j]).T).min() < close for j in left)


def test_crowd_authorities_act_only_with_spread():
    """With one authority a period (the paper, the ablation's plain variants) the key changes
    nothing: the scenario may set it and a user's ``aac.authorities=1`` still gives one."""
    starts = [[0.9 * (k % 4), 0.9 * (k // 4), 0.0] for k in range(16)]
    goals = [[0.9 * (k % 4) + 20.0, 0.9 * (k // 4)] for k in range(16)]
    setup = experiments.build(config.load("swarm_rescue", swarm(starts, goals) + ["aac.authorities=1", "aac.crowd_authorities=5",
                                                                                 "controller.obstacle_slots=16"]))
    assert setup.coordinator.decide(setup.sim.observe()).notes["authorities"] == 1


def test_spread_gives_a_long_cluster_one_authority_per_stretch_that_cannot_meet():
    """Nine robots in a row 1.2 m apart, each reach disc meeting its neighbours': one cluster.
    "clusters" gives it one authority; "spread" more, every two of them with reach discs apart."""
    starts = [[1.2 * k, 0.0, 0.0] for k in range(9)]
    goals = [[1.2 * k + 20.0, 0.0] for k in range(9)]
    sets = swarm(starts, goals)
    one = experiments.build(config.load("swarm_rescue", sets))
    many = experiments.build(config.load("swarm_rescue", sets + ['aac.authorities="spread"']))
    world = many.sim.observe()
    coord = many.coordinator
    held = np.flatnonzero([r.authority for r in coord.decide(world).robots])
    radii = reach_radii(coord.fleet, world.states, coord.planner.config.horizon, 0.1)
    assert len(clusters(world.robot_centres(), radii, 0.05)) == 1
    assert one.coordinator.decide(one.sim.observe()).notes["authorities"] == 1
    assert len(held) >= 2
    centres = world.robot_centres()
    for a in held:
        for b in held[held > a]:
            assert np.hypot(*(centres[a] - centres[b])) - radii[a] - radii[b] > 0.05



def test_spread_extra_authorities_leave_the_lead_cycle_as_one_authority_runs_it():
    """During a lead, a group's first authority of each period cycles through the leader, a robot
    in its way and anyone, as with one authority; "spread"'s further authorities of the period
    go round robin to the rest, the longest-waiting first, and do not move that cycle on
    (before, they took the whole cycle within one period, and the leader held authority every
    period)."""
    starts = [[1.2 * k, 0.0, 0.0] for k in range(9)]
    goals = [[1.2 * k + 20.0, 0.0] for k in range(9)]
    setup = experiments.build(config.load("swarm_rescue", swarm(starts, goals) + ['aac.authorities="spread"']))
    coord, world = setup.coordinator, setup.sim.observe()
    coord.decide(world)
    coord.room = MakeRoom(9, stall_periods=10, lead_periods=80, corridor=1.0)
    coord.room.leader, coord.room.targets = 4, {5: np.zeros(2)}
    members = np.arange(9)
    records = [RobotDecision(False) for _ in members]
    firsts = []
    for period in range(1, 4):
        first, why = coord.choose_in_group(world, members, members, records, period)
        rest = members[members != first]
        longest = rest[np.argmin(coord.last_turn[rest])]
        extra, extra_why = coord.longest_waiting(rest, period)
        firsts.append(why)
        assert (extra, extra_why) == (longest, "round_robin")
    assert firsts[:2] == ["leader", "make_room"] and firsts[2] not in ("leader", "make_room")

@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), speed=st.floats(-1.5, 1.5), horizon=st.integers(1, 15))
def test_reach_radius_contains_every_committable_course(seed, speed, horizon):
    rng = np.random.default_rng(seed)
    robots = [small_robot(0)]
    fleet = Fleet(robots)
    state = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-np.pi, np.pi), speed])
    head = np.column_stack([rng.uniform(-2.0, 1.0, horizon), rng.uniform(-0.6, 0.6, horizon)])
    decel = 0.5 * 2.0
    c = stopping_commitment(fleet, 0, 0, state, head, rng.uniform(-np.pi, np.pi), decel, 0.0, 0.1)
    assert abs(c.states[-1, 3]) <= 1e-12  # the tail ends standing
    assert np.all(np.abs(np.diff(c.states[horizon:, 3])) <= decel * 0.1 + 1e-12)  # never braking harder than the tail's rate
    radius = reach_radii(fleet, state[None], horizon, 0.1, np.array([decel]))[0]
    centre0 = footprint_rows(state[None, None], fleet.offset, fleet.length, fleet.width)[0, 0, :2]
    rows = footprint_rows(c.states[None], fleet.offset, fleet.length, fleet.width)[0]
    corners = rows[:, None, :2] + 0.5 * np.hypot(0.6, 0.4) * np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])[None]
    assert np.hypot(*(corners - centre0).reshape(-1, 2).T).max() <= radius + 1e-9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 60), margin=st.floats(0.0, 1.0))
def test_clusters_are_the_components_of_overlapping_reach_discs(seed, n, margin):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 20, (n, 2))
    radii = rng.uniform(0.2, 3.0, n)
    groups = clusters(centres, radii, margin)
    label = np.empty(n, dtype=int)
    for g_id, g in enumerate(groups):
        label[g] = g_id
    assert sorted(np.concatenate(groups).tolist()) == list(range(n))
    touching = np.hypot(*(centres[:, None] - centres[None]).transpose(2, 0, 1)) - radii[:, None] - radii[None] < margin
    for i, j in zip(*np.nonzero(touching)):
        assert label[i] == label[j]
    for g in groups:  # no component splits into two parts that do not touch
        inside = touching[np.ix_(g, g)]
        reached = {0}
        frontier = [0]
        while frontier:
            k = frontier.pop()
            for m in np.flatnonzero(inside[k]):
                if m not in reached:
                    reached.add(int(m))
                    frontier.append(int(m))
        assert len(reached) == len(g)
    assert all(np.all(np.diff(g) > 0) for g in groups)  # each in index order
    assert [g[0] for g in groups] == sorted(g[0] for g in groups)  # ordered by their first robots


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), margin=st.floats(0.0, 0.5))
def test_course_clearance_is_exact_below_the_margin(seed, margin):
    rng = np.random.default_rng(seed)
    stages, m = 6, 3
    own = np.column_stack([rng.uniform(-2, 2, (stages, 2)), np.full(stages, 0.6), np.full(stages, 0.4), rng.uniform(-3, 3, stages)])
    others = np.concatenate([rng.uniform(-2, 2, (m, stages, 2)), np.full((m, stages, 1), 1.0), np.full((m, stages, 1), 0.5),
                             rng.uniform(-3, 3, (m, stages, 1))], axis=2)
    exact = min(pairwise_rect_clearance(own[[k]], others[:, k]).min() for k in range(stages))
    got = course_clearance(own, others, margin)
    if exact < margin:
        assert got == pytest.approx(exact, abs=1e-12)
    else:
        assert got >= margin - 1e-12


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), margin=st.floats(0.0, 0.5), spread=st.sampled_from([2.0, 20.0]))
def test_ragged_clearance_equals_the_padded_courses(seed, margin, spread):
    """Courses of different lengths, each standing at its last row once it has ended, give the
    same least clearance as the same courses padded to one length, and the lowest-index course
    that gives it; courses spread far apart (``spread`` 20 m) are mostly passed over by their
    boxes, without changing either answer."""
    rng = np.random.default_rng(seed)
    lengths = rng.integers(1, 8, 12)
    own = np.column_stack([rng.uniform(-2, 2, (5, 2)), np.full(5, 0.6), np.full(5, 0.4), rng.uniform(-3, 3, 5)])
    courses = [np.column_stack([rng.uniform(-spread, spread, (1, 2)) + rng.uniform(-1, 1, (k, 2)), np.full(k, 1.0), np.full(k, 0.5),
                                rng.uniform(-3, 3, k)]) for k in lengths]
    skip = int(rng.integers(-1, 12))
    steps = max(len(own), lengths.max())
    pad = lambda c: c[np.minimum(np.arange(steps), len(c) - 1)]
    padded = np.array([pad(c) for j, c in enumerate(courses) if j != skip]).reshape(-1, steps, 5)
    starts = np.r_[0, np.cumsum(lengths)[:-1]].astype(np.int64)
    flat = np.concatenate(courses)
    gap, nearest = ragged_nearest(own, flat, starts, lengths.astype(np.int64), course_boxes(flat, starts, lengths.astype(np.int64)), skip,
                                  margin)
    assert gap == course_clearance(pad(own), padded, margin) and nearest != skip
    each = [np.inf if j == skip else course_clearance(pad(own), pad(c)[None], margin) for j, c in enumerate(courses)]
    assert nearest == int(np.argmin(each))  # the course that gives it, the lowest index on ties


def test_a_refusal_is_remembered_only_while_the_same_course_meets_the_same_standing_footprint():
    """A standing robot whose candidate ran into a robot holding at the end of its commitment is
    refused again, without a check, only while both are unchanged; then the check agrees."""
    robots = [small_robot(i) for i in range(3)]
    fleet, dt = Fleet(robots), 0.1
    states = np.array([[0.0, 0.0, 0.0, 0.0], [0.9, 0.0, 0.0, 0.0], [0.0, 5.0, 0.0, 0.0]])
    stand = [stopping_commitment(fleet, i, 0, states[i], np.zeros((0, 2)), 0.0, 1.0, 0.0, dt) for i in range(3)]
    book = CommitmentBook(fleet, stand, 0.05)
    statics = np.empty((0, 5))
    forward = stopping_commitment(fleet, 0, 0, states[0], np.tile([1.0, 0.0], (5, 1)), 0.0, 1.0, 0.0, dt)  # into robot 1
    gap, blocker = book.check(0, forward, 0, statics)
    assert gap < book.margin and blocker == 1
    key = ("path", 0.0, 0.0)
    book.refuse(0, states[0], key, blocker, 0, statics)
    assert book.refused_again(0, states[0], key, statics)
    assert not book.refused_again(0, states[0] + [0.01, 0.0, 0.0, 0.0], key, statics)  # elsewhere: another course
    assert not book.refused_again(0, states[0], ("path", 0.1, 0.0), statics)
    book.replace(1, stopping_commitment(fleet, 1, 0, states[1], np.zeros((0, 2)), 0.0, 1.0, 0.0, dt), 0)
    assert not book.refused_again(0, states[0], key, statics)  # a new commitment of the blocker: check again
    book.refuse(0, np.array([0.0, 0.0, 0.0, 0.5]), key, 1, 0, statics)  # moving: nothing remembered
    assert not book.refused_again(0, np.array([0.0, 0.0, 0.0, 0.5]), key, statics)


def test_a_standing_authority_whose_plan_leaves_it_standing_creeps_only_on_a_checked_course_nearer_its_reference():
    """In the crowded centre of a 12-robot circle swap some standing authorities' solves leave
    them standing (the planner's regions are conservative); they creep instead
    (``CommittedAac.creep``). Pinned at every creep: the robot stood, its new commitment
    starts where it is, ends at least ``CREEP_GAIN`` nearer where its reference ends, drives
    forwards (backwards only while it backs off), is neither a make-room leader nor making room
    for one, and keeps
    the margin from every other commitment and the debris (the invariant, checked at every
    period as before)."""
    from aac_sumo.coordination.aac.creeping import CREEP_GAIN, CREEP_SPEED
    from aac_sumo.coordination.make_room import STILL_SPEED

    setup = experiments.build(config.load("circle_swap", PLAIN + ["circle_swap.n_robots=12", "aac.authorities=1"]))
    sim, coord = setup.sim, setup.coordinator
    creeps = 0
    for period in range(80):
        world = sim.observe()
        decision = coord.decide(world)
        commitments_apart(coord, world, period)
        for i, record in enumerate(decision.robots):
            if record.mode != "creep":
                continue
            creeps += 1
            c = coord.book.items[i]
            assert record.authority and abs(world.states[i, 3]) < STILL_SPEED
            assert coord.room is None or (i not in coord.room.targets and i != coord.room.leader)  # make room: MPC only
            assert c.start == period and np.array_equal(c.states[0], world.states[i])
            target = record.reference[-1, :2]
            assert np.hypot(*(c.states[-1, :2] - target)) <= np.hypot(*(world.states[i, :2] - target)) - CREEP_GAIN + 1e-12
            speeds = c.states[: c.planned + 1, 3]
            sign = -1.0 if coord.room is not None and coord.room.backing_off(i) else 1.0
            assert np.all(sign * speeds >= -1e-12) and np.all(np.abs(speeds) <= CREEP_SPEED + 1e-12)
        assert not sim.step(decision.inputs).overlaps
    assert creeps > 0  # the scene does make robots creep


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), period=st.integers(0, 40), steps=st.integers(0, 15))
def test_the_books_courses_are_each_commitments_course(seed, period, steps):
    """The book's courses (kept padded in one array) are the commitments' own, along them and
    after they end, also after a commitment is replaced by a longer one."""
    rng = np.random.default_rng(seed)
    robots = [small_robot(i) for i in range(6)]
    fleet = Fleet(robots)

    def random_commitment(i):
        state = np.r_[rng.uniform(0, 10, 2), rng.uniform(-3, 3), rng.uniform(0, 1)]
        return stopping_commitment(fleet, i, int(rng.integers(0, period + 1)), state, rng.uniform(-1, 1, (int(rng.integers(0, 25)), 2)), 0.0, 1.0,
                                   0.0, 0.1)

    book = CommitmentBook(fleet, [random_commitment(i) for i in range(6)], 0.05)
    book.replace(2, random_commitment(2), period)
    idx = rng.permutation(6)[: int(rng.integers(0, 7))]
    expected = np.array([book.items[j].course(period, steps) for j in idx]).reshape(len(idx), steps + 1, 4)
    np.testing.assert_array_equal(book.courses(period, idx, steps), expected)


def test_a_check_after_a_replacement_in_the_same_period_meets_the_new_commitment():
    """The book's footprints of this period follow a replacement at once: a robot checked after
    another's new commitment drives into it is refused by it, and one checked against the old
    place of that robot passes."""
    robots = [small_robot(i) for i in range(3)]
    fleet, dt = Fleet(robots), 0.1
    states = np.array([[0.0, 0.0, 0.0, 0.0], [3.0, 0.0, np.pi, 0.0], [0.0, 5.0, 0.0, 0.0]])
    stand = [stopping_commitment(fleet, i, 0, states[i], np.zeros((0, 2)), 0.0, 1.0, 0.0, dt) for i in range(3)]
    book, statics = CommitmentBook(fleet, stand, 0.05), np.empty((0, 5))
    assert book.check(2, stand[2], 0, statics)[0] >= book.margin  # the flat array of period 0 is built
    moved = stopping_commitment(fleet, 1, 0, np.array([0.0, 4.6, 0.0, 0.0]), np.zeros((0, 2)), 0.0, 1.0, 0.0, dt)
    book.replace(1, moved, 0)  # robot 1 now stands right below robot 2
    gap, blocker = book.check(2, stand[2], 0, statics)
    assert gap < book.margin and blocker == 1
    assert book.check(0, stopping_commitment(fleet, 0, 0, np.array([2.4, 0.0, 0.0, 0.0]), np.zeros((0, 2)), 0.0, 1.0, 0.0, dt),
                      0, statics)[0] >= book.margin  # where robot 1 stood before is free


def test_a_robot_taken_off_the_road_leaves_no_commitment_behind():
    """A car that finished and was taken off the road (parked far away) no longer holds the
    place where its commitment ended: a car behind it drives through that place, and the parked
    car's commitment is where it stands now. A robot still on the road keeps its commitment."""
    robots = [small_robot(i) for i in range(3)]
    fleet, dt = Fleet(robots), 0.1
    states = np.array([[0.0, 0.0, 0.0, 0.0], [1.5, 0.0, 0.0, 1.0], [0.0, 5.0, 0.0, 0.0]])
    ahead = stopping_commitment(fleet, 1, 0, states[1], np.tile([0.0, 0.0], (10, 1)), 0.0, 1.0, 0.0, dt)
    stand = [stopping_commitment(fleet, 0, 0, states[0], np.zeros((0, 2)), 0.0, 1.0, 0.0, dt), ahead,
             stopping_commitment(fleet, 2, 0, states[2], np.zeros((0, 2)), 0.0, 1.0, 0.0, dt)]
    book, statics = CommitmentBook(fleet, stand, 0.05), np.empty((0, 5))
    forward = stopping_commitment(fleet, 0, 3, states[0], np.tile([1.0, 0.0], (20, 1)), 0.0, 1.0, 0.0, dt)
    gap, blocker = book.check(0, forward, 3, statics)
    assert gap < book.margin and blocker == 1  # robot 1's commitment ends 2.5 m on, in robot 0's way
    parked = states.copy()
    parked[1] = [-1000.0, 0.0, 0.0, 0.0]
    book.park(np.array([False, True, False]), parked, 3)
    assert book.check(0, forward, 3, statics)[0] >= book.margin
    np.testing.assert_array_equal(book.courses(3, np.array([1]), 5)[0, :, :2], np.tile([-1000.0, 0.0], (6, 1)))
    assert book.items[2] is stand[2]


@settings(max_examples=40, deadline=None)
@given(speed=st.floats(0.0, 20.0), decel=st.floats(1.0, 9.0), accel=st.floats(-12.0, 2.0), heading=st.floats(-np.pi, np.pi))
def test_a_braking_course_is_the_closed_form_stop_along_the_velocity(speed, decel, accel, heading):
    """An uncontrolled vehicle's braking course starts where it is, goes along its velocity
    braking at the larger of ``decel`` and its own braking, and ends standing exactly
    ``v^2 / 2b`` on, after ``ceil(v / b dt)`` periods; cones, walkers and standing obstacles
    have none."""
    direction = np.array([np.cos(heading), np.sin(heading)])
    car = Obstacle("bg.0", "scripted", np.array([5.0, -2.0]), speed * direction, heading, 4.5, 1.8, accel=accel)
    others = [Obstacle("c", "cone", np.zeros(2), np.zeros(2), 0.0, 0.3, 0.3), Obstacle("p", "pedestrian", np.zeros(2), np.ones(2), 0.0, 0.5, 0.5)]
    (rows,) = braking_courses(others + [car], decel, 0.1)
    brake = max(decel, -accel)
    assert len(rows) == (int(np.ceil(speed / (brake * 0.1) - 1e-9)) if speed > 0 else 0) + 1
    np.testing.assert_allclose(rows[0, :2], car.centre)
    np.testing.assert_allclose(rows[-1, :2], car.centre + speed**2 / (2 * brake) * direction, atol=1e-9)
    travel = (rows[:, :2] - car.centre) @ direction
    assert np.all(np.diff(travel) >= -1e-12)  # never backwards
    np.testing.assert_array_equal(rows[:, 2:], np.tile([4.5, 1.8, heading], (len(rows), 1)))


@settings(max_examples=40, deadline=None)
@given(speed=st.floats(0.5, 20.0), decel=st.floats(1.0, 9.0), leg=st.floats(0.0, 30.0), turn=st.floats(-2.5, 2.5))
def test_a_braking_course_with_a_course_follows_it_round_the_corner(speed, decel, leg, turn):
    """A SUMO car whose course turns by ``turn`` after ``leg`` metres (its route through a
    junction) stops ``v^2 / 2b`` along that course, not along its velocity: every row lies on the
    polyline at the closed-form travel of its centre, headed along the leg it is on, until its
    body reaches the corner; across it, as SUMO places a car on its lane, its front is on the
    polyline half a length on and it is headed along the chord from the point half a length back."""
    course = np.array([[0.0, 0.0], [leg, 0.0], [leg, 0.0], [leg + 50.0 * np.cos(turn), 50.0 * np.sin(turn)]])
    car = Obstacle("bg.0", "scripted", np.zeros(2), np.array([speed, 0.0]), 0.0, 4.5, 1.8, course=course)
    (rows,) = braking_courses([car], decel, 0.1)
    t = np.minimum(np.arange(len(rows)) * 0.1, speed / decel)
    travel = speed * t - 0.5 * decel * t**2
    def on_course(s):  # behind its start, straight back along its first leg (the turned one where the first is empty)
        first = np.array([1.0, 0.0]) if leg > 1e-9 else np.array([np.cos(turn), np.sin(turn)])
        return np.where((s < 0.0)[:, None], s[:, None] * first, np.where(s[:, None] <= leg, np.column_stack([s, np.zeros(len(s))]),
                        np.column_stack([leg + (s - leg) * np.cos(turn), (s - leg) * np.sin(turn)])))

    before, after = travel + 2.25 <= leg, travel - 2.25 >= leg  # the whole body before the corner, beyond it
    np.testing.assert_allclose(rows[before, :2], on_course(travel[before]), atol=1e-9)
    np.testing.assert_allclose(rows[after, :2], on_course(travel[after]), atol=1e-9)
    assert rows[0, 4] == 0.0
    np.testing.assert_allclose(rows[1:, 4][before[1:]], 0.0, atol=1e-12)
    np.testing.assert_allclose(rows[1:, 4][after[1:]], turn, atol=1e-12)
    astride = np.flatnonzero(~before & ~after)
    astride = astride[astride > 0]
    ahead = np.column_stack([np.cos(rows[astride, 4]), np.sin(rows[astride, 4])])
    front, back = on_course(travel[astride] + 2.25), on_course(travel[astride] - 2.25)
    np.testing.assert_allclose(rows[astride, :2] + 2.25 * ahead, front, atol=1e-9)
    chord = front - back
    np.testing.assert_allclose(chord[:, 0] * ahead[:, 1] - chord[:, 1] * ahead[:, 0], 0.0, atol=1e-9)  # headed along the chord
    assert np.all(np.einsum("ij,ij->i", chord, ahead) >= 0.0)
    np.testing.assert_array_equal(rows[:, 2:4], np.tile([4.5, 1.8], (len(rows), 1)))


def test_a_car_behind_an_uncontrolled_car_may_commit_only_to_stop_behind_where_that_car_can_stop():
    """A SUMO car at 16 m/s 20 m ahead may brake at 4.5 m/s^2 and stand 28.4 m on. A robot
    behind it at 16 m/s whose stopping tail brakes at 2 m/s^2 (64 m) would run into it there and
    is refused, naming it; with a tail at 6 m/s^2 (21.3 m) it stops behind and passes; and a
    robot beside it in the next lane passes too. A SUMO car behind the robot keeps its own
    distance: the robot's gentle tail in front of it passes, though that car's braking course
    would run into it."""
    limits = VehicleLimits(-6.0, 3.0, 0.5, 0.0, 20.0)
    robots = [RobotSpec(f"car{i}", 4.0, 1.8, BicycleModel(2.6, limits)) for i in range(2)]
    fleet, dt = Fleet(robots), 0.1
    states = np.array([[0.0, 0.0, 0.0, 16.0], [0.0, 40.0, 0.0, 0.0]])
    ahead = Obstacle("bg.0", "scripted", np.array([22.0, 0.0]), np.array([16.0, 0.0]), 0.0, 4.5, 1.8)
    hard = [stopping_commitment(fleet, i, 0, states[i], np.zeros((0, 2)), 0.0, 6.0, 0.0, dt) for i in range(2)]
    book, statics = CommitmentBook(fleet, hard, 1.0), np.empty((0, 5))
    book.traffic = braking_courses([ahead], 4.5, dt)
    gentle = stopping_commitment(fleet, 0, 0, states[0], np.zeros((0, 2)), 0.0, 2.0, 0.0, dt)
    gap, blocker = book.check(0, gentle, 0, statics)
    assert gap < 0.0 and blocker == -3
    assert book.check(0, hard[0], 0, statics)[0] >= book.margin
    beside = stopping_commitment(fleet, 0, 0, np.array([0.0, 3.5, 0.0, 16.0]), np.zeros((0, 2)), 0.0, 2.0, 0.0, dt)
    assert book.check(0, beside, 0, statics)[0] >= book.margin
    in_front = stopping_commitment(fleet, 0, 0, np.array([30.0, 0.0, 0.0, 5.0]), np.zeros((0, 2)), 0.0, 2.0, 0.0, dt)
    assert book.check(0, in_front, 0, statics)[0] >= book.margin
    rows = footprint_rows(in_front.states[None], fleet.offset[[0]], fleet.length[[0]], fleet.width[[0]])[0]
    course = book.traffic[0]
    steps = max(len(rows), len(course))
    padded = [np.vstack([r, np.repeat(r[-1:], steps - len(r), axis=0)]) for r in (rows, course)]  # each stands at its end
    assert course_clearance(padded[0], padded[1][None], np.inf) < 0.0  # the course behind it would


def test_with_traffic_beside_a_course_swinging_into_the_next_lane_meets_the_car_coming_up_there():
    """A SUMO car at 12 m/s comes up in the next lane (3.2 m across), its centre 2 m behind the
    robot's rear axle. A robot that keeps its lane keeps the margin from it either way; one whose
    course swings into that lane as it stops is refused only with ``beside``; a car straight
    behind the robot in its own lane is never held (it keeps its distance itself)."""
    limits = VehicleLimits(-6.0, 3.0, 0.5, 0.0, 20.0)
    fleet, dt = Fleet([RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, limits))]), 0.1
    state = np.array([0.0, 0.0, 0.0, 6.0])
    lane = stopping_commitment(fleet, 0, 0, state, np.zeros((0, 2)), 0.0, 2.0, 0.0, dt)
    swing = stopping_commitment(fleet, 0, 0, np.array([0.0, 0.8, 0.4, 6.0]), np.zeros((0, 2)), 0.0, 2.0, 0.0, dt)
    book = CommitmentBook(fleet, [lane], 1.0)
    beside = Obstacle("bg.0", "scripted", np.array([-2.0, 3.2]), np.array([12.0, 0.0]), 0.0, 4.5, 1.8)
    behind = Obstacle("bg.1", "scripted", np.array([-9.0, 0.0]), np.array([8.0, 0.0]), 0.0, 4.5, 1.8)
    for flag in (False, True):
        book.beside = flag
        book.traffic = braking_courses([beside], 4.5, dt)
        assert book.traffic_gap(book.footprints(0, lane, 0), 0) >= book.margin
        assert (book.traffic_gap(book.footprints(0, swing, 0), 0) < book.margin) == flag
        book.traffic = braking_courses([behind], 4.5, dt)
        assert book.traffic_gap(book.footprints(0, lane, 0), 0) == np.inf


def test_a_continuation_stands_behind_where_each_vehicle_ahead_on_its_path_can_stop():
    """On a straight lane, the standing point of a SUMO car ahead in the lane is where its
    braking course stands, less half its length and the gap; a car behind the robot, one in the
    next lane (3.5 m across) and a standing cone give none; a car changing lanes, seen over both
    lanes (5 m wide), counts from the next lane."""
    from aac_sumo.references import PathReference

    path = PathReference(np.array([[0.0, 0.0], [1000.0, 0.0]]), 16.0, stop_at_end=False)
    def car(x, y, speed, width=1.8):
        return Obstacle(f"bg{x}", "scripted", np.array([x, y]), np.array([speed, 0.0]), 0.0, 4.5, width)
    vehicles = [car(100.0, 0.0, 15.0), car(20.0, 0.0, 15.0), car(150.0, 3.5, 15.0), car(300.0, 2.2, 9.0, width=5.0),
                Obstacle("cone", "cone", np.array([400.0, 0.0]), np.zeros(2), 0.0, 0.3, 0.3)]
    courses = braking_courses(vehicles, 4.5, 0.1)
    got = standing_points(path, courses, stop_lines(vehicles), np.array([50.0, 0.0]), 0.0, reach=1.9, gap=4.0)
    expected = [100.0 + 15.0**2 / 9.0 - 2.25 - 4.0, 300.0 + 9.0**2 / 9.0 - 2.25 - 4.0]
    np.testing.assert_allclose(np.sort(got), expected, atol=1e-6)


def test_a_vehicle_beside_a_stretch_of_the_route_already_driven_is_no_place_to_stand_behind():
    """A route east along y = 0, north up x = 100, then west along y = 50 (a U round a block). A
    car on the last leg at x = 80 heading west sees a SUMO car ahead of it (west, at x = 40) that
    drives east on the first leg: nearest to arc 40, which the car passed long ago; it gives no
    standing point. One in the car's own lane ahead at x = 40 does."""
    from aac_sumo.references import PathReference

    path = PathReference(np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0], [0.0, 50.0]]), 10.0, stop_at_end=False)
    beside_first_leg = Obstacle("bg.0", "scripted", np.array([40.0, 0.0]), np.zeros(2), 0.0, 4.5, 1.8)
    in_lane_ahead = Obstacle("bg.1", "scripted", np.array([40.0, 50.0]), np.zeros(2), np.pi, 4.5, 1.8)
    here = np.array([80.0, 50.0])
    for vehicle, expected in ((beside_first_leg, []), (in_lane_ahead, [150.0 + 60.0 - 2.25 - 4.0])):
        got = standing_points(path, braking_courses([vehicle], 4.5, 0.1), stop_lines([vehicle]), here, np.pi, reach=1.9, gap=4.0)
        np.testing.assert_allclose(got, expected, atol=1e-6)


@settings(max_examples=30, deadline=None)
@given(gap=st.floats(0.5, 40.0), speed=st.floats(0.0, 20.0), stages=st.integers(1, 60))
def test_traffic_clearances_are_the_bumper_gaps_to_a_standing_car_ahead_stage_by_stage(gap, speed, stages):
    """A car at ``speed`` [m/s] drives straight along a lane towards a SUMO car standing ``gap``
    [m] ahead (bumper to bumper); per stage its clearance is the distance between their centres
    less their half lengths (2 and 2.25 m), and where they overlap the shallower of that overlap
    and their width (1.8 m). A SUMO car behind it counts for nothing."""
    course = np.array([[speed * 0.1 * k, 0.0, 4.0, 1.8, 0.0] for k in range(stages + 1)])
    ahead = Obstacle("bg.0", "scripted", np.array([2.0 + gap + 2.25, 0.0]), np.zeros(2), 0.0, 4.5, 1.8)
    behind = Obstacle("bg.1", "scripted", np.array([-10.0, 0.0]), np.array([30.0, 0.0]), 0.0, 4.5, 1.8)
    got = traffic_clearances(course, braking_courses([ahead, behind], 4.5, 0.1), np.zeros(2, dtype=bool))
    assert len(got) == stages + 1
    expected = np.abs(ahead.centre[0] - course[:, 0]) - 4.25
    expected = np.where(expected < 0.0, np.maximum(expected, -1.8), expected)
    np.testing.assert_allclose(got, expected, atol=1e-9)
    assert np.all(np.isinf(traffic_clearances(course, braking_courses([behind], 4.5, 0.1), np.zeros(1, dtype=bool))))


def test_a_stop_line_holds_the_cars_that_come_up_to_it_and_not_those_that_cross_in_front_of_it():
    """An eastbound lane's red stop line (a standing box, heading 0) stands in the way of two
    courses: an eastbound car's, which must stop behind it, and a car's that crosses the junction
    northbound just beyond the line (as one turning from another approach does). Only the first
    one is held; a SUMO car standing at the same spot holds both."""
    line = Obstacle("signal J 7 in_0", "signal", np.array([10.5, 0.0]), np.zeros(2), 0.0, 1.0, 1.8)
    car = Obstacle("bg.0", "scripted", np.array([10.5, 0.0]), np.zeros(2), 0.0, 1.0, 1.8)
    east = np.array([[2.0 * k, 0.0, 4.0, 1.8, 0.0] for k in range(12)])
    north = np.array([[10.5, -12.0 + 2.0 * k, 4.0, 1.8, 0.5 * np.pi] for k in range(12)])
    for obstacle, holds_north in ((line, False), (car, True)):
        courses, lines = braking_courses([obstacle], 4.5, 0.1), stop_lines([obstacle])
        assert traffic_clearances(east, courses, lines).min() < 0.0
        assert (traffic_clearances(north, courses, lines).min() < 0.0) == holds_north
        assert obstacle.binds(0.3) and obstacle.binds(0.5 * np.pi) == holds_north and obstacle.binds(np.pi) == holds_north
    from aac_sumo.references import PathReference
    path = PathReference(np.array([[0.0, 0.0], [100.0, 0.0]]), 10.0, stop_at_end=False)
    assert standing_points(path, braking_courses([line], 4.5, 0.1), stop_lines([line]), np.zeros(2), 0.0, 1.0, 4.0).size == 1
    assert standing_points(path, braking_courses([line], 4.5, 0.1), stop_lines([line]), np.array([10.5, -10.0]), 0.5 * np.pi, 1.0, 4.0).size == 0


@pytest.mark.parametrize("disabled", [False, True])
def test_a_robot_whose_commitment_a_harder_braking_vehicle_breaks_brakes_for_it_at_once(disabled):
    """A lead (an uncontrolled vehicle) brakes at 8 m/s^2, harder than the 4.5 m/s^2 the check
    assumes of it, 9 m ahead of a robot on committed plans: within the same period the robot's
    commitment either keeps the margin from the lead's braking course or brakes at once (it
    renews or brakes, mode ``traffic_brake``), and nothing touches. With that step switched off
    (``disabled``), the robot keeps a commitment that runs into the lead's course."""
    scenario = config.load("scenarios/braking.toml", ["controller.coordinator=aac", "aac.commit=true", "aac.tail_brake=0.3333",
                                                      "braking.gap=9", "braking.lead_decel=8", "aac.safety_stop=false"])
    setup = experiments.build(scenario)
    sim, coord = setup.sim, setup.coordinator
    if disabled:
        coord.brake_for_traffic = lambda *args, **kwargs: 0
    broken, braked, overlaps = 0, 0, set()
    for _ in range(80):
        world = sim.observe()
        decision = coord.decide(world)
        book, period = coord.book, coord.period - 1
        commitment = book.items[0]
        gap = book.traffic_gap(book.footprints(0, commitment, period), period)
        braking = commitment.start == period and commitment.planned == 0  # a stop from now, no plan before it
        broken += gap < book.margin and not braking
        braked += decision.notes["traffic_brakes"]
        overlaps |= sim.step(decision.inputs).overlaps
    assert not overlaps
    if disabled:
        assert broken > 0
    else:
        assert broken == 0 and braked > 0


def test_a_reactive_check_holds_a_car_to_stopping_behind_a_vehicle_once_it_sees_it_brake():
    """A car at 16 m/s, 20 m behind a SUMO car at 16 m/s, committed to 4 s more at its speed and
    then a 2 m/s^2 tail: against its own course the check refuses it (the vehicle may stop 28 m on
    while the car goes 64 m before braking). Held reactively (:attr:`CommitmentBook.reaction`:
    one period of the commitment, then braking at 3 m/s^2, 43 m) it passes; at 10 m behind it does
    not."""
    limits = VehicleLimits(-6.0, 3.0, 0.5, 0.0, 20.0)
    robots = [RobotSpec(f"car{i}", 4.0, 1.8, BicycleModel(2.6, limits)) for i in range(2)]
    fleet, dt = Fleet(robots), 0.1
    states = np.array([[0.0, 0.0, 0.0, 16.0], [0.0, 40.0, 0.0, 0.0]])
    stand = [stopping_commitment(fleet, i, 0, states[i], np.zeros((0, 2)), 0.0, 6.0, 0.0, dt) for i in range(2)]
    book, statics = CommitmentBook(fleet, stand, 1.0), np.empty((0, 5))
    cruise = stopping_commitment(fleet, 0, 0, states[0], np.zeros((40, 2)), 0.0, 2.0, 0.0, dt)
    for gap, passes in ((20.0, True), (10.0, False)):
        ahead = Obstacle("bg.0", "scripted", np.array([1.3 + gap + 4.25, 0.0]), np.array([16.0, 0.0]), 0.0, 4.5, 1.8)
        book.traffic, book.reaction = braking_courses([ahead], 4.5, dt), None
        assert book.check(0, cruise, 0, statics)[0] < book.margin
        book.reaction = (np.array([3.0, 3.0]), dt)
        assert (book.check(0, cruise, 0, statics)[0] >= book.margin) == passes


def test_a_reaction_in_the_middle_of_a_lane_change_finishes_it_and_keeps_clear_of_the_car_in_the_lane_beyond():
    """A car at 12 m/s three quarters of the way through a change from the lane at y = 0 to the one at y = -3.5
    (heading -0.15 rad) reacts by braking at 6 m/s^2. Braking straight on at its angle it would
    cross its target lane (13 m of stopping, 1.9 m further right) to within the 1 m margin of a
    car driving in the lane beyond (y = -7); along its path (:attr:`CommitmentBook.paths`) it
    settles into its target lane, and the two reactions keep the margin."""
    from aac_sumo.references import PathReference

    limits = VehicleLimits(-6.0, 3.0, 0.5, 0.0, 20.0)
    robots = [RobotSpec(f"car{i}", 4.0, 1.8, BicycleModel(2.6, limits)) for i in range(2)]
    fleet, dt = Fleet(robots), 0.1
    change = PathReference(np.array([[0.0, 0.0], [20.0, 0.0], [43.3, -3.5], [500.0, -3.5]]), 12.0, stop_at_end=False)
    beside = PathReference(np.array([[0.0, -7.0], [500.0, -7.0]]), 12.0, stop_at_end=False)
    states = np.array([[37.0, -2.55, -0.15, 12.0], [38.0, -7.0, 0.0, 12.0]])
    cruise = [stopping_commitment(fleet, i, 0, states[i], np.zeros((20, 2)), path, 2.0, 0.0, dt)
              for i, path in enumerate((change, beside))]
    book = CommitmentBook(fleet, cruise, 1.0)
    book.reaction = (np.array([6.0, 6.0]), dt)
    straight = book.reaction_course(0, cruise[0], 0)
    assert straight.states[-1, 1] < -4.4  # its right side 0.6 m from the car beyond
    assert book.reaction_gap(0, cruise[0], 0)[0] < book.margin
    book.paths = [change, beside]
    along = book.reaction_course(0, cruise[0], 0)
    assert along.states[-1, 3] == pytest.approx(0.0, abs=1e-9) and abs(along.states[-1, 1] + 3.5) < 0.6
    cruise[0].react = None  # the reaction held straight on was kept for this period
    assert book.reaction_gap(0, cruise[0], 0)[0] >= book.margin


@pytest.mark.parametrize("walker_brake", [False, True])
def test_a_walker_set_down_in_a_committed_robots_way_makes_it_brake_at_once_with_walker_brake(walker_brake):
    """A walker appears (as SUMO sets a pedestrian down) standing in the lane 14 m ahead of a
    robot at 10 m/s whose commitment runs through her region. With ``aac.walker_brake`` the robot
    brakes to a stop from that period on (mode ``traffic_brake``), stops short of her, and nothing
    touches; without it, it keeps its commitment into her region."""
    import dataclasses

    scenario = config.load("scenarios/braking.toml", ["controller.coordinator=aac", "aac.commit=true", "aac.tail_brake=0.3333",
                                                      "braking.gap=80", "aac.safety_stop=false", f"aac.walker_brake={str(walker_brake).lower()}"])
    setup = experiments.build(scenario)
    sim, coord = setup.sim, setup.coordinator
    for _ in range(5):
        sim.step(coord.decide(sim.observe()).inputs)
    world = sim.observe()
    ego = world.robot_centres()[0]
    walker = Obstacle("p0", "pedestrian", ego + np.array([14.0, 0.0]), np.zeros(2), 0.0, 0.5, 0.5)
    decision = coord.decide(dataclasses.replace(world, obstacles=world.obstacles + [walker]))
    book, period = coord.book, coord.period - 1
    commitment = book.items[0]
    rows = book.footprints(0, commitment, period)
    if walker_brake:
        assert decision.notes["traffic_brakes"] == 1 and decision.robots[0].mode == "traffic_brake"
        assert commitment.start == period and commitment.planned == 0
        stand = rows[-1, 0] + 0.5 * rows[-1, 2]  # the robot's front where it stands
        assert stand < walker.centre[0] - 0.25
    else:
        assert decision.notes["traffic_brakes"] == 0
        assert book.walkers.slack(rows) < 0.0


@pytest.mark.parametrize("radius", [60.0, 150.0, 400.0])
def test_a_stopping_tail_on_a_lane_that_curves_brakes_along_it(radius):
    """A car at 10 m/s on a lane that curves (radius 60, 150 or 400 m; a path that goes on) brakes
    at 2 m/s^2 along it: its rear axle stays within 0.25 m of the lane's centre line until it stands
    about 25 m on. On a path that ends in a stop (a robot's way to its goal) the tail keeps the
    heading of the segment where it starts and leaves the curve (1 m or more inside at 150 m)."""
    from aac_sumo.references import PathReference

    limits = VehicleLimits(a_min=-6.0, a_max=3.0, steer_max=0.5, v_max=20.0, a_lat_max=3.0, steer_rate_max=0.5, a_comfort=3.0)
    fleet = Fleet([RobotSpec("car", 4.0, 1.8, BicycleModel(2.6, limits))])
    angle = np.linspace(0.0, 60.0 / radius, 121)  # 60 m of arc, turning left
    points = np.column_stack([radius * np.sin(angle), radius * (1.0 - np.cos(angle))])
    state = np.array([0.0, 0.0, 0.0, 10.0])
    lane = PathReference(points, 10.0, stop_at_end=False)
    tail = stopping_commitment(fleet, 0, 0, state, np.zeros((0, 2)), lane, 2.0, 0.0, 0.1)
    off = np.abs(np.hypot(tail.states[:, 0], tail.states[:, 1] - radius) - radius)
    assert abs(tail.states[-1, 3]) <= 1e-12 and 24.0 <= lane.project(tail.states[-1, :2])[0] <= 26.0
    assert off.max() <= 0.25
    if radius == 150.0:
        goal = PathReference(points, 10.0, stop_at_end=True)
        straight = stopping_commitment(fleet, 0, 0, state, np.zeros((0, 2)), goal, 2.0, 0.0, 0.1)
        assert np.abs(np.hypot(straight.states[-1, 0], straight.states[-1, 1] - radius) - radius) >= 1.0
