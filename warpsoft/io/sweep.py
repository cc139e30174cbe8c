"""Sweeps over a scene's parameters: many designs stepped together, as the worlds of one model.

    warpsoft sweep SCENE.py [--grid NAME=[v, ...] ...] [--random N NAME=lo:hi[:log] ...]
                            [--param NAME=VALUE ...] [--batch 256] [--steps N] [--device cuda]
                            [--ray [ADDRESS]] [--parquet] --out DIR

A design is one dictionary of scene parameters (``build(**params)``). Designs are meshed first,
in parallel processes, into the mesh cache (``WARPSOFT_MESH_CACHE``, by default a folder of
the output). They are then stepped ``batch`` at a time: each batch is one
:func:`warpsoft.finalize` model with one world per design, so its designs share every launch.
A design is the unit of failure. One whose ``build`` fails, in any way, is recorded as
``invalid``. A step that fails names its worlds: those designs are ``failed``, with the steps
they finished and the error they meet alone, and the rest of the batch runs again together. Any
other error of a batch (a solver's, the scene's own code raising at some time, a model the
designs cannot share) runs the batch again in halves, down to each design alone, where the one
that meets it is ``failed`` with its type and message and the steps it finished; the others
complete.

Per design (:class:`DesignResult`): the probe and effector trajectories, the actuators' delta and
lambda, the effector error, the warnings. The row of the results table holds the parameters,
the status, and the metrics: the scene's own (an optional ``metrics(result) -> dict`` next to
``build``), or by default each probe's last position and each effector's last error. The table
is written as ``results.csv`` (and ``results.parquet`` on request); ``plot_sweep`` draws a metric
over one or two parameters. With ``ray``, the batches are Ray tasks (:mod:`warpsoft.io.cluster`).
"""

from __future__ import annotations

import csv
import itertools
import math
import os
import re
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack, contextmanager, nullcontext
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from ..errors import SceneError, SimulationError
from ..model import finalize
from ..processes import bind_to_parent
from ..simulator import Simulator
from .atomic import write_whole
from .compiling import ModuleLoads
from .runner import build_scene, load_scene_module, parse_value
from .store import ResultStore, fingerprint, folder_lock

_PROGRESS = {"on": False}  # set while a sweep with progress runs here: its batches show theirs (not in Ray tasks)


@dataclass
class DesignResult:
    """One design's run. Trajectories are ``(steps + 1, 3)`` for probes (the initial position
    first) and ``(steps, ...)`` for what a step reports; units as in
    :class:`warpsoft.stats.WorldStats` (m, N, Pa).

    Attributes:
        index: the design's place in the sweep.
        params: its scene parameters (the sweep's fixed ones included).
        status: "completed", "failed" (a step failed: ``steps`` says how many finished) or
            "invalid" (its ``build`` failed).
        error: why it failed, else None.
        steps: steps finished.
        seconds: wall time of its batch, shared among the batch's designs (s).
        metrics: the table's values for it (see the module doc).
    """

    index: int
    params: dict
    status: str = "completed"
    error: str | None = None
    steps: int = 0
    seconds: float = 0.0
    probes: dict[str, np.ndarray] = field(default_factory=dict)
    effectors: dict[str, np.ndarray] = field(default_factory=dict)
    targets: dict[str, np.ndarray] = field(default_factory=dict)
    effector_error: dict[str, np.ndarray] = field(default_factory=dict)
    actuator_delta: dict[str, np.ndarray] = field(default_factory=dict)
    actuator_lambda: dict[str, np.ndarray] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    metrics: dict[str, float] = field(default_factory=dict)


# ---- designs -------------------------------------------------------------------------------
def grid(axes: dict[str, Sequence]) -> list[dict]:
    """Every combination of the values of ``axes`` (name -> values), the last name varying fastest."""
    for name, values in axes.items():
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not len(values):
            raise SceneError(f"sweep: grid axis {name!r} needs a non-empty list of values, got {values!r}")
    names = list(axes)
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*(axes[n] for n in names))]


