"""The one thing pyproject.toml cannot say: the package list. It is the code packages setuptools
finds under aac_sumo/ plus the two data packages that pyproject.toml's package-dir maps in from
the top-level scenarios/ and sumo_networks/ (a hand-kept list would miss a new subpackage)."""

from setuptools import find_packages, setup

setup(packages=find_packages(include=["aac_sumo", "aac_sumo.*"]) + ["aac_sumo._bundled.scenarios", "aac_sumo._bundled.sumo_networks"])
