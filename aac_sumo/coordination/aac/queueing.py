"""How a road's cars follow one another on committed plans (a mixin of
:class:`~aac_sumo.coordination.aac.committed.CommittedAac`): which car renews its continuation
first, whether a renewal takes a car further, and at which speeds a car sees the cars ahead.

Frames and units: world frame [m], speeds [m/s], periods of ``dt`` [s].
"""

from __future__ import annotations

import numpy as np

from aac_sumo.world import WorldState

#: A renewal must take the car at least RENEW_GAIN [m] further along its path than its commitment.
RENEW_GAIN = 0.5
#: A car's plan and continuation see every other robot at the speed its commitment has
#: LEAD_LOOK [s] on (a queue's cars follow the one ahead as it has committed to set off, not as
#: it stands now; S2 seeds 10-14 at N = 10: 34.0 s, against 34.4 s with the speeds of now in
#: the MPC's reference).
LEAD_LOOK = 1.0


class Queueing:
    """The queue rules of committed AAC on a road (needs the coordinator's ``book``, ``path``
    and ``planner``)."""

    def gains(self, j: int, new, old, period: int) -> bool:
        """Whether robot ``j``'s commitment ``new`` (from ``period``) takes it at least
        ``RENEW_GAIN`` [m] further along its path than ``old`` does by the time ``new`` ends
        (the old one may run on longer: compared at the same moment, a queue's car sets off
        on the continuation that speeds up sooner)."""
        k = min(period - old.start + len(new.states) - 1, len(old.states) - 1)
        s = self.path(j).project_many(np.array([new.states[-1, :2], old.states[k, :2]]))[0]
        return bool(s[0] > s[1] + RENEW_GAIN)

    def lead_speeds(self, world: WorldState, i: int, period: int) -> np.ndarray:
        """The robots' speeds [m/s] (n,) as robot ``i``'s anticipation sees them: its own now,
        the others' those their commitments have ``LEAD_LOOK`` on (its plan and its continuation
        follow a queue as the cars ahead have committed to set off)."""
        speeds, look = world.states[:, 3].copy(), int(round(LEAD_LOOK / self.planner.config.dt))
        others = np.flatnonzero(np.arange(len(speeds)) != i)
        speeds[others] = self.book.courses(period, others, look)[:, look, 3]
        return speeds

    def front_first(self, world: WorldState) -> np.ndarray:
        """The robots' indices, furthest along their paths first (a road: a car renews its
        continuation after the one ahead of it has, so its check sees where that one goes on)."""
        return np.argsort([-self.path(j).project(world.states[j, :2])[0] for j in range(len(world.robots))], kind="stable")
