"""Experiment kinds and coordinators by name, so that a user can add their own without editing
the package; the bundled ones register here too (``aac_sumo.experiments``).

* ``@register_experiment("kind", keys={...})`` registers a builder ``builder(scenario) -> Setup``
  (:class:`aac_sumo.experiments.common.Setup`) for ``scenario.kind = "kind"``, with the keys of its
  own ``[kind]`` section (:class:`aac_sumo.config.Key`), checked like every other key.
* ``@register_coordinator("name")`` registers a factory
  ``factory(scenario, planner, tasks, corridors, finished) -> Coordinator``
  (:class:`aac_sumo.coordination.base.Coordinator`) for ``controller.coordinator = "name"``.

Registering makes the name a valid value of the key in every scenario loaded afterwards.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from aac_sumo import config

EXPERIMENTS: dict[str, Callable] = {}
COORDINATORS: dict[str, Callable] = {}


def _allow(section: str, key: str, value: str) -> None:
    """Add ``value`` to the allowed strings of the choice key ``section.key``."""
    declared = config.COMMON[section][key]
    if value not in declared.type:
        config.COMMON[section][key] = dataclasses.replace(declared, type=declared.type + (value,))


def register_experiment(kind: str, keys: dict[str, config.Key] | None = None,
                        sections: dict[str, dict[str, config.Key]] | None = None):
    """Decorator registering ``builder(scenario) -> Setup`` for ``scenario.kind = kind``.

    ``keys`` declares the ``[kind]`` section (omit it for a kind the schema already declares);
    ``sections`` declares further sections the kind reads (as lane_change reads ``[sumo]``)."""

    def decorate(builder: Callable) -> Callable:
        if keys is not None or kind not in config.KIND_SECTIONS:
            config.KIND_SECTIONS[kind] = dict(keys or {})
        if sections:
            config.KIND_EXTRA_SECTIONS[kind] = dict(sections)
        _allow("scenario", "kind", kind)
        EXPERIMENTS[kind] = builder
        return builder

    return decorate


def register_coordinator(name: str):
    """Decorator registering ``factory(scenario, planner, tasks, corridors, finished) -> Coordinator``
    for ``controller.coordinator = name``."""

    def decorate(factory: Callable) -> Callable:
        _allow("controller", "coordinator", name)
        COORDINATORS[name] = factory
        return factory

    return decorate
