"""Batches of designs as Ray tasks: a sweep or an optimization over the GPUs of a machine, or of
many machines (``--ray [ADDRESS]``).

Ray schedules; warpsoft only cuts the designs into batches. Each batch is one task running
:func:`warpsoft.io.sweep.run_designs` (one model, one world per design) and asking Ray for one
GPU when the device is CUDA (Ray then shows that task a single GPU, its ``cuda:0``), or one CPU
otherwise (a GPU task also takes the cluster's CPUs per GPU, for its threaded host side).
The results come back as the tasks end, in any order; the caller puts them in
order.

- Address: ``True`` joins the cluster of ``RAY_ADDRESS``, else starts a Ray instance on this
  machine (stopped at the end); a string joins that cluster (``ray start --head`` on one machine,
  ``ray start --address=HEAD:6379`` on the others). A Ray session already started in this
  process (``ray.init`` by the user) is used as it is.
- Every machine needs warpsoft installed (the same version). The scene file's text travels with
  each task: a machine that does not have the file at the same path runs the text. Each
  machine meshes into its own cache, at the path the driver uses.
- A task that dies (a worker lost, an error outside warpsoft) fails the designs of its batch,
  named with Ray's error; the other batches go on.

Ray has no in-process "local mode" any more (removed in Ray 2.x); the tests run a Ray instance
of this machine on its CPU.
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import SceneError
from .sweep import DesignResult, run_designs


def _ray():
    try:
        import ray
    except ImportError:
        raise SceneError("--ray needs Ray: pip install 'warpsoft[ray]'") from None
    return ray


@contextmanager
def ray_session(address: bool | str = True):
    """Ray, started or joined (see the module doc) for the time of the block, then stopped if
    it was started here. Nested sessions use the outer one."""
    ray = _ray()
    started = not ray.is_initialized()
    if started:
        ray.init(address=None if address is True else str(address), include_dashboard=False,
                 logging_level=logging.WARNING)
    try:
        yield ray
    finally:
        if started:
            ray.shutdown()


def parallel_batches(device: str | None) -> int:
    """How many batches the cluster of the current :func:`ray_session` runs at once: its GPUs
    for a CUDA device, else its CPUs (a Warp CPU launch uses one core)."""
    resources = _ray().cluster_resources()
    key = "GPU" if _wants_gpu(device) else "CPU"
    return max(1, int(resources.get(key, 0)))


def _wants_gpu(device: str | None) -> bool:
    if device is None:
        import warp as wp

        return wp.get_device().is_cuda
    return str(device).startswith("cuda")


def ray_batches(scene_file: str | Path, chunks: list[list[DesignResult]], steps: int | None, device: str | None,
                options: dict) -> Iterator[list[DesignResult]]:
    """Run each chunk of designs as one Ray task, in the current :func:`ray_session`; yield
    each chunk, filled, as its task ends."""
    ray = _ray()
    gpu, resources = _wants_gpu(device), ray.cluster_resources()
    if gpu and not resources.get("GPU"):
        raise SceneError(f"--ray with device {device or 'cuda (Warp default)'}: the Ray cluster has no GPU "
                         f"(resources: {resources})")
    # A GPU task also takes its share of the CPUs: Ray caps a task's threads (OMP_NUM_THREADS) at
    # its CPUs, and the host side of a batch (the preconditioner's factorizations) is threaded.
    # (Measured on the 2-GPU H200 host with the dense blocks, LAPACK's inverses: one thread instead
    # of 32 cost 6 % of the stepping.)
    cpus = max(1, int(resources.get("CPU", 1) // resources.get("GPU", 1))) if gpu else 1
    task = ray.remote(num_gpus=1 if gpu else 0, num_cpus=cpus, max_retries=0)(_remote_batch)
    source = Path(scene_file).read_text()
    cache = os.environ.get("WARPSOFT_MESH_CACHE")
    worker_device = "cuda" if gpu else device  # a task sees the one GPU Ray gave it as cuda:0
    pending = {task.remote(str(Path(scene_file).resolve()), source, chunk, steps, worker_device, options, cache): chunk
               for chunk in chunks}
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            chunk = pending.pop(done[0])
            try:
                yield ray.get(done[0])
            except ray.exceptions.RayError as exc:  # the task itself died: its designs are marked
                for r in chunk:
                    r.status, r.error = "failed", f"ray task: {type(exc).__name__}: {str(exc).splitlines()[0]}"
                yield chunk
    finally:
        for ref in pending:  # stopped early (an error, or the caller stopped reading): cancel the rest
            ray.cancel(ref)


def _remote_batch(path: str, source: str, chunk: list[DesignResult], steps: int | None, device: str | None,
                  options: dict, cache: str | None) -> list[DesignResult]:
    """In a Ray worker: the scene file where the driver has it, or its text in a temporary file."""
    if cache:
        os.environ["WARPSOFT_MESH_CACHE"] = cache
    if Path(path).is_file() and Path(path).read_text() == source:
        return run_designs(path, chunk, steps, device, options)
    with tempfile.TemporaryDirectory(prefix="warpsoft-scene-") as folder:
        local = Path(folder) / Path(path).name
        local.write_text(source)
        return run_designs(local, chunk, steps, device, options)
