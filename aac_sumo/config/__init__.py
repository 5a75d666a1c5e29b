"""Scenario files: a TOML schema where every key is declared, typed, checked and documented.

A scenario is a TOML file of sections (``[scenario]``, ``[controller]``, ``[robot]``,
``[metrics]`` and one section named after the scenario's ``kind``). Keys left out take the
defaults declared by the sections' parameter dataclasses (:mod:`aac_sumo.config.schema`; ``[scenario]``
in :mod:`aac_sumo.config.keys`); any key not declared is an error. ``--set section.key=value`` overrides a
key after loading, with the same type checks. Every error is a :class:`ScenarioError` whose
message is one line naming the file, the key and what was expected.
"""

from __future__ import annotations

import copy
import difflib
import importlib
import pkgutil
import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from aac_sumo.config import package_data, schema
from aac_sumo.config.keys import COMMON, KIND_EXTRA_SECTIONS, KIND_SECTIONS, PLUGINS, PROVIDERS, Key, ScenarioError

#: The bundled scenarios (:mod:`aac_sumo.config.package_data`: an installed wheel's package data, or the checkout's ``scenarios/``).
BUNDLED_DIR = package_data.scenarios_dir()


_completed = False


def common() -> dict[str, dict[str, Key]]:
    """``COMMON`` with what the package's components declare: the first time, the modules of
    ``PROVIDERS`` and then every other module of the ``PLUGINS`` packages are imported (by name:
    they sit above this layer), and so register their experiment kinds and coordinators
    (:mod:`aac_sumo.registry`) and declare the sections of their parameter dataclasses."""
    global _completed
    if not _completed:
        _completed = True  # not again while they are imported (a registration in them does not reload them)
        try:
            for module in PROVIDERS:
                importlib.import_module(module)
            for package in PLUGINS:
                for found in pkgutil.walk_packages(importlib.import_module(package).__path__, package + "."):
                    importlib.import_module(found.name)
        except BaseException:
            _completed = False  # a module that failed to import: the next use tries again and says why
            raise
        for name in schema.SECTIONS:
            declare(name)
    return COMMON


def declare(name: str) -> None:
    """Section ``[name]`` of ``COMMON`` with the keys its dataclasses declare (:func:`schema.section`)."""
    COMMON[name] = dict(COMMON.get(name, {})) | schema.section_keys(name)


class Scenario:
    """A validated scenario: nested ``{section: {key: value}}`` plus where it came from."""

    def __init__(self, data: dict[str, dict[str, Any]], source: str):
        self.data = data
        self.source = source

    @property
    def kind(self) -> str:
        return self.data["scenario"]["kind"]

    def __getitem__(self, dotted: str) -> Any:
        section, key = dotted.split(".", 1)
        return self.data[section][key]

    def schema(self) -> dict[str, dict[str, Key]]:
        return schema_for(self.kind)

    def with_overrides(self, assignments: list[str], flag: str = "--set") -> "Scenario":
        """A copy with ``section.key=value`` assignments applied and type-checked; errors name
        the command-line ``flag`` they came from."""
        data = copy.deepcopy(self.data)
        where = f"{self.source} {flag}"
        for text in assignments:
            dotted, sep, raw = text.partition("=")
            if not sep:
                raise ScenarioError(self.source, text, "--set KEY=VALUE")
            schema = schema_for(data["scenario"]["kind"])
            section, key = _lookup(schema, dotted.strip(), where)
            data[section][key] = _check(schema, section, key, parse_value(raw.strip(), schema[section][key]), where)
            if (section, key) == ("scenario", "kind"):  # the new kind's sections, defaults where the data has none
                data = {s: data.get(s, _defaults(keys)) for s, keys in schema_for(data["scenario"]["kind"]).items()}
        return Scenario(data, self.source)

    @classmethod
    def from_dict(cls, raw: dict[str, dict[str, Any]], source: str = "<dict>") -> "Scenario":
        """A scenario from nested ``{section: {key: value}}`` as a TOML file would hold it:
        validated, defaults filled; ``source`` names it in errors."""
        head, declared = raw.get("scenario"), common()["scenario"]["kind"]
        kind = head.get("kind", declared.default) if isinstance(head, dict) else declared.default
        if not isinstance(kind, str) or kind not in declared.type:
            raise ScenarioError(source, "scenario.kind", declared.expected(), kind)
        schema = schema_for(kind)
        data = {section: _defaults(keys) for section, keys in schema.items()}
        for section, table in raw.items():
            if section not in schema:
                raise ScenarioError(source, section, "a section among " + ", ".join(schema) + _did_you_mean(section, schema))
            if not isinstance(table, dict):
                raise ScenarioError(source, section, "a [section] table", table)
            for key, value in table.items():
                _lookup(schema, f"{section}.{key}", source)
                data[section][key] = _check(schema, section, key, value, source)
        return cls(data, source)

    def to_toml(self) -> str:
        """The full scenario as TOML text (every key, defaults included), written by tomli-w."""
        return tomli_w.dumps(self.data)


