"""Gap acceptance for lane changes: MOBIL's safety criterion, in the form of SUMO's LC2013
secure gaps. A car moves into a lane only when what is there leaves it a safe gap ahead and
behind.

Gaps are bumper to bumper along the target lane's centre line [m], speeds are along it [m/s]
(negative ones count as 0). With a time gap ``tau`` [s], a safe deceleration ``b`` [m/s^2] and a
standstill gap ``g0`` [m], a car at speed ``v`` may move in behind a leader at ``v_l`` with the
gap ``g_a`` and ahead of a follower at ``v_f`` with the gap ``g_b`` when

    g_a >= g0 + tau v   + max(0, v^2   - v_l^2) / (2 b)   (it can come down to the leader's speed braking at b)
    g_b >= g0 + tau v_f + max(0, v_f^2 - v^2)   / (2 b)   (the follower can come down to its speed braking at b)

for every agent in the lane within ``LOOK`` metres (a fast car farther back may need more room
than a slow one close behind), and when nothing is beside it (overlapping it along the lane). In
the lane is whatever agent's footprint reaches into it (centre within half the lane's width plus
half its own width of the centre line: SUMO-driven cars, controlled cars, cones, walkers), and the
controlled cars that are moving into it (``also``). A change under way is judged without the
time gaps (``headway=False``): it goes on while both could still come down to each other's
speed at ``b``.

Frames and units: SUMO's network frame [m], headings [rad], speeds [m/s]. No simulator here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.coordination.anticipation import agents
from aac_sumo.references import PathReference
from aac_sumo.world import WorldState

#: Agents farther along the lane than this from the car are not judged [m] (a follower at
#: 27 m/s behind a standing car needs 2 + 27 + 27^2 / 6 = 151 m at tau = 1 s, b = 3 m/s^2).
LOOK = 200.0


@dataclass(frozen=True)
class GapRule:
    """The safe gaps of a lane change: time gap [s], safe deceleration [m/s^2], standstill gap [m]."""

    time_gap: float = 1.0
    decel: float = 3.0
    min_gap: float = 2.0

    def ahead(self, v: float, v_lead: float, headway: bool = True) -> float:
        """The smallest gap [m] behind a leader at ``v_lead`` [m/s] for a car at ``v`` [m/s]."""
        v, v_lead = max(v, 0.0), max(v_lead, 0.0)
        return self.min_gap + (self.time_gap * v if headway else 0.0) + max(0.0, v * v - v_lead * v_lead) / (2.0 * self.decel)

    def behind(self, v_follow: float, v: float, headway: bool = True) -> float:
        """The smallest gap [m] ahead of a follower at ``v_follow`` [m/s] for a car at ``v`` [m/s]."""
        v, v_follow = max(v, 0.0), max(v_follow, 0.0)
        return self.min_gap + (self.time_gap * v_follow if headway else 0.0) + max(0.0, v_follow**2 - v * v) / (2.0 * self.decel)


@dataclass(frozen=True)
class GapVerdict:
    """Whether the gap is safe, the smallest margin (gap minus the rule's gap [m]; -inf with
    something beside the car, +inf with nothing in the lane), and who leaves it: its name ("" when
    safe), its robot index (-1 for an uncontrolled agent or when safe) and how far ahead of the
    car it is along the lane [m] (negative: behind)."""

    safe: bool
    margin: float
    blocker: str = ""
    robot: int = -1
    along: float = 0.0


def judge_gap(world: WorldState, i: int, line: PathReference, half_width: float, rule: GapRule, headway: bool = True,
              also: tuple[int, ...] = ()) -> GapVerdict:
    """:class:`GapVerdict` of robot ``i`` moving into the lane of centre line ``line`` and half
    width ``half_width`` [m] now (see the module); ``also`` are the robots that count as in the
    lane wherever they are."""
    index, centres, headings, lengths, widths, velocity, _, _ = agents(world)
    me = int(np.flatnonzero(index == i)[0])
    others = np.flatnonzero((index != i) & (np.hypot(*(centres - centres[me]).T) <= LOOK + 0.5 * (lengths + lengths[me])))
    if others.size == 0:
        return GapVerdict(True, np.inf)
    s, off = line.project_many(centres[others])
    inside = (off < half_width + 0.5 * widths[others]) | np.isin(index[others], np.asarray(also, dtype=int))
    others, s = others[inside], s[inside]
    if others.size == 0:
        return GapVerdict(True, np.inf)
    s_me = line.project(centres[me])[0]
    tangent = line.pose_at(np.r_[s_me, s])[:, 2]
    v_along = np.einsum("ij,ij->i", velocity[np.r_[me, others]], np.column_stack([np.cos(tangent), np.sin(tangent)]))
    v, v_other = float(v_along[0]), v_along[1:]
    ahead = s - s_me
    gap = np.abs(ahead) - 0.5 * (lengths[others] + lengths[me])
    need = np.array([rule.ahead(v, u, headway) if a >= 0.0 else rule.behind(u, v, headway) for a, u in zip(ahead, v_other)])
    margin = np.where(gap < 0.0, -np.inf, gap - need)
    worst = int(np.argmin(margin))
    if margin[worst] >= 0.0:
        return GapVerdict(True, float(margin[worst]))
    names = [world.robots[j].name for j in np.flatnonzero(world.on_road)] + [o.name for o in world.obstacles]
    return GapVerdict(False, float(margin[worst]), names[others[worst]], int(index[others[worst]]), float(ahead[worst]))
