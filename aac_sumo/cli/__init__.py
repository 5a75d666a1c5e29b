"""The ``aac-sumo`` command line: :func:`main` is the console script's entry point."""

from __future__ import annotations

import signal
import sys
import threading

#: Set by a Ctrl-C that came while the command line was starting, also one whose KeyboardInterrupt
#: Python swallowed (raised inside a callback of the import machinery, it is only reported as
#: "Exception ignored"): the command then stops at its first chance (:func:`aac_sumo.cli.app.main`).
INTERRUPTED = threading.Event()


def _interrupt(signum, frame):
    INTERRUPTED.set()
    raise KeyboardInterrupt


def _unraisable(unraisable) -> None:
    if issubclass(unraisable.exc_type, KeyboardInterrupt):
        INTERRUPTED.set()  # swallowed by Python: noted here, and not printed as a traceback
        return
    sys.__unraisablehook__(unraisable)


def main(argv: list[str] | None = None) -> int:
    """Run ``aac-sumo`` with ``argv`` (default: the process's arguments) and return its exit
    status (:func:`aac_sumo.cli.app.main`); a Ctrl-C while the command line is still loading
    ends it with status 130 and one line, as one at any later moment does."""
    INTERRUPTED.clear()
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, _interrupt) if main_thread else None
    hook, sys.unraisablehook = sys.unraisablehook, _unraisable
    try:
        try:
            from aac_sumo.cli.app import main as app_main
        except KeyboardInterrupt:
            print("aac-sumo: interrupted while starting", file=sys.stderr)
            return 130
        return app_main(argv)
    finally:
        sys.unraisablehook = hook
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


__all__ = ["INTERRUPTED", "main"]
