"""How the SUMO co-simulation starts SUMO (:class:`SumoOptions`: network, route files, GUI, seed,
SUMO's own output files, a user's .sumocfg), the lane orders SUMO's own driver gets
(:class:`LaneOrder`), and :class:`SumoError`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from aac_sumo.config.keys import NN
from aac_sumo.config.schema import from_section, param
from aac_sumo.network import sumo_binary


class SumoError(RuntimeError):
    """SUMO failed (start-up or mid-run); the message says what SUMO said and when."""


#: SUMO prints at most this many warnings of one kind, then a count (``--aggregate-warnings``),
#: unless ``sumo.extra_args`` sets it: a car SUMO thinks is braking too hard is warned about every
#: step (4,600 lines in one highway run). Its collisions are read through the API either way.
AGGREGATE_WARNINGS = 5


#: SUMO's own output files on request (``sumo.outputs``): name -> (option, file name).
OUTPUTS = {
    "fcd": ("--fcd-output", "fcd.xml"),
    "tripinfo": ("--tripinfo-output", "tripinfo.xml"),
    "collision": ("--collision-output", "collision.xml"),
    "summary": ("--summary-output", "summary.xml"),
    "lanechange": ("--lanechange-output", "lanechange.xml"),
}


def _names(v) -> bool:
    return all(isinstance(x, str) and x.strip() for x in v)


@dataclass(frozen=True)
class SumoParams:
    """Section ``[sumo]`` of the kinds that co-simulate with SUMO (lane_change): the network and
    route files (paths relative to the scenario file), which of SUMO's vehicles we control, the
    GUI, SUMO's own outputs and options; the experiment turns them into :class:`SumoOptions`."""

    config: str = param("", "a SUMO configuration (.sumocfg): its net-file, route-files, additional files and options are used "
                        "(the scenario's step length, seed and collision options still apply; empty: none)")
    extra_args: str = param("", "more SUMO command-line options, passed through (e.g. \"--default.speeddev 0\"); ours apply after them")
    net: str = param("", "SUMO .net.xml (empty: the bundled sumo_networks/lane_change network, or sumo.config's net-file)")
    routes: str = param("", "comma-separated SUMO route files with cones, pedestrians, other traffic (empty: the bundled ones "
                        "with the bundled net, none otherwise)")
    edges: str = param("", "edge ids of the road in driving order, separated by spaces or commas (empty: the longest chain "
                       "with the car lanes the scenario needs; aac-sumo net info NET lists them)")
    cone_types: str = param("cone", "comma-separated vType ids whose vehicles are cones (static obstacles)")
    controlled_types: tuple[str, ...] = param((), "vType ids of SUMO's own vehicles (route files, sumo.config) that we control "
                                              "from their departure on, on their own routes; instead of lane_change.vehicles "
                                              "(empty: none)", parse=tuple, raw_default=[], check=_names, expect="a list of vType ids")
    controlled_ids: tuple[str, ...] = param((), "as controlled_types, for SUMO's vehicles whose id matches one of these globs "
                                            "(e.g. \"aac.*\")", parse=tuple, raw_default=[], check=_names, expect="a list of id globs")
    gui: bool = param(False, "show the run in sumo-gui (set by aac-sumo run --gui)")
    delay: float = param(0.0, "sumo-gui's pause per simulation step, to watch a run (set by aac-sumo run --delay) [ms]", **NN)
    fcd: bool = param(False, "write SUMO's floating-car-data trajectories, fcd.xml, into sumo.output_dir (as sumo.outputs = [\"fcd\"])")
    outputs: tuple[str, ...] = param((), "SUMO's own output files to write into sumo.output_dir, any of fcd, tripinfo, collision, "
                                     "summary, lanechange (fcd.xml, tripinfo.xml, collision.xml, summary.xml, lanechange.xml)",
                                     parse=tuple, raw_default=[], check=lambda v: all(x in OUTPUTS for x in v),
                                     expect="a list of " + ", ".join(OUTPUTS))
    isolate: bool = param(True, "run SUMO in a process of its own, so that a SUMO crash (a segfault in libsumo) ends the run with "
                          "its error and everything recorded until then, not the whole command (false: in aac-sumo's process; "
                          "sumo-gui always runs in its own)")
    driver_speed: float = param(-1.0, "controller.coordinator = sumo on kind lane_change: the most SUMO's driver drives the cars "
                                "at [m/s]; -1: lane_change.speed, our references' cruise speed (a like-for-like comparison); 0: "
                                "SUMO's own desired speed (the lane's limit times the vType's speed factor, 13.9 m/s on the bundled road)")
    lateral_resolution: float = param(0.0, "SUMO's sublane model: --lateral-resolution for SUMO's own traffic [m] (0: off, "
                                      "the lane-based model, unless sumo.config or sumo.extra_args set it)", **NN)
    declared_decel: float = param(0.0, "the comfortable deceleration SUMO is told each controlled car brakes at (its vType's "
                                  "decel, which SUMO's drivers assume of it when they change lanes in front of it, set by "
                                  "vehicle.setDecel when the car becomes ours) [m/s^2]; 0: the vType's own", **NN)
    declared_at_insertion: bool = param(True, "with declared_decel, SUMO's vTypes of the controlled cars of its routes are told "
                                        "it before any departs, so that departSpeed=\"max\" inserts a car no faster than it "
                                        "can stop at it behind what stands ahead, and (on a city's routes) before the end of its "
                                        "first edge where that junction may make it wait (false: only once each car is ours)")
    output_dir: str = param("", "directory of SUMO's own output files and of its message log sumo.log (aac-sumo run sets it to "
                            "--out; empty: out/<scenario name> when outputs are asked for, else no files and SUMO's warnings off)")


