"""The declared scenario keys: :class:`Key` (type, default, check, doc) and the tables of every
section, ``COMMON`` (every kind's sections), ``KIND_SECTIONS`` (a kind's own section) and
``KIND_EXTRA_SECTIONS`` (further sections a kind reads, as lane_change reads ``[sumo]``).
:mod:`aac_sumo.registry` adds the sections of registered experiments and coordinators.

The sections of the planner and the coordinators (``[controller]`` but its ``coordinator``,
``[aac]``, ``[lfc]``, ``[orca]``, ``[cbf_qp]``) are not written here: their parameter dataclasses
declare them (:mod:`aac_sumo.config.schema`), in the modules named in :data:`PROVIDERS`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable


class ScenarioError(Exception):
    """A scenario problem the user must fix; ``str()`` is one line: file, key, expectation."""

    def __init__(self, file, key: str, expected: str, got: Any = None):
        self.file, self.key, self.expected = str(file), key, expected
        tail = "" if got is None else f", got {got!r}"
        super().__init__(f"{self.file}: {key}: expected {expected}{tail}")


@dataclass(frozen=True)
class Key:
    """A declared key: its type (``float``, ``int``, ``bool``, ``str``, or a tuple of allowed
    strings), default, optional extra check and a description of the expected value."""

    type: type | tuple[str, ...]
    default: Any
    doc: str
    check: Callable[[Any], bool] | None = None
    expect: str = ""

    def expected(self) -> str:
        if isinstance(self.type, tuple):
            return "one of " + ", ".join(self.type)
        if self.type is object:
            return self.expect
        base = {float: "a number", int: "an integer", bool: "true or false", str: "a string", list: "a list"}[self.type]
        return f"{base} {self.expect}".strip()

    def validate(self, value: Any) -> Any:
        """The value converted to the key's type, or ``ValueError``."""
        if isinstance(self.type, tuple):
            ok = isinstance(value, str) and value in self.type
        elif self.type is object:  # any value its check accepts
            ok = True
        elif self.type is float:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            value = float(value) if ok else value
        elif self.type is int:
            ok = isinstance(value, int) and not isinstance(value, bool)
        else:
            ok = isinstance(value, self.type)
        if not ok or (self.check is not None and not self.check(value)):
            raise ValueError(self.expected())
        return value


def _positive(x):
    return x > 0


def _non_negative(x):
    return x >= 0


def rows(*fields: str) -> dict:
    """Key options for a list of number rows, one per item, each ``[field, ...]``."""

    def check(value) -> bool:
        return all(isinstance(r, list) and len(r) == len(fields)
                   and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in r)
                   for r in value)

    return dict(check=check, expect=f"of [{', '.join(fields)}] rows")


P = dict(check=_positive, expect="> 0")
#: Upper bounds that keep a typo (``n_robots=1000000000``) from hanging a run or exhausting memory.
MAX_ROBOTS = 200
MAX_SEED = 2**31 - 1
NN = dict(check=_non_negative, expect=">= 0")

COMMON: dict[str, dict[str, Key]] = {
    "scenario": {
        "name": Key(str, "unnamed", "label written into metrics.json"),
        "kind": Key((), "braking", "which experiment builds the world"),  # the allowed kinds: registered (registry.py)
        "seed": Key(int, 0, "seed of every random choice in the run (SUMO's seed is a 32-bit integer)",
                    check=lambda s: 0 <= s <= MAX_SEED, expect=f"in 0..{MAX_SEED}"),
        "dt": Key(float, 0.1, "control period and simulation step [s]", check=lambda dt: 0.001 <= dt <= 1.0, expect="in [0.001, 1]"),
        "duration": Key(float, 20.0, "time limit, at most a day [s]", check=lambda d: 0 < d <= 86400.0, expect="in (0, 86400]"),
    },
    "controller": {  # the allowed coordinators and their meanings: registered (registry.py)
        "coordinator": Key((), "aac", "who plans when"),
    },
    "robot": {
        "length": Key(float, 1.0, "footprint length [m]", **P),
        "width": Key(float, 0.6, "footprint width [m]", **P),
        "wheelbase": Key(float, 0.8, "wheelbase L [m]", **P),
        "a_min": Key(float, -6.0, "strongest braking [m/s^2]", check=lambda a: a < 0, expect="< 0"),
        "a_max": Key(float, 3.0, "strongest acceleration [m/s^2]", **P),
        "steer_max": Key(float, 0.6, "steering limit [rad]", check=lambda s: 0 < s < 1.5, expect="in (0, 1.5)"),
        "v_max": Key(float, 30.0, "speed limit [m/s]", **P),
        "allow_reverse": Key(bool, False, "allow negative speed down to -v_max"),
        "a_lat_max": Key(float, 3.0, "friction/comfort limit on the lateral acceleration v^2 |tan(steer)| / wheelbase [m/s^2]", **P),
        "steer_rate_max": Key(float, 0.5, "how fast the steering angle may change [rad/s]", **P),
        "a_comfort": Key(float, 3.0, "deceleration used unless an emergency needs more (capped at |a_min|) [m/s^2]", **P),
    },
    "aac": {},  # sections declared by parameter dataclasses (schema.py, PROVIDERS) are filled on first use
    "lfc": {},
    "metrics": {
        "accel_threshold": Key(float, 3.0, "|longitudinal acceleration| that counts as aggressive [m/s^2]", **P),
        "lat_accel_threshold": Key(float, 3.0, "lateral acceleration v^2 |curvature| that counts as aggressive [m/s^2]", **P),
        "stop_speed": Key(float, 0.05, "speed below which a robot counts as stopped [m/s]", **NN),
        "ttc_max": Key(float, 10.0, "time-to-collision above this is no conflict and stays out of ttc_mean_s [s]", **P),
        "deadlock_time": Key(float, 5.0, "a run ends as a deadlock when no unfinished robot got further than stop_speed * deadlock_time, at any time in the last deadlock_time, from where it was deadlock_time before (a robot that drove off and came back is not stuck) [s]", **P),
    },
}

