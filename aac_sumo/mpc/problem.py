"""The MPC-FCBF optimal control problem (paper eq. 25), built once per shape and solved many times.

Decision variables are ordered stage by stage, ``[Z0, U0, Z1, U1, ..., Z_N]``, and constraints
likewise, so structure-exploiting solvers (fatrop) see an optimal-control problem. Each stage
state ``Z_k = [x, y, heading, v, m_accel, m_steer]`` carries the input ``m_k`` applied before
stage k (``m_{k+1} = U_k``), so the input-change cost ``S (U_k - m_k)^2`` is a stage cost: fatrop
sees the Hessian only in stage blocks, and a cost coupling ``U_k`` with ``U_{k-1}`` directly would
lose its cross terms (the solver then crawled to its iteration cap). The measured initial state
and the previous input pin ``Z0`` through the variable bounds. Everything else that changes between
solves (reference, weights, wheelbase,
gamma, ego disc offsets, obstacle ellipses per stage, the lateral band of the rear axle per
stage, the vehicle's lateral-acceleration and steering-rate limits, the terminal stopping
regions and the ego's braking for them) is a parameter.

The terminal stopping condition: from its stage-N state the ego brakes at ``stop_decel`` = b along
its heading, which takes at most ``(v + b dt / 2)^2 / (2 b)`` metres in the explicit Euler model
(for v >= 0; the bound is attained where ``v / (b dt) + 1/2`` is a whole number). Each covering
disc must stop short of every slot's terminal region, the region an obstacle occupies where it
could stop at the earliest (see :func:`~aac_sumo.barriers.stopping_barrier`).
"""

from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import casadi as ca
import numpy as np

from aac_sumo.barriers import N_STAGE_FIELDS, N_TERMINAL_FIELDS, barrier_value, stopping_barrier
from aac_sumo.dynamics import NU, NX, bicycle_step
from aac_sumo.mpc.codegen import compile_library

SOLVERS = ("fatrop", "sqp", "ipopt")
#: The weight vector's parts, in order, defined once: the diagonals of Q on the ``[x, y, heading,
#: v]`` errors, R on ``[accel, steer]``, S on input changes and the terminal P (same rows as Q).
#: :meth:`MpcConfig.weights` fills it by these names and the cost reads it by them.
WEIGHT_PARTS = (("q", 4), ("r", 2), ("s", 2), ("p", 4))
WEIGHTS = {name: slice(sum(n for _, n in WEIGHT_PARTS[:i]), sum(n for _, n in WEIGHT_PARTS[:i + 1]))
           for i, (name, _) in enumerate(WEIGHT_PARTS)}
N_WEIGHTS = sum(n for _, n in WEIGHT_PARTS)
assert N_WEIGHTS == 12 and WEIGHTS["p"] == slice(8, 12)
NZ = NX + NU  # stage state: the robot's state and the input applied before the stage


@dataclass(frozen=True)
class ProblemShape:
    """What a compiled problem is specialised for."""

    horizon: int
    slots: int
    discs: int
    solver: str
    dt: float
    max_iter: int = 100
    max_cpu_time: float = 1.0
    codegen: bool = False
    band: bool = False  # with the lateral band rows (two inequalities per stage)
    terminal: bool = False  # with the terminal stopping rows (one per slot and disc)


@dataclass
class SolveOutcome:
    """Raw result of one solve: states (N+1, 4), inputs (N, 2), status, wall time [ms], iterations,
    the solver's detail, and whether the solver stopped at its iteration cap (``max_iter``)
    without converging: such a solve whose iterate is feasible is still ``solved``."""

    states: np.ndarray
    inputs: np.ndarray
    status: str
    solve_ms: float
    iterations: int
    detail: str
    capped: bool = False


