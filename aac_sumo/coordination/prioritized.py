"""LFC with committed plans (``lfc.commit = true``; beyond the paper): prioritized planning.

Every period every active robot plans, in index order (robot 0 first, as the paper's LFC ranks
them), around the others' commitments: those that have planned this period (the higher
priorities) with their new ones, the others with those of their last period. A robot commits to
its plan only when the plan with its stopping tail passes the exact footprint check against every
other commitment (:mod:`~aac_sumo.coordination.commitments`), as AAC's committed authorities do,
and so this variant is collision-free by construction too. It shares AAC's committed-plan machinery
and the deadlock rules that apply without authority rotation: creeping, tracking extensions,
make-room references, detours and manoeuvres (their settings come from ``[aac]``, so both run with the same
rules); the safety-stop options come from ``[lfc]``. Each period costs one solve per active robot,
as the paper's LFC; AAC's own variant solves one per group.
"""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.aac.committed import CommittedAac
from aac_sumo.coordination.base import RobotDecision
from aac_sumo.world import WorldState


class PrioritizedLfc(CommittedAac):
    """LFC with committed plans (see the module)."""

    name = "lfc"
    commit = None  # not one of AAC's modes (AacCoordinator.modes): it is built directly

    def groups(self, world: WorldState, parked: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """One turn per active robot, in index order; each plans around all the others."""
        everyone = np.arange(len(world.robots))
        return [(everyone, np.array([i])) for i in np.flatnonzero(~parked)]

    def turns_in_group(self, world: WorldState, members: np.ndarray, candidates: np.ndarray, records: list[RobotDecision],
                       period: int):
        """The group's one candidate, by its priority (whatever ``aac.authorities`` says)."""
        i = int(candidates[0])
        self.last_turn[i] = period
        yield i, "priority"
