"""Randomized stress campaigns: ``aac-sumo stress``.

Run ``i`` of a campaign of seed ``S`` has the kind ``kinds[i mod len(kinds)]`` and draws every
value from ``numpy.random.default_rng([S, 0, i])`` (:func:`draw`), so the plan is a pure
function of the seed and the run index: a resumed or longer campaign plans the same runs. Each
run is a bundled scenario plus ``--set KEY=VALUE`` overrides (``scenario.seed`` last), which
``aac-sumo run KIND --set ...`` reproduces. Lane-change runs also name files the campaign writes
into its output folder: a few generated roads (plain XML built with netconvert,
:func:`road_variants`, drawn from ``[S, 1]``) and one route file per run with its cones and
pedestrians.

The distributions (``docs/reliability.md`` has the table) are chosen so that no draw is
impossible: starts are spaced wider than two footprints plus their jitter, debris stays clear of
starts and goals, cones stand beyond every car's lane change and within the first edge. Every
draw is checked by the config loader when planned (a rejection is a bug and stops the
campaign). ``random_crossing`` draws its own geometry from the scenario seed by rejection
sampling; a scenario seed whose geometry fails is replaced by the next one from the run's
generator (deterministic, at most ``CROSSING_TRIES`` times).

The runs go through the sweep executor (:func:`aac_sumo.runs.sweep.run_tasks`: local processes or
Dask, ``--resume``). ``results.csv`` is its progress file; at the end ``stress.csv`` (one row
per run, with its outcome and reproducing command) and ``stress.md`` are written.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from aac_sumo import config
from aac_sumo.runs import sweep
from aac_sumo.config import ScenarioError
from aac_sumo.runs.executor import SweepError
from aac_sumo.tables.common import BASELINES

#: Outcomes of a run, most severe first (see :func:`outcome`).
OUTCOMES = ("collision", "error", "deadlock", "timeout", "completed")
#: The keys every run draws: ``controller.coordinator`` (aac | lfc), ``controller.barrier``
#: (cbf | fcbf), ``controller.horizon`` (``HORIZONS``), each uniform.
COMMON_KEYS = ("controller.coordinator", "controller.barrier", "controller.horizon")
#: The drawn MPC horizons [steps]: the paper's. Each horizon compiles its own solver once per
#: machine (20-35 s here, then cached), so every horizon of 5..15 would cost minutes on a fresh one.
HORIZONS = (5, 10, 15)
SEED_RANGE = 100_000  # scenario seeds are uniform in 0..SEED_RANGE-1
CROSSING_TRIES = 20  # random_crossing scenario seeds tried before the campaign stops
ROAD_VARIANTS = 3  # generated lane-change roads per campaign: one straight, the others curved


def _f(x: float, digits: int = 2) -> str:
    """A drawn number as its ``--set`` text (rounded; ``str`` of a float reads back the same)."""
    return str(round(float(x), digits))


def _rows(rows) -> str:
    return "[" + ", ".join("[" + ", ".join(_f(v, 3) for v in row) + "]" for row in rows) + "]"


# --- the distributions, one function per kind ----------------------------------------------------


def draw_swarm(rng: np.random.Generator, campaign: "Campaign", index: int) -> dict[str, str]:
    """swarm_rescue: 3..7 robots on a start line x = 0, ``spacing`` U(1.6, 2.5) m apart (wider than
    two footprints with their 0.1 m jitter), each heading for a goal on the line x = ``width``
    U(10, 16) m at a randomly permuted slot of the same spacing (paths cross); 0..4 debris
    rectangles (length U(0.4, 1.0), width U(0.3, 0.8) m, any heading) with centres at
    x in U(3, width - 3), clear of every start and goal."""
    n = int(rng.integers(3, 8))
    spacing, width = rng.uniform(1.6, 2.5), rng.uniform(10.0, 16.0)
    ys = spacing * np.arange(n)
    goals = np.column_stack([np.full(n, width), ys[rng.permutation(n)]])
    starts = np.column_stack([np.zeros(n), ys, np.arctan2(goals[:, 1] - ys, width)])
    k = int(rng.integers(0, 5))
    debris = np.column_stack([rng.uniform(3.0, width - 3.0, k), rng.uniform(-0.5, ys[-1] + 0.5, k),
                              rng.uniform(0.4, 1.0, k), rng.uniform(0.3, 0.8, k), rng.uniform(-np.pi / 2, np.pi / 2, k)])
    return {"swarm_rescue.starts": _rows(starts), "swarm_rescue.goals": _rows(goals), "swarm_rescue.debris": _rows(debris)}


def draw_circle(rng: np.random.Generator, campaign: "Campaign", index: int) -> dict[str, str]:
    """circle_swap: 4..12 robots on a circle of radius U(3, 6) m (neighbours at least 1.55 m apart)."""
    return {"circle_swap.n_robots": str(int(rng.integers(4, 13))), "circle_swap.radius": _f(rng.uniform(3.0, 6.0))}


def draw_crossing(rng: np.random.Generator, campaign: "Campaign", index: int) -> dict[str, str]:
    """random_crossing: 4..12 robots, U(5, 9) m^2 of area per robot, U(0, 3) debris per 100 m^2."""
    return {"random_crossing.n_robots": str(int(rng.integers(4, 13))),
            "random_crossing.area_per_robot": _f(rng.uniform(5.0, 9.0)),
            "random_crossing.debris_density": _f(rng.uniform(0.0, 3.0))}


def draw_braking(rng: np.random.Generator, campaign: "Campaign", index: int) -> dict[str, str]:
    """braking: speed U(5, 25) m/s, gap (centre to centre) U(5, 15) m, lead deceleration U(2, 6)
    m/s^2 (at most the ego's strongest braking, so a stop without contact is possible)."""
    return {"braking.speed": _f(rng.uniform(5.0, 25.0)), "braking.gap": _f(rng.uniform(5.0, 15.0)),
            "braking.lead_decel": _f(rng.uniform(2.0, 6.0))}


def draw_lane_change(rng: np.random.Generator, campaign: "Campaign", index: int) -> dict[str, str]:
    """lane_change on a generated road (one of the campaign's :func:`road_variants`, uniform):
    3..9 cars, ``spacing`` U(24, 40) m; 3..5 cones U(6, 10) m apart in the rightmost lane of the
    first edge, the first one uniform between 15 m beyond the end of the frontmost rightmost-lane
    car's lane change and where the zone still ends at ``CONE_END``; 0..3 pedestrians,
    each walking across at U(0.8, 1.6) m/s in either direction, leaving U(0, 15) s after the
    start from U(1, 20) m beside the road."""
    n, spacing = int(rng.integers(3, 10)), rng.uniform(24.0, 40.0)
    road = int(rng.integers(0, ROAD_VARIANTS))
    count, gap = int(rng.integers(3, 6)), rng.uniform(6.0, 10.0)
    lc = config.load("lane_change").data["lane_change"]
    front = lc["start_s"] + (n - 1) // 3 * spacing + lc["start_jitter"]  # the frontmost car of lane 0 (cars 0, 3, 6)
    lo = front + lc["change_start"] + lc["change_length"] + 15.0
    hi = CONE_END - (count - 1) * gap
    first = rng.uniform(lo, max(lo, hi))
    cones = first + gap * np.arange(count)
    walkers = [(bool(rng.integers(0, 2)), rng.uniform(0.8, 1.6), rng.uniform(0.0, 15.0), rng.uniform(1.0, 20.0))
               for _ in range(int(rng.integers(0, 4)))]
    return {"lane_change.vehicles": str(n), "lane_change.spacing": _f(spacing),
            "sumo.net": str(campaign.road_net(road)), "sumo.routes": str(campaign.routes_path(index)),
            "road": campaign.roads[road].describe(), "cones": " ".join(_f(c, 1) for c in cones),
            "pedestrians": " ".join(f"{'N' if north else 'S'}{_f(v)}@{_f(t, 1)}s" for north, v, t, _ in walkers),
            ROUTES_TEXT: routes_xml(cones, walkers)}


@dataclass(frozen=True)
class Kind:
    """A ``--kinds`` name: its bundled scenario, the ``scenario.duration`` cap of its runs [s]
    (a typical run takes 5-30 s of wall time here, docs/reliability.md), its draw, and the keys
    (``--set`` keys, or descriptive columns for what a generated file holds) that draw sets.
    ``baseline``: the baseline coordinator every run of the kind uses (instead of AAC or LFC,
    drawn); its collisions are reported, not failures of ours."""

    scenario: str
    duration: float
    draw: Callable[[np.random.Generator, "Campaign", int], dict[str, str]]
    keys: tuple[str, ...]
    baseline: str | None = None


KINDS: dict[str, Kind] = {
    "swarm": Kind("swarm_rescue", 40.0, draw_swarm, ("swarm_rescue.starts", "swarm_rescue.goals", "swarm_rescue.debris")),
    "circle": Kind("circle_swap", 40.0, draw_circle, ("circle_swap.n_robots", "circle_swap.radius")),
    "crossing": Kind("random_crossing", 40.0, draw_crossing,
                     ("random_crossing.n_robots", "random_crossing.area_per_robot", "random_crossing.debris_density")),
    "lane-change": Kind("lane_change", 50.0, draw_lane_change,
                        ("lane_change.vehicles", "lane_change.spacing", "sumo.net", "sumo.routes", "road", "cones", "pedestrians")),
    "braking": Kind("braking", 20.0, draw_braking, ("braking.speed", "braking.gap", "braking.lead_decel")),
}
#: The baselines as kinds of their own: ``<baseline>-<kind>`` with the kind's draws, for every kind whose
#: scenario the baseline drives (:data:`~aac_sumo.tables.common.BASELINES`) and that this version declares.
KINDS |= {f"{b}-{k}": dataclasses.replace(kind, baseline=b) for b, scenarios in BASELINES.items() for k, kind in list(KINDS.items())
          if kind.scenario in scenarios and b in config.COMMON["controller"]["coordinator"].type}
#: Columns that describe a generated file's content; they are not ``--set`` keys.
DESCRIPTIVE = ("road", "cones", "pedestrians")
ROUTES_TEXT = "_routes_xml"  # a draw's route-file content (written by :func:`prepare`, not a column)
#: Columns of the drawn values in results.csv and stress.csv, after ``run`` and ``kind``.
DRAWN_KEYS = ("scenario.duration",) + COMMON_KEYS + tuple(k for kind in KINDS.values() for k in kind.keys)


# --- generated lane-change roads -----------------------------------------------------------------

ROAD_LENGTH = 420.0  # [m], as the bundled road
CROSSING_S = 240.0  # arc length of the zebra crossing and of the junction between the two edges [m]
FOOTPATH = 25.0  # length of each footpath from the road [m]
CONE_END = 205.0  # the cone zone ends before this arc length of lane E0_0 (the inner lane of a 150 m curve is ~225 m) [m]
PRIORITY = ' type="priority"'


@dataclass(frozen=True)
class Road:
    """A generated 3-lane road of ``ROAD_LENGTH`` along a circular arc of signed ``curvature``
    [1/m] (0: straight; > 0 bends left), built like the bundled one: edges E0 and E1 meeting at
    a zebra crossing at ``CROSSING_S``, footpaths FN and FS."""

    curvature: float

    def describe(self) -> str:
        if self.curvature == 0:
            return "straight"
        return f"{'left' if self.curvature > 0 else 'right'} R{abs(1 / self.curvature):.0f}"

    def point(self, s) -> np.ndarray:
        """Points (K, 2) [m] of the centre line at arc lengths ``s``."""
        s, k = np.atleast_1d(np.asarray(s, dtype=float)), self.curvature
        if k == 0:
            return np.column_stack([s, np.zeros_like(s)])
        return np.column_stack([np.sin(k * s) / k, (1 - np.cos(k * s)) / k])

    def sources(self) -> dict[str, str]:
        """The plain-XML files (name -> text) that netconvert builds this road from."""
        x = self.point(CROSSING_S)[0]
        normal = np.array([-np.sin(self.curvature * CROSSING_S), np.cos(self.curvature * CROSSING_S)])
        nodes = {"W": self.point(0.0)[0], "X": x, "E": self.point(ROAD_LENGTH)[0], "N": x + FOOTPATH * normal,
                 "S": x - FOOTPATH * normal}

        def shape(a: float, b: float) -> str:
            return " ".join(f"{px:.3f},{py:.3f}" for px, py in self.point(np.linspace(a, b, int((b - a) // 10) + 2)))

        nod = "\n".join(f'    <node id="{k}" x="{p[0]:.3f}" y="{p[1]:.3f}"{PRIORITY if k == "X" else ""}/>'
                        for k, p in nodes.items())
        car = 'numLanes="3" speed="13.89" width="3.2" allow="passenger"'
        foot = 'numLanes="1" speed="2.0" width="2.0" allow="pedestrian"'
        edg = "\n".join([f'    <edge id="E0" from="W" to="X" {car} shape="{shape(0.0, CROSSING_S)}"/>',
                         f'    <edge id="E1" from="X" to="E" {car} shape="{shape(CROSSING_S, ROAD_LENGTH)}"/>',
                         f'    <edge id="FN" from="N" to="X" {foot}/>', f'    <edge id="FS" from="X" to="S" {foot}/>'])
        con = "\n".join(f'    <connection from="E0" to="E1" fromLane="{i}" toLane="{i}"/>' for i in range(3))
        con += '\n    <crossing node="X" edges="E0" priority="true" width="4.0"/>'
        head = '<?xml version="1.0" encoding="UTF-8"?>\n<!-- generated by aac-sumo stress -->\n'
        return {"road.nod.xml": f"{head}<nodes>\n{nod}\n</nodes>\n", "road.edg.xml": f"{head}<edges>\n{edg}\n</edges>\n",
                "road.con.xml": f"{head}<connections>\n{con}\n</connections>\n"}


def road_variants(seed: int) -> list[Road]:
    """The campaign's ``ROAD_VARIANTS`` roads: the first straight, the others curved with a radius
    U(150, 400) m bending left or right (uniform), drawn from ``[seed, 1]``."""
    rng = np.random.default_rng([seed, 1])
    return [Road(0.0)] + [Road(float(rng.choice([-1, 1]) / rng.uniform(150.0, 400.0))) for _ in range(ROAD_VARIANTS - 1)]


def routes_xml(cones: np.ndarray, walkers: list[tuple[bool, float, float, float]]) -> str:
    """A route file: cones (vType ``cone``, their fronts at arc lengths ``cones`` [m] of lane E0_0)
    and pedestrians ``(northbound, speed [m/s], depart [s], distance from the road [m])``."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<!-- generated by aac-sumo stress -->", "<routes>",
             '    <vType id="cone" vClass="passenger" length="0.4" width="0.4" minGap="0" maxSpeed="0.01"/>']
    for k, s in enumerate(cones):
        lines += [f'    <vehicle id="cone{k}" type="cone" depart="0" departLane="0" departPos="{s:.2f}" departSpeed="0">',
                  '        <route edges="E0"/>',
                  f'        <stop lane="E0_0" startPos="{s - 0.4:.2f}" endPos="{s:.2f}" duration="100000"/>', "    </vehicle>"]
    walks = []
    for k, (north, speed, depart, away) in enumerate(walkers):
        lines.append(f'    <vType id="walker{k}" vClass="pedestrian" length="0.3" width="0.5" speedDev="0" '
                     f'maxSpeed="{speed:.2f}" desiredMaxSpeed="{speed:.2f}"/>')
        start, end, pos = ("FS", "FN", away) if north else ("FN", "FS", FOOTPATH - away)
        walks.append((depart, f'    <person id="p{k}" type="walker{k}" depart="{depart:.1f}" departPos="{pos:.2f}">\n'
                      f'        <walk from="{start}" to="{end}"/>\n    </person>'))
    lines += [text for _, text in sorted(walks)]  # SUMO wants departures in order
    return "\n".join(lines + ["</routes>"]) + "\n"


# --- planning ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Campaign:
    """What a campaign's draws share: its seed, output folder, generated roads, and the cap of
    every run's ``scenario.duration`` (``--duration``; None: each kind's own)."""

    seed: int
    out: Path
    duration: float | None = None

    @property
    def roads(self) -> list[Road]:
        return road_variants(self.seed)

    def road_net(self, variant: int) -> Path:
        return self.out / "roads" / f"road{variant}" / f"road{variant}.net.xml"

    def routes_path(self, index: int) -> Path:
        return self.out / "routes" / f"run{index:04d}.rou.xml"


@dataclass(frozen=True)
class Draw:
    """Run ``index`` of a campaign: its ``--kinds`` name, drawn values (``--set`` keys and
    descriptive columns), ``--set`` overrides (``scenario.seed`` last) and files to write."""

    index: int
    kind: str
    values: dict[str, str]
    sets: tuple[str, ...]
    seed: int
    files: tuple[tuple[Path, str], ...] = ()

    @property
    def scenario(self) -> str:
        return KINDS[self.kind].scenario

    def command(self) -> str:
        """The ``aac-sumo run`` command line that reproduces this run."""
        return " ".join(["aac-sumo", "run", self.scenario] + [f"--set {shlex.quote(s)}" for s in self.sets])


def draw(campaign: Campaign, index: int, kinds: list[str]) -> Draw:
    """Run ``index`` of ``campaign``: kind ``kinds[index mod len(kinds)]``, values from
    ``default_rng([seed, 0, index])``; checked by the config loader (a ``ScenarioError`` here is a
    bug in the distributions)."""
    kind = kinds[index % len(kinds)]
    spec = KINDS[kind]
    rng = np.random.default_rng([campaign.seed, 0, index])
    values = {"scenario.duration": _f(min(spec.duration, campaign.duration or math.inf)),
              "controller.coordinator": str(rng.choice(["aac", "lfc"])), "controller.barrier": str(rng.choice(["cbf", "fcbf"])),
              "controller.horizon": str(int(rng.choice(HORIZONS)))}
    values |= spec.draw(rng, campaign, index)
    if spec.baseline is not None:
        values["controller.coordinator"] = spec.baseline
    files = ((campaign.routes_path(index), values.pop(ROUTES_TEXT)),) if ROUTES_TEXT in values else ()
    sets = [f"{k}={v}" for k, v in values.items() if k not in DESCRIPTIVE]
    for _ in range(CROSSING_TRIES):
        seed = int(rng.integers(0, SEED_RANGE))
        scenario = config.load(spec.scenario, sets + [f"scenario.seed={seed}"], "stress --set")
        if kind != "crossing" or _crossing_ok(scenario):
            return Draw(index, kind, values, tuple(sets + [f"scenario.seed={seed}"]), seed, files)
    raise SweepError(f"stress: run {index}: random_crossing: expected a placeable geometry within {CROSSING_TRIES} seeds")


def _crossing_ok(scenario) -> bool:
    from aac_sumo.experiments import random_crossing

    try:
        random_crossing.draw(scenario)
    except ScenarioError:
        return False
    return True


def plan(runs: int, kinds: list[str], seed: int, out: Path, duration: float | None = None) -> list[Draw]:
    """Every run of a campaign (:func:`draw` of 0..runs-1)."""
    campaign = Campaign(seed, out, duration)
    return [draw(campaign, i, kinds) for i in range(runs)]


def parse_kinds(text: str) -> list[str]:
    """``--kinds swarm,braking`` as a list; an unknown name is a :class:`SweepError`."""
    kinds = [k.strip() for k in text.split(",") if k.strip()]
    unknown = [k for k in kinds if k not in KINDS]
    if unknown or not kinds:
        raise SweepError(f"stress: --kinds {text!r}: expected comma-separated names among {', '.join(KINDS)}")
    return list(dict.fromkeys(kinds))


def prepare(draws: list[Draw], seed: int, out: Path) -> None:
    """Write the files the runs need: each used road (netconvert, once; kept on resume) and each
    run's route file."""
    from aac_sumo import network

    campaign = Campaign(seed, out)
    for variant, road in enumerate(campaign.roads):
        net = campaign.road_net(variant)
        if net.is_file() or not any(d.values.get("sumo.net") == str(net) for d in draws):
            continue
        net.parent.mkdir(parents=True, exist_ok=True)
        for name, text in road.sources().items():
            (net.parent / name.replace("road", f"road{variant}")).write_text(text)
        network.build(net.parent)
    for d in draws:
        for path, text in d.files:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)


# --- outcomes and reports ------------------------------------------------------------------------


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0


def is_baseline(row: dict) -> bool:
    """Whether a stress row ran one of the baselines (its collisions are not failures of ours)."""
    return KINDS[row["kind"]].baseline is not None if row.get("kind") in KINDS else False


def outcome(row: dict) -> str:
    """A run's outcome: ``collision`` when ``collisions`` or ``sim_collisions`` > 0; else ``error``
    when its status is error (it raised, or its worker died); else ``completed`` when every robot
    finished, ``deadlock`` when the runner's deadlock rule ended it, ``timeout`` otherwise (the
    time limit ``scenario.duration`` came first)."""
    if _positive(row.get("collisions")) or _positive(row.get("sim_collisions")):
        return "collision"
    if row.get("status") != "ok":
        return "error"
    if row.get("completed") is True:
        return "completed"
    return "deadlock" if row.get("deadlock") is True else "timeout"


def stress_columns() -> list[str]:
    """``stress.csv`` columns: run, kind, outcome, the drawn values, then results.csv's (seed,
    metrics, status, error, provenance), then the reproducing command."""
    rest = sweep.columns([])
    return ["run", "kind", "outcome", *DRAWN_KEYS] + rest + ["command"]


def _split(rows: list[dict], key: Callable[[dict], str]) -> list[str]:
    groups: dict[str, list[str]] = {}
    for r in rows:
        groups.setdefault(key(r), []).append(r["outcome"])
    lines = []
    for name, outs in groups.items():
        lines.append(f"| {name} | {len(outs)} | " + " | ".join(str(outs.count(o)) for o in OUTCOMES) + " |")
    return lines


def _worst(rows: list[dict], metric: str) -> str:
    known = [r for r in rows if isinstance(r.get(metric), (int, float)) and math.isfinite(r[metric])]
    if not known:
        return f"- `{metric}`: no run measured it"
    r = min(known, key=lambda r: r[metric])
    return f"- `{metric}` = {r[metric]:.3g} m in run {r['run']} ({r['kind']}, {r['outcome']}): `{r['command']}`"


def markdown(rows: list[dict], title: str) -> str:
    """``stress.md``: the outcome split per kind and per (coordinator, barrier), the worst
    clearance and distance, and every failure with the command that reproduces it."""
    head = ["| | runs | " + " | ".join(OUTCOMES) + " |", "|---|---|" + "---|" * len(OUTCOMES)]
    lines = [f"# {title}", "", "Outcomes (docs/reliability.md defines them): collision (footprint overlap or a "
             "SUMO-reported collision), error (the run raised or its worker died), deadlock, timeout (the time "
             "limit `scenario.duration` came first), completed.", "", "## Per kind", "", *head]
    lines += _split(rows, lambda r: r["kind"])
    lines += ["", "## Per coordinator and barrier", "", *head]
    lines += _split(sorted(rows, key=lambda r: (str(r.get("controller.coordinator")), str(r.get("controller.barrier")))),
                    lambda r: f"{r.get('controller.coordinator')} / {r.get('controller.barrier')}")
    lines += ["", "## Closest approach", "", _worst(rows, "min_clearance_m"), _worst(rows, "min_distance_m")]
    failed = [r for r in rows if r["outcome"] != "completed"]
    lines += ["", f"## Failures ({len(failed)} of {len(rows)} runs)", ""]
    for r in sorted(failed, key=lambda r: (OUTCOMES.index(r["outcome"]), r["run"])):
        why = r.get("error") or r.get("incomplete_reason") or ""
        lines.append(f"- run {r['run']} ({r['kind']}): **{r['outcome']}**{': ' + why if why else ''}  \n  `{r['command']}`")
    if not failed:
        lines.append("None.")
    return "\n".join(lines) + "\n"


def _manifest(out: Path, mine: dict, resume: bool) -> None:
    """Refuse to resume a campaign of another seed, kinds or duration cap (``OUT/stress.json``)."""
    path = out / "stress.json"
    if resume and path.is_file():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError):
            old = {}
        for key in mine:
            if key in old and old[key] != mine[key]:
                raise SweepError(f"--resume {path}: {key}: expected the interrupted campaign's {old[key]}, got {mine[key]}")
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(mine, indent=2) + "\n")


def stress(runs: int, kinds: list[str], seed: int, out: Path, workers: int | None = None, scheduler: str | None = None,
           resume: bool = False, progress: bool = True, duration: float | None = None) -> tuple[list[dict], str]:
    """The whole ``aac-sumo stress`` command: plan, write the generated files, run (``resume``:
    only the runs without a ``status=ok`` row in ``OUT/results.csv``), write stress.csv and
    stress.md. Returns the stress.csv rows and the markdown."""
    if seed < 0:
        raise SweepError(f"stress: --seed {seed}: expected an integer >= 0")
    if duration is not None and not 0 < duration < math.inf:
        raise SweepError(f"stress: --duration {duration}: expected a number of seconds > 0")
    _manifest(out, {"seed": seed, "kinds": kinds, "duration": duration}, resume)
    draws = plan(runs, kinds, seed, out, duration)
    prepare(draws, seed, out)
    tasks = [sweep.Task(d.index, str(config.resolve(d.scenario).resolve()), d.sets,
                        (("run", d.index), ("kind", d.kind), *d.values.items()), d.seed,
                        config.load(d.scenario, list(d.sets), "stress --set")) for d in draws]
    results = sweep.run_tasks(tasks, ["run", "kind", *DRAWN_KEYS], out, workers, progress, desc="stress",
                              scheduler=scheduler, resume=resume)
    rows = [r | {"outcome": outcome(r), "command": d.command()} for r, d in zip(results, draws)]
    with open(out / "stress.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=stress_columns(), extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in rows)
    text = markdown(rows, f"Stress campaign: {runs} runs of {', '.join(kinds)}, seed {seed}")
    (out / "stress.md").write_text(text)
    return rows, text
