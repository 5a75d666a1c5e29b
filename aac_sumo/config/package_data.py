"""Where the bundled scenarios (``scenarios/*.toml``) and SUMO networks (``sumo_networks/``) are.

In the repository they are the top-level folders ``scenarios/`` and ``sumo_networks/``.
``pyproject.toml`` maps both into the wheel as package data, side by side under
``aac_sumo/_bundled/``, so that a bundled scenario's relative path ``../sumo_networks/...`` finds
its network in a checkout and in an installed wheel alike. An installed wheel is found through
:mod:`importlib.resources`; without it (an editable install, or the checkout on ``sys.path``)
the folders are those of the checkout the package is imported from.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

#: The folder of the package data inside an installed wheel (``aac_sumo/_bundled``).
PACKAGED = "_bundled"


def root() -> Path:
    """The folder that holds ``scenarios/`` and ``sumo_networks/``: ``aac_sumo/_bundled`` of an
    installed wheel, else the source checkout the package is imported from."""
    package = files("aac_sumo")
    packaged = package / PACKAGED
    if (packaged / "scenarios").is_dir():
        return Path(str(packaged))
    return Path(str(package)).resolve().parent


def scenarios_dir() -> Path:
    """The folder of the bundled ``*.toml`` scenarios."""
    return root() / "scenarios"


def networks_dir() -> Path:
    """The folder of the bundled SUMO networks, one subfolder each."""
    return root() / "sumo_networks"
