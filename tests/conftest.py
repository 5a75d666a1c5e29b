"""Imported by pytest before any test module: the package comes first, so that its CPU-dispatch
pins (``aac_sumo/__init__.py``) are in place before a test module imports numpy."""

import aac_sumo  # noqa: F401
