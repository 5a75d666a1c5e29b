"""The declared scenario keys: :class:`Key` (type, default, check, doc) and the tables of every
section, ``COMMON`` (every kind's sections), ``KIND_SECTIONS`` (a kind's own section) and
``KIND_EXTRA_SECTIONS`` (further sections a kind reads, as lane_change reads ``[sumo]``).
:mod:`aac_sumo.registry` adds the sections of registered experiments and coordinators.

The sections of the planner and the coordinators (``[controller]`` but its ``coordinator``,
``[aac]``, ``[lfc]``, ``[orca]``, ``[cbf_qp]``) and each experiment kind's own section are not
written here: their parameter dataclasses declare them (:mod:`aac_sumo.config.schema`), in the
modules named in :data:`PROVIDERS` (the kinds' through
:func:`aac_sumo.registry.register_experiment`)."""

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

#: Each kind's own section, declared by the parameter dataclass its module registers
#: (:func:`aac_sumo.registry.register_experiment` ``params``); named here in the order of the
#: listings (``aac-sumo keys``), whatever the import order.
KIND_SECTIONS: dict[str, dict[str, Key]] = {kind: {} for kind in ("braking", "swarm_rescue", "circle_swap", "random_crossing",
                                                                    "lane_change")}
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