def random_designs(count: int, ranges: dict[str, tuple], seed: int = 0) -> list[dict]:
    """``count`` designs spread over ``ranges`` (name -> ``(lo, hi)`` or ``(lo, hi, "log")``) by a
    Latin hypercube (SciPy's ``qmc``): each parameter's range is cut into ``count`` equal slices
    (of its logarithm with "log"), each slice used once."""
    from scipy.stats import qmc

    if int(count) < 1:
        raise SceneError(f"sweep: --random needs at least 1 design, got {count}")
    bounds = {}
    for name, r in ranges.items():
        lo, hi, *scale = r
        log = scale == ["log"]
        if scale and not log:
            raise SceneError(f"sweep: range of {name!r}: the third field may only be 'log', got {scale[0]!r}")
        check_range("sweep", name, lo, hi, log)
        bounds[name] = (math.log(lo), math.log(hi), True) if log else (float(lo), float(hi), False)
    if not bounds:
        raise SceneError("sweep: --random needs at least one NAME=lo:hi range")
    unit = qmc.LatinHypercube(d=len(bounds), seed=seed).random(int(count))
    designs = []
    for u in unit:
        d = {}
        for x, (name, (lo, hi, log)) in zip(u, bounds.items(), strict=True):
            v = lo + x * (hi - lo)
            d[name] = float(math.exp(v) if log else v)
        designs.append(d)
    return designs


def check_range(what: str, name: str, lo: float, hi: float, log: bool) -> None:
    """A swept or searched range: finite, ``lo < hi``, and ``lo > 0`` on a log scale (``what``
    names the command in the error)."""
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi) or (log and lo <= 0.0):
        raise SceneError(f"{what}: range of {name!r} must be finite with lo < hi (and lo > 0 for log), got {lo}:{hi}")


def parse_grid(items: Sequence[str]) -> dict[str, list]:
    """``["name=[v1, v2]", ...]`` (CLI ``--grid``) -> axes for :func:`grid`."""
    axes = {}
    for item in items:
        name, sep, text = item.partition("=")
        value = parse_value(text.strip())
        if not sep or not name.strip() or not isinstance(value, (list, tuple)):
            raise SceneError(f"sweep: --grid expects NAME=[v1, v2, ...], got {item!r}")
        axes[name.strip()] = list(value)
    return axes


def parse_ranges(items: Sequence[str]) -> dict[str, tuple]:
    """``["name=lo:hi", "name=lo:hi:log", ...]`` (CLI ``--random N ...``) -> ranges for
    :func:`random_designs`."""
    ranges = {}
    for item in items:
        name, sep, text = item.partition("=")
        fields = text.strip().split(":")
        try:
            if not sep or not name.strip() or len(fields) not in (2, 3):
                raise ValueError
            ranges[name.strip()] = (float(fields[0]), float(fields[1]), *fields[2:])
        except ValueError:
            raise SceneError(f"sweep: --random expects NAME=lo:hi or NAME=lo:hi:log, got {item!r}") from None
    return ranges


# ---- meshing in parallel processes ----------------------------------------------------------
def _build_for_cache(scene_file: str, params: dict) -> str | None:
    """In a worker process: build the scene once, so that its meshes land in the cache."""
    try:
        build_scene(scene_file, params)
    except Exception as exc:  # any error of the design: the sweep records it when it builds the design itself
        return f"{type(exc).__name__}: {exc}"
    return None


def premesh(scene_file: str | Path, designs: Sequence[dict], workers: int) -> None:
    """Build every design once in ``workers`` processes (spawned: no Warp state is shared), so
    that the sweep's own builds read their meshes from the cache. Nothing to do for one worker."""
    if workers <= 1 or len(designs) <= 1:
        return
    with ProcessPoolExecutor(max_workers=min(workers, len(designs)), mp_context=get_context("spawn"),
                             initializer=bind_to_parent, initargs=(os.getpid(),)) as pool:
        built = pool.map(_build_for_cache, [str(scene_file)] * len(designs), designs)
        if _PROGRESS["on"]:
            from tqdm import tqdm

            built = tqdm(built, total=len(designs), desc=f"meshing ({min(workers, len(designs))} processes)",
                         unit="design", disable=None, leave=False)
        list(built)


