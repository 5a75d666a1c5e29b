"""Threads for the per-period work that runs in compiled code without Python's lock (numba's
``nogil`` kernels): the same results in the same order on any number of threads."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterable, TypeVar

T = TypeVar("T")
R = TypeVar("R")

_POOLS: dict[int, ThreadPoolExecutor] = {}  # one pool per size, shared by every coordinator of the process


def cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else max(os.cpu_count() or 1, 1)


def thread_map(fn: Callable[[T], R], items: Iterable[T], workers: int, least: int = 2) -> list[R]:
    """``[fn(x) for x in items]``, on up to ``workers`` threads (0: one per core) when there are at
    least ``least`` items (below that, the threads' hand-over costs more than it saves). ``fn``
    must not depend on the order of the calls (each call reads only what the caller gave it)."""
    items = list(items)
    threads = min(workers if workers > 0 else cores(), len(items))
    if threads <= 1 or len(items) < least:
        return [fn(x) for x in items]
    pool = _POOLS.get(threads)
    if pool is None:
        pool = _POOLS[threads] = ThreadPoolExecutor(threads, thread_name_prefix="aac-sumo")
    return list(pool.map(fn, items))
