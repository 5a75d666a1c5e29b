"""SUMO road networks: build them from plain XML, read the road's lanes, check what a scenario needs.

Positions are SUMO network coordinates [m] (our world frame: x right, y up). A *road* is a chain
of normal edges a vehicle drives in order; its lane ``i`` is the concatenation of lane ``i`` of
every edge (lane 0 = rightmost lane open to cars), junction gaps bridged by straight segments.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aac_sumo.config import ScenarioError

#: The SUMO vehicle class our controlled vehicles drive as.
VEHICLE_CLASS = "passenger"


def sumo_binary(name: str) -> str:
    """Path of a binary (``sumo``, ``sumo-gui``, ``netconvert``) of the eclipse-sumo wheel."""
    import sumo

    return str(Path(sumo.SUMO_HOME) / "bin" / name)


def build(directory: Path) -> list[Path]:
    """Run the wheel's netconvert on the plain-XML sources in ``directory``; the built networks.

    Every ``*.netccfg`` there is run as ``netconvert -c FILE``. Without one, the ``*.nod.xml``,
    ``*.edg.xml``, ``*.con.xml`` and ``*.typ.xml`` files are converted into
    ``<directory name>.net.xml``. A netconvert failure raises ``ScenarioError`` with its first
    error line.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise ScenarioError(directory, "net build", "a directory with plain-XML network sources")
    configs = sorted(directory.glob("*.netccfg"))
    jobs: list[tuple[list[str], Path]] = []
    for cfg in configs:
        out = _netccfg_output(cfg)
        jobs.append((["-c", cfg.name], directory / out))
    if not configs:
        sources = {flag: sorted(p.name for p in directory.glob(f"*.{ext}.xml"))
                   for flag, ext in (("--node-files", "nod"), ("--edge-files", "edg"), ("--connection-files", "con"), ("--type-files", "typ"))}
        if not sources["--edge-files"]:
            raise ScenarioError(directory, "net build", "a *.netccfg file or at least one *.edg.xml file")
        out = directory / f"{directory.resolve().name}.net.xml"
        args = [a for flag, files in sources.items() if files for a in (flag, ",".join(files))]
        jobs.append((args + ["--offset.disable-normalization", "true", "-o", out.name], out))
    for args, out in jobs:
        done = subprocess.run([sumo_binary("netconvert"), *args], cwd=directory, capture_output=True, text=True)
        if done.returncode != 0 or not out.is_file():
            lines = [ln for ln in (done.stderr + done.stdout).splitlines() if ln.strip()]
            first = next((ln for ln in lines if ln.startswith("Error")), lines[0] if lines else "no output")
            raise ScenarioError(directory, "net build", f"sources netconvert accepts ({first.strip()})")
    return [out for _, out in jobs]


def _netccfg_output(cfg: Path) -> str:
    import xml.etree.ElementTree as ET

    node = ET.parse(cfg).find(".//output-file")
    if node is None:
        raise ScenarioError(cfg, "output-file", "an <output-file value=...> in the netconvert configuration")
    return node.get("value")


def read(path: Path, key: str, source: str, **options):
    """The sumolib network at ``path`` (``options`` go to ``sumolib.net.readNet``); a missing or
    unreadable file is a ``ScenarioError`` on ``key``."""
    import sumolib

    if not Path(path).is_file():
        raise ScenarioError(source, key, f"an existing SUMO .net.xml file{build_hint(Path(path))}", str(path))
    try:
        net = sumolib.net.readNet(str(path), **options)
    except Exception as exc:  # sumolib raises plain xml / attribute errors
        raise ScenarioError(source, key, f"a readable SUMO network ({type(exc).__name__}: {exc})", str(path)) from None
    if not any(e.getLanes() for e in net.getEdges()):  # sumolib reads an .edg.xml, say, as edges without lanes
        raise ScenarioError(source, key, "a SUMO network with lanes (a .net.xml that netconvert built)", str(path))
    return net


def build_hint(missing: Path) -> str:
    """``" (build the network first: aac-sumo net build DIR)"`` when the missing network file
    ``missing`` lies in a folder DIR of plain-XML sources netconvert can build it from (a
    ``*.netccfg`` or ``*.edg.xml`` file there), else ``""``."""
    folder = Path(missing).parent
    if not folder.is_dir() or not (any(folder.glob("*.netccfg")) or any(folder.glob("*.edg.xml"))):
        return ""
    return f" (build the network first: aac-sumo net build {folder})"


def car_lanes(edge) -> list:
    """The lanes of ``edge`` open to ``VEHICLE_CLASS``, rightmost first."""
    return [lane for lane in edge.getLanes() if lane.allows(VEHICLE_CLASS)]


