"""Where many runs go: one interface over a local ``spawn`` process pool and a Dask cluster, used
by sweeps, tables and tuning (:mod:`aac_sumo.runs.sweep`)."""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
import threading
from collections import deque
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, as_completed, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterator

#: Seconds to wait for a Dask scheduler (and for its first worker) before giving up.
CONNECT_TIMEOUT_S = 10.0


class SweepError(ValueError):
    """A command-line mistake in a sweep specification (one line)."""


def one_line(exc: BaseException) -> str:
    """``Type: first line of the message``."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}".rstrip(": ")


def _init_worker() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is handled by the parent alone
    parent = multiprocessing.parent_process()
    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent.sentinel,), name="parent watch", daemon=True).start()


def _exit_with(sentinel: int) -> None:
    """End this worker when its parent has gone (a sweep killed by SIGTERM or SIGKILL left its
    pool's workers behind, polling for work that never came)."""
    multiprocessing.connection.wait([sentinel])
    os._exit(1)


class WorkerDied(RuntimeError):
    """The worker process died while it ran this call (a crash in native code, or killed)."""


class Executor:
    """Runs picklable calls in separate worker processes: a local ``spawn`` process pool of
    ``workers`` processes, or the workers of the Dask scheduler at ``scheduler``
    (``tcp://HOST:PORT``) through ``dask.distributed``'s ``concurrent.futures`` executor.

    Use it as a context manager; :meth:`map` may be called many times (the local pool's worker
    processes, and with them their compiled solvers, live until the ``with`` block ends).
    """

    def __init__(self, workers: int | None = None, scheduler: str | None = None):
        self.scheduler = scheduler
        self.workers = max(1, workers or os.cpu_count() or 1)
        self._pool: ProcessPoolExecutor | None = None
        self._client = None
        self._dask = None

    # -- lifetime -----------------------------------------------------------------------------

    def __enter__(self) -> "Executor":
        if self.scheduler is not None:
            self._connect()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(abort=exc_type is not None)

    def close(self, abort: bool = False) -> None:
        if self._pool is not None:
            self._drop_pool(abort)
        if self._client is not None:
            if self._dask is not None:
                self._dask.shutdown(wait=not abort)
            self._client.close()
            self._client = self._dask = None

    @property
    def slots(self) -> int:
        """How many calls run at once (local workers, or the cluster's worker processes)."""
        if self._client is None:
            return self.workers
        return max(1, len(self._client.scheduler_info().get("workers", {})))

    def _connect(self) -> None:
        where = f"--scheduler {self.scheduler}"
        try:
            from distributed import Client
        except ImportError:
            raise SweepError(f"{where}: dask.distributed: expected the cluster extra to be installed "
                             "(pip install 'aac-sumo[cluster]')") from None
        try:
            client = Client(self.scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise SweepError(f"{where}: scheduler: expected a reachable Dask scheduler address "
                             f"(tcp://HOST:PORT), got {one_line(exc)}") from None
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
            versions = client.run(_worker_version)
        except Exception as exc:
            client.close()
            raise SweepError(f"{where}: workers: expected at least one worker that can import aac_sumo "
                             f"(pip install aac-sumo on every worker), got {one_line(exc)}") from None
        mine = _worker_version()
        other = sorted({v for v in versions.values() if v != mine})
        if other:
            print(f"aac-sumo: note: cluster workers run aac-sumo {', '.join(other)}, this machine {mine}",
                  file=sys.stderr)
        self._client = client
        self._dask = client.get_executor(pure=False)

    # -- running ------------------------------------------------------------------------------

    def map(self, fn: Callable[[Any], Any], items: list) -> Iterator[tuple[int, Any]]:
        """``(index, fn(items[index]))`` as calls finish (completion order). A call that raises,
        or whose worker process dies, yields ``(index, exception)``; the others go on."""
        if not items:
            return iter(())
        if self._client is not None:
            return self._map_dask(fn, items)
        return self._map_local(fn, items)

    def _map_dask(self, fn, items) -> Iterator[tuple[int, Any]]:
        """As :meth:`_map_local`: a worker that dies fails every call it held (``KilledWorker``
        once the scheduler's ``allowed-failures`` are spent), so each such call is rerun alone at
        the end, where only the culprit fails again."""
        from distributed import KilledWorker

        futures = {self._dask.submit(fn, item): i for i, item in enumerate(items)}
        suspects: list[int] = []
        try:
            for fut in as_completed(futures):
                exc = fut.exception()
                if isinstance(exc, KilledWorker):
                    suspects.append(futures[fut])
                else:
                    yield futures[fut], exc if exc is not None else fut.result()
            for i in sorted(suspects):
                fut = self._dask.submit(fn, items[i])
                futures[fut] = i
                exc = fut.exception()
                yield i, exc if exc is not None else fut.result()
        finally:
            for fut in futures:
                fut.cancel()

    def _map_local(self, fn, items) -> Iterator[tuple[int, Any]]:
        """At most ``workers`` calls in flight, so that when a worker process dies the suspects
        are exactly the calls that were running; each suspect is then rerun alone in a fresh
        process, where only the culprit dies again (and yields :class:`WorkerDied`)."""
        queue = deque(enumerate(items))
        inflight: dict = {}
        try:
            while queue or inflight:
                pool = self._get_pool()
                while queue and len(inflight) < self.workers:
                    i, item = queue.popleft()
                    try:
                        inflight[pool.submit(fn, item)] = (i, item)
                    except BrokenProcessPool:  # a worker died since the last wait: settle what was in flight first
                        queue.appendleft((i, item))
                        if not inflight:
                            self._drop_pool(abort=True)
                        break
                suspects: list = []
                yield from _settle(wait(inflight, return_when=FIRST_COMPLETED)[0], inflight, suspects)
                if not suspects:
                    continue
                # a broken pool fails every call in flight at once
                yield from _settle(wait(inflight)[0], inflight, suspects)
                self._drop_pool(abort=True)
                for i, item in sorted(suspects, key=lambda s: s[0]):
                    yield i, self._run_alone(fn, item)
        except BaseException:  # Ctrl-C, or the consumer stopped: running calls are lost
            self._drop_pool(abort=True)
            raise

    def _run_alone(self, fn, item) -> Any:
        pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker)
        try:
            return pool.submit(fn, item).result()
        except BrokenProcessPool:
            return WorkerDied("the worker process died while running this call (a crash in native code, "
                              "or it was killed); the other runs were not affected")
        except Exception as exc:
            return exc
        finally:
            _terminate(pool)

    def _get_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_init_worker)
        return self._pool

    def _drop_pool(self, abort: bool) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if abort:
            _terminate(pool)
        else:
            pool.shutdown()


def _settle(done, inflight: dict, suspects: list) -> Iterator[tuple[int, Any]]:
    """Yield the outcome of each finished future (removed from ``inflight``); calls lost to a
    broken pool go to ``suspects`` instead."""
    for fut in done:
        i, item = inflight.pop(fut)
        exc = fut.exception()
        if isinstance(exc, BrokenProcessPool):
            suspects.append((i, item))
        else:
            yield i, exc if exc is not None else fut.result()


def _terminate(pool: ProcessPoolExecutor) -> None:
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


def _worker_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("aac-sumo")
    except PackageNotFoundError:
        return "unknown"
