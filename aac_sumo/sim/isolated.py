"""A simulator in its own process, so that a crash in native code (a segfault in libsumo) ends
the simulator, not the run that drives it.

:class:`IsolatedSimulator` starts a child process (``multiprocessing``'s ``spawn`` context) that
builds the real simulator from a picklable factory and its arguments, and forwards every call to
it over a pipe: the :class:`~aac_sumo.sim.base.Simulator` methods, and any other public
attribute or method by name (:meth:`IsolatedSimulator.call`, :meth:`IsolatedSimulator.fetch`,
or plain attribute access). It knows nothing of the simulator it hosts.

- An exception in the child comes back as the same exception in the parent (when it survives
  pickling; else as the ``error`` class with ``Type: message``), the child's traceback as a note.
- When the child dies (a signal, ``os._exit``), the call raises ``error``: ``"SUMO's process died
  (signal 11, SIGSEGV) at t=12.30 s"``, with ``t`` the simulator's time after its last step.
- Values come back as copies: changing an attribute fetched from the child changes nothing there.
  A step's reply carries the next ``observe()`` and ``agents()`` (``PREFETCH``), served once
  each unless another request comes first.
- The child ignores SIGINT: Ctrl-C in a terminal reaches the whole process group, and it is the
  parent's to handle (``aac-sumo run`` stops between two periods, then closes the simulator).
  The child exits when :meth:`IsolatedSimulator.close` asks it to or when the parent is gone.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import pickle
import signal
import time
import traceback
from multiprocessing import resource_tracker
from typing import Any, Callable

import numpy as np

from aac_sumo.sim.base import ContactReport, Crossing, Simulator
from aac_sumo.world import WorldState

#: Seconds :meth:`IsolatedSimulator.close` waits for the child to close its simulator (SUMO
#: writes its output files then) and exit, before it kills it.
CLOSE_TIMEOUT_S = 60.0
#: Calls whose reply also carries the results of other (argument-free) calls: after a step, the
#: next period's reads, which only a step changes; this saves two round trips per period.
PREFETCH = {"step": ("observe", "agents")}
#: Seconds to wait for a child whose pipe broke to be reaped before it is killed.
REAP_TIMEOUT_S = 5.0

class _Method:
    """The reply to fetching a method: call it by name instead."""


class IsolatedSimulator(Simulator):
    """A :class:`Simulator` running ``factory(*args, **kwargs)`` in a child process.

    ``name`` names the simulator in messages, ``error`` is the exception class raised when the
    child dies (and for child exceptions that cannot be sent back), and ``mirror`` lists
    attributes (``t``, ``removed``, ...) whose values the child sends back after every call, so
    that reading them costs no round trip. Start-up failures raise as in the child. After a call
    the parent gave up on (a KeyboardInterrupt while it waited), only :meth:`close` is safe.
    """

    def __init__(self, factory: Callable[..., Simulator], args: tuple = (), kwargs: dict | None = None, *,
                 name: str = "simulator", error: type[Exception] = RuntimeError, mirror: tuple[str, ...] = ("t", "dt")):
        self._name, self._error, self._mirrored, self._started = name, error, {}, False
        self._prefetched: dict[str, Any] = {}  # results sent ahead with the last reply, each served once
        context = multiprocessing.get_context("spawn")
        self._conn, child_end = context.Pipe()
        self._process = context.Process(target=_serve, args=(child_end, factory, args, kwargs or {}, tuple(mirror)),
                                        name=f"{name} simulator", daemon=True)
        with _sigint_held():  # the child inherits the block from its start: a Ctrl-C while it loads is the parent's alone
            self._process.start()
        child_end.close()  # the child holds the other end: its death reads as EOF here
        try:
            self._reply()
        except BaseException:
            self.close()
            raise
        self._started = True

    # -- the protocol --------------------------------------------------------------------------

    def call(self, method: str, *args, **kwargs) -> Any:
        """The child's simulator's ``method(*args, **kwargs)``."""
        return self._request("call", method, args, kwargs)

    def fetch(self, attribute: str) -> Any:
        """A copy of the child's simulator's ``attribute`` (a ``_Method`` for a method)."""
        return self._request("get", attribute, (), {})

    def __getattr__(self, attribute: str) -> Any:
        """Public attributes the proxy lacks are the child's: mirrored values from the last
        reply, other values fetched, methods as functions that call the child's."""
        if attribute.startswith("_"):
            raise AttributeError(attribute)
        mirrored = self.__dict__.get("_mirrored", {})
        if attribute in mirrored:
            return mirrored[attribute]
        value = self.fetch(attribute)
        if isinstance(value, _Method):
            return lambda *args, **kwargs: self.call(attribute, *args, **kwargs)
        return value

    def _request(self, op: str, attribute: str, args: tuple, kwargs: dict) -> Any:
        if self._process is None:
            raise self._error(f"{self._name} is closed")
        message = pickle.dumps((op, attribute, args, kwargs), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            self._conn.send_bytes(message)
        except OSError:
            raise self._died() from None
        return self._reply()

    def _reply(self) -> Any:
        try:
            status, value, mirrored, self._prefetched = self._conn.recv()
        except (EOFError, OSError):
            raise self._died() from None
        self._mirrored = mirrored
        if status == "ok":
            return value
        payload, kind, text, where = value
        exc = _unpickled(payload) if payload is not None else None
        if not isinstance(exc, BaseException):
            exc = self._error(f"{kind}: {text}")
        exc.add_note(f"in {self._name}'s process:\n{where}")
        raise exc

    def _died(self) -> Exception:
        """The ``error`` saying how the child died, after reaping it."""
        process = self._process
        process.join(REAP_TIMEOUT_S)
        if process.exitcode is None:  # its pipe broke but it lives on: end it
            process.kill()
            process.join()
        code = process.exitcode
        if code < 0:
            how = f"signal {-code}, {_signal_name(-code)}"
        else:
            how = f"exit status {code}"
        t = self._mirrored.get("t")
        when = "while starting" if not self._started else f"at t={t:.2f} s" if t is not None else "mid-run"
        self._conn.close()
        self._process = None
        return self._error(f"{self._name}'s process died ({how}) {when}")

    # -- the Simulator interface ---------------------------------------------------------------

    def observe(self) -> WorldState:
        return self._prefetched.pop("observe") if "observe" in self._prefetched else self.call("observe")

    def step(self, inputs: np.ndarray) -> ContactReport:
        return self.call("step", np.asarray(inputs, dtype=float))

    def agents(self) -> list[dict]:
        return self._prefetched.pop("agents") if "agents" in self._prefetched else self.call("agents")

    def show(self, authority: set[str], stopped: set[str]) -> None:
        self.call("show", authority, stopped)

    def crossings(self) -> list[Crossing] | None:
        return self.call("crossings")

    def close(self) -> None:
        """Close the child's simulator, let the child exit and reap it (killing it after
        ``CLOSE_TIMEOUT_S``); safe to call again, and after the child died."""
        process = self.__dict__.get("_process")
        if process is None:
            return
        self._process = None
        deadline = time.monotonic() + CLOSE_TIMEOUT_S
        try:
            if process.is_alive():
                self._conn.send_bytes(pickle.dumps(("close", "", (), {})))
            while process.is_alive() and time.monotonic() < deadline:
                if self._conn.poll(0.05):  # the reply to a call interrupted in the parent (Ctrl-C)
                    self._conn.recv_bytes()
        except (EOFError, OSError):  # it has gone, or is going
            process.join(max(0.0, deadline - time.monotonic()))
        if process.exitcode is None:
            process.kill()
            process.join()
        self._conn.close()


@contextlib.contextmanager
def _sigint_held():
    """SIGINT blocked in this thread within the block; a process started within it inherits the
    block (``_serve`` ignores SIGINT, then unblocks it, so a Ctrl-C while it loads is discarded
    there). The handler is left as it is: a SIGINT that arrives meanwhile either reaches another
    thread, whose Python-level handler only sets a flag for this one, or stays pending here until
    the block ends. Ignoring it instead lost a Ctrl-C that Linux handed to another thread.
    ``multiprocessing``'s resource tracker unblocks SIGINT after its own start: it is started
    first."""
    resource_tracker.ensure_running()
    try:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    except ValueError:
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return "unknown signal"


def _unpickled(payload: bytes) -> BaseException | None:
    try:
        return pickle.loads(payload)
    except Exception:  # an exception class whose constructor takes other arguments
        return None


def _failure(exc: BaseException, mirrored: dict) -> tuple:
    """The reply carrying ``exc``: the pickled exception when it pickles, its type name, its
    first line and the child's traceback."""
    try:
        payload = pickle.dumps(exc)
        pickle.loads(payload)
    except Exception:
        payload = None
    lines = str(exc).strip().splitlines()
    where = "".join(traceback.format_exception(exc)).rstrip()
    return "error", (payload, type(exc).__name__, lines[0] if lines else "", where), mirrored, {}


def _prefetch(target, names: tuple[str, ...]) -> dict:
    """``{name: target.name()}`` for each of ``names`` that succeeds (a failure is left for the
    call itself to report)."""
    out = {}
    for name in names:
        try:
            out[name] = getattr(target, name)()
        except Exception:
            pass
    return out


def _serve(conn, factory: Callable[..., Any], args: tuple, kwargs: dict, mirror: tuple[str, ...]) -> None:
    """The child: build the simulator, then answer requests until asked to close or the parent
    is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C, then closes us;
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # held since the start (_sigint_held): now discarded

    def mirrored(target) -> dict:
        return {name: getattr(target, name) for name in mirror if hasattr(target, name)}

    try:
        target = factory(*args, **kwargs)
    except BaseException as exc:
        conn.send(_failure(exc, {}))
        return
    conn.send(("ok", None, mirrored(target), {}))
    while True:
        try:
            op, attribute, call_args, call_kwargs = pickle.loads(conn.recv_bytes())
        except EOFError:  # the parent is gone
            op = "close"
        if op == "close":
            target.close()
            return
        try:
            value = getattr(target, attribute)
            if op == "call":
                value = value(*call_args, **call_kwargs)
            elif callable(value):
                value = _Method()
            reply = ("ok", value, mirrored(target), _prefetch(target, PREFETCH.get(attribute, ())) if op == "call" else {})
            conn.send(reply)
        except OSError:  # the parent is gone
            target.close()
            return
        except Exception as exc:  # the call's, or its value's pickling
            conn.send(_failure(exc, mirrored(target)))
