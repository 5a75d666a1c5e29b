"""Pure-numpy world: controlled bicycle robots, scripted agents and static obstacles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aac_sumo.dynamics import FleetModel
from aac_sumo.sim.base import ContactReport, Simulator, agent_rows, footprint_contacts
from aac_sumo.world import Obstacle, RobotSpec, WorldState


@dataclass
class ScriptedAgent:
    """An uncontrolled agent driving straight along ``heading`` [rad] from footprint centre
    ``centre`` [m] at ``speed`` [m/s]; from time ``t`` of each ``(t, accel)`` in ``schedule`` it
    accelerates at ``accel`` [m/s^2], never below zero speed."""

    name: str
    centre: np.ndarray
    heading: float
    speed: float
    length: float
    width: float
    schedule: tuple[tuple[float, float], ...] = ()
    kind: str = "scripted"

    def accel_at(self, t: float) -> float:
        active = [a for start, a in self.schedule if t >= start - 1e-9]
        return active[-1] if active else 0.0

    def advance(self, t: float, dt: float) -> None:
        """Exact constant-acceleration motion over [t, t + dt], stopping at zero speed."""
        a = self.accel_at(t)
        tau = dt if a >= 0 or self.speed + a * dt >= 0 else self.speed / -a
        distance = self.speed * tau + 0.5 * a * tau**2
        self.centre = self.centre + distance * np.array([np.cos(self.heading), np.sin(self.heading)])
        self.speed = max(0.0, self.speed + a * dt)

    def as_obstacle(self) -> Obstacle:
        vel = self.speed * np.array([np.cos(self.heading), np.sin(self.heading)])
        return Obstacle(self.name, self.kind, self.centre.copy(), vel, self.heading, self.length, self.width)


class InternalSimulator(Simulator):
    """Steps controlled robots with their bicycle models and scripted agents exactly, then runs
    its own footprint check. Agents whose footprints overlapped are wrecked: they stop where
    they are and ignore further inputs, so no robot drives through another."""

    def __init__(self, robots: list[RobotSpec], states: np.ndarray, dt: float,
                 scripted: list[ScriptedAgent] = (), statics: list[Obstacle] = ()):
        self.robots = list(robots)
        self.states = np.array(states, dtype=float)
        self.dt = dt
        self.scripted = list(scripted)
        self.statics = list(statics)
        self.t = 0.0
        self.wrecked: set[str] = set()
        self.model = FleetModel([r.model for r in self.robots])

    def observe(self) -> WorldState:
        obstacles = [a.as_obstacle() for a in self.scripted] + self.statics
        return WorldState(self.t, self.states.copy(), self.robots, obstacles)

    def step(self, inputs: np.ndarray) -> ContactReport:
        inputs = np.asarray(inputs, dtype=float)
        moving = np.array([r.name not in self.wrecked for r in self.robots], dtype=bool)
        self.states[moving] = self.model.step(self.states, inputs, self.dt)[moving]
        for agent in self.scripted:
            if agent.name not in self.wrecked:
                agent.advance(self.t, self.dt)
        self.t += self.dt
        report = footprint_contacts(self.observe())
        self.wrecked.update(name for pair in report.overlaps for name in pair)
        for i, robot in enumerate(self.robots):
            if robot.name in self.wrecked:
                self.states[i, 3] = 0.0
        for agent in self.scripted:
            if agent.name in self.wrecked:
                agent.speed = 0.0
        return report

    def agents(self) -> list[dict]:
        return agent_rows(self.observe())
