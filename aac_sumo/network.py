"""SUMO road networks: build them from plain XML, read the road's lanes, check what a scenario needs.

Positions are SUMO network coordinates [m] (our world frame: x right, y up). A *road* is a chain
of normal edges a vehicle drives in order; its lane ``i`` is the concatenation of lane ``i`` of
every edge (lane 0 = rightmost lane open to cars), junction gaps bridged by straight segments.
"""

from __future__ import annotations

import subprocess
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


def read(path: Path, key: str, source: str):
    """The sumolib network at ``path``; a missing or unreadable file is a ``ScenarioError`` on ``key``."""
    import sumolib

    if not Path(path).is_file():
        raise ScenarioError(source, key, "an existing SUMO .net.xml file", str(path))
    try:
        return sumolib.net.readNet(str(path))
    except Exception as exc:  # sumolib raises plain xml / attribute errors
        raise ScenarioError(source, key, f"a readable SUMO network ({type(exc).__name__}: {exc})", str(path)) from None


def _car_lanes(edge) -> list:
    return [lane for lane in edge.getLanes() if lane.allows(VEHICLE_CLASS)]


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


def road(net, edges: str, source: str, key: str = "sumo.edges") -> Road:
    """The road along ``edges`` (space-separated ids), or, when empty, the longest chain of
    car edges from an edge without car predecessors, following the successor with most lanes."""
    if edges.strip():
        chain = []
        for eid in edges.split():
            if not net.hasEdge(eid):
                raise ScenarioError(source, key, "edge ids of the network", eid)
            edge = net.getEdge(eid)
            if chain and edge not in chain[-1].getOutgoing():
                raise ScenarioError(source, key, f"a connected chain of edges ({chain[-1].getID()} does not lead to {eid})")
            chain.append(edge)
    else:
        chain = _longest_chain(net)
        if not chain:
            raise ScenarioError(source, key, f"a network with an edge open to {VEHICLE_CLASS} vehicles")
    counts = [len(_car_lanes(e)) for e in chain]
    n = min(counts)
    lanes, widths = [], []
    for i in range(n):
        parts = [np.asarray(_car_lanes(e)[i].getShape(), dtype=float) for e in chain]
        lanes.append(np.vstack(parts))
        widths.append(min(_car_lanes(e)[i].getWidth() for e in chain))
    return Road([e.getID() for e in chain], lanes, widths)


def _longest_chain(net) -> list:
    car_edges = [e for e in net.getEdges() if _car_lanes(e)]
    has_pred = {o for e in car_edges for o in e.getOutgoing() if _car_lanes(o)}
    best: list = []
    for start in sorted((e for e in car_edges if e not in has_pred), key=lambda e: e.getID()) or car_edges[:1]:
        chain = [start]
        while True:
            nxt = sorted((o for o in chain[-1].getOutgoing() if _car_lanes(o) and o not in chain),
                         key=lambda o: (-len(_car_lanes(o)), o.getID()))
            if not nxt:
                break
            chain.append(nxt[0])
        if sum(e.getLength() for e in chain) > sum(e.getLength() for e in best):
            best = chain
    return best


def require_lanes(net, rd: Road, lanes: int, source: str, key: str = "sumo.net") -> None:
    """``ScenarioError`` naming the narrowest edge when the road has fewer than ``lanes`` car lanes."""
    if rd.n_lanes < lanes:
        counts = {eid: len(_car_lanes(net.getEdge(eid))) for eid in rd.edges}
        eid = min(counts, key=counts.get)
        n = counts[eid]
        raise ScenarioError(source, key, f"a road with at least {lanes} car lanes (edge {eid} has {n} lane{'s' * (n != 1)}; lane_change needs at least {lanes})")
