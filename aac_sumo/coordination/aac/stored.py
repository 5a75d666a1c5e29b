"""AAC as the paper runs it (``aac.commit = false``): stored plans.

Each control period exactly one active robot holds authority and solves MPC-(F)CBF (the
paper); with ``authorities`` k or per cluster (beyond the paper), one in each of up to k groups
of :meth:`~aac_sumo.coordination.aac.authority.AacCoordinator.groups`, or in every cluster of
robots that can meet within the horizon, each planning around its own group only (robots of
two clusters cannot come within reach of each other in N periods, whatever either does, so
each authority gets the inputs it would get alone):

1. **Close pairs** of active robots (centre distance below ``close_distance``, KD-tree). Active
   are the unfinished robots and those whose task goes on after finishing (a car that has
   passed the cones still drives among the others); robots parked at their goal are not.
2. With close pairs, the **proximity decision** picks the authority among the robots in them;
   without, **round robin** gives it to the next active robot after the last holder.
3. Every other robot applies the next input of its stored plan, or the tracking law when its
   plan is used up (robots parked at their goal brake to a stop).
4. Optional **safety stop** (beyond the paper, ``safety_stop``; see
   :mod:`~aac_sumo.coordination.safety`): a non-authority robot whose stored input, followed
   by braking to a stop, would bring its footprint within ``safety_margin`` of another robot's
   or a moving obstacle's footprint (a standing one: into contact), closer than it is now and
   than braking at once, brakes instead (as gently as passes the same check, turning towards
   its reference's heading) and drops its plan.
   The authority robot's first planned input gets the same check after its solve, but against
   actual contact only (its MPC keeps its own margins, and looks only N periods ahead).
   When its solve fails it brakes along its lane (the planner's fallback plan, as the paper's
   robots do), or, with ``fallback = "tracking"`` (beyond the paper; needs the safety stop), it
   applies the tracking law through the full safety check, as a robot without a plan does: a
   car hemmed in by conservative regions may then still creep on where its footprint is safe.
   With ``ignore_followers`` (beyond the paper; needs the safety stop) the authority does not
   avoid the robots straight behind it: they keep their distance through the safety stop, as
   a following car does on a road, and a car slowing for the traffic ahead no longer has to
   outrun the one behind it.
5. The authority robot plans around the obstacles and the swept **convex-hull regions** of the
   others: at stage k, an ellipse containing the hull of a robot's footprints at k and k+1 along
   its known motion (stored plan, else constant velocity; the authority's own current motion
   is what the others assume).
"""

from __future__ import annotations

import time

import numpy as np

from aac_sumo.coordination.aac.authority import AacCoordinator
from aac_sumo.coordination.base import Decision, RobotDecision, straight_behind
from aac_sumo.coordination.tracking import track
from aac_sumo.world import WorldState


#: A car slower than this share of its cruise speed whose tracking law accelerates more than its
#: stored plan, by over HOLD_TOLERANCE [m/s^2], has been outrun by the traffic ahead: it drops the
#: plan (see :meth:`StoredPlanAac.intended_inputs`; chosen on S2 seeds 10-14, docs/lane_change.md).
OUTRUN_SHARE = 0.6
HOLD_TOLERANCE = 1e-3


