"""Goal cruise (``aac.goal_cruise``, committed plans): on a path that ends at a goal (a swarm), a
committed plan goes on along the path on the tracking law before its stopping tail, so that the
others, planning round its commitment, see the robot keep going instead of braking as soon as its
plan of N periods ends (with one authority a period, it may wait several periods for its next turn)."""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.tracking import track_course
from aac_sumo.world import WorldState


class GoalCruise:
    """Mixin of :class:`~aac_sumo.coordination.aac.committed.CommittedAac`: the goal cruise."""

    def goal_cruise_periods(self, i: int) -> int:
        """Periods of ``goal_cruise`` on robot ``i``'s path (0 on a path that goes on)."""
        return int(round(self.params.goal_cruise / self.planner.config.dt)) if self.path(i).stop_at_end else 0

    def gentle_cruise(self, i: int, v: float, more: np.ndarray) -> np.ndarray:
        """The inputs ``more`` (K, 2) of robot ``i``'s cruise from speed ``v`` [m/s] up to where the law's stop at
        the goal would brake harder than the robot's tail or reverse it (the tail takes over there)."""
        speeds = v + np.cumsum(more[:, 0]) * self.planner.config.dt
        hard = np.flatnonzero((speeds * v <= 0.0) | (more[:, 0] < -self.tail_decel()[i]))
        return more[: hard[0]] if len(hard) else more

    def cruising_to_goal(self, world: WorldState, i: int, period: int, head: np.ndarray, statics: np.ndarray):
        """Robot ``i``'s commitment to ``head`` (m, 2) continued on the tracking law (comfort bounds) along its path, which
        ends at its goal, for ``goal_cruise`` [s], else half or a quarter of it, then its stopping tail: the longest that
        passes the exact check, else None."""
        cfg, task, periods = self.planner.config, self.path(i), self.goal_cruise_periods(i)
        end = self.fleet.rollout(np.array([i]), world.states[[i]], head[None], cfg.dt)[0, -1]
        up = cfg.comfort_accel if cfg.comfort_accel > 0.0 else None
        more = track_course(world.robots[i], end, task, self.params.pursuit, self.params.speed_gain, float(head[-1, 1]), cfg.dt, periods,
                            self.keep_right_shift(world, i), a_lat=self.tracking_lat(), a_up=up)
        more = self.gentle_cruise(i, float(end[3]), more)
        periods = len(more)
        for k in (periods, periods // 2, periods // 4):
            candidate = self.passing(world, i, period, np.vstack([head, more[:k]]), statics) if k > 0 else None
            if candidate is not None:
                return candidate
        return None
