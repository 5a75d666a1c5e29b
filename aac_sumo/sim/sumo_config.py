"""A user's SUMO configuration (``.sumocfg``) read for the co-simulation: its network and route
files, and which of its options the scenario's own settings override.

SUMO starts with ``-c`` on the file, so everything else it sets (additional files, vTypes in
them, outputs, ...) applies as written; paths in it are relative to its folder, as SUMO reads them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from xml.parsers import expat
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class SumoConfig:
    """The file ``path``, its ``net-file`` (None when it names none), its ``route-files``, and
    every option it sets (name -> value as written)."""

    path: Path
    net: Path | None
    routes: list[Path] = field(default_factory=list)
    options: dict[str, str] = field(default_factory=dict)

    def overridden(self, ours: dict[str, str]) -> list[str]:
        """``name=value`` of each of its options that ``ours`` (name -> value: the options the
        co-simulation sets itself, ``SumoOptions.our_options``) sets differently (numbers
        compared as numbers)."""
        return [f"{name}={self.options[name]}" for name, value in ours.items() if name in self.options
                and not _same(self.options[name], value)]


def _same(a: str, b: str) -> bool:
    try:
        return float(a) == float(b)
    except ValueError:
        return a.strip().lower() == b.strip().lower()


def read_config(path: Path) -> SumoConfig:
    """The configuration at ``path``; ``ValueError`` with one line when it is not one."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise ValueError(f"a SUMO configuration file (XML): {str(exc).splitlines()[0]}") from None
    if root.tag != "configuration":
        raise ValueError(f"a SUMO configuration file (<configuration>), got <{root.tag}>")
    options = {option.tag: option.get("value", "") for section in root for option in section if option.get("value") is not None}
    folder = path.parent

    def files(name: str) -> list[Path]:
        return [folder / item for item in options.get(name, "").replace(",", " ").split()]

    nets = files("net-file")
    return SumoConfig(path, nets[0] if nets else None, files("route-files"), options)


def xml_problem(path: Path) -> str | None:
    """Why the file at ``path`` is not well-formed XML (one line), or None when it is. Streamed
    through expat in chunks: no tree is kept, so large route files cost little."""
    parser = expat.ParserCreate()
    try:
        with open(path, "rb") as fh:
            while chunk := fh.read(1 << 20):
                parser.Parse(chunk, False)
        parser.Parse(b"", True)
    except expat.ExpatError as exc:
        return f"not XML: {expat.ErrorString(exc.code)} at line {exc.lineno}, column {exc.offset}"
    except OSError as exc:
        return exc.strerror or str(exc)
    return None