#: The baselines' sections: ORCA (aac_sumo/coordination/orca.py, docs/baselines.md) and CBF-QP
#: (aac_sumo/coordination/cbf_qp.py, docs/baselines_cbf_qp.md), declared by their parameter dataclasses.
COMMON["orca"] = {}
COMMON["cbf_qp"] = {}

#: The modules that declare sections (``@schema.section``) and register experiment kinds and
#: coordinators (:mod:`aac_sumo.registry`), in the order of the listings (``aac-sumo keys``, the
#: allowed values of ``scenario.kind`` and ``controller.coordinator``); the config imports them
#: by name on first use of the schema (:func:`aac_sumo.config.common`), then every other module
#: of the ``PLUGINS`` packages, so that a new module there registers without being listed.
PROVIDERS = ("aac_sumo.mpc.settings", "aac_sumo.coordination.anticipation", "aac_sumo.coordination.aac",
             "aac_sumo.coordination.lfc", "aac_sumo.coordination.independent", "aac_sumo.coordination.sumo_driver",
             "aac_sumo.coordination.orca", "aac_sumo.coordination.cbf_qp", "aac_sumo.experiments.braking",
             "aac_sumo.experiments.swarm", "aac_sumo.experiments.lane_change", "aac_sumo.experiments.random_crossing")
PLUGINS = ("aac_sumo.coordination", "aac_sumo.experiments")

KIND_SECTIONS: dict[str, dict[str, Key]] = {
    "braking": {
        "speed": Key(float, 10.0, "initial speed of ego and lead [m/s]", **P),
        "gap": Key(float, 7.0, "initial centre-to-centre distance, lead ahead of ego [m]", **P),
        "t_brake": Key(float, 1.0, "time the lead starts braking [s]", **NN),
        "t_brake_jitter": Key(float, 0.2, "the seed shifts t_brake uniformly within +- this [s]", **NN),
        "lead_decel": Key(float, 6.0, "lead deceleration magnitude [m/s^2]", **P),
        "lead_length": Key(float, 1.0, "lead footprint length [m]", **P),
        "lead_width": Key(float, 0.6, "lead footprint width [m]", **P),
        "lane_y": Key(float, 0.0, "y of the lane centre line [m]"),
        "lane_width": Key(float, 1.0, "lane width; the ego's rear axle keeps (lane_width - robot.width)/2 from the centre line [m]", **P),
    },
}