class StoredPlanAac(AacCoordinator):
    """AAC with the paper's stored plans (see the module)."""

    commit = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.used = np.zeros(len(self.tasks), dtype=int)  # inputs already applied from each stored plan

    def admit(self, world: WorldState, i: int) -> None:
        """Robot ``i`` has just come onto the road: it has no stored plan to follow."""
        super().admit(world, i)
        self.used[i] = 0

    def _decide(self, world: WorldState) -> Decision:
        n, cfg = len(world.robots), self.planner.config
        done = self.finished(world)
        parked = self.parked(world, done)
        active = np.flatnonzero(~parked)  # finished robots that drive on (cars past the cones) still take turns
        records = [RobotDecision(False) for _ in range(n)]
        inputs = np.zeros((n, 2))
        notes: dict = {}
        if active.size == 0:
            for i in range(n):
                inputs[i], records[i].mode = self.hold_inputs(world, i, 1)[0], "hold"
            return Decision(inputs, records, notes=dict(authority="", reason="all finished"))

        start = time.perf_counter()
        turns = self.stored_turns(world, parked, active, records)
        proximity_ms = (time.perf_counter() - start) * 1e3 if any(reason == "proximity" for _, reason, _ in turns) else 0.0
        holding = np.zeros(n, dtype=bool)
        holding[[i for i, _, _ in turns]] = True
        others = np.flatnonzero(world.on_road & ~holding)  # robots off the road stand still, far away
        safety = self.safety_check(world) if self.params.safety_stop else None
        if safety is not None and self.anticipation is not None:
            self.hold_before_strips(safety)
        horizon_inputs = np.zeros((len(others), cfg.horizon + 2, 2))
        for row, j in enumerate(others):
            horizon_inputs[row], records[j].mode = self.intended_inputs(world, j, parked[j], cfg.horizon + 2)

        inputs[others] = horizon_inputs[:, 0]
        if safety is not None:
            inputs = safety.safe_inputs(others, inputs, self.params.safety_margin)
        first = inputs[others]
        stops = np.any(first != horizon_inputs[:, 0], axis=1)
        for row in np.flatnonzero(stops):
            j = others[row]
            after = world.robots[j].model.stopping_inputs(world.states[j, 3] + first[row, 0] * cfg.dt, first[row, 1], cfg.dt, cfg.horizon + 1)
            horizon_inputs[row] = np.vstack([first[row], after])
            records[j].mode = "safety_stop"
            if self.plans[j] is not None:
                self.used[j] = len(self.plans[j].inputs)
        traj = self.fleet.rollout(others, world.states[others], horizon_inputs, cfg.dt)
        self.used[others] += 1
        stopped = int(stops.sum())
        for authority, reason, members in turns:
            mine = np.isin(others, members)
            self.stored_turn(world, authority, reason, others[mine], traj[mine], records, inputs)
        if safety is not None:
            stopped += self.check_authorities(world, [i for i, _, _ in turns], records, inputs, safety)
        notes.update(authority=" ".join(world.robots[i].name for i, _, _ in turns), reason=" ".join(sorted({r for _, r, _ in turns})),
                     safety_stops=stopped, proximity_ms=proximity_ms, authorities=len(turns))
        return Decision(inputs, records, notes=notes)

    def stored_turn(self, world: WorldState, authority: int, reason: str, others: np.ndarray, traj: np.ndarray,
                    records: list[RobotDecision], inputs: np.ndarray) -> None:
        """The ``authority`` plans around the obstacles and the swept regions of ``others`` along
        their known courses ``traj`` (m, N+3, 4), and takes its plan's first input (``inputs``
        and ``records`` changed in place)."""
        cfg = self.planner.config
        avoid = ~straight_behind(world, self.fleet, authority, others) if self.params.ignore_followers else np.ones(len(others), dtype=bool)
        regions = self.fleet.swept_regions(others[avoid], traj[avoid], cfg.horizon, cfg.barrier, cfg.fcbf)
        decided = self.solve(world, authority, world.obstacles + regions, reason)
        decided.score, decided.progress = records[authority].score, records[authority].progress
        records[authority] = decided
        inputs[authority] = self.plans[authority].inputs[0]
        self.used[authority] = 1

    def check_authorities(self, world: WorldState, holders: list[int], records: list[RobotDecision], inputs: np.ndarray,
                          safety) -> int:
        """The safety stop on the first inputs of the authorities ``holders`` (``inputs`` and
        ``records`` changed in place): against contact only, since each plan keeps its own margins
        over its N periods; an authority whose solve failed applies, with ``fallback =
        "tracking"``, the tracking law instead, checked with ``safety_margin`` as a robot without
        a plan is. Returns how many inputs the stop changed."""
        cfg = self.planner.config
        margins = np.zeros(len(holders))
        for row, i in enumerate(holders):
            if records[i].status != "solved" and self.params.fallback == "tracking":
                inputs[i] = track(world.robots[i], world.states[i], self.tasks[i], self.params.pursuit, self.params.speed_gain,
                                  self.last_inputs[i, 1], cfg.dt, target_speed=self.tracking_speed(world, i, self.params.speed_gain),
                                  a_lat=self.tracking_lat())
                self.used[i] = len(self.plans[i].inputs)  # no plan to follow: tracking until its next turn
                records[i].mode, margins[row] = "tracking", self.params.safety_margin
        stopped = 0
        holders = np.asarray(holders, dtype=np.int64)
        for margin in np.unique(margins):
            group = holders[margins == margin]
            checked = safety.safe_inputs(group, inputs, float(margin))
            for i in group[np.any(checked[group] != inputs[group], axis=1)]:
                inputs[i], records[i].mode = checked[i], "safety_stop"
                self.used[i] = len(self.plans[i].inputs)
                stopped += 1
        return stopped

    def intended_inputs(self, world: WorldState, j: int, parked: bool, steps: int) -> tuple[np.ndarray, str]:
        """Robot ``j``'s inputs (steps, 2) as far as they are known: the rest of its stored
        plan, then zero (constant velocity); the tracking law now when the plan is used up;
        braking when it is ``parked`` (:meth:`~aac_sumo.coordination.base.Coordinator.parked`).
        With ``anticipation``, a stored plan's next acceleration is at most the tracking law's
        (:meth:`~aac_sumo.coordination.base.Coordinator.tracking_speed`, braking at most at the
        comfort deceleration): the plan was made up to a horizon ago, and the traffic ahead may
        have stopped since. A car slower than ``OUTRUN_SHARE`` of its cruise speed whose law
        accelerates more than its plan (the queue ahead has set off since the plan was made)
        drops the plan and drives on the law, steering and speed together, until its next turn,
        so that a stopped or slowed queue sets off together rather than one car per authority
        turn."""
        out = np.zeros((steps, 2))
        task = self.tasks[j]
        if parked:
            return self.hold_inputs(world, j, steps), "hold"
        plan = self.plans[j]
        speed = self.tracking_speed(world, j, self.params.speed_gain)
        if plan is not None and self.used[j] < len(plan.inputs):
            rest = plan.inputs[self.used[j]:][:steps]
            out[: len(rest)] = rest
            lawful = None if speed is None else self.params.speed_gain * (speed - world.states[j, 3])
            if lawful is not None and world.states[j, 3] < OUTRUN_SHARE * task.speed and lawful > out[0, 0] + HOLD_TOLERANCE:
                self.used[j] = len(plan.inputs)  # held up by a plan the traffic has outrun: the law drives it off
            else:
                if lawful is not None:
                    out[0, 0] = min(out[0, 0], max(lawful, -world.robots[j].model.limits.comfort_decel))
                if self.yielding(world, j):  # it keeps its lane on the tracking law's steering (a plan made a period
                    # or more ago, driven open-loop at 9 m/s, took a car 0.54 m off its lane beside a walker)
                    out[0, 1] = track(world.robots[j], world.states[j], task, self.params.pursuit, self.params.speed_gain,
                                      self.last_inputs[j, 1], self.planner.config.dt, a_lat=self.tracking_lat())[1]
                return out, "plan"
            out[:] = 0.0
        out[0] = track(world.robots[j], world.states[j], task, self.params.pursuit, self.params.speed_gain, self.last_inputs[j, 1],
                       self.planner.config.dt, target_speed=speed, a_lat=self.tracking_lat())
        return out, "tracking"
