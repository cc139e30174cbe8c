"""Worker processes end with the process that started them, even when it is killed."""

import multiprocessing
import os
import signal
import time

import numpy as np
import pytest

import warpsoft as ws
from warpsoft import processes
from warpsoft.linear import WorldFactors, factors
from warpsoft.linear.refactor import Refactorizer

from .test_blocks import beam

fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="workers fork")


def _ended(pid: int) -> bool:
    """Whether process ``pid`` has ended (gone, or a zombie no one reaped yet)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True


def _wait_ended(pids: list[int], seconds: float = 10.0) -> list[int]:
    """The processes of ``pids`` still running after ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not all(_ended(p) for p in pids):
        time.sleep(0.05)
    return [p for p in pids if not _ended(p)]


_REPORT = []  # (a parent's pipe, which its forked workers inherit)


def _report_and_wait(*args) -> None:
    """A block's factorization in a pool worker that tells its pid and takes a minute."""
    _REPORT[0].send(os.getpid())
    time.sleep(60)


def _pool_parent(conn) -> None:
    """A parent in its first factorization of two blocks, by a pool of two forked workers, each
    busy with its block."""
    _REPORT.append(conn)
    factors.POOL_FROM, factors.WORKERS, factors.factor_programs = 2, 2, _report_and_wait
    sim = ws.Simulator(ws.finalize([beam(cells=12), beam(cells=16)]), solver="direct")
    WorldFactors(sim.operator, 2, "float64", share=False).prepare()


def _refactorizer_parent(conn) -> None:
    """A parent as a batch's own refreshes have: a refactorizer of two forked workers, idle."""
    refactor = Refactorizer({}, [[], []], [8, 8], 2, 4, np.float64, "cpu")
    conn.send([proc.pid for proc, _ in refactor._procs])
    time.sleep(120)


@fork
@pytest.mark.parametrize("parent", [_pool_parent, _refactorizer_parent])
def test_workers_end_when_their_parent_is_killed(parent):
    """A parent killed outright (SIGKILL: no atexit, no finalizer) takes its workers with it
    within a second or so: the first factorization's pool and the own refreshes' workers. (Before,
    each waited on its siblings' pipes for ever.)"""
    context = multiprocessing.get_context("fork")
    mine, theirs = context.Pipe()
    proc = context.Process(target=parent, args=(theirs,))  # (not a daemon: it has children)
    proc.start()
    assert mine.poll(60), "the parent never started its workers"
    workers = mine.recv()
    if isinstance(workers, int):  # (the pool's workers tell their pids one by one)
        assert mine.poll(60)
        workers = [workers, mine.recv()]
    assert len(workers) == 2 and not any(_ended(p) for p in workers)
    time.sleep(1.0)  # (alive past a look or two at their parent)
    assert not any(_ended(p) for p in workers)
    os.kill(proc.pid, signal.SIGKILL)
    proc.join(10)
    left = _wait_ended(workers)
    for pid in left:  # (not left behind by a failing test)
        os.kill(pid, signal.SIGKILL)
    assert left == []


def test_the_threaded_stable_sort_is_numpys(monkeypatch):
    """The sort of a batch's node ids (the node-element incidence's), cut into pieces sorted side
    by side, gives numpy's stable argsort: keys world by world with ties (cut between worlds), keys
    in no order (one sort), and keys all equal."""
    monkeypatch.setattr(processes, "SORT_PIECE", 1000)
    monkeypatch.setattr(processes, "usable_cores", lambda: 4)
    rng = np.random.default_rng(3)
    worlds = np.concatenate([rng.integers(100 * w, 100 * w + 60, 1500) for w in range(6)])
    for key in (worlds, rng.integers(0, 50, 9000), np.zeros(5000, dtype=np.int64)):
        assert np.array_equal(processes.stable_order(key), np.argsort(key, kind="stable"))
