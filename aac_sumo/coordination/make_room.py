"""Deadlock resolution for committed-plan AAC (beyond the paper): a stalled robot leads, the
robots in its way make room.

A robot that has stood (speed below ``STILL_SPEED``) for ``stall_periods`` periods without
having finished may become the **leader**: the stalled robot that led least recently (ties: the
lowest index). While it leads, the robots whose footprint centres lie within ``corridor`` [m] of
the segment from its footprint centre to its goal (ahead of it, and no further than the
``LEAD_PROGRESS`` its lead asks for plus ``corridor``) are **blockers**; each gets a
make-room target, its rear axle moved away from that segment until its centre lies
``corridor`` plus ``ROOM_EXTRA`` off it and ``corridor`` further along the leader's way (away
from the leader: a robot facing it backs off diagonally, which a car-like robot can do where a
sideways step is impossible), and drives there when it holds authority. In the
leader's group the authority cycles: the leader, then a blocker (the one that held it longest
ago), then whoever the usual rule picks, so that no one else starves meanwhile. The lead ends when the leader has got ``LEAD_PROGRESS`` [m] closer to its goal,
has finished, or after ``lead_periods`` periods. Safety is untouched: every move still passes the
commitments' exact check. Positions in the world frame [m].
"""

from __future__ import annotations

import numpy as np

#: Speed [m/s] below which a robot counts as standing.
STILL_SPEED = 0.05
#: Progress [m] towards its goal after which a leader's lead ends.
LEAD_PROGRESS = 1.5
#: Room [m] a blocker makes beyond the corridor.
ROOM_EXTRA = 0.2


class MakeRoom:
    """Stall counters and the current lead of ``n`` robots."""

    def __init__(self, n: int, stall_periods: int, lead_periods: int, corridor: float):
        self.stall_periods, self.lead_periods, self.corridor = stall_periods, lead_periods, corridor
        self.still = np.zeros(n, dtype=int)
        self.led_last = np.full(n, -1)
        self.leader, self.lead_start, self.start_gap = -1, 0, 0.0
        self.targets: dict[int, np.ndarray] = {}

    def update(self, states: np.ndarray, centres: np.ndarray, goals: np.ndarray, active: np.ndarray, period: int) -> None:
        """Count standing periods, end or start a lead, and find the blockers and their targets.
        ``states`` (n, 4) rear-axle states, ``centres`` (n, 2) footprint centres, ``goals`` (n, 2)
        rear-axle goals, ``active`` (n,) the robots that have not finished."""
        self.still = np.where(active & (np.abs(states[:, 3]) < STILL_SPEED), self.still + 1, 0)
        gap = np.hypot(*(states[:, :2] - goals).T)
        if self.leader >= 0:
            i = self.leader
            if not active[i] or gap[i] <= self.start_gap - LEAD_PROGRESS or period - self.lead_start >= self.lead_periods:
                self.leader = -1
        if self.leader < 0:
            stalled = np.flatnonzero(active & (self.still >= self.stall_periods))
            if stalled.size:
                i = int(stalled[np.argmin(self.led_last[stalled])])
                self.leader, self.lead_start, self.start_gap = i, period, float(gap[i])
                self.led_last[i] = period
        self.targets = {}
        if self.leader >= 0:
            self.targets = self.room_targets(states, centres, goals[self.leader], self.leader)

    def backing_off(self, i: int) -> bool:
        """Whether robot ``i`` should back off now: in every second stretch of ``stall_periods``
        standing periods (it tries its own way in between)."""
        return bool(self.still[i] >= self.stall_periods and (self.still[i] // self.stall_periods) % 2 == 1)

    def room_targets(self, states: np.ndarray, centres: np.ndarray, goal: np.ndarray, leader: int) -> dict[int, np.ndarray]:
        """Make-room targets (rear axle [m]) of the robots within ``corridor`` of the segment
        from the leader's centre to ``goal``, ahead of the leader within the reach of its lead:
        out of the corridor and on along it, away from the leader. (Without the reach, a leader
        10 m from its goal pushed a parked robot near that goal off it, lead after lead.)"""
        a = centres[leader]
        seg = goal - a
        length = float(np.hypot(*seg))
        if length < 1e-9:
            return {}
        u = seg / length
        rel = centres - a
        along = rel @ u
        across = rel @ np.array([-u[1], u[0]])
        out = {}
        reach = min(length, LEAD_PROGRESS + self.corridor) + self.corridor
        for j in np.flatnonzero((along > 0.0) & (along < reach) & (np.abs(across) < self.corridor)):
            if j == leader:
                continue
            side = 1.0 if across[j] >= 0.0 else -1.0
            shift = side * (self.corridor + ROOM_EXTRA) - across[j]
            out[int(j)] = states[j, :2] + shift * np.array([-u[1], u[0]]) + self.corridor * u
        return out
