"""The plan of a stress campaign (:mod:`aac_sumo.stress.campaign`): the distributions, one
function per kind, and the draw of each run. Run ``i`` of a campaign of seed ``S`` has the kind
``kinds[i mod len(kinds)]`` and draws every value from ``numpy.random.default_rng([S, 0, i])``
(:func:`draw`), so the plan is a pure function of the seed and the run index."""

from __future__ import annotations

import dataclasses
import math
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from aac_sumo import config
from aac_sumo.config import ScenarioError
from aac_sumo.runs.executor import SweepError
from aac_sumo.stress.roads import CONE_END, ROAD_VARIANTS, Road, road_variants, routes_xml
from aac_sumo.tables.common import BASELINES


#: The keys every run draws: ``controller.coordinator`` (aac | lfc), ``controller.barrier``
#: (cbf | fcbf), ``controller.horizon`` (``HORIZONS``), each uniform.
COMMON_KEYS = ("controller.coordinator", "controller.barrier", "controller.horizon")
#: The drawn MPC horizons [steps]: the paper's. Each horizon compiles its own solver once per
#: machine (20-35 s here, then cached), so every horizon of 5..15 would cost minutes on a fresh one.
HORIZONS = (5, 10, 15)
SEED_RANGE = 100_000  # scenario seeds are uniform in 0..SEED_RANGE-1
CROSSING_TRIES = 20  # random_crossing scenario seeds tried before the campaign stops


def _f(x: float, digits: int = 2) -> str:
    """A drawn number as its ``--set`` text (rounded; ``str`` of a float reads back the same)."""
    return str(round(float(x), digits))


def _rows(rows) -> str:
    return "[" + ", ".join("[" + ", ".join(_f(v, 3) for v in row) + "]" for row in rows) + "]"


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
#: scenario kind the baseline drives (:data:`~aac_sumo.tables.common.BASELINES`).
KINDS |= {f"{b}-{k}": dataclasses.replace(kind, baseline=b) for b, kinds in BASELINES.items() for k, kind in list(KINDS.items())
          if kind.scenario in kinds}
#: Columns that describe a generated file's content; they are not ``--set`` keys.
DESCRIPTIVE = ("road", "cones", "pedestrians")
ROUTES_TEXT = "_routes_xml"  # a draw's route-file content (written by :func:`prepare`, not a column)
#: Columns of the drawn values in results.csv and stress.csv, after ``run`` and ``kind``.
DRAWN_KEYS = ("scenario.duration",) + COMMON_KEYS + tuple(k for kind in KINDS.values() for k in kind.keys)


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
