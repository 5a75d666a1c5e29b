"""What the ``sumo`` coordinator's runs need from the road: a road lane as SUMO numbers it on
each edge, for the lane orders SUMO's driver gets (:class:`~aac_sumo.sim.sumo_options.LaneOrder`)."""

from __future__ import annotations

from aac_sumo import network


def lane_indices(net, edges, lane: int) -> dict[str, int]:
    """Road lane ``lane`` (0 = rightmost car lane, following the network's connections) of the
    chain of edge ids ``edges``, as SUMO's lane index on each edge (sidewalks count there)."""
    chain = network.chain_of(net, list(edges))
    return {edge.getID(): network.car_lanes(edge)[chain.tracks[lane][i]].getIndex() for i, edge in enumerate(chain.edges)}
