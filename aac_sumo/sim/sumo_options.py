"""How the SUMO co-simulation starts SUMO (:class:`SumoOptions`: network, route files, GUI, seed,
SUMO's own output files, a user's .sumocfg), the lane orders SUMO's own driver gets
(:class:`LaneOrder`), and :class:`SumoError`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

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