def schema_for(kind: str) -> dict[str, dict[str, Key]]:
    """All sections a scenario of ``kind`` may hold."""
    return common() | {kind: KIND_SECTIONS[kind]} | KIND_EXTRA_SECTIONS.get(kind, {})


def _defaults(keys: dict[str, Key]) -> dict[str, Any]:
    return {k: copy.deepcopy(key.default) for k, key in keys.items()}


def parse_value(raw: str, key: Key) -> Any:
    """A ``--set`` value as ``key``'s schema type reads it. A string key takes the text as it is
    (``153177820``, ``264306385#2``, ``:J0_0``, ``-12``; a quoted TOML string loses its quotes). A
    list key takes a TOML array or comma-separated items (``a.rou.xml,b.rou.xml``, ``1,2``).
    Anything else is a TOML literal (``10``, ``0.5``, ``true``), or the bare text."""
    literal = _toml_literal(raw)
    if key.type is str or isinstance(key.type, tuple):
        return literal if isinstance(literal, str) else raw
    if key.type is list and not isinstance(literal, list):
        items = _toml_literal(f"[{raw}]")
        return items if isinstance(items, list) else [item.strip() for item in raw.split(",")]
    return literal


def _toml_literal(raw: str) -> Any:
    """``raw`` read as a TOML value, else ``raw`` itself."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def resolve(name_or_path: str) -> Path:
    """A bundled scenario name (``braking``) or a path to a ``.toml`` file."""
    path = Path(name_or_path)
    if path.suffix != ".toml" and not path.is_file():  # a folder named like the scenario (an --out) does not hide it
        path = BUNDLED_DIR / f"{name_or_path}.toml"
    if not path.is_file():
        names = sorted(p.stem for p in BUNDLED_DIR.glob("*.toml"))
        hint = _did_you_mean(name_or_path, names) or (f" ({', '.join(names)})" if names else f" (none is bundled in {BUNDLED_DIR})")
        raise ScenarioError(name_or_path, "scenario", f"an existing .toml file or a bundled name{hint}")
    return path


def load(name_or_path: str, overrides: list[str] | None = None, flag: str = "--set") -> Scenario:
    """Load, validate and fill defaults; then apply ``overrides`` (``section.key=value``, given
    with the command-line ``flag``)."""
    path = resolve(name_or_path)
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(path, "(syntax)", f"valid TOML ({exc})") from None
    return Scenario.from_dict(raw, str(path)).with_overrides(overrides or [], flag)


def _did_you_mean(word: str, known) -> str:
    """`` (did you mean X?)`` for the closest of ``known`` to ``word``, or nothing."""
    match = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f" (did you mean {match[0]}?)" if match else ""


def _lookup(schema, dotted: str, source) -> tuple[str, str]:
    section, _, key = dotted.partition(".")
    if section not in schema or key not in schema[section]:
        hint = _did_you_mean(dotted, [f"{s}.{k}" for s, keys in schema.items() for k in keys])
        known = ", ".join(f"{section}.{k}" for k in schema.get(section, {})) or ", ".join(schema)
        raise ScenarioError(source, dotted, f"a known key{hint}" if hint else f"a known key ({known})")
    return section, key


def _check(schema, section: str, key: str, value: Any, source) -> Any:
    try:
        return schema[section][key].validate(value)
    except ValueError as exc:
        raise ScenarioError(source, f"{section}.{key}", str(exc), value) from None


def toml_value(value: Any) -> str:
    """``value`` as a TOML value (tomli-w), as the saved scenario writes it."""
    return tomli_w.dumps({"v": value}).split("=", 1)[1].strip()
