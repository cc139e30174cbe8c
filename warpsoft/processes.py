"""Worker processes bound to the process that started them, and work spread over threads.

warpsoft starts worker processes in three places: the meshes of a sweep (spawned), the first
factorization of many blocks (a forked pool) and the worlds' own refreshes (forked, for the
whole run). A forked worker holds the write ends of its siblings' pipes, so when the parent is
killed (the kernel's out-of-memory killer, a ``kill -9``, a cluster's time limit) no pipe
closes and the workers wait on them for ever: 4096 Diamonds on the H200's host left 16 of them,
29 GB each, after their parent was killed (docs/performance.md). :func:`bind_to_parent` ends a
worker soon after its parent ends, however it ended.
"""

from __future__ import annotations

import ctypes
import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import numpy as np

PERIOD = 0.5  # s between a worker's looks at its parent
T, R = TypeVar("T"), TypeVar("R")


def _watch(parent: int, period: float) -> None:
    """End this process (at once, nothing flushed: its parent, gone, reads nothing) once its
    parent is no longer ``parent``."""
    while os.getppid() == parent:
        time.sleep(period)
    os._exit(1)


def bind_to_parent(parent: int, period: float = PERIOD) -> None:
    """In a worker process: end it within about ``period`` seconds once its parent, pid ``parent``,
    has ended (its parent pid then changes: the worker is adopted). A daemon thread looks, so
    the worker's own work goes on meanwhile; a worker whose parent is already gone ends at
    once. (Not Linux's ``PR_SET_PDEATHSIG``: that fires when the *thread* that started the
    worker ends, and a simulator may be built in a thread that ends before it.)

    Pass it, with ``os.getpid()`` read in the parent, as a pool's ``initializer``, or call it
    first thing in a process's target."""
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=_watch, args=(parent, period), daemon=True, name="warpsoft-parent-watch").start()


def usable_cores() -> int:
    """The cores this process may run on (its affinity where the system says it; else every core)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def release_freed() -> None:
    """Give the memory this process has freed back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). The blocks' programs of a first factorization are freed in arrays of a few MB, which
    glibc keeps in its heap for later: 64 different Diamonds on the 2-core VM kept about 150 MB of
    them (2.4 MB a block) after their first step."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


THREADED_FROM = 8  # items from which in_threads uses threads


def in_threads(work: Callable[[T], R], items: Sequence[T]) -> list[R]:
    """``[work(item) for item in items]``, the items side by side in a thread each core (numpy's
    and SciPy's array work runs outside the GIL) from :data:`THREADED_FROM` items; an error is
    the first item's in order that raised, as in the loop."""
    if len(items) < THREADED_FROM or usable_cores() < 2:
        return [work(item) for item in items]
    with ThreadPoolExecutor(min(usable_cores(), len(items))) as pool:
        return list(pool.map(work, items))


SORT_PIECE = 1 << 20  # keys per thread in stable_order (below two pieces: one sort)


def stable_order(key: np.ndarray) -> np.ndarray:
    """``np.argsort(key, kind="stable")`` for a ``(n,)`` integer ``key``, sorted in pieces, one
    thread each, cut where every key before the cut is at or below every key after it (a batch's
    node ids come world by world, each world's nodes after the last one's)."""
    pieces = min(-(-len(key) // SORT_PIECE), usable_cores())
    if pieces < 2:
        return np.argsort(key, kind="stable")
    before = np.maximum.accumulate(key)[:-1]  # the largest key before each cut 1..n-1
    after = np.minimum.accumulate(key[::-1])[::-1][1:]  # the smallest from it on
    cuts = np.flatnonzero(before <= after) + 1
    if not len(cuts):
        return np.argsort(key, kind="stable")
    wanted = np.linspace(0, len(key), pieces + 1)[1:-1]
    near = np.clip(np.searchsorted(cuts, wanted), 0, len(cuts) - 1)
    bounds = np.unique(np.concatenate([[0], cuts[near], [len(key)]]))
    with ThreadPoolExecutor(len(bounds) - 1) as pool:  # (numpy's sorts run outside the GIL)
        orders = list(pool.map(lambda a, b: np.argsort(key[a:b], kind="stable"), bounds[:-1], bounds[1:]))
    return np.concatenate([o + a for o, a in zip(orders, bounds[:-1], strict=True)])
