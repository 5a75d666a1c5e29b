"""AAC's settings, and how many robots hold authority in a period."""

from __future__ import annotations

from dataclasses import dataclass

from aac_sumo.config.keys import NN, P
from aac_sumo.config.schema import ParamError, param, section
from aac_sumo.coordination.base import FALLBACKS, check_safety_options
from aac_sumo.coordination.proximity import ProximityParams
from aac_sumo.coordination.tracking import AimsAhead


@dataclass(frozen=True)
class Authorities:
    """How many robots hold authority per period: one in every cluster of robots that can meet
    within the horizon (``per_cluster``), and with ``spread`` (committed plans) more in a cluster,
    each one whose reach disc cannot meet those of the cluster's authorities before it; else at
    most ``count`` (1: the paper), each in its own group. The scenario key ``aac.authorities``
    is an integer, ``"clusters"`` or ``"spread"`` (:meth:`parse`)."""

    count: int = 1
    per_cluster: bool = False
    spread: bool = False

    def __post_init__(self):
        if not (isinstance(self.count, int) and not isinstance(self.count, bool) and self.count >= 1):
            raise ValueError("authorities must be a positive integer or 'clusters'")

    @classmethod
    def parse(cls, value: int | str) -> "Authorities":
        """``"clusters"`` or a positive integer; ValueError otherwise."""
        if value == "clusters":
            return cls(per_cluster=True)
        if value == "spread":
            return cls(per_cluster=True, spread=True)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError("authorities must be a positive integer, 'clusters' or 'spread'")
        return cls(count=value)

    @property
    def single(self) -> bool:
        """One authority among all robots (the paper)."""
        return not self.per_cluster and self.count == 1


