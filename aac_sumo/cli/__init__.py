"""The ``aac-sumo`` command line: :func:`main` is the console script's entry point."""

from aac_sumo.cli.main import main

__all__ = ["main"]
