"""What every coordinator shares: the MPC planner component, per-robot memory, and the record
of a decision. Coordinators see a :class:`~aac_sumo.world.WorldState` and never a simulator."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from aac_sumo.config.schema import ParamError
from aac_sumo.barriers import ObstaclePrediction, RegionTrack
from aac_sumo.coordination.anticipation import Anticipation, anticipated_reference, anticipated_speeds, intended_courses, near_pedestrian
from aac_sumo.coordination.regions import Fleet
from aac_sumo.coordination.safety import SafetyCheck, WalkerSpeeds
from aac_sumo.mpc.planner import FALLBACK_TURN_TIME, MpcPlanner
from aac_sumo.mpc.plan import Plan
from aac_sumo.prediction import SpeedHistory
from aac_sumo.references import LateralBand, PathReference
from aac_sumo.world import Obstacle, WorldState

Finished = Callable[[WorldState], np.ndarray]
#: Spacing [m] of the path headings the safety stop's braking courses follow.
HEADING_SPACING = 1.0
#: What a robot whose solve failed applies: the planner's braking fallback, or the tracking law
#: through the coordinator's safety stop.
FALLBACKS = ("brake", "tracking")


def check_safety_options(safety_stop: bool, fallback: str, ignore_followers: bool, commit: bool = True, detour: bool = False) -> None:
    """The rules of a coordinator's safety options, the one place they are written: a
    :class:`~aac_sumo.config.schema.ParamError` (a ValueError; a ScenarioError naming the key
    when the params come from a scenario) unless ``fallback`` is one of FALLBACKS, detours
    have committed plans, and the options that rely on the safety stop (the tracking
    fallback, ignoring followers) have it."""
    if fallback not in FALLBACKS:
        raise ParamError("fallback", "one of " + ", ".join(FALLBACKS), fallback)
    if detour and not commit:
        raise ParamError("detour", "false unless {section}.commit is true", True)
    if safety_stop:
        return
    if fallback == "tracking":
        raise ParamError("fallback", "brake unless {section}.safety_stop is true", "tracking")
    if ignore_followers:
        raise ParamError("ignore_followers", "false unless {section}.safety_stop is true", True)


def straight_behind(world: WorldState, fleet: Fleet, i: int, others: np.ndarray) -> np.ndarray:
    """Which of robots ``others`` drive straight behind robot ``i`` (bool, len(others)): their
    footprint centre lies more than half the two lengths behind ``i``'s along ``i``'s heading,
    and less than half the two widths beside it. A coordinator may leave keeping that distance
    to them (the follower is responsible, as on a road), when its safety stop makes them do so."""
    centres = world.robot_centres()
    heading = world.states[i, 2]
    rel = centres[others] - centres[i]
    along = rel[:, 0] * np.cos(heading) + rel[:, 1] * np.sin(heading)
    across = -rel[:, 0] * np.sin(heading) + rel[:, 1] * np.cos(heading)
    return (along < -0.5 * (fleet.length[i] + fleet.length[others])) & (np.abs(across) < 0.5 * (fleet.width[i] + fleet.width[others]))


@dataclass
class RobotDecision:
    """One robot's part of a decision.

    ``authority`` is true when the robot solved its MPC this period, and ``status`` is then the
    solve status (None otherwise). ``reason`` says why it holds authority (``round_robin``,
    ``proximity``, ``priority``, ``independent``) and ``mode`` what it applies (``mpc``: its
    plan, or the braking fallback when the solve failed; ``creep``: a committed-plan authority's
    short exact-checked course instead, see :meth:`~aac_sumo.coordination.aac.committed.CommittedAac.creep`; ``plan``: the next input of its stored
    plan; ``tracking``: the tracking law, also after a failed solve with the tracking fallback;
    ``hold``: braking at its goal; ``safety_stop``). ``score``/``progress`` are its proximity-decision
    figures when it was a candidate.
    """

    authority: bool
    status: str | None = None
    solve_ms: float = 0.0
    solver: str = ""
    reference: np.ndarray | None = None
    reason: str = ""
    mode: str = ""
    score: float | None = None
    progress: float | None = None
    iterations: int = -1  # of its solve, and whether it stopped at its iteration cap (Plan); -1 without one
    capped: bool = False


@dataclass
class Decision:
    """Inputs (n, 2) ``[accel, steer]`` for every controlled robot, per-robot records, the
    coordinator's wall time for the period [ms] and free-form notes."""

    inputs: np.ndarray
    robots: list[RobotDecision]
    compute_ms: float = 0.0
    notes: dict = field(default_factory=dict)


