"""What is bundled and what can be set: the bundled scenarios with their one-line purpose, and
every scenario key with its default, unit and meaning, read from the schema (:mod:`aac_sumo.config`)."""

from __future__ import annotations

import re
from pathlib import Path

from aac_sumo import config
from aac_sumo.config import common, KIND_EXTRA_SECTIONS, KIND_SECTIONS, Key, Scenario, toml_value

_UNIT = re.compile(r"\s*\[([^\[\]]+)\]$")
#: Longer defaults (lists of rows) are cut to this many characters in the listing.
DEFAULT_WIDTH = 30


def purpose(path: Path) -> str:
    """The first sentence of a scenario file's leading comment, or ``""``."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("# ").strip())
    text = " ".join(lines)
    return re.split(r"\.\s+(?=[A-Z])", text)[0].rstrip(".") + "." if text else ""


def bundled() -> list[tuple[str, str]]:
    """``(name, purpose)`` of every bundled scenario, by name."""
    return [(path.stem, purpose(path)) for path in sorted(config.BUNDLED_DIR.glob("*.toml"))]


def split_unit(doc: str) -> tuple[str, str]:
    """A key's doc as ``(meaning, unit)``: the unit is a trailing ``[...]``, ``-`` without one."""
    found = _UNIT.search(doc)
    return (doc[:found.start()], found.group(1)) if found else (doc, "-")


def key_rows(scenario: Scenario | None = None) -> list[tuple[str, str, str, str]]:
    """``(section.key, default, unit, meaning)`` for every key: of ``scenario``'s schema, with the
    value it sets as the default, or of every section of every kind with the schema defaults."""
    if scenario is not None:
        sections, values = scenario.schema(), scenario.data
    else:
        sections = dict(common()) | KIND_SECTIONS
        for extra in KIND_EXTRA_SECTIONS.values():
            sections |= extra
        values = {s: {k: key.default for k, key in keys.items()} for s, keys in sections.items()}
    rows = []
    for section, keys in sections.items():
        for name, key in keys.items():
            meaning, unit = split_unit(key.doc)
            default = toml_value(values[section][name])
            default = default if len(default) <= DEFAULT_WIDTH else default[:DEFAULT_WIDTH - 3] + "..."
            rows.append((f"{section}.{name}", default, unit, _expected(key, meaning)))
    return rows


def _expected(key: Key, meaning: str) -> str:
    """The meaning, with the allowed strings of a choice key."""
    return f"{meaning} ({key.expected()})" if isinstance(key.type, tuple) else meaning
