"""The declared scenario keys: :class:`Key` (type, default, check, doc), the keys of
``[scenario]`` (the config's own) and of ``controller.coordinator`` (a registry choice), and the
sections in the order of the listings: ``COMMON`` (every kind's sections), ``KIND_SECTIONS`` (a
kind's own section) and ``KIND_EXTRA_SECTIONS`` (further sections a kind reads, as lane_change
reads ``[sumo]``).

Every other section is not written here: its parameter dataclass declares it
(:mod:`aac_sumo.config.schema`) in the module that uses it, named in :data:`PROVIDERS` or found
in :data:`PLUGINS`: ``[controller]`` (``MpcConfig``, ``Anticipation``), ``[robot]``
(``RobotParams``), ``[aac]``, ``[lfc]``, ``[orca]``, ``[cbf_qp]`` (their coordinators' params),
``[metrics]`` (``MetricsParams``), and through :func:`aac_sumo.registry.register_experiment`
each kind's own section and ``[sumo]`` (``SumoParams``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable


class ScenarioError(Exception):
    """A scenario problem the user must fix; ``str()`` is one line: file, key, expectation."""

    def __init__(self, file, key: str, expected: str, got: Any = None):
        self.file, self.key, self.expected = str(file), key, expected
        tail = "" if got is None else f", got {got!r}"
        super().__init__(f"{self.file}: {key}: expected {expected}{tail}")


@dataclass(frozen=True)
class Key:
    """A declared key: its type (``float``, ``int``, ``bool``, ``str``, or a tuple of allowed
    strings), default, optional extra check and a description of the expected value."""

    type: type | tuple[str, ...]
    default: Any
    doc: str
    check: Callable[[Any], bool] | None = None
    expect: str = ""

    def expected(self) -> str:
        if isinstance(self.type, tuple):
            return "one of " + ", ".join(self.type)
        if self.type is object:
            return self.expect
        base = {float: "a number", int: "an integer", bool: "true or false", str: "a string", list: "a list"}[self.type]
        return f"{base} {self.expect}".strip()

    def validate(self, value: Any) -> Any:
        """The value converted to the key's type, or ``ValueError``."""
        if isinstance(self.type, tuple):
            ok = isinstance(value, str) and value in self.type
        elif self.type is object:  # any value its check accepts
            ok = True
        elif self.type is float:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            value = float(value) + 0.0 if ok else value  # + 0.0: a negative zero is zero (numpy's uniform(-x, x) refuses x = -0.0)
        elif self.type is int:
            ok = isinstance(value, int) and not isinstance(value, bool)
        else:
            ok = isinstance(value, self.type)
        if not ok or (self.check is not None and not self.check(value)):
            raise ValueError(self.expected())
        return value


def _positive(x):
    return x > 0


def _non_negative(x):
    return x >= 0


def rows(*fields: str) -> dict:
    """Key options for a list of number rows, one per item, each ``[field, ...]``."""

    def check(value) -> bool:
        return all(isinstance(r, list) and len(r) == len(fields)
                   and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in r)
                   for r in value)

    return dict(check=check, expect=f"of [{', '.join(fields)}] rows")


P = dict(check=_positive, expect="> 0")
#: Upper bounds that keep a typo (``n_robots=1000000000``) from hanging a run or exhausting memory.
MAX_ROBOTS = 200
#: The random crossing's own bound: its draw and its clusters were measured at 1,000 robots (docs/benchmarks.md).
MAX_CROSSING_ROBOTS = 1_000
MAX_SEED = 2**31 - 1
NN = dict(check=_non_negative, expect=">= 0")

COMMON: dict[str, dict[str, Key]] = {
    "scenario": {
        "name": Key(str, "unnamed", "label written into metrics.json"),
        "kind": Key((), "braking", "which experiment builds the world"),  # the allowed kinds: registered (registry.py)
        "seed": Key(int, 0, "seed of every random choice in the run (SUMO's seed is a 32-bit integer)",
                    check=lambda s: 0 <= s <= MAX_SEED, expect=f"in 0..{MAX_SEED}"),
        "dt": Key(float, 0.1, "control period and simulation step [s]", check=lambda dt: 0.001 <= dt <= 1.0, expect="in [0.001, 1]"),
        "duration": Key(float, 20.0, "time limit, at most a day [s]", check=lambda d: 0 < d <= 86400.0, expect="in (0, 86400]"),
    },
    "controller": {  # the allowed coordinators and their meanings: registered (registry.py)
        "coordinator": Key((), "aac", "who plans when"),
    },
    "robot": {},  # declared by RobotParams (experiments/common.py)
    "aac": {},  # sections declared by parameter dataclasses (schema.py, PROVIDERS) are filled on first use
    "lfc": {},
    "metrics": {},  # declared by MetricsParams (metrics.py)
}

#: The baselines' sections: ORCA (aac_sumo/coordination/orca.py, docs/baselines.md) and CBF-QP
#: (aac_sumo/coordination/cbf_qp.py, docs/baselines_cbf_qp.md), declared by their parameter dataclasses.
COMMON["orca"] = {}
COMMON["cbf_qp"] = {}

#: The modules that declare sections (``@schema.section``) and register experiment kinds and
#: coordinators (:mod:`aac_sumo.registry`), in the order of the listings (``aac-sumo keys``, the
#: allowed values of ``scenario.kind`` and ``controller.coordinator``); the config imports them
#: by name on first use of the schema (:func:`aac_sumo.config.common`), then every other module
#: of the ``PLUGINS`` packages, so that a new module there registers without being listed.
PROVIDERS = ("aac_sumo.metrics", "aac_sumo.mpc.settings", "aac_sumo.coordination.anticipation", "aac_sumo.coordination.aac",
             "aac_sumo.coordination.lfc", "aac_sumo.coordination.independent", "aac_sumo.coordination.sumo_driver",
             "aac_sumo.coordination.orca", "aac_sumo.coordination.cbf_qp", "aac_sumo.experiments.braking",
             "aac_sumo.experiments.swarm", "aac_sumo.experiments.lane_change", "aac_sumo.experiments.random_crossing",
             "aac_sumo.experiments.city")
PLUGINS = ("aac_sumo.coordination", "aac_sumo.experiments")

#: Each kind's own section, declared by the parameter dataclass its module registers
#: (:func:`aac_sumo.registry.register_experiment` ``params``); named here in the order of the
#: listings (``aac-sumo keys``), whatever the import order.
KIND_SECTIONS: dict[str, dict[str, Key]] = {kind: {} for kind in ("braking", "swarm_rescue", "circle_swap", "random_crossing",
                                                                    "lane_change", "city")}
#: Sections beyond COMMON and the kind's own that a kind uses, ``{kind: {section: keys}}``: each
#: declared by the dataclass the kind registers (``register_experiment(sections=...)``; lane_change's
#: ``[sumo]`` by :class:`aac_sumo.sim.sumo_options.SumoParams`).
KIND_EXTRA_SECTIONS: dict[str, dict[str, dict[str, Key]]] = {}