class Coordinator(ABC):
    """Holds the planner, each robot's task (reference path), optional position box
    (``[x_min, x_max, y_min, y_max]``, see :meth:`MpcPlanner.plan`), last plan and last input.
    ``finished(world)`` tells which robots have finished their task (none, without it); a robot
    not on the road (:attr:`WorldState.present`) counts as finished and parked. With the
    planner's ``constant_acceleration`` prediction, or with ``anticipation``, it keeps every
    moving obstacle's observed speeds and hands the obstacles on with their estimated
    acceleration (the planner's ``constant_velocity`` prediction does not use it)."""

    name = "base"
    #: Reference speeds and lanes that look beyond the horizon (:mod:`~aac_sumo.coordination.anticipation`); None: the task's.
    anticipation: Anticipation | None = None
    #: Whether the safety stop leaves each robot's uncontrolled followers to keep their distance (:func:`~aac_sumo.coordination.safety.following`).
    leaves_followers: bool = False

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors: list[np.ndarray | None] | None = None,
                 finished: Finished | None = None):
        self.planner = planner
        self.tasks = tasks
        self.corridors = corridors or [None] * len(tasks)
        self.task_finished = finished or (lambda world: np.zeros(len(world.robots), dtype=bool))
        self.plans: list[Plan | None] = [None] * len(tasks)
        self.last_inputs = np.zeros((len(tasks), 2))
        self.fleet: Fleet | None = None
        self.held: list[dict] = [{} for _ in tasks]  # per robot, the walkers it yields to (anticipation.stop_points)
        self.walker_speeds = WalkerSpeeds()  # the walkers' speeds of late, for the safety stop
        self.strips: np.ndarray | None = None  # this period's distances to walkers' paths the safety stop holds robots before
        self.courses: np.ndarray | None = None  # this period's courses of the robots along their tasks (anticipation.intended_courses)
        cfg = planner.config
        self.speeds = SpeedHistory(cfg.prediction_window, cfg.dt) if cfg.prediction == "constant_acceleration" else None

    def decide(self, world: WorldState) -> Decision:
        """Inputs for this period; ``compute_ms`` is the wall time of the whole decision."""
        start = time.perf_counter()
        if self.fleet is None:
            self.fleet = Fleet(world.robots)
        if self.speeds is None and self.anticipation is not None:  # the anticipation sees braking vehicles (obstacles' accel)
            cfg = self.planner.config
            self.speeds = SpeedHistory(cfg.prediction_window, cfg.dt)
        if self.speeds is not None:
            world = self.speeds.annotate(world)
        self.strips = None
        if self.anticipation is not None:
            self.courses = intended_courses(world, self.tasks, 0.5 * self.anticipation.cut_in)
        decision = self._decide(world)
        decision.compute_ms = (time.perf_counter() - start) * 1e3
        self.last_inputs = decision.inputs.copy()
        return decision

    @abstractmethod
    def _decide(self, world: WorldState) -> Decision: ...

    def warm_up(self, world: WorldState) -> None:
        """Pay the one-off costs (a compiled kernel's first call) of what a later period may need
        and a :meth:`decide` on ``world`` does not reach, without changing any later decision.
        The runner calls it on a throw-away copy before the first period (:func:`aac_sumo.runs.runner.warm_up`).
        The base coordinator has none."""

    def finished(self, world: WorldState) -> np.ndarray:
        """Which robots (n,) have finished their task or are not on the road."""
        return np.asarray(self.task_finished(world), dtype=bool) | ~world.on_road

    def parked(self, world: WorldState, done: np.ndarray) -> np.ndarray:
        """Which robots (n,) take no turn and only hold still: those ``done`` whose task stops
        at its end, and those not on the road."""
        return (done & np.array([task.stop_at_end for task in self.tasks])) | ~world.on_road

    def admit(self, world: WorldState, i: int) -> None:
        """Robot ``i`` has just come onto the road (its task is set): forget what it did before."""
        self.plans[i] = None
        self.last_inputs[i] = 0.0
        self.held[i] = {}

    def retask(self, i: int) -> None:
        """Robot ``i``'s task has changed ahead of it (a lane change put off, say): it drops its
        stored plan, made for the old task, and follows the new one from its next input on."""
        self.plans[i] = None

    def reference(self, world: WorldState, i: int, speeds: np.ndarray | None = None) -> np.ndarray:
        """Robot ``i``'s reference over the horizon (N+1, 4): its task's, with speeds that
        anticipate what lies ahead on its path when ``anticipation`` is set (seeing the robots
        at ``speeds`` (n,) [m/s], None: at their speeds now)."""
        cfg = self.planner.config
        if self.anticipation is not None and not self.tasks[i].heading_free(world.states[i]):
            return anticipated_reference(world, i, self.tasks[i], cfg.horizon, cfg.dt, self.anticipation, self.held[i],
                                         self.strips_ahead(i), self.courses, speeds)
        return self.tasks[i].horizon(world.states[i], cfg.horizon, cfg.dt)

    def tracking_lat(self) -> float | None:
        """The lateral acceleration [m/s^2] the tracking law keeps within besides the vehicle's
        limit: the planner's comfort envelope (``comfort_lat``) when set, as a plan's first try
        (a car catching up with its path on the law steered at 2.06 m/s^2); else None."""
        lat = self.planner.config.comfort_lat
        return lat if lat > 0.0 else None

    def hold_before_strips(self, safety: SafetyCheck) -> None:
        """From now on this period, every robot's anticipated reference also stops where
        ``safety`` holds it before a walker's path (:meth:`~aac_sumo.coordination.safety.SafetyCheck.walker_paths`):
        the reference and the safety stop then agree. (A car standing 0.4 m before a walker's
        path, her 1 m beyond its lane walking away, had a reference at its cruise speed: its
        tracking law set off at 1.5 m/s^2 and its next solve braked at 2.8 m/s^2 for her.)"""
        self.strips = safety.walker_paths()[2]

    def strips_ahead(self, i: int) -> np.ndarray:
        """Distances [m] ahead of robot ``i`` to the walkers' paths it is held before this period
        (:meth:`hold_before_strips`; none before it is called)."""
        if self.strips is None:
            return np.zeros(0)
        return self.strips[i][np.isfinite(self.strips[i])]

    def yielding(self, world: WorldState, i: int) -> bool:
        """Whether robot ``i`` is within the anticipation's ``yield_distance`` of a walker (with
        ``anticipation`` set), where it keeps to its lane: it yields, it does not swerve."""
        rules = self.anticipation
        return rules is not None and near_pedestrian(world, i, rules.yield_distance)

    def corridor(self, world: WorldState, i: int):
        """Robot ``i``'s corridor this period: its lateral band hugs its reference while it is
        :meth:`yielding`."""
        band = self.corridors[i]
        if isinstance(band, LateralBand) and self.yielding(world, i):
            return band.hugging(self.anticipation.yield_band)
        return band

    def solve(self, world: WorldState, i: int, obstacles: list[Obstacle | ObstaclePrediction | RegionTrack], reason: str) -> RobotDecision:
        """Plan robot ``i`` around ``obstacles``, remember the plan, and report it."""
        ref = self.reference(world, i)
        plan = self.planner.plan(world.robots[i], world.states[i], ref, self.last_inputs[i], obstacles, self.plans[i], self.corridor(world, i))
        self.plans[i] = plan
        return RobotDecision(True, plan.status, plan.solve_ms, plan.solver, ref, reason=reason, mode="mpc",
                             iterations=plan.iterations, capped=plan.capped)

    def tracking_speed(self, world: WorldState, i: int, speed_gain: float) -> float | None:
        """The speed [m/s] robot ``i``'s tracking law (gain ``speed_gain`` [1/s]) drives towards
        when ``anticipation`` is set, so that the law accelerates and brakes as the reference
        does: its anticipated reference speed ``1 / speed_gain`` seconds ahead, or, where the
        reference's ramp ends sooner (a stop, or the speed it settles at), the speed that gives
        the ramp's rate up to there; else None (its task's speed). (Aiming at the speed 1 s ahead,
        a car below 1.5 m/s that had to stop braked at only its speed per second and crept on a
        metre: into its gap to a standing car, whose region in the MPC then braked it at 4 m/s^2.)"""
        if self.anticipation is None:
            return None
        dt = self.planner.config.dt
        ahead = max(1, int(round(1.0 / (speed_gain * dt))))
        v = anticipated_speeds(world, i, self.tasks[i], ahead, dt, self.anticipation, self.held[i], self.strips_ahead(i), self.courses)[1]
        ends = max(1, int(np.argmax(np.abs(v - v[-1]) < 1e-9)))  # the first stage at the ramp's last speed
        return float(v[0] + (v[ends] - v[0]) / (ends * dt * speed_gain))

    def safety_check(self, world: WorldState) -> SafetyCheck:
        """The safety stop of this period: robots brake turning towards their reference's heading
        (a car brakes along its lane, as the planner's fallback does), following the path's
        headings every ``HEADING_SPACING`` metres ahead as far as their comfortable stops and the
        turn's lead reach; the walkers' speeds of late bound theirs
        (:class:`~aac_sumo.coordination.safety.WalkerSpeeds`)."""
        fleet, dt = self.fleet, self.planner.config.dt
        v = float(np.max(np.abs(world.states[:, 3]) + fleet.a_max * dt)) if len(world.robots) else 0.0
        reach = v * v / (2.0 * float(np.min(fleet.comfort))) + v * (FALLBACK_TURN_TIME + dt)
        count = int(np.ceil(reach / HEADING_SPACING)) + 2
        headings = np.array([task.headings_ahead(state[:2], count, HEADING_SPACING) for task, state in zip(self.tasks, world.states)])
        return SafetyCheck(world, fleet, self.planner.config, headings.reshape(len(world.robots), count), self.last_inputs[:, 1],
                           followers=self.leaves_followers, walker_speeds=self.walker_speeds.update(world), spacing=HEADING_SPACING)

    def hold_inputs(self, world: WorldState, i: int, steps: int) -> np.ndarray:
        """Inputs (steps, 2) that bring robot ``i`` to a stop where it is, at its comfort
        deceleration, straightening its steering within the limits."""
        return world.robots[i].model.stopping_inputs(world.states[i, 3], self.last_inputs[i, 1], self.planner.config.dt, steps)
