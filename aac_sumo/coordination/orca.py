"""ORCA baseline: RVO2's optimal reciprocal collision avoidance (the ``pyrvo`` wheel), driven
by a velocity-tracking law on our bicycle robots.

What it does each control period:

1. **Discs.** Each robot is its covering disc (:func:`~aac_sumo.mpc.planner.ego_discs` with one
   disc: centred on the footprint, radius ``hypot(length, width) / 2``) grown by
   ``radius_margin``. Its RVO2 velocity is the footprint centre's, from the robot's speed,
   heading and last steering angle.
2. **Preferred velocity** along its reference: towards the path point ``lookahead`` metres ahead
   of the rear axle's projection (the goal itself within ``lookahead`` of it), at the task's
   speed, slowing to stop at the goal as the reference does (``speed_at``, with the remaining
   distance the larger of the path's and the straight line's). A robot whose task is finished
   prefers to stand (it still makes way, as RVO2's agents do). ``pref_noise`` adds a seeded
   uniform perturbation of that size [m/s] in a random direction (the known remedy for ORCA's
   symmetric jams); 0 by default.
3. **Static obstacles** (debris) are RVO2 obstacles: their footprint rectangles as polygons,
   counter-clockwise, processed once. Moving obstacles are not supported (the kinds ORCA runs
   on have none).
4. **ORCA** (``doStep``) gives each disc a new velocity within ``max_speed``; RVO2's own
   position update is discarded: positions come from our simulator every period.
5. **Tracking law** (our robots are bicycles, not holonomic discs): the robot turns its heading
   towards the ORCA velocity's direction (or, driving backwards when the robot may reverse and
   the velocity points behind it, its back), with time constant ``turn_time``, and drives its
   speed in one period towards the ORCA speed times the cosine of the heading error (slower
   while it turns), all within the vehicle limits: acceleration, braking, steering angle,
   steering rate and lateral acceleration (``tracking = "direct"``, the default). With
   ``tracking = "halfplanes"`` the speed is instead the one reachable this period along the
   next heading that keeps ORCA's half-planes (RVO2's ORCA lines of the robot) and is nearest
   that speed, or else the one violating them least. The simulator then moves the bicycle and counts
   collisions on the rectangular footprints; ORCA's guarantees hold only for discs that take
   their velocity instantly, so overlaps can and do happen, and they are counted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import param, section
from aac_sumo.coordination.base import Coordinator, Decision, Finished, RobotDecision
from aac_sumo.geometry import wrap_angle
from aac_sumo.mpc.planner import MpcPlanner, ego_discs
from aac_sumo.references import PathReference
from aac_sumo.registry import register_coordinator
from aac_sumo.world import WorldState

#: Obstacle kinds handed to RVO2 as polygons (they never move).
STATIC_KINDS = ("static", "cone")
#: |cos| of the heading error below which a robot keeps its present driving direction
#: (forward or backward), so that it does not switch direction at every period near 90 degrees.
DIRECTION_HYSTERESIS = 0.2
#: ORCA speeds below this [m/s] count as standing: the heading is kept, the robot brakes.
STANDING = 1e-3
#: How the tracking law picks the speed: ``direct`` (the tracking speed, clipped to the limits,
#: whatever ORCA's half-planes say; the default, the tables' law), ``halfplanes`` (among the
#: speeds it can reach in one period along its next heading, the one nearest the tracking speed
#: that keeps every ORCA half-plane, or else the one that violates them least).
TRACKING = ("direct", "halfplanes")
#: Speeds tried per period by the ``halfplanes`` tracking law, evenly over the reachable interval.
SPEED_SAMPLES = 41


@section("orca")
@dataclass(frozen=True)
class OrcaParams:
    """RVO2's agent settings (neighbour distance [m], most neighbours, time horizons [s] against
    agents and against obstacles, most speed [m/s], 0: each robot's task speed), the disc's
    extra radius [m], the preferred velocity's look-ahead along the path [m] and seeded noise
    [m/s], the tracking law's heading time constant [s], whether it may drive backwards (when the
    robot may), and how it picks the speed (``TRACKING``)."""

    neighbor_dist: float = param(3.0, "RVO2 neighbour distance: other discs farther than this are ignored [m]", **P)
    max_neighbors: int = param(10, "RVO2: most neighbours each robot considers", check=lambda n: 1 <= n <= 1000, expect="in 1..1000")
    time_horizon: float = param(2.0, "RVO2 time horizon against other robots [s]", **P)
    time_horizon_obst: float = param(2.0, "RVO2 time horizon against static obstacles (debris polygons) [s]", **P)
    radius_margin: float = param(0.0, "added to each robot's covering-disc radius hypot(length, width) / 2 [m]", **NN)
    max_speed: float = param(0.0, "RVO2 most speed, at most robot.v_max (0: each robot's cruise speed, as the preferred speed) [m/s]", **NN)
    lookahead: float = param(1.0, "the preferred velocity points at the path point this far ahead of the rear axle's projection [m]", **P)
    pref_noise: float = param(0.0, "seeded random perturbation of each preferred velocity, up to this size (0: plain ORCA) [m/s]", **NN)
    turn_time: float = param(0.3, "tracking law: time constant of turning the heading towards the ORCA velocity's direction [s]", **P)
    reverse: bool = param(True, "tracking law: drive backwards when the ORCA velocity points behind the robot (needs robot.allow_reverse)")
    seed: int = param(0, "seed of the preferred-velocity noise", key="scenario.seed")
    tracking: str = param("direct", "tracking law's speed: direct (the ORCA speed times the cosine of the "
                          "heading error, within the limits) or halfplanes (the speed reachable in one period along the next heading "
                          "nearest that which keeps ORCA's half-planes, else the one violating them least)", type=TRACKING)


def rectangle_polygon(centre, length: float, width: float, heading: float) -> list[tuple[float, float]]:
    """The corners of a footprint rectangle, counter-clockwise (RVO2's obstacle orientation)."""
    c, s = np.cos(heading), np.sin(heading)
    local = ((0.5 * length, -0.5 * width), (0.5 * length, 0.5 * width), (-0.5 * length, 0.5 * width), (-0.5 * length, -0.5 * width))
    return [(float(centre[0] + c * u - s * v), float(centre[1] + s * u + c * v)) for u, v in local]


class OrcaCoordinator(Coordinator):
    """ORCA through pyrvo for every robot, then the tracking law (see the module docstring).
    The planner is not used for decisions (only for its period and the shared safety-check
    helpers); no MPC is solved, so ``solves`` is 0."""

    name = "orca"

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                 params: OrcaParams = OrcaParams()):
        super().__init__(planner, tasks, corridors, finished)
        self.params = params
        self.rng = np.random.default_rng(params.seed)
        self._rvo = None  # built at the first decision, when the robots and the debris are known

    def __getstate__(self) -> dict:
        """Copies (the runner's warm-up copy) build their own RVO2 simulator: a pyrvo object
        cannot be copied, and every agent's position and velocity is set each period anyway."""
        state = self.__dict__.copy()
        state["_rvo"] = None
        return state

    def radii(self, world: WorldState) -> np.ndarray:
        """Each robot's ORCA disc radius [m]: its covering disc plus ``radius_margin``."""
        return np.array([ego_discs(r, 1)[1] for r in world.robots]) + self.params.radius_margin

    def max_speeds(self, world: WorldState) -> np.ndarray:
        """Each robot's RVO2 most speed [m/s]: ``max_speed`` (0: its task's speed), within its ``v_max``."""
        wanted = np.array([self.params.max_speed or task.speed for task in self.tasks])
        return np.minimum(wanted, [r.model.limits.v_max for r in world.robots])

    def _build(self, world: WorldState):
        import pyrvo  # the wheel is needed only by this baseline

        p = self.params
        sim = pyrvo.RVOSimulator()
        sim.set_time_step(self.planner.config.dt)
        for centre, radius, speed in zip(world.robot_centres(), self.radii(world), self.max_speeds(world)):
            sim.add_agent((float(centre[0]), float(centre[1])), p.neighbor_dist, p.max_neighbors, p.time_horizon,
                          p.time_horizon_obst, float(radius), float(speed), (0.0, 0.0))
        for o in world.obstacles:
            if o.kind not in STATIC_KINDS or np.any(o.velocity != 0.0):
                raise ValueError(f"the orca coordinator takes static obstacles only, not {o.kind} {o.name}")
            sim.add_obstacle(rectangle_polygon(o.centre, o.length, o.width, o.heading))
        if world.obstacles:
            sim.process_obstacles()
        return sim

    def centre_velocities(self, world: WorldState) -> np.ndarray:
        """Velocities (n, 2) [m/s] of the footprint centres: the rear axle's plus the turn's
        (yaw rate from the speed and the last steering angle)."""
        x = world.states
        wheelbase = np.array([r.model.wheelbase for r in world.robots])
        offset = np.array([r.centre_offset for r in world.robots])
        yaw_rate = x[:, 3] * np.tan(self.last_inputs[:, 1]) / wheelbase
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        return np.column_stack([x[:, 3] * c - yaw_rate * offset * s, x[:, 3] * s + yaw_rate * offset * c])

    def preferred_velocities(self, world: WorldState, done: np.ndarray) -> np.ndarray:
        """Each robot's preferred velocity (n, 2) [m/s] along its reference (zero once done)."""
        pref = np.zeros((len(world.robots), 2))
        look = self.params.lookahead
        for i in np.flatnonzero(~done):
            task, rear = self.tasks[i], world.states[i, :2]
            s, _ = task.project(rear)
            goal = task.points[-1]
            to_goal = float(np.hypot(*(goal - rear)))
            remaining = max(task.length - s, to_goal) if task.stop_at_end else np.inf
            target = goal if task.stop_at_end and remaining <= look else task.pose_at(s + look)[0, :2]
            heading = target - rear
            norm = float(np.hypot(*heading))
            if norm < 1e-9:
                continue
            speed = float(task.speed_at(task.length - remaining)) if task.stop_at_end else float(task.speed_at(s))
            pref[i] = speed * heading / norm
        if self.params.pref_noise > 0.0:
            angle = self.rng.uniform(0.0, 2.0 * np.pi, len(pref))
            size = self.rng.uniform(0.0, self.params.pref_noise, len(pref))
            pref[~done] += (size[:, None] * np.column_stack([np.cos(angle), np.sin(angle)]))[~done]
        return pref

    def orca_velocities(self, world: WorldState, pref: np.ndarray) -> np.ndarray:
        """RVO2's new velocity (n, 2) [m/s] of every disc for this period (its half-planes stay
        readable in the simulator until the next step: :meth:`half_planes`)."""
        if self._rvo is None:
            self._rvo = self._build(world)
        sim = self._rvo
        for i, (c, v, u) in enumerate(zip(world.robot_centres(), self.centre_velocities(world), pref)):
            sim.set_agent_position(i, (float(c[0]), float(c[1])))
            sim.set_agent_velocity(i, (float(v[0]), float(v[1])))
            sim.set_agent_pref_velocity(i, (float(u[0]), float(u[1])))
        sim.do_step()
        return np.array([sim.get_agent_velocity(i).to_tuple() for i in range(len(world.robots))]).reshape(-1, 2)

    def half_planes(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Robot ``i``'s ORCA half-planes of this period, obstacles' first: directions (k, 2) and
        points (k, 2); a velocity ``u`` keeps line j when ``det(direction_j, point_j - u) <= 0``
        (RVO2's convention: the permitted side is left of the direction)."""
        sim = self._rvo
        lines = [sim.get_agent_orca_line(i, k) for k in range(sim.get_agent_num_orca_lines(i))]
        if not lines:
            return np.zeros((0, 2)), np.zeros((0, 2))
        arr = np.array(lines, dtype=float)
        return arr[:, 0], arr[:, 1]

    def pick_speed(self, i: int, direction: np.ndarray, low: float, high: float, target: float) -> float:
        """The speed in [``low``, ``high``] [m/s] whose velocity along the unit ``direction``
        keeps robot ``i``'s ORCA half-planes and is nearest ``target``; when none does, the one
        that violates them least (by the largest violation [m/s]), then nearest ``target``."""
        dirs, points = self.half_planes(i)
        if high - low < 1e-12:
            return low
        speeds = np.unique(np.r_[np.linspace(low, high, SPEED_SAMPLES), min(max(target, low), high)])
        if len(dirs) == 0:
            return float(speeds[np.argmin(np.abs(speeds - target))])
        rel = points[None, :, :] - speeds[:, None, None] * direction[None, None, :]
        violation = np.maximum(dirs[None, :, 0] * rel[..., 1] - dirs[None, :, 1] * rel[..., 0], 0.0).max(axis=1)
        best = violation <= violation.min() + 1e-6
        return float(speeds[best][np.argmin(np.abs(speeds[best] - target))])

    def track_velocity(self, world: WorldState, i: int, velocity: np.ndarray) -> np.ndarray:
        """Input ``[accel, steer]`` of robot ``i`` towards the disc velocity ``velocity`` [m/s]
        within its vehicle limits (module docstring, step 5)."""
        robot, (_, _, h, v) = world.robots[i], world.states[i]
        model, lim, dt = robot.model, robot.model.limits, self.planner.config.dt
        previous = self.last_inputs[i, 1]
        speed = float(np.hypot(*velocity))
        if speed < STANDING:
            target_v, target_h = 0.0, h
        else:
            psi = float(np.arctan2(velocity[1], velocity[0]))
            cos_err = float(np.cos(psi - h))
            may_reverse = self.params.reverse and lim.v_min < 0.0
            if abs(cos_err) < DIRECTION_HYSTERESIS:
                backward = may_reverse and v < 0.0
            else:
                backward = may_reverse and cos_err < 0.0
            target_h = psi + np.pi if backward else psi
            target_v = speed * cos_err
            target_v = min(target_v, 0.0) if backward else max(target_v, 0.0)
        target_v = min(max(target_v, lim.v_min), lim.v_max)
        accel = min(max((target_v - v) / dt, lim.a_min), lim.a_max)
        steer = self.steer_towards(model, h, v, v + accel * dt, target_h, previous, dt)
        steer = float(model.limit_steer(steer, v, previous, dt, accel))
        if self.params.tracking == "halfplanes":
            heading = h + v * np.tan(steer) / model.wheelbase * dt  # the heading the next period drives along
            low = max(v + lim.a_min * dt, lim.v_min)
            high = min(v + lim.a_max * dt, lim.v_max)
            if not (self.params.reverse and lim.v_min < 0.0):
                low = max(low, min(0.0, v))  # forward only: never drive it backwards
            v_next = self.pick_speed(i, np.array([np.cos(heading), np.sin(heading)]), low, max(low, high), v + accel * dt)
            accel = min(max((v_next - v) / dt, lim.a_min), lim.a_max)
            steer = float(model.limit_steer(steer, v, previous, dt, accel))
        return np.array([accel, steer])

    def steer_towards(self, model, h: float, v: float, v_next: float, target_h: float, previous: float, dt: float) -> float:
        """The steering angle [rad] that turns heading ``h`` towards ``target_h`` with the time
        constant ``turn_time`` at the speed ``v_next`` (``previous`` at standstill), before limits."""
        if abs(v_next) <= 1e-6:
            return previous
        turn = min(1.0, dt / self.params.turn_time) * float(wrap_angle(target_h - h))
        return float(np.arctan2(model.wheelbase * turn * np.sign(v_next), abs(v_next) * dt))

    def _decide(self, world: WorldState) -> Decision:
        n = len(world.robots)
        done = self.finished(world)
        velocity = self.orca_velocities(world, self.preferred_velocities(world, done))
        inputs = np.zeros((n, 2))
        for i in range(n):
            inputs[i] = self.track_velocity(world, i, velocity[i])
        records = [RobotDecision(False, reason="orca", mode="orca") for _ in range(n)]
        return Decision(inputs, records, notes=dict(authority="", reason="orca", safety_stops=0))


register_coordinator("orca", OrcaCoordinator, params=OrcaParams, kinds=("swarm_rescue", "circle_swap", "random_crossing"),
                     baseline=True, label="ORCA (RVO2)", doc="RVO2's ORCA on covering discs, a baseline; docs/baselines.md")