#: Per-stage lateral band layout: unit normal (nx, ny) and bounds (lo, hi) on nx*x + ny*y [m].
BAND_FIELDS = 4
#: Band row that constrains nothing.
OPEN_BAND = (0.0, 0.0, -1e9, 1e9)
#: Vehicle-limit parameters: the lateral-acceleration limit [m/s^2] and the steering change allowed
#: per period [rad]; each bounds its quantity on both sides at every stage (``LIMIT_ROWS`` rows).
N_LIMITS = 2
LIMIT_ROWS = 4
#: What stands for "no limit" in those parameters (the solvers want finite constraint values).
NO_LIMIT = 1e6
#: Smoothing [m^2/s^2] of |v| in the terminal stopping distance ``v (sqrt(v^2 + eps) / (2 b) + dt / 2) + b dt^2 / 8``.
STOP_EPS = 1e-4


class MpcProblem:
    """One compiled MPC-FCBF problem. Build with :func:`get_problem` so each shape is built once."""

    def __init__(self, shape: ProblemShape):
        self.shape = shape
        n, slots, discs = shape.horizon, shape.slots, shape.discs
        self.n_w = (n + 1) * NZ + n * NU
        index = np.arange(self.n_w)
        z_index = np.array([index[self._z_index(k)] for k in range(n + 1)])
        #: Positions in the decision vector of the states (N+1, NX), the carried inputs m (N+1, NU)
        #: and the inputs U (N, NU), so that packing and unpacking are single indexing operations.
        self.state_index, self.carried_index = z_index[:, :NX], z_index[:, NX:]
        self.input_index = np.array([index[self._u_index(k)] for k in range(n)]).reshape(n, NU)
        self.param_sizes = {
            "wheelbase": 1,
            "gamma": 1,
            "disc_offsets": discs,
            "weights": N_WEIGHTS,
            "x_ref": (n + 1) * NX,
            "obstacles": (n + 1) * slots * N_STAGE_FIELDS,
            "band": n * BAND_FIELDS if shape.band else 0,
            "limits": N_LIMITS,
            "terminal": slots * N_TERMINAL_FIELDS if shape.terminal else 0,
            "stop_decel": 1 if shape.terminal else 0,
        }
        self.equality = constraint_kinds(shape)
        self.n_g = len(self.equality)
        self._lbg = np.zeros(self.n_g)
        self._ubg = np.where(self.equality, 0.0, np.inf)
        plugin, options = _solver_plugin(shape), _solver_options(shape, self.equality)
        library = library_path(shape) if shape.codegen else None
        if library is not None and library.exists():  # compiled before: no need to build the problem again
            self.solver = ca.nlpsol("mpc", plugin, str(library), options)
        else:
            w, p, cost, g = self._symbolic()
            self.solver = ca.nlpsol("mpc", plugin, {"x": w, "p": p, "f": cost, "g": g}, options)
            if library is not None:
                compile_library(self.solver, library)
                self.solver = ca.nlpsol("mpc", plugin, str(library), options)
        self._bind()

    def _bind(self) -> None:
        """Bind one numpy array to each of the solver's inputs and outputs (casadi's
        ``FunctionBuffer``): a solve writes its inputs there, evaluates and reads its results
        there, with the same results as a call by keywords, without that call's conversions
        (0.25 ms a solve at N = 15, a quarter of it; ``docs/benchmarks.md``)."""
        solver = self.solver
        self._in = {name: np.zeros(solver.numel_in(k)) for k, name in enumerate(solver.name_in())}
        self._out = {name: np.zeros(solver.numel_out(k)) for k, name in enumerate(solver.name_out())}
        self._buffer, self._evaluate = solver.buffer()
        for k, name in enumerate(solver.name_in()):
            self._buffer.set_arg(k, memoryview(self._in[name]))
        for k, name in enumerate(solver.name_out()):
            self._buffer.set_res(k, memoryview(self._out[name]))
        self._in["lbg"][:], self._in["ubg"][:] = self._lbg, self._ubg

    def __deepcopy__(self, memo) -> "MpcProblem":
        """A fresh problem of the same shape, never a shared solver: solvers keep state from one
        solve to the next, so a copy that shared them would change what the original solves."""
        return MpcProblem(self.shape)

    def _symbolic(self) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
        """Decision vector, parameter vector, cost and constraints (in :func:`constraint_kinds`'
        order) as casadi SX expressions."""
        shape = self.shape
        n, slots, discs = shape.horizon, shape.slots, shape.discs
        p = ca.SX.sym("p", sum(self.param_sizes.values()))
        par = self._split(p)
        w = ca.SX.sym("w", self.n_w)
        zs = [w[self._z_index(k)] for k in range(n + 1)]
        xs, ms = [z[:NX] for z in zs], [z[NX:] for z in zs]
        us = [w[self._u_index(k)] for k in range(n)]
        weights = par["weights"]
        q, r, s, pw = (weights[WEIGHTS[name]] for name in ("q", "r", "s", "p"))
        x_ref = ca.reshape(par["x_ref"], NX, n + 1)
        obstacles = ca.reshape(par["obstacles"], N_STAGE_FIELDS, (n + 1) * slots)
        band = ca.reshape(par["band"], BAND_FIELDS, n) if shape.band else None
        lateral, rate = par["limits"][0] * par["wheelbase"], par["limits"][1]

        cost = 0
        g = []
        for k in range(n):
            err = xs[k] - x_ref[:, k]
            du = us[k] - ms[k]
            cost += ca.dot(q, err**2) + ca.dot(r, us[k] ** 2) + ca.dot(s, du**2)
            x_next = bicycle_step(xs[k], us[k], shape.dt, par["wheelbase"], xp=ca)
            g.append(zs[k + 1] - ca.vertcat(x_next, us[k]))
            # barrier condition of stage k depends on (x_k, u_k) only
            for slot in range(slots):
                ob_now = obstacles[:, k * slots + slot]
                ob_next = obstacles[:, (k + 1) * slots + slot]
                for disc in range(discs):
                    h_now = self._disc_barrier(xs[k], par["disc_offsets"][disc], ob_now)
                    h_next = self._disc_barrier(x_next, par["disc_offsets"][disc], ob_next)
                    active = ob_next[6]
                    g.append(active * (h_next - (1 - par["gamma"]) * h_now) + (1 - active))
            if band is not None:  # lateral band of the rear axle at stage k+1: lo <= n . p <= hi
                across = band[0, k] * x_next[0] + band[1, k] * x_next[1]
                g += [across - band[2, k], band[3, k] - across]
            # vehicle limits: lateral acceleration v^2 |tan(steer)| / L and steering change per period
            turn = xs[k][3] ** 2 * ca.tan(us[k][1])
            g += [lateral - turn, lateral + turn, rate - du[1], rate + du[1]]
        err = xs[n] - x_ref[:, n]
        cost += ca.dot(pw, err**2)
        if shape.terminal:
            # terminal stopping condition: braking at stop_decel from stage N, each disc stops short of
            # each slot's terminal region (where that obstacle could stop at the earliest)
            terminal = ca.reshape(par["terminal"], N_TERMINAL_FIELDS, slots)
            v_n = xs[n][3]
            speed_n = ca.sqrt(v_n**2 + STOP_EPS)
            stop = v_n * (0.5 * speed_n / par["stop_decel"] + 0.5 * shape.dt) + par["stop_decel"] * shape.dt**2 / 8
            ux, uy = ca.cos(xs[n][2]), ca.sin(xs[n][2])
            for slot in range(slots):
                ob = terminal[:, slot]
                for disc in range(discs):
                    offset = par["disc_offsets"][disc]
                    h = stopping_barrier(xs[n][0] + offset * ux, xs[n][1] + offset * uy, ux, uy, stop,
                                         *(ob[i] for i in range(6)), ob[7], ob[8], xp=ca)
                    g.append(ob[6] * h + (1 - ob[6]))
        g = ca.cse(ca.vertcat(*g))
        assert g.shape[0] == self.n_g, "constraints out of step with constraint_kinds"
        return w, p, cost, g

    def _split(self, p):
        out, i = {}, 0
        for name, size in self.param_sizes.items():
            out[name] = p[i : i + size]
            i += size
        return out

    def _z_index(self, k: int) -> slice:
        start = k * (NZ + NU)
        return slice(start, start + NZ)

    def _u_index(self, k: int) -> slice:
        start = k * (NZ + NU) + NZ
        return slice(start, start + NU)

    @staticmethod
    def _disc_barrier(state, offset, ob):
        px = state[0] + offset * ca.cos(state[2])
        py = state[1] + offset * ca.sin(state[2])
        return barrier_value(px, py, ob[0], ob[1], ob[2], ob[3], ob[4], ob[5])

    def pack(self, states: np.ndarray, inputs: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        """Decision vector from states (N+1, 4), inputs (N, 2) and the input applied before them."""
        w = np.empty(self.n_w)
        w[self.state_index] = states
        w[self.carried_index[0]] = u_prev
        w[self.carried_index[1:]] = inputs
        w[self.input_index] = inputs
        return w

    def unpack(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (N+1, 4) and inputs (N, 2) from a decision vector."""
        return w[self.state_index], w[self.input_index]

    def parameters(self, **values) -> np.ndarray:
        """Concatenate named parameter blocks (see ``param_sizes``) into the parameter vector."""
        parts = []
        for name, size in self.param_sizes.items():
            block = np.asarray(values[name], dtype=float).ravel()
            if block.size != size:
                raise ValueError(f"parameter {name} has {block.size} values, expected {size}")
            parts.append(block)
        return np.concatenate(parts)

    def bounds(self, x0, u_prev, lower_state, upper_state, lower_input, upper_input) -> tuple[np.ndarray, np.ndarray]:
        """Variable bounds: ``Z0`` pinned to the measured state ``x0`` and the previous input
        ``u_prev``, then per-state (4,) and per-input (2,) limits on the later stages (the
        carried inputs are bounded by the inputs they copy)."""
        lbx, ubx = (self.pack(np.broadcast_to(state, self.state_index.shape), np.broadcast_to(inputs, self.input_index.shape), u_prev)
                    for state, inputs in ((lower_state, lower_input), (upper_state, upper_input)))
        lbx[self.state_index[0]] = ubx[self.state_index[0]] = x0
        lbx[self.carried_index[1:]], ubx[self.carried_index[1:]] = -np.inf, np.inf
        return lbx, ubx

    def solve(self, params: np.ndarray, w0: np.ndarray, lbx: np.ndarray, ubx: np.ndarray) -> SolveOutcome:
        """Solve once from the initial guess ``w0``; never raises on solver failure. A problem
        with a NaN among its parameters, its guess or its bounds is not handed to the solver
        (it fails at once): handed to fatrop (casadi 3.8.2), such a solve either never returned
        or left every later solve of the problem failing at its first iteration."""
        start = time.perf_counter()
        try:
            if np.isnan(params).any() or np.isnan(w0).any() or np.isnan(lbx).any() or np.isnan(ubx).any():
                raise RuntimeError("NaN in the problem's parameters, guess or bounds")
            self._in["x0"][:], self._in["p"][:], self._in["lbx"][:], self._in["ubx"][:] = w0, params, lbx, ubx
            self._evaluate()
            w, g = self._out["x"].copy(), self._out["g"].copy()
            stats = self._buffer.stats()
            detail = str(stats.get("return_status", ""))
            feasible = self._satisfies(w, g, lbx, ubx)
            status = _classify(stats, detail)
            if status == "solved" and not feasible:
                status, detail = "failed", f"{detail} (constraint check failed)"
            elif status != "solved" and feasible:  # stopped early at a verified-feasible iterate
                status, detail = "solved", f"suboptimal: {detail}"
            iterations = int(stats.get("iter_count", -1))
            capped = _capped(stats, iterations, self.shape.max_iter)
        except RuntimeError as exc:  # casadi raises on evaluation errors (NaN, etc.)
            w, status, detail, iterations, capped = w0, "failed", str(exc).splitlines()[0], -1, False
        solve_ms = (time.perf_counter() - start) * 1e3
        states, inputs = self.unpack(w)
        return SolveOutcome(states, inputs, status, solve_ms, iterations, detail, capped)

    def _satisfies(self, w, g, lbx, ubx, tol: float = 1e-6) -> bool:
        """Every constraint and bound holds within ``tol`` and the iterate is finite."""
        ok_g = np.all(g >= self._lbg - tol) and np.all(g <= self._ubg + tol)
        ok_x = np.all(w >= lbx - tol) and np.all(w <= ubx + tol)
        return bool(ok_g and ok_x and np.all(np.isfinite(w)))


def _classify(stats: dict, detail: str) -> str:
    if stats.get("success", False):
        return "solved"
    if "nfeasib" in detail:  # Infeasible_Problem_Detected, Local infeasibility, ...
        return "infeasible"
    return "failed"


def _capped(stats: dict, iterations: int, max_iter: int) -> bool:
    """The solver stopped at its iteration cap without converging. ipopt and sqpmethod then
    report ``max_iter`` iterations (``Maximum_Iterations_Exceeded``), fatrop ``max_iter + 1``
    (it counts its starting point); a time limit or another failure stops them earlier."""
    return not stats.get("success", False) and iterations >= max_iter


def _solver_plugin(shape: ProblemShape) -> str:
    return {"fatrop": "fatrop", "sqp": "sqpmethod", "ipopt": "ipopt"}[shape.solver]


def cache_dir() -> Path:
    """Where compiled problems are kept: ``$AAC_SUMO_CACHE`` or ``~/.cache/aac-sumo``."""
    return Path(os.environ.get("AAC_SUMO_CACHE", Path.home() / ".cache" / "aac-sumo"))


def constraint_kinds(shape: ProblemShape) -> list[bool]:
    """Whether each constraint row is an equality, stage by stage: the NZ dynamics rows, then
    one barrier condition per slot and ego disc, then the two lateral-band rows if any, then
    the ``LIMIT_ROWS`` vehicle-limit rows; after the last stage, if the shape has them, one
    terminal stopping condition per slot and ego disc."""
    stage = [True] * NZ + [False] * (shape.slots * shape.discs) + ([False, False] if shape.band else []) + [False] * LIMIT_ROWS
    return stage * shape.horizon + [False] * (shape.slots * shape.discs if shape.terminal else 0)


#: The modules whose code defines the symbolic problem and how it is compiled: a compiled library
#: is reused only while they, the shape and casadi's version are unchanged.
_PROBLEM_SOURCES = (Path(__file__), Path(barrier_value.__code__.co_filename), Path(bicycle_step.__code__.co_filename),
                    Path(compile_library.__code__.co_filename))


def library_path(shape: ProblemShape) -> Path:
    """Where the compiled functions of ``shape``'s problem are cached: under a hash of the shape,
    casadi's version and the problem's source code, so a cached library is found without
    building the problem again."""
    key = repr(shape).encode() + ca.__version__.encode() + b"".join(p.read_bytes() for p in _PROBLEM_SOURCES)
    return cache_dir() / f"mpc_{hashlib.sha256(key).hexdigest()[:16]}.so"


def _solver_options(shape: ProblemShape, equality: list[bool]) -> dict:
    common = {"print_time": False, "error_on_fail": False}
    if shape.solver == "ipopt":
        return common | {
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "max_iter": shape.max_iter,
                "max_cpu_time": shape.max_cpu_time,
                "tol": 1e-6,
                "acceptable_tol": 1e-4,
                "mu_strategy": "adaptive",
            }
        }
    if shape.solver == "fatrop":
        return common | {
            "structure_detection": "auto",
            "equality": equality,
            "fatrop": {"print_level": 0, "max_iter": shape.max_iter, "tol": 1e-6, "mu_init": 1e-3},
        }
    if shape.solver == "sqp":
        return common | {
            "qpsol": "qrqp",
            "qpsol_options": {"print_iter": False, "print_header": False, "error_on_fail": False},
            "max_iter": shape.max_iter,
            "print_header": False,
            "print_iteration": False,
            "print_status": False,
            "hessian_approximation": "exact",
            "convexify_strategy": "eigen-clip",
        }
    raise ValueError(f"unknown solver {shape.solver!r}; expected one of {SOLVERS}")


@lru_cache(maxsize=None)
def get_problem(shape: ProblemShape) -> MpcProblem:
    """The compiled problem for ``shape``, built on first use and cached until ``cache_clear()``.

    The solver keeps state from one solve to the next (a run's result would depend on what the
    process solved before), so the runner clears this cache at the start of every run."""
    return MpcProblem(shape)
