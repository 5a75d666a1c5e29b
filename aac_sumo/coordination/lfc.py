"""Leader-follower control (LFC), the paper's baseline: index priority, every robot plans.

Robots are ranked by index (robot 0 leads). Each period every unfinished robot solves the same
MPC in that order; robot i avoids the swept regions of the plans that robots 0..i-1 made this
period, the current constant-velocity motion of the robots that have not planned yet (and of
finished ones), and the obstacles. That is n solves per period. Other priority planners rank
robots by distance to their goal or to a conflict; the paper ranks by index, and so do we.

The paper's LFC has no safety layer. With ``safety_stop`` (off by default) every robot's first
planned input then passes the same safety stop as AAC's robots (:mod:`~aac_sumo.coordination.safety`),
so that both coordinators can be compared with the same safety net. A robot whose solve fails
brakes along its lane (the planner's fallback), or, with ``fallback = "tracking"`` (needs the
safety stop), applies the tracking law through the safety stop, as AAC's robots without a plan
do; the robots after it then assume that input once and constant velocity. With
``ignore_followers`` (needs the safety stop) a robot does not avoid the robots straight behind
it, as AAC's authority with the same option.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import from_section, param, section
from aac_sumo.coordination.aac.params import AacParams
from aac_sumo.coordination.base import FALLBACKS, Coordinator, Decision, Finished, RobotDecision, check_safety_options, straight_behind
from aac_sumo.coordination.tracking import AimsAhead, track
from aac_sumo.coordination.prioritized import PrioritizedLfc
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import PathReference
from aac_sumo.registry import register_coordinator
from aac_sumo.world import WorldState


@section("lfc")
@dataclass(frozen=True)
class LfcParams(AimsAhead):
    """LFC settings: the optional safety stop and its footprint margin [m], what a robot whose
    solve fails applies (``brake`` or ``tracking``), that tracking law's lookahead [m] and
    speed gain [1/s], and whether a robot ignores the robots straight behind it (needs the
    safety stop)."""

    safety_stop: bool = param(False, "every robot's first planned input passes AAC's safety stop (the paper's LFC has none)")
    safety_margin: float = param(0.1, "footprint gap below which the safety stop triggers [m]", **NN)
    fallback: str = param("brake", "what a robot whose solve fails applies: brake (the planner's fallback) or tracking "
                          "(the tracking law below through the safety stop; needs safety_stop)", type=FALLBACKS)
    lookahead: float = param(1.0, "pure-pursuit lookahead of that tracking law [m]", **P)
    lookahead_time: float = param(0.0, "with > 0, at low speed the lookahead shrinks to the distance covered in this time, but not below "
                                  "lookahead_min: a car that turns a tight corner slowly aims at the corner, not beyond it [s]", **NN)
    lookahead_min: float = param(0.0, "the shortest lookahead with lookahead_time > 0 [m]", **NN)
    speed_gain: float = param(1.0, "speed-error gain of that tracking law [1/s]", **P)
    ignore_followers: bool = param(False, "a robot does not avoid robots straight behind it: they keep their distance "
                                   "through the safety stop (needs safety_stop); nor does the safety stop brake for uncontrolled vehicles "
                                   "behind a robot that drive its way (SUMO's cars keep their own distance)")
    commit: bool = param(False, "committed plans (prioritized planning): every robot plans in index order around the "
                         "others' commitments and commits only where the exact check passes, with [aac]'s committed-plan "
                         "settings and deadlock rules; false = the paper's LFC")

    def __post_init__(self):
        check_safety_options(self.safety_stop, self.fallback, self.ignore_followers)


class LfcCoordinator(Coordinator):
    name = "lfc"

    def __init__(self, planner: MpcPlanner, tasks: list[PathReference], corridors=None, finished: Finished | None = None,
                 params: LfcParams = LfcParams()):
        super().__init__(planner, tasks, corridors, finished)
        self.params = params
        self.leaves_followers = params.ignore_followers

    def _decide(self, world: WorldState) -> Decision:
        n, cfg = len(world.robots), self.planner.config
        parked = self.parked(world, self.finished(world))
        inputs = np.zeros((n, 2))
        records: list[RobotDecision] = [RobotDecision(False) for _ in range(n)]
        safety = self.safety_check(world) if self.params.safety_stop else None
        if safety is not None and self.anticipation is not None:
            self.hold_before_strips(safety)
        # Everyone's known motion this period: constant velocity until a robot has planned.
        motion = self.fleet.rollout(np.arange(n), world.states, np.zeros((n, cfg.horizon + 1, 2)), cfg.dt)
        for i in range(n):
            if parked[i]:
                hold = self.hold_inputs(world, i, cfg.horizon + 1)
                inputs[i], records[i].mode = hold[0], "hold"
                motion[i] = self.fleet.rollout(np.array([i]), world.states[[i]], hold[None], cfg.dt)[0]
                continue
            others = np.array([j for j in range(n) if j != i], dtype=int)
            if self.params.ignore_followers:
                others = others[~straight_behind(world, self.fleet, i, others)]
            regions = self.fleet.swept_regions(others, motion[others], cfg.horizon, cfg.barrier, cfg.fcbf)
            records[i] = self.solve(world, i, world.obstacles + regions, "priority")
            plan = self.plans[i]
            if plan.status != "solved" and self.params.fallback == "tracking":
                inputs[i] = track(world.robots[i], world.states[i], self.tasks[i], self.params.pursuit, self.params.speed_gain,
                                  self.last_inputs[i, 1], cfg.dt, target_speed=self.tracking_speed(world, i, self.params.speed_gain),
                                  a_lat=self.tracking_lat())
                records[i].mode = "tracking"
                once = np.zeros((1, cfg.horizon + 1, 2))
                once[0, 0] = inputs[i]
                motion[i] = self.fleet.rollout(np.array([i]), world.states[[i]], once, cfg.dt)[0]
                continue
            inputs[i] = plan.inputs[0]
            motion[i, : cfg.horizon + 1] = plan.states
            motion[i, -1] = self.fleet.rollout(np.array([i]), plan.states[None, -1], np.zeros((1, 1, 2)), cfg.dt)[0, -1]
        stopped = 0
        if self.params.safety_stop:
            moving = np.flatnonzero([r.mode in ("mpc", "tracking") for r in records])
            checked = safety.safe_inputs(moving, inputs, self.params.safety_margin)
            for i in moving[np.any(checked[moving] != inputs[moving], axis=1)]:
                records[i].mode = "safety_stop"
                stopped += 1
            inputs = checked
        return Decision(inputs, records, notes=dict(authority="", reason="priority", safety_stops=stopped))


@register_coordinator("lfc", params=LfcParams, doc="every robot in index-priority order", label="LFC-MPC-FCBF")
def lfc_coordinator(scenario, planner: MpcPlanner, tasks, corridors, finished) -> LfcCoordinator | PrioritizedLfc:
    """The paper's LFC, or with ``lfc.commit`` prioritized planning on committed plans (its
    committed-plan settings from ``[aac]``, its safety options from ``[lfc]``)."""
    lfc = from_section(LfcParams, scenario, "lfc")
    if lfc.commit:
        params = from_section(AacParams, scenario, "aac", commit=True, safety_stop=lfc.safety_stop, safety_margin=lfc.safety_margin,
                              fallback=lfc.fallback, lookahead=lfc.lookahead, speed_gain=lfc.speed_gain,
                              ignore_followers=lfc.ignore_followers, detour=scenario["aac.detour"] and scenario["aac.commit"],
                              manoeuvre=scenario["aac.manoeuvre"] and scenario["aac.commit"])
        return PrioritizedLfc(planner, tasks, corridors, finished, params=params)
    return LfcCoordinator(planner, tasks, corridors, finished, params=lfc)
