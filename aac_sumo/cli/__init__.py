"""The ``aac-sumo`` command line: :func:`main` is the console script's entry point."""

from __future__ import annotations

import sys

from aac_sumo.cli.interrupt import watching


def main(argv: list[str] | None = None) -> int:
    """Run ``aac-sumo`` with ``argv`` (default: the process's arguments) and return its exit
    status (:func:`aac_sumo.cli.app.main`); a Ctrl-C while the command line is still loading
    ends it with status 130 and one line, as one at any later moment does, also one whose
    KeyboardInterrupt Python swallowed (:mod:`aac_sumo.cli.interrupt`)."""
    with watching():
        try:
            from aac_sumo.cli.app import main as app_main
        except KeyboardInterrupt:
            print("aac-sumo: interrupted while starting", file=sys.stderr)
            return 130
        return app_main(argv)


__all__ = ["main"]