@dataclass(frozen=True)
class Chain:
    """Consecutive edges and the car lanes that run through all of them: road lane ``j``
    (0 = rightmost) is car lane ``tracks[j][i]`` of edge ``i``, following the network's lane
    connections, so lane counts may differ from edge to edge (a ramp's added lane, a lane drop)."""

    edges: tuple
    tracks: tuple[tuple[int, ...], ...]

    @property
    def ids(self) -> list[str]:
        return [e.getID() for e in self.edges]

    @property
    def n_lanes(self) -> int:
        return len(self.tracks)

    @property
    def length(self) -> float:
        """Sum of the edges' lengths [m] (junctions left out)."""
        return float(sum(e.getLength() for e in self.edges))

    def lanes(self, j: int) -> list:
        """The sumolib lanes of road lane ``j``, one per edge."""
        return [car_lanes(e)[i] for e, i in zip(self.edges, self.tracks[j])]

    def describe(self) -> str:
        """``edges A B, 3 lanes, 420 m``."""
        return f"edges {' '.join(self.ids)}, {self.n_lanes} lane{'s' * (self.n_lanes != 1)}, {self.length:.0f} m"

    def then(self, edge) -> "Chain":
        """This chain continued by ``edge``: the lanes that connect, with one shift of lane index
        for all of them (the shift that keeps most adjacent lanes)."""
        here, there = car_lanes(self.edges[-1]), car_lanes(edge)
        pairs = {(here.index(c.getFromLane()), there.index(c.getToLane())) for c in self.edges[-1].getConnections(edge)
                 if c.getFromLane() in here and c.getToLane() in there}
        runs = [[]]  # runs of adjacent tracks that continue with one shift
        for shift in sorted({b - a for a, b in pairs}, key=abs):
            runs.append([])
            for track in self.tracks:
                if (track[-1], track[-1] + shift) in pairs:
                    runs[-1].append(track + (track[-1] + shift,))
                else:
                    runs.append([])
        return Chain(self.edges + (edge,), tuple(max(runs, key=len)))


#: Connection directions a road follows: straight on and partial turns, no turns or U-turns.
THROUGH = frozenset("sLR")
#: Chains explored before the search stops (a bound on pathological networks).
SEARCH_LIMIT = 20000


def chain_of(net, ids: list[str]) -> Chain:
    """The chain along edge ids ``ids``; ``ValueError`` where an edge does not lead to the next."""
    edges = [net.getEdge(eid) for eid in ids]
    chain = Chain((edges[0],), tuple((i,) for i in range(len(car_lanes(edges[0])))))
    for edge in edges[1:]:
        if edge not in chain.edges[-1].getOutgoing():
            raise ValueError(f"{chain.edges[-1].getID()} does not lead to {edge.getID()}")
        chain = chain.then(edge)
    return chain


def candidates(net, lanes: int) -> list[Chain]:
    """Every maximal chain of edges with at least ``lanes`` car lanes running through it, along
    straight-on connections (``THROUGH``), longest first. Chains start at edges no such chain
    leads into (anywhere on a ring)."""
    def onward(chain: Chain) -> list[Chain]:
        last = chain.edges[-1]
        nxt = sorted({to for to, conns in last.getOutgoing().items() if any(c.getDirection() in THROUGH for c in conns)}
                     - set(chain.edges), key=lambda e: e.getID())
        return [c for c in (chain.then(e) for e in nxt) if c.n_lanes >= lanes]

    singles = [Chain((e,), tuple((i,) for i in range(len(car_lanes(e)))))
               for e in sorted(net.getEdges(withInternal=False), key=lambda e: e.getID()) if len(car_lanes(e)) >= lanes]
    entered = {c.edges[-1] for s in singles for c in onward(s)}
    stack = [s for s in singles if s.edges[0] not in entered] or singles
    found, explored = [], 0
    while stack and explored < SEARCH_LIMIT:
        chain = stack.pop()
        explored += 1
        more = onward(chain)
        stack += more
        if not more:
            found.append(chain)
    return sorted(found, key=lambda c: (-c.length, c.ids))


@dataclass
class Road:
    """The chain of edges ``edges`` and, per lane index, its centre line (M_i, 2) [m] and width [m]."""

    edges: list[str]
    lanes: list[np.ndarray]
    widths: list[float]

    @property
    def n_lanes(self) -> int:
        return len(self.lanes)

    def length(self, lane: int) -> float:
        """Arc length [m] of lane ``lane``'s centre line."""
        return float(np.hypot(*np.diff(self.lanes[lane], axis=0).T).sum())