KIND_SECTIONS["swarm_rescue"] = {
    "starts": Key(list, [[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]], "start poses of the robots' rear axles [m, m, rad]", **rows("x", "y", "heading")),
    "goals": Key(list, [[10.0, 2.0], [10.0, 0.0]], "goal of each robot's rear axle, one per start [m]", **rows("x", "y")),
    "debris": Key(list, [], "static obstacles as footprint rectangles [m, m, m, m, rad]", **rows("cx", "cy", "length", "width", "heading")),
    "cruise_speed": Key(float, 1.0, "reference speed along the straight path to the goal [m/s]", **P),
    "goal_tolerance": Key(float, 0.3, "a robot has arrived when its rear axle is this close to its goal [m]", **P),
    "start_jitter": Key(float, 0.1, "the seed shifts every start position uniformly within +- this [m]", **NN),
}
KIND_SECTIONS["circle_swap"] = {
    "n_robots": Key(int, 8, "robots evenly spaced on the circle", check=lambda n: 2 <= n <= MAX_ROBOTS, expect=f"in 2..{MAX_ROBOTS}"),
    "radius": Key(float, 4.0, "circle radius; each robot drives to the antipodal point [m]", **P),
    "cruise_speed": Key(float, 1.0, "reference speed along the straight path to the goal [m/s]", **P),
    "goal_tolerance": Key(float, 0.3, "a robot has arrived when its rear axle is this close to its goal [m]", **P),
    "start_jitter": Key(float, 0.05, "the seed shifts every start position uniformly within +- this [m]", **NN),
}
KIND_SECTIONS["random_crossing"] = {
    "n_robots": Key(int, 20, "robots, each with a seeded random start and a goal far across the area",
                    check=lambda n: 2 <= n <= MAX_ROBOTS, expect=f"in 2..{MAX_ROBOTS}"),
    "area_per_robot": Key(float, 6.0, "the square area's side is sqrt(n_robots * area_per_robot): the density stays "
                          "constant as n grows [m^2]", **P),
    "min_travel_fraction": Key(float, 0.6, "each goal is at least this fraction of the area side from its start, so "
                               "paths cross the middle", check=lambda f: 0 <= f <= 1.2, expect="in [0, 1.2]"),
    "clearance": Key(float, 0.5, "gap kept between start footprints, between goals' reach discs (the footprint at the goal "
                     "in any heading) and from every debris footprint [m]", **NN),
    "path_clearance": Key(float, 0.5, "distance every straight start-goal path (rear-axle line) keeps from every debris "
                          "footprint [m]", **NN),
    "debris_density": Key(float, 2.0, "random debris rectangles per 100 m^2 of area (rounded)", **NN),
    "debris_min_size": Key(float, 0.4, "smallest debris length or width [m]", **P),
    "debris_max_size": Key(float, 1.2, "largest debris length or width [m]", **P),
    "cruise_speed": Key(float, 1.0, "reference speed along the straight path to the goal [m/s]", **P),
    "goal_tolerance": Key(float, 0.3, "a robot has arrived when its rear axle is this close to its goal [m]", **P),
}
KIND_SECTIONS["lane_change"] = {
    "vehicles": Key(int, 15, "controlled vehicles, dealt to the lanes in turn (vehicle k starts in lane k mod lanes)",
                    check=lambda n: 1 <= n <= MAX_ROBOTS, expect=f"in 1..{MAX_ROBOTS}"),
    "speed": Key(float, 10.0, "cruise speed of every reference [m/s]", **P),
    "spacing": Key(float, 24.0, "distance between consecutive vehicles of one lane; lane i is shifted by i*spacing/lanes [m]", **P),
    "start_s": Key(float, 10.0, "arc length of the rearmost start (rear axle) along its lane [m]", **NN),
    "start_jitter": Key(float, 1.0, "the seed shifts every start along its lane uniformly within +- this [m]", **NN),
    "change_start": Key(float, 5.0, "a vehicle's lane change begins this far beyond its start [m]", **NN),
    "change_length": Key(float, 40.0, "arc length over which the reference moves from start lane to target lane [m]", **P),
    "curve_lat_accel": Key(float, 2.0, "the references slow down on curves to keep their lateral acceleration within this (and within robot.a_lat_max) [m/s^2]", **P),
    "finish_margin": Key(float, 20.0, "a vehicle has passed the cone zone when its rear axle is this far beyond the last cone [m]", **NN),
    "lane_tolerance": Key(float, 0.5, "lateral distance to the target lane's centre line that counts as arrived in it [m]", **P),
    "closure_lead": Key(float, 30.0, "cars from SUMO's routes (sumo.controlled_types) leave a lane that cones close ahead this far "
                        "before its first cone [m]", **NN),
    "exit_lanes": Key(list, [], "cars from SUMO's routes: beyond the last cones each changes to one of these road lanes (0 = rightmost "
                      "car lane), drawn by the seed per car; empty: it keeps its lane",
                      check=lambda v: all(isinstance(x, int) and not isinstance(x, bool) and 0 <= x < 16 for x in v),
                      expect="a list of lane indices 0..15"),
    "exit_spread": Key(float, 0.0, "cars from SUMO's routes begin the change to their exit lane at a point drawn by the seed "
                       "within this far beyond finish_margin past the last cone, so that they do not all weave at once [m]", **NN),
    "closure_window": Key(float, 100.0, "cars from SUMO's routes begin to leave a lane that cones close this far before their latest "
                          "begin (the one that ends closure_lead before the first cone), so that a car without a gap can slow down "
                          "and wait for one before it [m]", **NN),
    "gap_acceptance": Key(bool, True, "cars from SUMO's routes begin (and go on with) a lane change only into a safe gap "
                          "(gap_time, gap_decel, gap_min; docs/highway_work_zone.md); otherwise they keep their lane, slow down "
                          "(gap_speed) and try again further on"),
    "gap_time": Key(float, 1.0, "gap acceptance: the time gap a lane change keeps to the leader in the target lane (at its own speed) "
                    "and leaves the follower there (at the follower's speed) [s]", **NN),
    "gap_decel": Key(float, 3.0, "gap acceptance: the safe deceleration: the car must be able to come down to its new leader's "
                     "speed, and its new follower to its speed, braking at most this hard [m/s^2]", **P),
    "gap_min": Key(float, 2.0, "gap acceptance: the standstill gap, bumper to bumper, on top [m]", **NN),
    "gap_speed": Key(float, 0.75, "gap acceptance: a car whose lane change waits for a gap slows to this share of lane_change.speed "
                     "until it has changed, so that the traffic beside it moves on",
                     check=lambda f: 0 < f <= 1, expect="in (0, 1]"),
}
SUMO_SECTION: dict[str, Key] = {
    "config": Key(str, "", "a SUMO configuration (.sumocfg): its net-file, route-files, additional files and options are used "
                  "(the scenario's step length, seed and collision options still apply; empty: none)"),
    "extra_args": Key(str, "", "more SUMO command-line options, passed through (e.g. \"--default.speeddev 0\"); ours apply after them"),
    "net": Key(str, "", "SUMO .net.xml (empty: the bundled sumo_networks/lane_change network, or sumo.config's net-file)"),
    "routes": Key(str, "", "comma-separated SUMO route files with cones, pedestrians, other traffic (empty: the bundled ones with the bundled net, none otherwise)"),
    "edges": Key(str, "", "edge ids of the road in driving order, separated by spaces or commas (empty: the longest chain "
                 "with the car lanes the scenario needs; aac-sumo net info NET lists them)"),
    "cone_types": Key(str, "cone", "comma-separated vType ids whose vehicles are cones (static obstacles)"),
    "controlled_types": Key(list, [], "vType ids of SUMO's own vehicles (route files, sumo.config) that we control from their "
                            "departure on, on their own routes; instead of lane_change.vehicles (empty: none)",
                            check=lambda v: all(isinstance(x, str) and x.strip() for x in v), expect="a list of vType ids"),
    "controlled_ids": Key(list, [], "as controlled_types, for SUMO's vehicles whose id matches one of these globs (e.g. \"aac.*\")",
                          check=lambda v: all(isinstance(x, str) and x.strip() for x in v), expect="a list of id globs"),
    "gui": Key(bool, False, "show the run in sumo-gui (set by aac-sumo run --gui)"),
    "delay": Key(float, 0.0, "sumo-gui's pause per simulation step, to watch a run (set by aac-sumo run --delay) [ms]", **NN),
    "fcd": Key(bool, False, "write SUMO's floating-car-data trajectories, fcd.xml, into sumo.output_dir (as sumo.outputs = [\"fcd\"])"),
    "outputs": Key(list, [], "SUMO's own output files to write into sumo.output_dir, any of fcd, tripinfo, collision, summary, "
                   "lanechange (fcd.xml, tripinfo.xml, collision.xml, summary.xml, lanechange.xml)",
                   check=lambda v: all(x in ("fcd", "tripinfo", "collision", "summary", "lanechange") for x in v),
                   expect="a list of fcd, tripinfo, collision, summary, lanechange"),
    "isolate": Key(bool, True, "run SUMO in a process of its own, so that a SUMO crash (a segfault in libsumo) ends the run with "
                   "its error and everything recorded until then, not the whole command (false: in aac-sumo's process; "
                   "sumo-gui always runs in its own)"),
    "driver_speed": Key(float, -1.0, "controller.coordinator = sumo on kind lane_change: the most SUMO's driver drives the cars at "
                        "[m/s]; -1: lane_change.speed, our references' cruise speed (a like-for-like comparison); 0: SUMO's "
                        "own desired speed (the lane's limit times the vType's speed factor, 13.9 m/s on the bundled road)"),
    "lateral_resolution": Key(float, 0.0, "SUMO's sublane model: --lateral-resolution for SUMO's own traffic [m] (0: off, "
                              "the lane-based model, unless sumo.config or sumo.extra_args set it)", **NN),
    "output_dir": Key(str, "", "directory of SUMO's own output files and of its message log sumo.log (aac-sumo run sets it to --out; "
                      "empty: out/<scenario name> when outputs are asked for, else no files and SUMO's warnings off)"),
}
#: Sections beyond COMMON and the kind's own that a kind uses.
KIND_EXTRA_SECTIONS: dict[str, dict[str, dict[str, Key]]] = {"lane_change": {"sumo": SUMO_SECTION}}