@section("aac")
@dataclass(frozen=True)
class AacParams(AimsAhead):
    """AAC settings: close-pair distance [m], proximity decision, safety stop (on/off, margin
    [m]), tracking law (lookahead [m], speed gain [1/s]), what an authority whose solve fails
    applies (``brake``: the planner's fallback; ``tracking``: the tracking law through the
    safety stop), whether the authority ignores the robots straight behind it
    (:func:`~aac_sumo.coordination.base.straight_behind`; needs the safety stop), the seed
    of the sampling trees; committed plans (``commit``), their stopping tails' share of the
    strongest braking (``tail_brake``; ``firm_tail`` where that fails the check) and the gap every two commitments keep
    (``commit_margin`` [m]); authorities per period (:class:`Authorities`); the keep-right
    rule (shift, trigger range and growth limit [m]); the make-room lead (on/off, standing
    time that makes a leader, longest lead [s]); and detours (on/off, the clearance [m] they
    keep from standing footprints where there is room; :mod:`~aac_sumo.coordination.detour`);
    and how long [s] a commitment may continue along its path, at the speeds its anticipated
    reference has, before its stopping tail (``cruise``; 0: the tail follows the plan)."""

    close_distance: float = param(2.0, "robots whose footprint centres are closer than this form a close pair [m]", **P)
    proximity: ProximityParams = param(ProximityParams(), "the proximity decision's sampling trees", nested=True)
    safety_stop: bool = param(False, "non-authority robots brake when their stored input would take them into another's region "
                              "(off by default, as lfc.safety_stop: the paper has no such layer)")
    safety_margin: float = param(0.1, "footprint gap below which the safety stop triggers [m]", **NN)
    lookahead: float = param(1.0, "pure-pursuit lookahead of the tracking law for robots without a plan [m]", **P)
    lookahead_time: float = param(0.0, "with > 0, at low speed the lookahead shrinks to the distance covered in this time, but not below "
                                  "lookahead_min: a car that turns a tight corner slowly aims at the corner, not beyond it [s]", **NN)
    lookahead_min: float = param(0.0, "the shortest lookahead with lookahead_time > 0 [m]", **NN)
    speed_gain: float = param(1.0, "speed-error gain of the tracking law [1/s]", **P)
    fallback: str = param("brake", "what an authority whose solve fails applies: brake (the planner's fallback, as in the paper) or "
                          "tracking (the tracking law through the safety stop; needs safety_stop)", type=FALLBACKS)
    ignore_followers: bool = param(False, "the authority does not avoid robots straight behind it: they keep their distance "
                                   "through the safety stop (needs safety_stop); nor does the safety stop brake for uncontrolled vehicles "
                                   "behind a robot that drive its way (SUMO's cars keep their own distance)")
    seed: int = param(0, "seed of the sampling trees", key="scenario.seed")
    commit: bool = param(True, "committed plans: every robot drives the plan of its last turn, ending in a stopping tail, "
                         "and a new plan replaces it only when it keeps commit_margin from every other commitment (collision-free "
                         "by construction); false: the paper's stored plan, then the tracking law")
    authorities: Authorities = param(Authorities(), "robots holding authority per period: 1 (the paper), a larger integer, or \"clusters\" "
                                     "(one per group of robots that can interact within the horizon), with committed or stored plans, or \"spread\" "
                                     "(committed plans: in a cluster, more wherever their reach discs cannot meet)",
                                     type=object, parse=lambda a: Authorities.parse(a), raw_default=1,
                                     check=lambda a: a in ("clusters", "spread") or (isinstance(a, int) and not isinstance(a, bool) and a >= 1),
                                     expect="a positive integer, \"clusters\" or \"spread\"")
    crowd_authorities: int = param(0, "with authorities = \"spread\", up to this many more robots of a cluster plan each period after "
                                   "those out of reach: the longest-waiting first, each at least close_distance from every robot that "
                                   "planned before it in the period, round the commitments made before it (0: none; no effect "
                                   "with other authorities settings)",
                                   check=lambda k: 0 <= k <= 1000, expect="in 0..1000")
    tail_brake: float = param(0.5, "deceleration of a commitment's stopping tail, as a share of the strongest braking |robot.a_min|",
                              check=lambda x: 0 < x <= 1, expect="in (0, 1]")
    firm_tail: float = param(0.0, "a commitment whose stopping tail at tail_brake fails the exact check is tried again with its "
                             "tail at this share of |robot.a_min| (at most robot.a_comfort; 0: no second try): gentle tails where "
                             "they pass, firmer ones behind SUMO's cars, which may brake harder than our tails", check=lambda x: 0 <= x <= 1,
                             expect="in [0, 1]")
    commit_margin: float = param(0.05, "footprint gap every two commitments keep at every period [m]", **NN)
    cruise: float = param(0.0, "with commit, on a path that goes on (a road): a commitment continues along its path for up "
                          "to this long (then half, a quarter) at the speeds its reference anticipates (slowing for what is ahead, "
                          "yielding to walkers) before its stopping tail, where the exact check passes; 0: the tail follows the plan [s]",
                          check=lambda x: 0 <= x <= 60, expect="in [0, 60]")
    goal_cruise: float = param(0.0, "with commit, on a path that ends at a goal (a swarm): a committed plan goes on along its path on "
                               "the tracking law for up to this long (then half, a quarter) before its stopping tail, where the exact "
                               "check passes, so the others see it keep going; 0: the tail follows the plan [s]",
                               check=lambda x: 0 <= x <= 60, expect="in [0, 60]")
    continuation_jerk: float = param(6.0, "with cruise, a continuation changes its acceleration by at most this per second, from "
                                     "the acceleration before it (except braking for where a SUMO car ahead could stand); 0: "
                                     "no bound (chosen on S2's seeds 10-14: jerk p95 6 against 15-16 unbounded, tasks 0.2-0.5 s longer) [m/s^3]", **NN)
    traffic_decel: float = param(4.5, "with commit, the vehicles no coordinator drives (SUMO's own cars) are in the exact check as "
                                 "braking at this from their speed along their lanes until they stand (SUMO's default passenger "
                                 "vType decel) [m/s^2]", **P)
    traffic_reaction: bool = param(False, "with commit, a commitment is held against SUMO's cars as its first period, then braking "
                                   "at the firm tail (firm_tail, else tail_brake): a car can always stop behind where a car ahead "
                                   "could, once it sees it brake (as a driver's time gap keeps), rather than on its own committed "
                                   "tail; false: the commitment's own course")
    reaction_brake: float = param(0.0, "with traffic_reaction, the share of |robot.a_min| the reaction brakes at, beyond the "
                                  "comfort bound (0: the firm tail's): the check then asks that a car can stop behind a car ahead "
                                  "braking at traffic_decel at all, and a car that must brake still tries the gentle tail, the firm "
                                  "tail and then firmer stops first", check=lambda x: 0 <= x <= 1, expect="in [0, 1]")
    walker_brake: bool = param(False, "with commit, a robot whose commitment already meets a walker's region (one SUMO sets down "
                               "beside the road, or one who leaves what the check assumed of her) renews its continuation or "
                               "brakes at once, as for SUMO's cars (mode traffic_brake)")
    walkway_to_end: bool = param(False, "with commit, a walker on a walkway of her own who can reach its nearer end within "
                                 "controller.walkway_time keeps to her way in the exact check until she could get there (SUMO's "
                                 "walkers leave a sidewalk only at its ends), then may be anywhere within her reach of where she is, "
                                 "as without it; false: from now")
    traffic_beside: bool = param(False, "with commit, the exact check holds a commitment against the braking courses of the "
                                 "uncontrolled vehicles beside and behind the robot in another lane too, not only those ahead "
                                 "(a car whose nose swings into the next lane at a junction meets the cars coming up there); "
                                 "the ones straight behind it keep their distance themselves")
    keep_right: float = param(0.0, "right-hand rule: the authority's reference shifts this far to the right while another "
                              "robot is ahead within keep_right_range (0: off, the paper) [m]", **NN)
    keep_right_range: float = param(4.0, "distance within which a robot ahead triggers keep_right [m]", **P)
    keep_right_max: float = param(4.0, "a robot held up in a crowd (slower than 0.3 of its cruise speed) shifts further right, "
                                  "growing at 0.5 m/s up to this [m]", **NN)
    make_room: bool = param(True, "deadlock resolution (with commit): a robot that has stood for stall_time leads, and the "
                            "robots in its way drive aside while it passes")
    stall_time: float = param(1.0, "standing time after which an unfinished robot may lead [s]", **P)
    lead_time: float = param(8.0, "longest lead [s]", **P)
    detour: bool = param(False, "detours (with commit): a robot that has stood for stall_time, or whose reference runs within "
                         "detour_clearance of debris or of a parked or long-standing robot, follows a grid A* path round them "
                         "to its goal instead")
    detour_clearance: float = param(0.5, "gap a detour keeps from standing footprints where there is room; it squeezes closer "
                                    "(down to half the robot width + commit_margin) where there is not [m]", **P)
    manoeuvre: bool = param(False, "manoeuvres (with commit): a robot that has stood for manoeuvre_time and whose plan leaves it "
                            "standing searches a way to its goal on exact footprints (short arcs from standstill to standstill, "
                            "forwards and, where it may reverse, backwards), and drives it when it passes the exact check; no "
                            "walkers or uncontrolled vehicles about")
    manoeuvre_time: float = param(3.0, "standing time after which a robot may manoeuvre [s]", **P)
    livelock_time: float = param(0.0, "with manoeuvre: a robot that got no nearer its goal for this long [s], nor did any "
                                 "unfinished robot near it, may manoeuvre even while it moves (rocking); 0 = off", **NN)
    manoeuvre_subgoal: float = param(0.0, "with manoeuvre: where no way to its goal is found, a robot farther than this + 0.5 m "
                                     "from its goal searches one to within 0.5 m of the point this far along the straight line to "
                                     "it (a way out of a jam far from its goal); 0 = off [m]", **NN)

    def __post_init__(self):
        check_safety_options(self.safety_stop, self.fallback, self.ignore_followers, self.commit, self.detour)
        if not isinstance(self.authorities, Authorities):
            raise ValueError("authorities must be an Authorities (Authorities.parse(1 | k | 'clusters' | 'spread'))")
        if self.manoeuvre and not self.commit:
            raise ParamError("manoeuvre", "false unless {section}.commit is true", True)
        if self.authorities.spread and not self.commit:
            raise ParamError("authorities", "\"clusters\" or an integer unless {section}.commit is true", "spread")