# ---- the sweep -----------------------------------------------------------------------------
def sweep(scene_file: str | Path, designs: Sequence[dict], steps: int | None = None, batch: int = 256,
          device: str | None = None, fixed: dict | None = None, workers: int | None = None,
          out: str | Path | None = None, progress: bool = False, ray: bool | str = False, parquet: bool = False,
          append: bool = False, overwrite: bool = False, **options) -> list[DesignResult]:
    """Run every design of ``designs`` (scene parameters, each merged over ``fixed``) for ``steps``
    steps (by default the scene's, from each batch's first design), ``batch`` designs per model.
    ``workers`` processes mesh the designs first into the mesh cache (default: the CPU count; 1:
    none; no cache, no meshing ahead). ``ray``: run the batches as Ray tasks (True: the cluster
    of ``RAY_ADDRESS`` or a new one on this machine; a string: that cluster's address; see
    :mod:`warpsoft.io.cluster`). ``options`` go to the :class:`Simulator`.

    With ``out``, the folder keeps every finished design's row as its batch ends
    (:mod:`warpsoft.io.store`) and ``results.csv`` (and ``results.parquet`` with ``parquet``)
    rewritten whole after each batch. The same command into the same folder skips the designs it
    finished; another sweep's folder is refused unless ``append`` (its designs are added to that
    table) or ``overwrite`` (its results are cleared). Returns one :class:`DesignResult` per
    design, in order; a design finished by an earlier run has its row's values, not its
    trajectories."""
    if not designs:
        raise SceneError("sweep: no design to run")
    designs = [dict(fixed or {}) | dict(d) for d in designs]
    if out is None:
        with mesh_cache(None):
            return evaluate(scene_file, designs, steps, batch, device, workers, ray, options)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    load_scene_module(scene_file)  # a missing scene file: said before the folder is touched
    with folder_lock(out), mesh_cache(out):
        store = ResultStore(out, fingerprint(scene_file, designs, steps, options), len(designs), append, overwrite)
        todo = [k for k in range(len(designs)) if store.done(k) is None]
        seen: set[int] = set()

        def on_batch(results: list[DesignResult]) -> None:
            new = [r for r in results if r.index not in seen]
            seen.update(r.index for r in new)
            store.add([{"design": store.first + todo[r.index], "status": r.status, "steps": r.steps,
                        "seconds": r.seconds, "params": r.params, "metrics": r.metrics, "error": r.error} for r in new])
            for path in [out / "results.csv"] + ([out / "results.parquet"] if parquet else []):
                write_rows(store.table(), path)
            if progress:
                finished = [row for k in range(len(designs)) if (row := store.done(k)) is not None]
                failed = sum(row["status"] != "completed" for row in finished)
                elapsed = time.perf_counter() - started
                rate = sum(r.steps for r in results) / max(elapsed, 1e-9)
                left = elapsed / len(seen) * (len(todo) - len(seen))
                print(f"warpsoft sweep: {len(finished)}/{len(designs)} designs finished, {failed} of them failed; "
                      f"{rate:,.0f} design-steps/s so far, about {left:,.0f} s left", flush=True)

        if progress and len(todo) < len(designs):
            print(f"warpsoft sweep: {len(designs) - len(todo)} of {len(designs)} designs finished in {out} already; "
                  "running the others", flush=True)
        _PROGRESS["on"] = progress
        started = time.perf_counter()
        try:
            ran = evaluate(scene_file, [designs[k] for k in todo], steps, batch, device, workers, ray, options,
                           on_batch) if todo else []
        finally:
            _PROGRESS["on"] = False
    by_index = {todo[r.index]: r for r in ran}
    for r in ran:
        r.index = todo[r.index]
    return [by_index.get(k) or _from_row(k, store.done(k)) for k in range(len(designs))]


def _from_row(index: int, row: dict) -> DesignResult:
    """A design an earlier run finished, from its stored row."""
    return DesignResult(index, dict(row["params"]), row["status"], row["error"] or None, int(row["steps"]),
                        float(row["seconds"]), metrics=dict(row["metrics"]))


@contextmanager
def mesh_cache(out: Path | None):
    """The mesh cache of the sweep: ``WARPSOFT_MESH_CACHE`` if set, else ``out/mesh_cache`` while
    the sweep runs (its meshing processes inherit it), else none (the designs mesh once each)."""
    if out is None or os.environ.get("WARPSOFT_MESH_CACHE"):
        yield
        return
    os.environ["WARPSOFT_MESH_CACHE"] = str(Path(out).resolve() / "mesh_cache")
    try:
        yield
    finally:
        os.environ.pop("WARPSOFT_MESH_CACHE", None)  # (a cache that could not write has turned itself off)