def sumo_params(scenario) -> SumoParams:
    """Section ``[sumo]`` of a validated scenario (:class:`aac_sumo.config.Scenario`)."""
    return from_section(SumoParams, scenario, "sumo")


@dataclass
class SumoOptions:
    """How to start SUMO: network, route files (cones, pedestrians, other traffic), the vTypes
    that are cones, GUI, SUMO's random seed, the GUI's delay, the folder ``output_dir`` of
    SUMO's own files (None: none), and which of ``OUTPUTS`` to write there. With a folder,
    SUMO's messages (warnings included) go to ``sumo.log`` in it; without one they are off. A
    user's ``config`` (.sumocfg) is loaded first and ``extra_args`` follow it; the options set
    here come last and apply.
    The GUI starts running at once and stays open when the run ends, until its window is closed."""

    net: Path
    routes: list[Path] = field(default_factory=list)
    cone_types: tuple[str, ...] = ("cone",)
    gui: bool = False
    seed: int = 0
    delay: float = 0.0  # sumo-gui's pause per simulation step [ms]
    output_dir: Path | None = None
    outputs: tuple[str, ...] = ()
    config: Path | None = None  # a user's .sumocfg, loaded first: ours override what it sets
    extra_args: tuple[str, ...] = ()  # more SUMO options, before ours
    lateral_resolution: float = 0.0  # SUMO's sublane model's lateral resolution [m]; 0: off (not set by us)
    sumo_drives: bool = False  # SUMO's own driver moves the controlled vehicles (see the module)
    declared_decel: float = 0.0  # the decel SUMO is told our cars brake at [m/s^2]; 0: their vType's
    declared_types: tuple[str, ...] = ()  # vTypes of the controlled cars of SUMO's routes, told declared_decel before any departs
    insertion_speeds: tuple[tuple[str, float], ...] = ()  # (controlled vehicle id, the most SUMO inserts it at [m/s]) of SUMO's routes

    def our_options(self, dt: float) -> dict[str, str]:
        """The SUMO options the co-simulation sets itself, name -> value."""
        return {"step-length": repr(dt), "seed": str(self.seed), "collision.action": "warn", "collision.mingap-factor": "0",
                "collision.check-junctions": "true", "intermodal-collision.action": "warn", "time-to-teleport": "-1",
                **({"lateral-resolution": repr(float(self.lateral_resolution))} if self.lateral_resolution > 0 else {})}

    def command(self, dt: float) -> list[str]:
        cmd = [sumo_binary("sumo-gui" if self.gui else "sumo")] + (["-c", str(self.config)] if self.config else [])
        cmd += list(self.extra_args) + ["-n", str(self.net)]
        for name, value in self.our_options(dt).items():
            cmd += [f"--{name}", value]
        cmd += ["--no-step-log", "--duration-log.disable"]
        cmd += ["--log", str(self.output_dir / "sumo.log")] if self.output_dir is not None else ["--no-warnings"]
        if self.output_dir is not None and "--aggregate-warnings" not in self.extra_args:
            cmd += ["--aggregate-warnings", str(AGGREGATE_WARNINGS)]
        if self.routes:
            cmd += ["-r", ",".join(str(p) for p in self.routes)]
        for name in self.outputs:
            option, filename = OUTPUTS[name]
            cmd += [option, str(self.output_dir / filename)]
        if self.gui:
            cmd += ["--start", "--delay", repr(float(self.delay))]
        return cmd


@dataclass(frozen=True)
class LaneOrder:
    """A lane SUMO's driver is asked to take once the vehicle has driven ``after`` metres since
    its departure (SUMO's odometer, ``vehicle.getDistance``): per edge id, that lane's SUMO index
    on the edge (lane counts and sidewalks may differ between edges). On an edge it does not
    name (a junction's internal lane) the last lane asked holds."""

    after: float
    lanes: dict[str, int]
