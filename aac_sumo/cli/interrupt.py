"""A Ctrl-C while the command line starts: noted even where Python swallows its KeyboardInterrupt
(raised inside a callback of the import machinery, it is only reported as "Exception ignored"),
so that the command stops at its first chance (:func:`aac_sumo.cli.app.main`)."""

from __future__ import annotations

import signal
import sys
import threading

#: Set by a Ctrl-C since :func:`watching` began.
INTERRUPTED = threading.Event()


def _interrupt(signum, frame):
    INTERRUPTED.set()
    raise KeyboardInterrupt


def _unraisable(unraisable) -> None:
    if issubclass(unraisable.exc_type, KeyboardInterrupt):
        INTERRUPTED.set()  # swallowed by Python: noted here, and not printed as a traceback
        return
    sys.__unraisablehook__(unraisable)


class watching:
    """Within this context Ctrl-C sets :data:`INTERRUPTED` (and still raises KeyboardInterrupt
    where it can), and a swallowed one sets it too; on leaving, the handlers and the flag are
    as they were before."""

    def __enter__(self):
        INTERRUPTED.clear()
        main_thread = threading.current_thread() is threading.main_thread()
        self.previous = signal.signal(signal.SIGINT, _interrupt) if main_thread else None
        self.hook, sys.unraisablehook = sys.unraisablehook, _unraisable
        return self

    def __exit__(self, *exc):
        sys.unraisablehook = self.hook
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        INTERRUPTED.clear()
        return False