def evaluate(scene_file: str | Path, designs: Sequence[dict], steps: int | None, batch: int, device: str | None,
             workers: int | None = None, ray: bool | str = False, options: dict | None = None,
             on_batch: Callable[[list[DesignResult]], None] | None = None) -> list[DesignResult]:
    """Designs (complete parameter dicts) run ``batch`` at a time, here or as Ray tasks; the body
    of :func:`sweep` and of :func:`warpsoft.io.optimize.optimize`. ``on_batch(results)`` is
    called with the designs run so far, in order, after each batch (a run stopped keeps them)."""
    if int(batch) < 1:
        raise SceneError(f"sweep: batch must be >= 1, got {batch}")
    load_scene_module(scene_file)  # a missing or broken scene file: said before anything runs
    if os.environ.get("WARPSOFT_MESH_CACHE"):  # (without a cache, meshing ahead would mesh twice)
        premesh(scene_file, designs, (os.cpu_count() or 1) if workers is None else int(workers))
    chunks = [[DesignResult(start + k, dict(d)) for k, d in enumerate(designs[start:start + int(batch)])]
              for start in range(0, len(designs), int(batch))]
    results: list[DesignResult] = []
    with ExitStack() as stack:
        if ray:
            from .cluster import ray_batches, ray_session

            stack.enter_context(ray_session(ray))
            batches = ray_batches(scene_file, chunks, steps, device, dict(options or {}))
        else:
            batches = (run_designs(scene_file, chunk, steps, device, dict(options or {})) for chunk in chunks)
        for chunk in batches:
            results = sorted(results + chunk, key=lambda r: r.index)
            if on_batch is not None:
                on_batch(results)
    return results


def run_designs(scene_file: str | Path, chunk: list[DesignResult], steps: int | None, device: str | None,
                options: dict) -> list[DesignResult]:
    """One batch: each design built (a refused build: ``invalid``), the valid ones stepped as
    the worlds of one model for ``steps`` steps (None: the first one's scene's), then their
    metrics. Fills and returns ``chunk``."""
    metrics = getattr(load_scene_module(scene_file), "metrics", None)
    scenes = []
    for r in chunk:
        try:
            scenes.append(build_scene(scene_file, r.params))
        except Exception as exc:  # any error of one design's build (its own code's included): that design's
            r.status, r.error = "invalid", f"{type(exc).__name__}: {exc}"
    valid = [r for r in chunk if r.status != "invalid"]
    if valid:
        run_batch(scenes, valid, int(scenes[0].steps if steps is None else steps), device, options)
    for r in chunk:
        r.metrics = design_metrics(r, metrics)
    return chunk


def run_batch(scenes: list, results: list[DesignResult], steps: int, device: str | None, options: dict) -> None:
    """Step ``scenes`` together (one world each) and fill ``results``. When a step fails, the
    worlds it names keep their record up to the failure (``failed``) and the others run again
    as a batch; any other failure runs the batch again in halves, down to the designs alone,
    where it is that design's."""
    try:
        _step_worlds(scenes, results, steps, device, options)
    except Exception as exc:  # (not KeyboardInterrupt: a stop is the sweep's, not a design's)
        named = exc.worlds if isinstance(exc, SimulationError) else None
        if len(scenes) == 1:
            message = _own_message(exc) if isinstance(exc, SimulationError) else str(exc)
            results[0].status, results[0].error = "failed", f"{type(exc).__name__}: {message}"
            return
        failed = set(named or [])
        if not failed:  # halves, again and again: a few failing designs among many cost a few batches each
            half = len(scenes) // 2
            for part in (range(half), range(half, len(scenes))):
                for k in part:
                    _clear(results[k])
                run_batch([scenes[k] for k in part], [results[k] for k in part], steps, device, options)
            return
        for w in failed:
            results[w].status, results[w].error = "failed", f"{type(exc).__name__}: {_own_message(exc)}"
        rest = [k for k in range(len(scenes)) if k not in failed]
        for k in rest:
            _clear(results[k])
        if rest:
            run_batch([scenes[k] for k in rest], [results[k] for k in rest], steps, device, options)


