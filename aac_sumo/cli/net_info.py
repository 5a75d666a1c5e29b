"""``aac-sumo net info NET [ROUTES...]``: what a user needs to choose a road in a SUMO network.

The candidate roads (chains of edges and the car lanes running through them, see
:func:`network.candidates`) with lanes, length [m] and the classes every lane allows; where
pedestrians may walk and cross; and the vTypes, vehicles and persons of route files.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

from aac_sumo import network
from aac_sumo.config import ScenarioError
from aac_sumo.sim.sumo_routes import FLOW_END, RoutesError, flow_departures

SHOWN = 8  # candidate roads listed
SHOWN_IDS = 6  # ids listed of a longer list, then how many more
WHERE = "net info"


def describe(net_path: Path, routes: list[Path]) -> str:
    """The report on the network at ``net_path`` and the route files ``routes``, as text."""
    from aac_sumo.experiments.lane_change import MIN_LANES

    net = network.read(net_path, "NET", WHERE, withInternal=True)
    edges = net.getEdges(withInternal=False)
    lines = [f"network {net_path}: {len(edges)} edges, {sum(bool(network.car_lanes(e)) for e in edges)} open to "
             f"{network.VEHICLE_CLASS}", "", *_roads(net, MIN_LANES), "", *_pedestrians(net, edges)]
    for path in routes:
        lines += ["", *_routes(path)]
    return "\n".join(lines) + "\n"


def _roads(net, need: int) -> list[str]:
    chosen = next(iter(network.candidates(net, need)), None)
    top = max((len(network.car_lanes(e)) for e in net.getEdges(withInternal=False)), default=0)
    seen, chains = set(), []
    for k in range(top, 0, -1):
        for chain in network.candidates(net, k):
            if tuple(chain.ids) not in seen:
                seen.add(tuple(chain.ids))
                chains.append(chain)
    chains.sort(key=lambda c: (-c.n_lanes, -c.length, c.ids))
    if not chains:
        return [f"roads: none (no edge is open to {network.VEHICLE_CLASS})"]
    lines = [f"roads (chains of edges; lanes open to {network.VEHICLE_CLASS} that run through every edge; "
             f"lane_change takes the longest with at least {need} lanes unless --set sumo.edges=\"ID ID ...\" names one):",
             "  lanes  length  edges  [classes every lane allows]"]
    shown = chains[:SHOWN]
    for chain in shown:
        lines.append(_chain_row(chain, chosen))
    if len(chains) > SHOWN:
        lines.append(f"  ... and {len(chains) - SHOWN} shorter or narrower")
        if chosen is not None and not any(chain.ids == chosen.ids for chain in shown):
            lines.append(_chain_row(chosen, chosen))
    if chosen is None:
        lines.append(f"  none has {need} lanes: lane_change cannot run on this network")
    else:
        lines.append(f"  lane_change takes the road marked <- lane_change: {chosen.n_lanes} lanes, {chosen.length:.0f} m, "
                     f"edges {chosen.ids[0]} to {chosen.ids[-1]} ({_count(chosen.ids, 'edge')})")
        lines.append(f"  lane_change's rightmost car lane (where cones close a lane): {_first([lane.getID() for lane in chosen.lanes(0)])}")
    return lines


def _chain_row(chain, chosen) -> str:
    """One row of the roads' table: lanes, length, edges, the classes every lane allows, and a
    mark on the chain lane_change takes."""
    allowed = set.intersection(*(set(lane.getPermissions()) for j in range(chain.n_lanes) for lane in chain.lanes(j)))
    mark = "  <- lane_change" if chosen is not None and chain.ids == chosen.ids else ""
    return f"  {chain.n_lanes:5d}  {chain.length:4.0f} m  {' '.join(chain.ids)}  [{_classes(allowed)}]{mark}"


def _classes(allowed: set[str]) -> str:
    """``allowed`` vehicle classes, or ``all but ...`` when that is shorter."""
    from sumolib.net.lane import SUMO_VEHICLE_CLASSES

    rest = set(SUMO_VEHICLE_CLASSES) - allowed
    if len(rest) < len(allowed):
        return "all but " + ", ".join(sorted(rest)) if rest else "all"
    return ", ".join(sorted(allowed))


def _pedestrians(net, edges) -> list[str]:
    walk = [e.getID() for e in edges if any(set(lane.getPermissions()) == {"pedestrian"} for lane in e.getLanes())]
    shared = [e.getID() for e in edges if e.getID() not in walk and e.allows("pedestrian")]
    crossings = [e for e in net.getEdges() if e.getFunction() == "crossing"]
    crossed = sorted({c.getID() for e in crossings for c in e.getCrossingEdges()})
    lines = [f"pedestrians: sidewalks or footpaths on {_count(walk, 'edge')}{_some(walk)}; "
             f"on the road itself on {_count(shared, 'more edge')}{_some(shared)}",
             f"  crossings: {len(crossings)}" + (f" (over {' '.join(crossed)})" if 0 < len(crossed) <= SHOWN_IDS else
                                                     f" (over {len(crossed)} edges: {_first(crossed)})" if crossed else "")]
    if not walk:
        lines.append("  walkers need sidewalks: netconvert --sidewalks.guess, or sidewalkWidth on the edges")
    if not crossings:
        lines.append("  walkers cannot cross a road: netconvert --crossings.guess, or <crossing> in a .con.xml")
    return lines


def _count(items: list, noun: str) -> str:
    return f"{len(items)} {noun}{'s' * (len(items) != 1)}"


def _some(ids: list[str]) -> str:
    return "" if not ids else f" ({_first(ids)})"


def _first(ids: list[str]) -> str:
    """The first ``SHOWN_IDS`` of ``ids``, and how many more there are (DRT's 1180 sidewalk
    edges were 1180 ids)."""
    more = len(ids) - SHOWN_IDS
    return " ".join(ids[:SHOWN_IDS]) + (f" ... and {more} more" if more > 0 else "")


def _routes(path: Path) -> list[str]:
    if not Path(path).is_file():
        raise ScenarioError(WHERE, "ROUTES", "an existing SUMO route file", str(path))
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ScenarioError(path, WHERE, f"a SUMO route file (XML: {exc})") from None
    if root.tag not in ("routes", "additional"):
        raise ScenarioError(path, WHERE, f"a SUMO route file (<routes>, found <{root.tag}>)")
    randomized: list[str] = []
    used = Counter(v.get("type", "DEFAULT_VEHTYPE") for v in root.iter() if v.tag in ("vehicle", "trip"))
    for flow in root.iter("flow"):  # its vehicles, as SUMO departs them (a randomized flow: one row, no count)
        try:
            used[flow.get("type", "DEFAULT_VEHTYPE")] += len(flow_departures(path, flow, FLOW_END))
        except RoutesError:
            randomized.append(f"  flow {flow.get('id')} (vType {flow.get('type', 'DEFAULT_VEHTYPE')}): randomized, "
                              "its vehicles are known only as SUMO departs them")
    persons = [p for p in root.iter() if p.tag in ("person", "personFlow")]
    walkers = Counter(p.get("type", "DEFAULT_PEDTYPE") for p in persons)
    lines = [f"{path}:"]
    for vt in root.iter("vType"):
        tid = vt.get("id")
        role = "  [cones: sumo.cone_types names cone by default]" if tid == "cone" else ""
        size = "".join(f", {vt.get(k)} m {k}" for k in ("length", "width") if vt.get(k))
        lines.append(f"  vType {tid} (vClass {vt.get('vClass', 'passenger')}{size}): "
                     f"{used.pop(tid, 0)} vehicles, {walkers.pop(tid, 0)} persons{role}")
    lines += [f"  vType {tid} (SUMO's default): {count} vehicles" for tid, count in used.items()]
    lines += [f"  vType {tid} (SUMO's default): {count} persons" for tid, count in walkers.items()] + randomized
    for p in persons:
        stages = [w.get("edges") or f"{w.get('from')} -> {w.get('to')}" for w in p if w.tag == "walk"]
        lines.append(f"  person {p.get('id')}: walks {', '.join(stages) or 'nowhere'}")
    return lines
