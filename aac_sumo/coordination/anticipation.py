"""Driving beyond the MPC horizon: reference speeds that slow a robot in its lane, early and at a
comfortable rate, for what lies ahead on its path, and a lane kept near pedestrians.

The MPC looks one horizon ahead (1 s at car scale, 10 m at 10 m/s), too short to stop gently
(25 m from 10 m/s at 2 m/s^2). Here every agent ahead on the robot's path caps its reference
speed with a comfortable stopping profile, as a driver's car following does:

- another robot or a moving obstacle whose footprint reaches within ``lateral_margin`` [m] of
  the path ahead of the robot, or will within ``cut_in`` [s] at its speed towards the path
  (a car cutting in, so that the robot behind makes room early): the robot may drive at the
  speed ``v`` that keeps ``(v^2 - v_lead^2) / 2 b + time_gap v <= s_stop - s`` at arc length
  ``s``, with ``v_lead`` its speed along the path and ``s_stop`` the point ``gap`` [m] behind
  it: the time gap at the robot's own speed (as IDM keeps it), growing from none behind a
  standing leader to the whole behind one at 1 m/s, so that a standing queue sets off together;
  an obstacle that brakes (its estimated
  acceleration ``a < 0``, :attr:`~aac_sumo.world.Obstacle.accel`) also counts as standing
  ``v_lead^2 / 2|a|`` further on, where it stops at that rate (a SUMO car braking hard for a walker);
- a pedestrian near or on the path counts with ``v_lead = 0``: the robot yields, it does not
  overtake. A walker counts when it is within ``pedestrian_margin`` of the path, or may be by
  the time the robot, at its current speed, has passed her with the margin: the longer of her
  velocity towards the path times that time and ``pedestrian_reach`` [m/s] (she may step out at any moment, as the
  planner and the safety stop assume) times that time or the robot's comfortable stopping
  time, whichever is shorter (so a robot creeps past a walker who stands beside its lane
  instead of waiting for good). A walker who walks away from the path is not taken to turn
  back: the robot goes once she is beyond ``pedestrian_margin`` of it.

A walker that counted goes on counting for ``hold`` seconds unless it walks away from the path
(one who pauses on the crossing for a moment is still yielded to). Past the point of no return,
a walker not yet within ``pedestrian_margin`` of the path whom the robot can no longer stop for
at its comfort deceleration does not count when it cannot reach the path at its own speed before
the robot has passed it: the robot goes on, rather than brake into the walker's way.

The reference speed over the horizon then ramps from the robot's speed towards that cap by at
most ``accel`` / ``decel`` [m/s^2] per second (with ``brake``, harder, up to it and the robot's
comfort deceleration, towards a stop it can no longer meet at ``decel``: one seen late, such as a
walker stepping towards the path), and its positions follow these speeds along the path. Within ``yield_distance`` [m] of a pedestrian a robot on a lateral band keeps within
``yield_band`` [m] of its reference: it slows, it does not swerve.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param, section
from aac_sumo.geometry import wrap_angle
from aac_sumo.kernels.anticipation import ramped_speeds, stop_rows
from aac_sumo.references import PathReference
from aac_sumo.world import WorldState


@section("controller")
@dataclass(frozen=True)
class Anticipation:
    """Comfortable rates [m/s^2] (and ``brake``, towards a stop seen late: see
    :func:`anticipated_reference`), gaps [m], time gap [s], how far ahead it looks [m], the
    lateral reach of the path [m], and the pedestrian rules (see the module; ``hold`` [s]: how
    long a walker who counted goes on counting, see :func:`stop_points`; ``walkway_time``, see
    :meth:`~aac_sumo.world.Obstacle.step_out_speed`)."""

    enabled: bool = param(False, "reference speeds that slow a robot in its lane, early and gently, for what lies ahead on its path "
                          "(cars, walkers near it), and lanes kept near walkers (docs/lane_change.md)",
                          key="anticipate", after="retry_with_ipopt")
    decel: float = param(1.5, "comfortable deceleration of the anticipated reference speed [m/s^2]", key="anticipate_decel", **P)
    brake: float = param(0.0, "towards a stop it sees too late for anticipate_decel (a walker stepping towards its "
                         "path), the anticipated reference brakes as hard as it needs up to this, at most robot.a_comfort "
                         "(0: never harder than anticipate_decel) [m/s^2]", key="anticipate_brake", **NN)
    accel: float = param(1.5, "comfortable acceleration of the anticipated reference speed [m/s^2]", key="anticipate_accel", **P)
    gap: float = param(2.0, "standstill gap kept behind what lies ahead [m]", key="anticipate_gap", **NN)
    time_gap: float = param(1.0, "time gap kept behind a moving leader [s]", key="anticipate_time_gap", **NN)
    yield_distance: float = param(20.0, "within this of a walker a robot on a lateral band keeps within yield_band of its reference [m]", **NN)
    yield_band: float = param(0.25, "how far a robot near a walker may leave its reference sideways [m]", **P)
    pedestrian_margin: float = param(0.0, "declared by MpcConfig (the same key)", shared=True)
    pedestrian_reach: float = param(0.0, "declared by MpcConfig (the same key)", shared=True)
    walkway_time: float = param(0.0, "declared by MpcConfig (the same key)", shared=True)
    look: float = param(80.0, "how far ahead along the path it looks [m]", internal=True)
    lateral_margin: float = param(0.3, "a footprint within this of the path ahead is on it [m]", internal=True)
    cut_in: float = param(2.0, "a footprint that reaches the path within this time at its speed towards it is on it [s]", internal=True)
    hold: float = param(2.0, "how long a walker who counted goes on counting (see stop_points) [s]", internal=True)

    @cached_property
    def rules(self) -> np.ndarray:
        """The rules as :func:`aac_sumo.kernels.stop_rows` takes them."""
        return np.array([self.look, self.lateral_margin, self.cut_in, self.pedestrian_margin, self.decel, self.gap, self.time_gap,
                         self.hold])


def across_extent(length, width, relative_heading) -> np.ndarray:
    """Half extent [m] of rectangles (length, width) across a direction at ``relative_heading``."""
    return 0.5 * np.abs(length * np.sin(relative_heading)) + 0.5 * np.abs(width * np.cos(relative_heading))


def agents(world: WorldState, courses: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """Every agent on the road but the robots off it, as arrays over them: the robot index
    (-1 for an obstacle), footprint centre (K, 2) [m], heading [rad], length and width [m],
    velocity (K, 2) [m/s], whether it is a walker, and its longitudinal acceleration [m/s^2]
    (an obstacle's estimate, :attr:`~aac_sumo.world.Obstacle.accel`; 0 for a robot). With
    ``courses`` (n,) [rad], a robot's velocity points along its course there (where its task
    takes it, :func:`intended_courses`) instead of its heading. Computed once per world (a
    snapshot) and courses."""
    key = ("_agents", courses is None)
    cached = world.__dict__.get(key)
    if cached is None:
        robots = np.flatnonzero(world.on_road)
        obstacles = world.obstacles
        heading = world.states[robots, 2]
        course = heading if courses is None else np.asarray(courses, dtype=float)[robots]
        cached = (np.r_[robots, np.full(len(obstacles), -1)],
                  np.vstack([world.robot_centres()[robots]] + [o.centre[None, :] for o in obstacles]).reshape(-1, 2),
                  np.r_[heading, [o.heading for o in obstacles]],
                  np.r_[[world.robots[j].length for j in robots], [o.length for o in obstacles]],
                  np.r_[[world.robots[j].width for j in robots], [o.width for o in obstacles]],
                  np.vstack([world.states[robots, 3:4] * np.column_stack([np.cos(course), np.sin(course)])]
                            + [np.asarray(o.velocity, dtype=float)[None, :] for o in obstacles]).reshape(-1, 2),
                  np.array([False] * len(robots) + [o.kind == "pedestrian" for o in obstacles], dtype=bool),
                  np.r_[np.zeros(len(robots)), [o.accel for o in obstacles]])
        world.__dict__[key] = cached
    return cached


def intended_courses(world: WorldState, tasks: list[PathReference], preview: float) -> np.ndarray:
    """Each robot's course [rad] (n,): the heading of its task's path ``preview`` [s] ahead at its
    speed (at least 1 m/s), where the path takes it; its heading where the path leaves the heading
    free (the goal approach). The robots share their tasks: a car that changes lanes beside
    another that changes lanes the same way is not cutting into its path."""
    courses = world.states[:, 2].copy()
    for j, (task, state) in enumerate(zip(tasks, world.states)):
        if world.on_road[j] and not task.heading_free(state):
            s = task.project(state[:2])[0] + max(abs(float(state[3])), 1.0) * preview
            courses[j] = float(task.pose_at(s)[0, 2])
    return courses


def stop_points(world: WorldState, i: int, task: PathReference, params: Anticipation, held: dict | None = None,
                projected: tuple[float, float] | None = None, courses: np.ndarray | None = None,
                speeds: np.ndarray | None = None) -> np.ndarray:
    """Rows ``[s_stop, v_lead, grow]`` (K, 3) of what robot ``i`` must stay behind on ``task``'s
    path: the arc length [m] where its rear axle must be able to come down to the speed
    ``v_lead`` [m/s] (>= 0) of what lies ahead, and how much room [m] per m/s of the robot's
    speed it keeps on top (a walker's reach while the robot brakes: ``pedestrian_reach / decel``
    [s]). ``held`` (walker name -> the time [s] it last counted, updated here) keeps a walker
    counting for ``hold`` seconds after it last did, while it is still ahead on the path and not
    walking away from it: a walker who pauses on the crossing for a moment is yielded to still.
    ``projected``: the robot's ``task.project`` when the caller has it; ``courses``: the robots'
    courses (:func:`intended_courses`; None: their headings); ``speeds`` (n,) [m/s]: the
    robots' speeds to take instead of their states' (robot ``i``'s own is its state's), without
    building the agents again. The loop is compiled (:func:`aac_sumo.kernels.stop_rows`)."""
    robot, state = world.robots[i], world.states[i]
    s0, off0 = task.project(state[:2]) if projected is None else projected
    index, centres, headings, lengths, widths, velocity, walker, accel = agents(world, courses)
    if speeds is not None:
        robots = np.flatnonzero(world.on_road)  # agents' first rows, in this order
        course = world.states[robots, 2] if courses is None else np.asarray(courses, dtype=float)[robots]
        velocity = velocity.copy()
        velocity[: len(robots)] = np.asarray(speeds, dtype=float)[robots, None] * np.column_stack([np.cos(course), np.sin(course)])
    rows = np.flatnonzero(index == i)
    held_since = np.full(len(index), -np.inf)
    walkers = _walker_rows(world) if held is not None else []
    for row, name in walkers:
        held_since[row] = held.get(name, -np.inf)
    ego = np.array([state[0], state[1], state[3], robot.length, robot.width, robot.centre_offset, robot.model.limits.comfort_decel])
    stops, counted = stop_rows(*task.arrays()[:-1], task.stop_at_end, ego, s0, off0, centres, headings, lengths, widths, velocity,
                               walker, _step_out_speeds(world, params), accel, rows[0] if rows.size else -1, held_since, world.t,
                               params.rules)
    for row, name in walkers:
        if counted[row]:
            held[name] = world.t
    if world.crossings:  # and before a crossing it could not clear (what stands beyond would stop it on it)
        stops = np.vstack([stops, crossing_rows(world, i, task, stops, params.pedestrian_margin)])
    return stops


def _step_out_speeds(world: WorldState, params: Anticipation) -> np.ndarray:
    """How fast [m/s] each of :func:`agents`' rows may step out of its way, as a walker
    (:meth:`~aac_sumo.world.Obstacle.step_out_speed`; 0 for the rest), cached per world."""
    key = ("_step_out", params.pedestrian_reach, params.walkway_time)
    cached = world.__dict__.get(key)
    if cached is None:
        first = int(np.count_nonzero(world.on_road))
        cached = np.zeros(first + len(world.obstacles))
        cached[first:] = [o.step_out_speed(params.pedestrian_reach, params.walkway_time) if o.kind == "pedestrian" else 0.0
                          for o in world.obstacles]
        world.__dict__[key] = cached
    return cached


def _walker_rows(world: WorldState) -> list[tuple[int, str]]:
    """``(row, name)`` of every walker among :func:`agents`' rows (cached per world)."""
    cached = world.__dict__.get("_walker_rows")
    if cached is None:
        first = int(np.count_nonzero(world.on_road))  # agents: the robots on the road, then the obstacles
        cached = [(first + k, o.name) for k, o in enumerate(world.obstacles) if o.kind == "pedestrian"]
        world.__dict__["_walker_rows"] = cached
    return cached