def _own_message(exc: Exception) -> str:
    """The error as the design would have met it alone: without the batch's world numbers."""
    return re.sub(r" \(worlds? [0-9, ]+\)", "", str(exc), count=1)


def _clear(r: DesignResult) -> None:
    r.steps, r.probes, r.effectors, r.targets, r.effector_error = 0, {}, {}, {}, {}
    r.actuator_delta, r.actuator_lambda, r.warnings = {}, {}, []


def _step_worlds(scenes: list, results: list[DesignResult], steps: int, device: str | None, options: dict) -> None:
    """One model of ``scenes``, stepped ``steps`` times; each world's record into its result (as
    it goes: a failure keeps the steps finished)."""
    sim = Simulator(finalize(scenes, device), device=device, **options)
    m = sim.model
    worlds = range(m.num_worlds)
    mine = [[i for i, w in enumerate(m.probe_world) if w == k] for k in worlds]  # each world's probes
    probes = [{m.probe_names[i]: [] for i in mine[w]} for w in worlds]
    tracks = [{"effectors": {}, "targets": {}, "effector_error": {}, "actuator_delta": {}, "actuator_lambda": {}}
              for _ in worlds]

    def record_probes() -> None:
        points = sim.probe_array()
        for w in worlds:
            for i in mine[w]:
                probes[w][m.probe_names[i]].append(points[i])

    record_probes()
    started = time.perf_counter()
    iterator = range(steps)
    if _PROGRESS["on"]:
        from tqdm import tqdm

        print(f"warpsoft sweep: a batch of {m.num_worlds} designs ({m.num_nodes} nodes) on {m.device}; its first "
              "step compiles the kernels (once per machine: they are cached)...", flush=True)
        iterator = tqdm(iterator, desc=f"batch of {m.num_worlds}", unit="step", disable=None, leave=False)
        _factor_bar(sim)
    loads = ModuleLoads(say=tqdm.write) if _PROGRESS["on"] else nullcontext()
    try:
        with loads:
            for _ in iterator:
                stats = sim.step()
                record_probes()
                for w, (r, ws) in enumerate(zip(results, stats.worlds, strict=True)):
                    for what, track in tracks[w].items():
                        for name, v in getattr(ws, what).items():
                            track.setdefault(name, []).append(v)
                    label = sim.world_label(w)
                    r.warnings += [msg for msg in stats.warnings if m.num_worlds == 1 or label in msg]
                    r.steps += 1
    finally:
        seconds = (time.perf_counter() - started) / len(results)
        for w, r in enumerate(results):
            r.seconds = seconds
            r.probes = {n: np.array(v) for n, v in probes[w].items()}
            for what, track in tracks[w].items():
                setattr(r, what, {n: np.array(v) for n, v in track.items()})


def _factor_bar(sim: Simulator) -> None:
    """A bar over the blocks each whole refresh of the preconditioner factorizes (the first comes
    in the first step: one block per design of its own mesh), where the solver keeps factors."""
    from tqdm import tqdm

    pre = getattr(sim.solver, "precond", None)
    if not hasattr(pre, "progress"):
        return
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if done == 1:
            tqdm.write(f"  factorizing the preconditioner's {total} blocks (a design's own, or shared by designs "
                       "whose systems are multiples)...")
            bar = tqdm(total=total, desc="factorization", unit="block", disable=None, leave=False)
        bar.update(done - bar.n)
        if done == total:
            bar.close()

    pre.progress = progress


def design_metrics(r: DesignResult, metrics: Callable | None) -> dict[str, float]:
    """The table's values of a design: the scene's ``metrics(result)`` (a dict of numbers), or
    each probe's last position (``NAME_x`` ...) and each effector's last error (m). None for a
    design that did not complete. An error in ``metrics`` fails the design, named."""
    if r.status != "completed":
        return {}
    if metrics is None:
        values = {}
        for name, p in r.probes.items():
            values |= {f"{name}_{a}": float(v) for a, v in zip("xyz", p[-1], strict=True)}
        values |= {f"{name}_error": float(e[-1]) for name, e in r.effector_error.items()}
        return values
    try:
        values = metrics(r)
        if not isinstance(values, dict):
            raise TypeError(f"returned {type(values).__name__}, not a dict")
        return {str(k): float(v) for k, v in values.items()}
    except Exception as exc:  # the user's code: the design is marked, the sweep goes on
        r.status, r.error = "failed", f"metrics(): {type(exc).__name__}: {exc}"
        return {}


