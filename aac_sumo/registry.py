"""Experiment kinds and coordinators by name, each registered with its own section of scenario
keys, so that a user adds one without editing the package; the bundled ones register the same
way, in their own modules (:data:`aac_sumo.config.keys.PROVIDERS`).

* ``register_coordinator("name", make, params=Params, kinds=(...), doc="...")`` makes
  ``controller.coordinator = "name"`` valid and the fields of ``Params`` (declared with
  :func:`aac_sumo.config.schema.param`) the keys of section ``[name]``. ``make`` is a
  :class:`~aac_sumo.coordination.base.Coordinator` subclass, built as
  ``make(planner, tasks, corridors, finished, params=from_section(Params, scenario, "name"))``
  (without ``params=`` when there is no ``Params``), or a factory
  ``make(scenario, planner, tasks, corridors, finished) -> Coordinator``. Without ``make`` it
  is a decorator.
* ``register_experiment("kind", build, keys={...} | params=Params)`` makes ``scenario.kind =
  "kind"`` valid, with section ``[kind]`` (``keys``: :class:`~aac_sumo.config.Key` by name;
  ``params``: a dataclass of ``param`` fields, which the builder reads as
  ``from_section(Params, scenario, "kind")``); ``build(scenario) -> Setup``
  (:class:`aac_sumo.experiments.common.Setup`). Without ``build`` it is a decorator. The bundled
  kinds all declare their section with ``params``.

Registering makes the name valid in every scenario loaded afterwards. The bundled components come
first in the allowed values (``aac-sumo keys``, error messages), then the others as registered.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

from aac_sumo import config
from aac_sumo.config import schema


@dataclass(frozen=True)
class RegisteredCoordinator:
    """A coordinator by name (see the module): ``kinds`` are the scenario kinds it drives (None:
    every kind); ``simulator_drives``: it plans nothing, the simulator moves the robots (the
    experiment starts its simulator in that mode); ``baseline``: a comparison method, not ours
    (the tables and stress campaigns add it where it drives the kind); ``label`` its name in tables."""

    name: str
    make: Callable
    params: type | None = None
    kinds: tuple[str, ...] | None = None
    simulator_drives: bool = False
    baseline: bool = False
    label: str = ""

    def drives(self, kind: str) -> bool:
        return self.kinds is None or kind in self.kinds

    def build(self, scenario, planner, tasks, corridors, finished):
        """The coordinator for ``scenario``: a ScenarioError naming ``controller.coordinator`` on
        a kind it does not drive."""
        if not self.drives(scenario.kind):
            raise config.ScenarioError(scenario.source, "controller.coordinator",
                                       f"{self.name} only with scenario.kind {', '.join(self.kinds)}", self.name)
        if not isinstance(self.make, type):
            return self.make(scenario, planner, tasks, corridors, finished)
        given = {} if self.params is None else {"params": schema.from_section(self.params, scenario, self.name)}
        return self.make(planner, tasks, corridors, finished, **given)


EXPERIMENTS: dict[str, Callable] = {}
#: The parameter dataclass of every section that a registered experiment declares with one (its
#: own, ``params``, and further ``sections``): ``{section: dataclass}``, the section's schema.
SECTION_PARAMS: dict[str, type] = {}
COORDINATORS: dict[str, RegisteredCoordinator] = {}


#: The choice keys as :mod:`aac_sumo.config.keys` declares them (no value allowed yet), and the
#: values registered for each: ``{value: (module, doc)}`` in registration order.
_DECLARED = {(s, k): config.COMMON[s][k] for s, k in (("scenario", "kind"), ("controller", "coordinator"))}
_CHOICES: dict[tuple[str, str], dict[str, tuple[str, str]]] = {choice: {} for choice in _DECLARED}


def _listed(module: str) -> int:
    """Where ``module`` comes in :data:`~aac_sumo.config.keys.PROVIDERS` (after them all when it is not there)."""
    return next((k for k, p in enumerate(config.PROVIDERS) if module == p or module.startswith(p + ".")), len(config.PROVIDERS))


def _allow(section: str, key: str, value: str, module: str, doc: str = "") -> None:
    """Add ``value`` (registered in ``module``) to the allowed strings of the choice key
    ``section.key``, and ``value (doc)`` to its description when ``doc`` is given. The values
    are listed in the order of PROVIDERS, then in registration order, whatever the import order."""
    choices = _CHOICES[section, key]
    choices[value] = (module, doc)
    order = sorted(choices, key=lambda v: _listed(choices[v][0]))
    declared = _DECLARED[section, key]
    docs = [f"{v} ({choices[v][1]})" for v in order if choices[v][1]]
    config.COMMON[section][key] = dataclasses.replace(declared, type=tuple(order),
                                                      doc=declared.doc + (": " + ", ".join(docs) if docs else ""))


def register_experiment(kind: str, build: Callable | None = None, *, keys: dict[str, config.Key] | None = None,
                        params: type | None = None, sections: dict[str, dict[str, config.Key] | type] | None = None):
    """Register ``build(scenario) -> Setup`` for ``scenario.kind = kind`` (see the module); a
    decorator without ``build``. Omit ``keys`` and ``params`` for a kind without keys of its own;
    ``sections`` declares further sections the kind reads (as lane_change reads ``[sumo]``), each
    a key table or a dataclass of ``param`` fields. A section keeps its place in the listings
    when :mod:`aac_sumo.config.keys` names it (``KIND_SECTIONS``), else it comes last."""

    def decorate(builder: Callable) -> Callable:
        if params is not None:
            config.KIND_SECTIONS[kind] = schema.keys_of(params)
            SECTION_PARAMS[kind] = params
        elif keys is not None or kind not in config.KIND_SECTIONS:
            config.KIND_SECTIONS[kind] = dict(keys or {})
        if sections:
            config.KIND_EXTRA_SECTIONS[kind] = {name: schema.keys_of(table) if isinstance(table, type) else dict(table)
                                                for name, table in sections.items()}
            SECTION_PARAMS.update({name: table for name, table in sections.items() if isinstance(table, type)})
        _allow("scenario", "kind", kind, builder.__module__)
        EXPERIMENTS[kind] = builder
        return builder

    return decorate if build is None else decorate(build)


def register_coordinator(name: str, make: Callable | None = None, *, params: type | None = None,
                         kinds: tuple[str, ...] | None = None, doc: str = "", simulator_drives: bool = False,
                         baseline: bool = False, label: str = ""):
    """Register coordinator ``name`` (see the module and :class:`RegisteredCoordinator`); a
    decorator without ``make``. ``doc`` describes it in ``controller.coordinator``'s meaning."""

    def decorate(made: Callable) -> Callable:
        if params is not None:
            schema.section(name)(params)
            config.declare(name)
        _allow("controller", "coordinator", name, made.__module__, doc)
        COORDINATORS[name] = RegisteredCoordinator(name, made, params, None if kinds is None else tuple(kinds),
                                                   simulator_drives, baseline, label or name)
        return made

    return decorate if make is None else decorate(make)


def coordinators() -> dict[str, RegisteredCoordinator]:
    """Every registered coordinator, the bundled ones included (loaded on first use), in the order
    of ``controller.coordinator``'s allowed values."""
    return {name: COORDINATORS[name] for name in config.common()["controller"]["coordinator"].type}


def kinds() -> tuple[str, ...]:
    """Every registered experiment kind, the bundled ones included."""
    return config.common()["scenario"]["kind"].type