def road(net, edges: str, lanes: int, source: str) -> Road:
    """The road along ``edges`` (edge ids separated by spaces or commas, key ``sumo.edges``) or,
    when empty, the longest chain of :func:`candidates` with ``lanes`` car lanes (key ``sumo.net``).
    A road with fewer lanes is a one-line ``ScenarioError`` naming the best candidate."""
    need = f"at least {lanes} lanes open to {VEHICLE_CLASS}"
    ids = edges.replace(",", " ").split()
    if ids:
        unknown = next((eid for eid in ids if not net.hasEdge(eid)), None)
        if unknown is not None:
            raise ScenarioError(source, "sumo.edges", "edge ids of the network (aac-sumo net info NET lists its roads)", unknown)
        try:
            chain = chain_of(net, ids)
        except ValueError as exc:
            raise ScenarioError(source, "sumo.edges", f"a connected chain of edges ({exc})") from None
        if chain.n_lanes < lanes:
            raise ScenarioError(source, "sumo.edges", f"a road with {need} running through every edge ({chain.describe()}; "
                                "aac-sumo net info NET lists the roads)")
    else:
        found = candidates(net, lanes)
        if not found:
            best = next((c[0] for k in range(lanes - 1, 0, -1) if (c := candidates(net, k))), None)
            hint = f"the best candidate: {best.describe()}" if best else f"no edge is open to {VEHICLE_CLASS}"
            raise ScenarioError(source, "sumo.net", f"a network with a road of {need} (none has them; {hint}; "
                                "aac-sumo net info NET lists the roads)")
        chain = found[0]
    return chain_road(chain)


def chain_road(chain: Chain) -> Road:
    """The :class:`Road` of ``chain``: each lane's centre line through its edges, and its
    narrowest width."""
    parts = [chain.lanes(j) for j in range(chain.n_lanes)]
    return Road(chain.ids, [np.vstack([np.asarray(lane.getShape(), dtype=float) for lane in part]) for part in parts],
                [min(lane.getWidth() for lane in part) for part in parts])


#: The controlled cars' vType that ``random_trips`` writes: the city scenario's car (4 m x 1.8 m).
TRIPS_VTYPE = '<vType id="{vtype}" length="4.0" width="1.8" accel="3.0" decel="6.0" maxSpeed="20"/>'


def random_trips(net: Path, out: Path, controlled: int, background: int, end: float, seed: int, vtype: str = "aac") -> list[Path]:
    """Routes on ``net`` made by the wheel's ``randomTrips.py`` (routed by its duarouter, fringe
    to fringe, at least 300 m): ``controlled`` cars of vType ``vtype`` (ids ``aac.K``) and
    ``background`` cars of SUMO's default vType (ids ``bg.K``), each set departing evenly over
    ``end`` [s], with randomTrips' ``seed`` (``seed + 1`` for the background). Writes
    ``out/controlled.rou.xml`` and ``out/background.rou.xml``; a failure is a ``ScenarioError``
    with randomTrips' first error line. Fewer routes may result where trips cannot be routed."""
    import sumo

    for flag, value in (("--controlled", controlled), ("--background", background)):
        if value < 0:
            raise ScenarioError(net, f"net trips {flag}", "a count >= 0", str(value))
    if controlled + background == 0:
        raise ScenarioError(net, "net trips --controlled/--background", "at least one car to route", "0")
    if not end > 0.0:
        raise ScenarioError(net, "net trips --end", "a time > 0 [s]", f"{end:g}")
    out = Path(out)
    if not Path(net).is_file():
        raise ScenarioError(net, "net trips", f"an existing SUMO .net.xml file{build_hint(Path(net))}")
    out.mkdir(parents=True, exist_ok=True)
    (out / "vtypes.add.xml").write_text(f"<additional>{TRIPS_VTYPE.format(vtype=vtype)}</additional>\n")
    tool = Path(sumo.SUMO_HOME) / "tools" / "randomTrips.py"
    env = dict(os.environ, SUMO_HOME=str(sumo.SUMO_HOME), PATH=f"{Path(sumo.SUMO_HOME) / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}")
    made = []
    for name, count, prefix, extra, offset in (("controlled", controlled, f"{vtype}.", f'type="{vtype}" ', 0),
                                              ("background", background, "bg.", "", 1)):
        if count <= 0:
            continue
        routes = out / f"{name}.rou.xml"
        args = [sys.executable, str(tool), "-n", str(Path(net).resolve()), "-r", routes.name, "-o", f"{name}.trips.xml", "--seed", str(seed + offset),
                "-b", "0", "-e", f"{end:g}", "-p", f"{end / count:g}", "--prefix", prefix, "--fringe-factor", "10",
                "--min-distance", "300", "--validate", "--trip-attributes", f'{extra}departLane="best" departSpeed="max"']
        if extra:
            args += ["--additional-file", "vtypes.add.xml"]
        done = subprocess.run(args, cwd=out, capture_output=True, text=True, env=env)
        if done.returncode != 0 or not routes.is_file():
            lines = [ln for ln in (done.stderr + done.stdout).splitlines() if ln.strip()]
            first = next((ln for ln in lines if "rror" in ln), lines[-1] if lines else "no output")
            raise ScenarioError(net, "net trips", f"routes randomTrips.py can make ({first.strip()})")
        made.append(routes)
    return made
