"""A robot's plan as the MPC planner returns it: states, inputs, status and solve statistics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


STATUSES = ("solved", "infeasible", "failed")


@dataclass
class Plan:
    """A robot's plan: states (N+1, 4), inputs (N, 2), status, solve wall time [ms] (every
    attempt), solver used; the iterations of the solve whose result it reports and whether that
    solve stopped at its iteration cap (``capped``, see :class:`~aac_sumo.mpc.problem.SolveOutcome`).
    The MPC brakes as hard as its constraints call for, up to ``a_min``: comfort comes from the
    references (anticipation) and the other input sources; braking beyond ``a_comfort`` is an
    emergency, counted in ``emergency_brakes``."""

    states: np.ndarray
    inputs: np.ndarray
    status: str
    solve_ms: float
    solver: str
    iterations: int = -1
    detail: str = ""
    capped: bool = False

    def shifted(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Warm start for the next period: drop the first stage, repeat the last, pin ``state``."""
        states = np.vstack([self.states[1:], self.states[-1:]])
        inputs = np.vstack([self.inputs[1:], self.inputs[-1:]])
        states[0] = state
        return states, inputs

    def comfortable_steps(self, accel: float, lateral: float, wheelbase: float, speed: float = 0.0) -> int:
        """How many of the first inputs keep |acceleration| <= ``accel`` and the lateral
        acceleration v^2 |tan(steer)| / ``wheelbase`` <= ``lateral`` [m/s^2, m] (inf: no bound),
        with v at least ``speed`` [m/s] (a steering that would not be comfortable at that speed is
        not, when the robot drives slower)."""
        v = np.maximum(np.abs(self.states[:-1, 3]), speed)
        lat = v ** 2 * np.abs(np.tan(self.inputs[:, 1])) / wheelbase
        beyond = (np.abs(self.inputs[:, 0]) > accel + 1e-6) | (lat > lateral + 1e-6)
        return int(np.argmax(beyond)) if beyond.any() else len(self.inputs)
