"""The simulator interface and the footprint check every simulator runs itself.

The check never asks the controller: it takes the true footprints after each step, measures
the exact rectangle clearance between every controlled robot and everything else, and reports
overlapping pairs. The runner counts a collision each time a pair starts to overlap.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from aac_sumo.neighbours import least_clearances
from aac_sumo.world import Crossing, WorldState


@dataclass
class ContactReport:
    """Per-step geometry facts measured by the simulator.

    ``clearance[i]`` is robot i's smallest footprint gap to anything [m] (negative = overlap),
    ``overlaps`` the set of overlapping ``(robot name, other name)`` pairs, and
    ``sim_collisions`` the simulator's own collision count this step (None if it has none).
    ``applied`` holds the inputs (n, 2) the robots actually followed this step when the
    simulator moved them itself (SUMO's own driver), None when they followed the given ones.
    """

    clearance: np.ndarray
    overlaps: set[tuple[str, str]]
    sim_collisions: int | None = None
    applied: np.ndarray | None = None


def footprint_contacts(world: WorldState) -> ContactReport:
    """Exact footprint clearances of controlled robots against robots and obstacles (every pair
    that could be the nearest or overlap: :func:`~aac_sumo.neighbours.least_clearances`)."""
    robots = world.robot_footprints()
    names = [r.name for r in world.robots]
    others = np.vstack([robots] + [o.footprint()[None, :] for o in world.obstacles])
    other_names = names + [o.name for o in world.obstacles]
    least, pairs = least_clearances(robots, others)
    overlaps = {tuple(sorted((names[i], other_names[j]))) for i, j in pairs}
    return ContactReport(least, overlaps)


def agent_rows(world: WorldState) -> list[dict]:
    """``trajectories.csv`` rows of every agent in ``world``: controlled robots on the road (kind
    ``controlled``) then obstacles (their own kind), footprint centre, heading, speed, size."""
    rows = [
        dict(name=r.name, kind="controlled", x=fp[0], y=fp[1], heading=fp[4], v=s[3], length=r.length, width=r.width)
        for r, fp, s, here in zip(world.robots, world.robot_footprints(), world.states, world.on_road) if here
    ]
    rows += [
        dict(name=o.name, kind=o.kind, x=o.centre[0], y=o.centre[1], heading=o.heading,
             v=float(np.hypot(*o.velocity)), length=o.length, width=o.width)
        for o in world.obstacles
    ]
    return rows


class Simulator(ABC):
    """Small common step interface of every world (internal, SUMO)."""

    dt: float

    @abstractmethod
    def observe(self) -> WorldState:
        """The current world as a coordinator sees it."""

    @abstractmethod
    def step(self, inputs: np.ndarray) -> ContactReport:
        """Apply ``inputs`` (n, 2) for one period ``dt`` and report the resulting contacts."""

    @abstractmethod
    def agents(self) -> list[dict]:
        """Every agent's current pose for ``trajectories.csv``: name, kind, x, y (footprint
        centre [m]), heading [rad], v [m/s], length, width [m]."""

    def crossings(self) -> list[Crossing] | None:
        """The map's pedestrian crossings (static), or None when the simulator has no map (the
        internal simulator)."""
        return None

    def show(self, authority: set[str], stopped: set[str]) -> None:
        """Mark in the simulator's GUI which robots (by name) hold authority and which are in a
        safety stop this period (nothing without a GUI)."""

    def close(self) -> None:
        """Release resources (nothing for the internal simulator)."""