def table_rows(results: Sequence[DesignResult]) -> list[dict]:
    """One row per design: index, status, steps, seconds, parameters, metrics, error."""
    return [{"design": r.index, "status": r.status, "steps": r.steps, "seconds": r.seconds} | r.params | r.metrics
            | {"error": r.error or ""} for r in results]


def write_table(results: Sequence[DesignResult], path: str | Path) -> Path:
    """The results table (:func:`table_rows`) as CSV, or as Parquet when ``path`` ends in
    ``.parquet`` (see :func:`write_rows`)."""
    return write_rows(table_rows(results), path)


def write_rows(rows: Sequence[dict], path: str | Path) -> Path:
    """Rows as a table at ``path``: CSV (columns: every key of every row, in order of first use;
    a missing value is empty), or Parquet for a ``.parquet`` path (pyarrow: typed columns, a
    missing value null; a column mixing numbers and text is stored as text)."""
    path = Path(path)
    columns = list(dict.fromkeys(k for row in rows for k in row))
    if path.suffix == ".parquet":
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise SceneError("a Parquet table needs pyarrow: pip install 'warpsoft[sweep]'") from None
        arrays = {}
        for c in columns:
            values = [row.get(c) for row in rows]
            try:
                arrays[c] = pa.array(values)
            except (pa.ArrowInvalid, pa.ArrowTypeError):  # e.g. a parameter given as 3 and as "soft"
                arrays[c] = pa.array([None if v is None else str(v) for v in values])
        return write_whole(path, lambda tmp: pq.write_table(pa.table(arrays), tmp))

    def write_csv(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=columns, restval="")
            writer.writeheader()
            writer.writerows(rows)

    return write_whole(path, write_csv)  # (a kill while writing leaves the last whole table)


def plot_sweep(results: Sequence[DesignResult], metric: str, params: Sequence[str], path: str | Path) -> Path:
    """``metric`` over one parameter (a line per value of a second one, if given, on a grid; else
    a scatter coloured by the metric), the completed designs only; a PNG at ``path``."""
    from matplotlib.ticker import MaxNLocator

    from .plot import _pyplot

    done = [r for r in results if r.status == "completed" and metric in r.metrics]
    if not done:
        raise SceneError(f"sweep plot: no completed design has the metric {metric!r}")
    unknown = [p for p in params if p not in done[0].params]
    if not params or len(params) > 2 or unknown:
        raise SceneError(f"sweep plot: give one or two swept parameters, got {list(params)} "
                         f"(the designs have: {', '.join(done[0].params)})")
    for p in params:
        if not all(isinstance(r.params[p], (int, float)) and not isinstance(r.params[p], bool) for r in done):
            raise SceneError(f"sweep plot: parameter {p!r} is not a number in every design; plot over a numeric one")
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    x = np.array([float(r.params[params[0]]) for r in done])
    y = np.array([r.metrics[metric] for r in done])
    if len(params) == 1:
        order = np.argsort(x)
        ax.plot(x[order], y[order], "o-")
        ax.set_ylabel(metric)
    else:
        z = np.array([float(r.params[params[1]]) for r in done])
        if len(np.unique(z)) <= 8:  # a grid: one line per value of the second parameter
            for value in np.unique(z):
                sel = z == value
                order = np.argsort(x[sel])
                ax.plot(x[sel][order], y[sel][order], "o-", label=f"{params[1]} = {value:g}")
            ax.legend()
            ax.set_ylabel(metric)
        else:  # scattered designs: the second parameter up, the metric as the colour
            points = ax.scatter(x, z, c=y, cmap="viridis")
            fig.colorbar(points, ax=ax, label=metric)
            ax.set_ylabel(params[1])
    ax.set_xlabel(params[0])
    ax.xaxis.set_major_locator(MaxNLocator(5))
    ax.set_title(f"{metric}: {len(done)} of {len(results)} designs completed")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
