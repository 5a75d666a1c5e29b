"""The vehicles a SUMO user's route files will bring, read before the run: which of them the
co-simulation controls (``sumo.controlled_types``, ``sumo.controlled_ids``), when each
departs, its vType's footprint and its route's edges.

Flows are expanded as SUMO does: vehicle ``FLOW.k`` departs at ``begin + k * period`` (period
from ``period``, ``vehsPerHour``, or ``(end - begin) / number``), for ``k < number`` and before
``end`` (24 hours without ``end`` and ``number``). A randomized flow (``probability``, ``period="exp(...)"``) cannot be known in advance
and is refused for a controlled vType. Routes come from a ``<route>`` child, a ``route`` id, or
``from``/``to`` (and ``via``) edges routed on the network's shortest path, as SUMO routes a trip.
"""

from __future__ import annotations

import fnmatch
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

#: SUMO's defaults for a vType that does not set its footprint (passenger car) [m].
DEFAULT_LENGTH, DEFAULT_WIDTH = 5.0, 1.8
#: SUMO's end of a flow that gives neither ``end`` nor ``number`` [s] (24 hours).
FLOW_END = 86400.0


@dataclass(frozen=True)
class RoutedVehicle:
    """One vehicle of the route files: its id, vType, departure time [s], footprint [m] and
    route (edge ids; for a trip, its ``from``, ``via`` and ``to`` edges until routed)."""

    id: str
    vtype: str
    depart: float
    length: float
    width: float
    edges: tuple[str, ...]
    trip: bool = False


class RoutesError(ValueError):
    """A route file the co-simulation cannot read as needed; one line naming file and element."""


def _number(path: Path, element: ET.Element, name: str, default: float | None = None) -> float | None:
    text = element.get(name)
    if text is None:
        return default
    try:
        return float(text)
    except ValueError:
        raise RoutesError(f"{path}: <{element.tag} id={element.get('id')!r}> {name}: expected a number of seconds, got {text!r}") from None


def read_routes(paths: list[Path], until: float) -> list[RoutedVehicle]:
    """Every vehicle, trip and flow vehicle in the route (or additional) files ``paths`` that
    departs before ``until`` [s], in departure order (ties: file order)."""
    vtypes: dict[str, tuple[float, float]] = {"DEFAULT_VEHTYPE": (DEFAULT_LENGTH, DEFAULT_WIDTH)}
    routes: dict[str, tuple[str, ...]] = {}
    found: list[RoutedVehicle] = []
    for path in paths:
        try:
            root = ET.parse(path).getroot()
        except (ET.ParseError, OSError) as exc:
            raise RoutesError(f"{path}: expected a SUMO route file (XML): {str(exc).splitlines()[0]}") from None
        for element in root.iter("vType"):
            vtypes[element.get("id", "")] = (_number(path, element, "length", DEFAULT_LENGTH), _number(path, element, "width", DEFAULT_WIDTH))
        for element in root.iter("route"):
            if element.get("id") is not None:
                routes[element.get("id")] = tuple(element.get("edges", "").split())
        for element in root:
            if element.tag in ("vehicle", "trip", "flow"):
                found += _expand(path, element, routes, vtypes, until)
    return sorted(found, key=lambda v: v.depart)


def _route(path: Path, element: ET.Element, routes: dict) -> tuple[tuple[str, ...], bool]:
    child = element.find("route")
    if child is not None:
        return tuple(child.get("edges", "").split()), False
    ref = element.get("route")
    if ref is not None:
        if ref not in routes:
            raise RoutesError(f"{path}: <{element.tag} id={element.get('id')!r}> route: expected a <route> defined before it, got {ref!r}")
        return routes[ref], False
    ends = [element.get("from")] + element.get("via", "").split() + [element.get("to")]
    if ends[0] is None or ends[-1] is None:
        raise RoutesError(f"{path}: <{element.tag} id={element.get('id')!r}>: expected a route (a <route> child, route=, or from= and to=)")
    return tuple(ends), True


def _expand(path: Path, element: ET.Element, routes: dict, vtypes: dict, until: float) -> list[RoutedVehicle]:
    vid, vtype = element.get("id", ""), element.get("type", "DEFAULT_VEHTYPE")
    length, width = vtypes.get(vtype, (DEFAULT_LENGTH, DEFAULT_WIDTH))
    edges, trip = _route(path, element, routes)
    if element.tag != "flow":
        depart = _number(path, element, "depart", 0.0)
        return [RoutedVehicle(vid, vtype, depart, length, width, edges, trip)] if depart < until else []
    return [RoutedVehicle(f"{vid}.{k}", vtype, depart, length, width, edges, trip)
            for k, depart in enumerate(flow_departures(path, element, until))]


def flow_departures(path: Path, element: ET.Element, until: float) -> list[float]:
    """Departure times [s] of the vehicles of the ``<flow>`` ``element`` of file ``path``
    before ``until`` [s]; ``RoutesError`` for a randomized flow."""
    vid = element.get("id", "")
    if element.get("probability") is not None or "exp" in (element.get("period") or ""):
        raise RoutesError(f"{path}: <flow id={vid!r}>: expected number, period or vehsPerHour (a randomized flow's "
                          "vehicles cannot be known before the run)")
    begin = _number(path, element, "begin", 0.0)
    number = _number(path, element, "number")
    end = _number(path, element, "end")
    period = _number(path, element, "period")
    if period is None and element.get("vehsPerHour") is not None:
        period = 3600.0 / max(_number(path, element, "vehsPerHour"), 1e-9)
    if period is None and number is not None and end is not None:
        period = (end - begin) / max(number, 1.0)
    if period is None or period <= 0.0:
        raise RoutesError(f"{path}: <flow id={vid!r}>: expected a positive period, vehsPerHour, or number with end")
    count = int(number) if number is not None else 10**9
    last = min(end if end is not None else FLOW_END if number is None else float("inf"), until)
    out = []
    for k in range(count):
        depart = begin + k * period
        if depart >= last:
            break
        out.append(depart)
    return out


def controlled(vehicles: list[RoutedVehicle], types: list[str], ids: list[str]) -> list[RoutedVehicle]:
    """The vehicles whose vType is one of ``types`` or whose id matches one of the globs ``ids``."""
    return [v for v in vehicles if v.vtype in types or any(fnmatch.fnmatchcase(v.id, pattern) for pattern in ids)]
