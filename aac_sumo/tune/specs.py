"""What ``aac-sumo tune`` is asked for (:mod:`aac_sumo.tune`): the tuned parameters
(``--param KEY=LO:HI[:log|:int]``), the objective (``--objective [max:]METRIC``) and the
constraints (``--constraint METRIC<op>VALUE``), parsed and checked; every mistake is a
:class:`TuneError` of one line."""

from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from aac_sumo.metrics import METRIC_KEYS
from aac_sumo.runs.sweep import SweepError


#: Metrics an objective or a constraint may name (the numeric metrics.json keys).
NUMERIC_METRICS = tuple(k for k in METRIC_KEYS if k not in ("scenario", "coordinator", "barrier", "seed"))
SCALES = ("linear", "log", "int")
OPS: dict[str, Callable[[float, float], bool]] = {
    "==": operator.eq, "<=": operator.le, ">=": operator.ge, "<": operator.lt, ">": operator.gt,
}
#: Significant digits of proposed float values (what trials.csv and best.toml show).
DIGITS = 6


class TuneError(SweepError):
    """A command-line mistake in a tuning specification (one line)."""


@dataclass(frozen=True)
class Param:
    """A tuned key and its range. ``scale``: ``linear`` (uniform), ``log`` (uniform in log10,
    lo > 0) or ``int`` (integers lo..hi, both included)."""

    key: str
    lo: float
    hi: float
    scale: str = "linear"

    def bounds(self) -> tuple:
        """The range in the optimiser's space (log10 for ``log``; ``(lo, hi, int)`` for ``int``)."""
        if self.scale == "log":
            return (math.log10(self.lo), math.log10(self.hi))
        if self.scale == "int":
            return (int(self.lo), int(self.hi), int)
        return (self.lo, self.hi)

    def value(self, u: float) -> float | int:
        """The key's value at optimiser coordinate ``u`` (clipped into the range; floats rounded
        to DIGITS significant digits)."""
        if self.scale == "int":
            return int(min(max(round(float(u)), self.lo), self.hi))
        x = 10.0 ** float(u) if self.scale == "log" else float(u)
        return min(max(float(f"{x:.{DIGITS}g}"), self.lo), self.hi)

    def coordinate(self, value: float) -> float:
        return math.log10(value) if self.scale == "log" else float(value)

    def sample(self, rng: np.random.RandomState) -> float | int:
        if self.scale == "int":
            return int(rng.randint(int(self.lo), int(self.hi) + 1))
        lo, hi = self.bounds()[:2]
        return self.value(rng.uniform(lo, hi))

    def assignment(self, value) -> str:
        """``KEY=VALUE`` for ``--set`` (a TOML literal)."""
        return f"{self.key}={value!r}" if isinstance(value, float) else f"{self.key}={value}"

    def __str__(self) -> str:
        tail = "" if self.scale == "linear" else f":{self.scale}"
        return f"{self.key}={_num_text(self.lo)}:{_num_text(self.hi)}{tail}"


def _num_text(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise TuneError(f"{where}: expected a finite number, got {text!r}")
    return value


def parse_param(text: str) -> Param:
    """``KEY=LO:HI[:log|:int]`` as a :class:`Param`; syntax and range errors raise :class:`TuneError`
    (whether KEY exists is checked against the scenario by :func:`check_params`)."""
    key, sep, spec = text.partition("=")
    key = key.strip()
    parts = [p.strip() for p in spec.split(":")]
    if not sep or not key or "." not in key or len(parts) not in (2, 3) or "" in parts[:2]:
        raise TuneError(f"--param {text!r}: expected KEY=LO:HI[:log|:int], e.g. controller.gamma=0.05:0.9")
    where = f"--param {key}"
    lo, hi = _number(parts[0], f"{where}: LO"), _number(parts[1], f"{where}: HI")
    scale = parts[2] if len(parts) == 3 else "linear"
    if scale not in SCALES:
        raise TuneError(f"{where}: scale: expected log or int (or nothing for linear), got {scale!r}")
    if lo >= hi:
        raise TuneError(f"{where}: range: expected LO < HI, got {parts[0]}:{parts[1]}")
    if scale == "log" and lo <= 0:
        raise TuneError(f"{where}: range: expected LO > 0 for a log scale, got {parts[0]}")
    if scale == "int" and not (lo.is_integer() and hi.is_integer()):
        raise TuneError(f"{where}: range: expected integer bounds for an int scale, got {parts[0]}:{parts[1]}")
    if key == "scenario.seed":
        raise TuneError(f"{where}: expected a scenario key other than the seed (use --seeds K)")
    return Param(key, lo, hi, scale)


def parse_params(texts: Iterable[str]) -> list[Param]:
    params = [parse_param(t) for t in texts]
    if not params:
        raise TuneError("tune: --param: expected at least one KEY=LO:HI[:log|:int]")
    seen: set[str] = set()
    for p in params:
        if p.key in seen:
            raise TuneError(f"--param {p.key}: expected each key once, given twice")
        seen.add(p.key)
    return params


@dataclass(frozen=True)
class Objective:
    """The metric to optimise; ``score`` turns it into a value to minimise."""

    metric: str
    maximise: bool = False

    def score(self, value: float) -> float:
        return -value if self.maximise else value

    def better(self, a: float, b: float) -> bool:
        return self.score(a) < self.score(b)

    def __str__(self) -> str:
        return f"max:{self.metric}" if self.maximise else self.metric


def _check_metric(metric: str, where: str, known: Sequence[str] | None) -> None:
    if known is not None and metric not in known:
        raise TuneError(f"{where}: {metric}: expected a numeric metric ({', '.join(known)})")


def parse_objective(text: str, known: Sequence[str] | None = NUMERIC_METRICS) -> Objective:
    """``METRIC`` (minimise), ``min:METRIC`` or ``max:METRIC`` (maximise)."""
    text = text.strip()
    maximise = text.startswith("max:")
    metric = text[4:] if maximise else text.removeprefix("min:")
    _check_metric(metric.strip(), "--objective", known)
    return Objective(metric.strip(), maximise)


@dataclass(frozen=True)
class Constraint:
    """``metric op bound``, checked on every seed's run."""

    metric: str
    op: str
    bound: float

    def holds(self, value: Any) -> bool:
        x = to_float(value)
        return math.isfinite(x) and OPS[self.op](x, self.bound)

    def __str__(self) -> str:
        return f"{self.metric}{self.op}{_num_text(self.bound)}"


_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(==|<=|>=|<|>)\s*(\S+)\s*$")


def parse_constraint(text: str, known: Sequence[str] | None = NUMERIC_METRICS) -> Constraint:
    """``METRIC==V``, ``<=``, ``>=``, ``<`` or ``>`` (``true``/``false`` count as 1/0)."""
    m = _CONSTRAINT.match(text)
    if not m:
        raise TuneError(f"--constraint {text!r}: expected METRIC<op>VALUE with op one of ==, <=, >=, <, > "
                        "(e.g. collisions==0)")
    metric, op, raw = m.groups()
    _check_metric(metric, "--constraint", known)
    bound = {"true": 1.0, "false": 0.0}.get(raw.lower())
    return Constraint(metric, op, bound if bound is not None else _number(raw, f"--constraint {metric}: VALUE"))


def to_float(value: Any) -> float:
    """A metric's value as a float; nan for a missing or non-numeric one."""
    if value is None or value == "":
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