def speed_cap(stops: np.ndarray, s, decel: float) -> np.ndarray:
    """The highest speed ``v`` [m/s] at arc lengths ``s`` from which braking at ``decel``
    [m/s^2] reaches every stop row ``[s_stop, v_lead, grow]`` at its speed with ``grow * v``
    [m] to spare: ``(v^2 - v_lead^2) / (2 decel) + grow v <= s_stop - s``; inf without any.
    Past a row (``s > s_stop``: closer to a leader than the gap it keeps) the cap falls below
    ``v_lead`` as if the room were negative, to zero where ``v_lead^2 < 2 decel (s - s_stop)``:
    the gap opens again at ``decel`` instead of staying closed at the leader's speed. (AAC's cars
    drive stale plans between their turns and closed up; their next solve then met the MPC's
    barrier with a one-period brake at 3-4 m/s^2.)"""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    if len(stops) == 0:
        return np.full(s.shape, np.inf)
    room = stops[None, :, 0] - s[:, None]
    lead, bk = stops[None, :, 1], decel * stops[None, :, 2]
    return np.maximum(np.sqrt(np.maximum(bk**2 + lead**2 + 2.0 * decel * room, 0.0)) - bk, 0.0).min(axis=1)


def anticipated_reference(world: WorldState, i: int, task: PathReference, steps: int, dt: float, params: Anticipation,
                          held: dict | None = None, stop_ahead=(), courses: np.ndarray | None = None,
                          speeds: np.ndarray | None = None) -> np.ndarray:
    """Robot ``i``'s reference (steps+1, 4) along ``task``'s path: its speeds start at the
    robot's speed and change by at most ``accel`` / ``decel`` [m/s^2] from stage to stage
    towards the path's speed, capped by :func:`speed_cap` of :func:`stop_points`; with ``brake``
    above ``decel``, a stop it can no longer meet at ``decel`` (seen late) it meets braking
    harder, as hard as it needs up to ``brake`` and the robot's comfort deceleration
    (``robot.a_comfort``). Its positions follow the speeds.
    ``held``: the walkers it yields to, as in :func:`stop_points`. ``stop_ahead`` [m]: more
    places to stop at, as distances of the rear axle along the path from where it is (before a
    walker's path, where the safety stop holds the robot). ``courses`` and ``speeds``: as in :func:`stop_points`."""
    state = world.states[i]
    s, v = anticipated_speeds(world, i, task, steps, dt, params, held, stop_ahead, courses, speeds)
    poses = task.pose_at(s)
    heading = state[2] + wrap_angle(poses[:, 2] - state[2])
    return np.column_stack([poses[:, :2], heading, v])


