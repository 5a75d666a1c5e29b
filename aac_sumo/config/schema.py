"""Parameter dataclasses as the schema of scenario sections: each field is declared once, with
:func:`param` (default, doc with its unit, check, and the scenario key when it is named otherwise).

* ``@section("aac")`` on a dataclass makes its fields the keys of ``[aac]``
  (:func:`section_keys` derives the :class:`~aac_sumo.config.keys.Key` table, in field order;
  a nested dataclass field adds its fields in its place).
* :func:`from_section` builds the dataclass from a validated scenario; a :class:`ParamError`
  that the dataclass raises for a combination of values becomes a
  :class:`~aac_sumo.config.ScenarioError` naming the key.

The modules that declare sections are named in :data:`~aac_sumo.config.keys.PROVIDERS` or sit in
a package of :data:`~aac_sumo.config.keys.PLUGINS`; the config loads them by name on first use
of the schema, so that ``aac_sumo.config`` itself imports nothing above it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable

from aac_sumo.config.keys import Key, ScenarioError

#: The metadata entry of a field declared with :func:`param`.
META = "aac_sumo.param"
#: ``raw_default`` when not given: the key's default is the field's.
UNSET = object()


@dataclass(frozen=True)
class Param:
    """What :func:`param` records of a field (see there)."""

    doc: str
    check: Callable[[Any], bool] | None = None
    expect: str = ""
    key: str | None = None
    type: Any = None
    parse: Callable[[Any], Any] | None = None
    raw_default: Any = UNSET
    nested: bool = False
    internal: bool = False
    shared: bool = False
    after: str | None = None


def param(default: Any, doc: str, *, check: Callable[[Any], bool] | None = None, expect: str = "", key: str | None = None,
          type: Any = None, parse: Callable[[Any], Any] | None = None, raw_default: Any = UNSET,
          nested: bool = False, internal: bool = False, shared: bool = False, after: str | None = None) -> Any:
    """A dataclass field with its scenario key's declaration.

    ``doc`` is the key's description (with its unit); ``check``/``expect`` its extra check and
    what it expects (``type`` its :class:`Key` type when the default's type does not tell it: a
    tuple of allowed strings, or ``object``). ``key`` is the key's name when it differs from
    the field's, or ``"section.key"`` for a value read from another section (declared there,
    e.g. ``scenario.seed``). ``parse`` turns the key's value into the field's, and
    ``raw_default`` is then the key's default. ``nested``: a dataclass whose fields are keys of
    this section. ``internal``: not a scenario key (set by code). ``shared``: the key is
    declared by another dataclass of the same section (same default). ``after``: in the key
    table, this field's block follows that key (for a section of several dataclasses)."""
    meta = Param(doc, check, expect, key, type, parse, raw_default, nested, internal, shared, after)
    return dataclasses.field(default=default, metadata={META: meta})


class ParamError(ValueError):
    """A dataclass's values that do not go together: ``field`` (its name) expected ``expected``
    (``{section}`` in it is filled with the scenario section's name), got ``got``."""

    def __init__(self, field: str, expected: str, got: Any, section: str = "params"):
        self.field, self.expected, self.got = field, expected, got
        super().__init__(f"{field}: expected {expected.format(section=section)}, got {got!r}")


def meta(f: dataclasses.Field) -> Param:
    """The :class:`Param` of field ``f`` (ValueError when it was not declared with :func:`param`)."""
    if META not in f.metadata:
        raise ValueError(f"field {f.name} is not declared with aac_sumo.config.schema.param")
    return f.metadata[META]


def key_name(f: dataclasses.Field) -> str:
    return meta(f).key or f.name


def scenario_fields(cls) -> list[tuple[dataclasses.Field, Param]]:
    """The fields of ``cls`` that are keys of its own section, nested dataclasses expanded, in order."""
    out = []
    for f in dataclasses.fields(cls):
        p = meta(f)
        if p.nested:
            out += scenario_fields(type(f.default))
        elif not p.internal and "." not in (p.key or ""):
            out.append((f, p))
    return out


def key_default(f: dataclasses.Field, p: Param) -> Any:
    """The scenario key's default of field ``f``: ``raw_default`` when the field parses its key, else its default."""
    return f.default if p.raw_default is UNSET else p.raw_default


def key_of(f: dataclasses.Field, p: Param) -> Key:
    """The :class:`Key` a field declares."""
    default = key_default(f, p)
    kind = p.type if p.type is not None else (bool if isinstance(default, bool) else type(default))
    return Key(kind, default, p.doc, check=p.check, expect=p.expect)


def keys_of(cls) -> dict[str, Key]:
    """The key table that the fields of ``cls`` declare, in field order (those not ``shared``)."""
    return {key_name(f): key_of(f, p) for f, p in scenario_fields(cls) if not p.shared}


#: Sections declared by dataclasses: ``{section: [dataclass, ...]}`` in declaration order.
SECTIONS: dict[str, list[type]] = {}


def section(name: str):
    """Class decorator: the dataclass's fields are keys of section ``[name]``."""

    def decorate(cls):
        if cls not in SECTIONS.setdefault(name, []):
            SECTIONS[name].append(cls)
        return cls

    return decorate


def section_keys(name: str) -> dict[str, Key]:
    """The key table of section ``name`` derived from its dataclasses, in field order."""
    table: dict[str, Key] = {}
    blocks = []
    for cls in SECTIONS.get(name, []):
        blocks.append((next((p.after for _, p in scenario_fields(cls) if p.after and not p.shared), None), keys_of(cls)))
    for after, block in sorted(blocks, key=lambda b: b[0] is not None):  # placed blocks last, whatever the import order
        if after is None:
            table |= block
        else:
            items = list(table.items())
            at = [k for k, _ in items].index(after) + 1
            table = dict(items[:at] + list(block.items()) + items[at:])
    return table


def from_section(cls, scenario, section: str, **given):
    """``cls`` built from section ``[section]`` of a validated ``scenario`` (fields in ``given``
    as given). A :class:`ParamError` of ``cls`` becomes a ScenarioError naming the key."""
    values = _values(cls, scenario, section, given)
    try:
        return cls(**values)
    except ParamError as exc:
        name = next((key_name(f) for f in dataclasses.fields(cls) if f.name == exc.field), exc.field)
        raise ScenarioError(scenario.source, f"{section}.{name}", exc.expected.format(section=section), exc.got) from None


def _values(cls, scenario, section: str, given: dict) -> dict:
    values = {}
    for f in dataclasses.fields(cls):
        p = meta(f)
        if f.name in given:
            values[f.name] = given[f.name]
        elif p.nested:
            values[f.name] = type(f.default)(**_values(type(f.default), scenario, section, {}))
        elif not p.internal:
            dotted = p.key if "." in (p.key or "") else f"{section}.{key_name(f)}"
            value = scenario[dotted]
            values[f.name] = p.parse(value) if p.parse is not None else value
    return values
