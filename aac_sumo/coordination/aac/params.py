"""AAC's settings, and how many robots hold authority in a period."""

from __future__ import annotations

from dataclasses import dataclass

from aac_sumo.coordination.base import check_safety_options
from aac_sumo.coordination.proximity import ProximityParams


@dataclass(frozen=True)
class Authorities:
    """How many robots hold authority per period: one in every cluster of robots that can meet
    within the horizon (``per_cluster``), else at most ``count`` (1: the paper), each in its own
    group. The scenario key ``aac.authorities`` is an integer or ``"clusters"``
    (:meth:`parse`)."""

    count: int = 1
    per_cluster: bool = False

    def __post_init__(self):
        if not (isinstance(self.count, int) and not isinstance(self.count, bool) and self.count >= 1):
            raise ValueError("authorities must be a positive integer or 'clusters'")

    @classmethod
    def parse(cls, value: int | str) -> "Authorities":
        """``"clusters"`` or a positive integer; ValueError otherwise."""
        if value == "clusters":
            return cls(per_cluster=True)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError("authorities must be a positive integer or 'clusters'")
        return cls(count=value)

    @property
    def single(self) -> bool:
        """One authority among all robots (the paper)."""
        return not self.per_cluster and self.count == 1


@dataclass(frozen=True)
class AacParams:
    """AAC settings: close-pair distance [m], proximity decision, safety stop (on/off, margin
    [m]), tracking law (lookahead [m], speed gain [1/s]), what an authority whose solve fails
    applies (``brake``: the planner's fallback; ``tracking``: the tracking law through the
    safety stop), whether the authority ignores the robots straight behind it
    (:func:`~aac_sumo.coordination.base.straight_behind`; needs the safety stop), the seed
    of the sampling trees; committed plans (``commit``), their stopping tails' share of the
    strongest braking (``tail_brake``) and the gap every two commitments keep
    (``commit_margin`` [m]); authorities per period (:class:`Authorities`); the keep-right
    rule (shift, trigger range and growth limit [m]); the make-room lead (on/off, standing
    time that makes a leader, longest lead [s]); and detours (on/off, the clearance [m] they
    keep from standing footprints where there is room; :mod:`~aac_sumo.coordination.detour`);
    and how long [s] a commitment may continue along its path, at the speeds its anticipated
    reference has, before its stopping tail (``cruise``; 0: the tail follows the plan)."""

    close_distance: float = 2.0
    proximity: ProximityParams = ProximityParams()
    safety_stop: bool = False
    safety_margin: float = 0.1
    lookahead: float = 1.0
    speed_gain: float = 1.0
    fallback: str = "brake"
    ignore_followers: bool = False
    seed: int = 0
    commit: bool = True
    authorities: Authorities = Authorities()
    tail_brake: float = 0.5
    commit_margin: float = 0.05
    keep_right: float = 0.0
    keep_right_range: float = 4.0
    keep_right_max: float = 4.0
    make_room: bool = True
    stall_time: float = 1.0
    lead_time: float = 8.0
    detour: bool = False
    detour_clearance: float = 0.5
    cruise: float = 0.0

    def __post_init__(self):
        check_safety_options(self.safety_stop, self.fallback, self.ignore_followers)
        if not isinstance(self.authorities, Authorities):
            raise ValueError("authorities must be an Authorities (Authorities.parse(1 | k | 'clusters'))")
        if self.detour and not self.commit:
            raise ValueError("detours need committed plans (commit = true)")