def anticipated_speeds(world: WorldState, i: int, task: PathReference, steps: int, dt: float, params: Anticipation,
                       held: dict | None = None, stop_ahead=(), courses: np.ndarray | None = None,
                       speeds: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The arc lengths [m] and speeds [m/s] (steps+1,) of :func:`anticipated_reference`."""
    state = world.states[i]
    projected = task.project(state[:2])
    s0 = projected[0]
    stops = stop_points(world, i, task, params, held, projected, courses, speeds)
    ahead = np.asarray(stop_ahead, dtype=float).reshape(-1)
    if ahead.size:
        stops = np.vstack([stops, np.column_stack([s0 + ahead, np.zeros((ahead.size, 2))])])
    limits = task.limits if task.limits is not None else np.zeros(0)
    brake = max(params.decel, min(params.brake, world.robots[i].model.limits.comfort_decel))
    return ramped_speeds(s0, float(state[3]), steps, dt, params.decel, params.accel, brake, stops, task.speed,
                         task.s, limits, task.stop_at_end, task.decel, task.length)  # speed_cap, stage by stage, compiled


#: A stop row of what moves slower than this [m/s] can hold a robot up beyond a crossing.
CLEAR_SPEED = 1.0


def crossing_rows(world: WorldState, i: int, task: PathReference, stops: np.ndarray, margin: float) -> np.ndarray:
    """Stop rows ``[s_stop, 0, 0]`` (rear axle, arc length on ``task`` [m]) before each of the
    world's pedestrian crossings ahead on robot ``i``'s path that it could not clear: a row of
    ``stops`` of something standing or slower than ``CLEAR_SPEED`` would stop it with its
    footprint on the crossing or within ``margin`` [m] of it. It then waits with its front
    ``margin`` before the crossing. A crossing whose strip the robot's front has reached
    gives no row: it drives on through."""
    slow = stops[stops[:, 1] <= CLEAR_SPEED, 0] if len(stops) else np.zeros(0)
    if not world.crossings or slow.size == 0:  # nothing that stands could stop it on a crossing
        return np.zeros((0, 3))
    robot, state = world.robots[i], world.states[i]
    front, rear = robot.centre_offset + 0.5 * robot.length, 0.5 * robot.length - robot.centre_offset
    s0 = task.project(state[:2])[0]
    rows = []
    for crossing in world.crossings:
        s_x = crossing_point(task, crossing)
        if s_x is None:
            continue
        half = 0.5 * crossing.width + margin
        s_stop, s_clear = s_x - half - front, s_x + half + rear
        if s0 < s_stop and np.any((slow > s_stop) & (slow < s_clear)):
            rows.append([s_stop, 0.0, 0.0])
    return np.array(rows, dtype=float).reshape(-1, 3)


def crossing_point(task: PathReference, crossing) -> float | None:
    """Arc length [m] on ``task``'s path where it crosses ``crossing``'s centre-line (between
    its two ends' projections, where their signed offsets change sign), None where it does not;
    cached on the path (both are static)."""
    cache = task.__dict__.setdefault("_crossing_points", {})
    if crossing.name not in cache:
        ends = np.asarray(crossing.shape, dtype=float)[[0, -1]]
        s_ends, offsets = task.project_many(ends)
        poses = task.pose_at(s_ends)
        side = np.sign(-np.sin(poses[:, 2]) * (ends[:, 0] - poses[:, 0]) + np.cos(poses[:, 2]) * (ends[:, 1] - poses[:, 1]))
        signed = side * offsets
        cache[crossing.name] = (None if signed[0] * signed[1] >= 0.0
                                else float(s_ends[0] + (s_ends[1] - s_ends[0]) * signed[0] / (signed[0] - signed[1])))
    return cache[crossing.name]


def near_pedestrian(world: WorldState, i: int, distance: float) -> bool:
    """Whether a pedestrian's centre lies within ``distance`` [m] of robot ``i``'s centre."""
    centre = world.robot_centres()[i]
    return any(o.kind == "pedestrian" and np.hypot(*(o.centre - centre)) <= distance for o in world.obstacles)
