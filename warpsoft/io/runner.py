"""Load scene files and run them: the engine behind ``warpsoft run`` (also usable from Python)."""

from __future__ import annotations

import ast
import importlib.util
import inspect
import json
import signal
import sys
import threading
from contextlib import contextmanager, nullcontext
from pathlib import Path
from types import CodeType, ModuleType

from ..errors import OutputError, SceneError, WarpsoftError
from ..scene import Scene
from ..simulator import Simulator
from .compiling import ModuleLoads
from .report import RunReport


def parse_value(text: str):
    """A ``--param`` value: a Python literal, else JSON, else the plain string."""
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        pass
    try:
        return json.loads(text)
    except ValueError:
        return text


def parse_params(items: list[str]) -> dict:
    """``["key=value", ...]`` -> dict, values parsed by :func:`parse_value`."""
    params = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise SceneError(f"--param expects key=value, got {item!r}")
        params[key.strip()] = parse_value(value.strip())
    return params


_CODE: dict[tuple, CodeType] = {}  # (scene file, its mtime and size) -> its compiled code


def load_scene_module(path: str | Path) -> ModuleType:
    """Import a scene file (it must define ``build(**params) -> Scene``)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"scene file {str(path)!r} does not exist")
    name = f"warpsoft_scene_{path.stem}_{abs(hash(str(path.resolve())))}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    if key not in _CODE:  # (a sweep builds each design from a fresh module of the same file: compiled once)
        _CODE[key] = compile(path.read_bytes(), str(path), "exec")
    exec(_CODE[key], module.__dict__)
    if not callable(getattr(module, "build", None)):
        raise SceneError(f"scene file {str(path)!r} defines no build(**params) function")
    return module


def build_scene(path: str | Path, params: dict | None = None) -> Scene:
    """Import ``path`` and call its ``build(**params)``; unknown parameters are an error."""
    module = load_scene_module(path)
    params = dict(params or {})
    sig = inspect.signature(module.build)
    takes_any = any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values())
    unknown = [k for k in params if k not in sig.parameters]
    if unknown and not takes_any:
        raise SceneError(f"scene {Path(path).name}: unknown parameter(s) {', '.join(unknown)} "
                         f"(it takes: {', '.join(sig.parameters) or 'none'})")
    scene = module.build(**params)
    if not isinstance(scene, Scene):
        raise SceneError(f"scene {Path(path).name}: build() returned {type(scene).__name__}, not a warpsoft Scene")
    scene.params = params
    scene.params_used = {k: p.default for k, p in sig.parameters.items()
                         if p.default is not inspect.Parameter.empty} | params  # defaults included
    return scene


class Interrupted(BaseException):
    """The run was asked to stop (SIGINT or SIGTERM). A BaseException, as KeyboardInterrupt is:
    code that catches every Exception (a QP wrapper, the user's own) must not swallow it."""


def check_output(path: str | Path | None, what: str, suffixes: tuple[str, ...] | None = None) -> Path | None:
    """Fail before any compute when an output cannot be written: its folder must exist or be
    creatable, the file must open for writing, the path must not be a folder, and its extension
    must be one of ``suffixes``."""
    if path is None:
        return None
    path = Path(path)
    if suffixes is not None and path.suffix not in suffixes:
        raise SceneError(f"{what} {str(path)!r}: the extension must be one of {', '.join(suffixes)}")
    if path.is_dir():
        raise SceneError(f"{what} {str(path)!r} is a folder, not a file")
    try:  # the real test: create the folders and open the file (or, when it is not there yet, a
        # sibling: an empty file at the path itself would be read, half-made, by whoever watches it)
        path.parent.mkdir(parents=True, exist_ok=True)
        probe = path if path.exists() else path.with_name(path.name + ".probe")
        with open(probe, "a"):
            pass
        if probe != path:
            probe.unlink()
    except OSError as exc:
        raise SceneError(f"{what} {str(path)!r} cannot be written ({exc.strerror or exc}); nothing was run") from None
    return path


def check_device(device: str | None) -> None:
    """A device Warp knows on this machine, else a clear error."""
    if device is None:
        return
    import warp as wp

    if device.startswith("cuda") and not wp.is_cuda_available():
        raise SceneError(f"run: device {device!r} asked for, but Warp sees no CUDA device here")
    try:
        wp.get_device(device)
    except (ValueError, RuntimeError) as exc:
        known = ", ".join(str(d) for d in wp.get_devices())
        raise SceneError(f"run: unknown device {device!r} (this machine has: {known})") from exc


@contextmanager
def stop_on_signals():
    """SIGINT and SIGTERM stop the run cleanly (main thread only): the first one lets the step
    under way finish and be recorded everywhere, then :class:`Interrupted` is raised by
    ``check()``; a second one raises it at once. Yields ``check``; the previous handlers come
    back after."""
    asked: list[str] = []

    def check() -> None:
        if asked:
            raise Interrupted(asked[0])

    if threading.current_thread() is not threading.main_thread():
        yield check
        return

    def handler(signum, frame):
        if asked:  # asked twice: stop now
            raise Interrupted(asked[0])
        asked.append(signal.Signals(signum).name)

    saved = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield check
    finally:
        for s, h in saved.items():
            signal.signal(s, h)


def run(scene: Scene, steps: int | None = None, device: str | None = None, usd: str | Path | None = None,
        report: str | Path | None = None, solver: str = "auto", tolerance: float = 1e-6, progress: bool = False,
        scene_file: str | None = None, flush_every: int = 50, newton_iterations: int = 10,
        newton_tolerance: float | None = None, usd_contacts: bool = False) -> RunReport:
    """Simulate ``steps`` steps (the scene's default if None), optionally writing USD and a JSON report.
    ``newton_iterations`` and ``newton_tolerance`` are the :class:`Simulator`'s; ``usd_contacts``
    adds each frame's contact points and forces to the USD.

    Outputs are checked before anything runs, and written as the run goes (every
    ``flush_every`` steps and at its end), so a run that fails, is interrupted (SIGINT, SIGTERM) or
    is killed keeps the steps it finished. The report's ``status`` says how it ended
    (completed, failed, interrupted) and ``error`` why; a failure is raised again after the
    outputs are written, an interruption returns the report.
    """
    steps = scene.steps if steps is None else int(steps)
    if steps < 1:
        raise SceneError(f"run: steps must be >= 1, got {steps}")
    if int(flush_every) < 1:
        raise SceneError(f"run: flush_every must be >= 1, got {flush_every}")
    report = check_output(report, "report")
    usd = check_output(usd, "USD output", (".usda", ".usdc", ".usd"))
    check_device(device)
    sim = Simulator(scene, device=device, solver=solver, tolerance=tolerance, newton_iterations=newton_iterations,
                    newton_tolerance=newton_tolerance)
    rep = RunReport(sim, scene_file=scene_file, params=scene.params, params_used=getattr(scene, "params_used", None),
                    options={"solver": solver, "tolerance": tolerance, "steps": steps,
                             "newton_iterations": newton_iterations,
                             "newton_tolerance": sim.newton.tolerance})
    writer = None
    if usd is not None:
        from .usd import UsdWriter

        writer = UsdWriter(usd, sim.model, contacts=usd_contacts)
        writer.write_frame(0, sim.state.positions(), sim.probe_positions())
        writer.write_rows(0, sim.constraint_geometry())

    def flush() -> None:
        """Both outputs, each whole or left as it was; the first that cannot be written is raised
        (the run then stops as failed, and says why in whatever can still be written)."""
        failed = None
        for write in ([writer.save] if writer is not None else []) + ([lambda: rep.write(report)] if report else []):
            try:
                write()
            except OutputError as exc:
                failed = failed or exc
                if rep.status == "running":
                    rep.status, rep.error = "failed", str(exc)
        if failed is not None:
            raise failed

    failure = None
    iterator = range(steps)
    if progress:
        from tqdm import tqdm

        m = sim.model
        print(f"warpsoft: model of {m.num_nodes} nodes and {m.num_elements} elements on {m.device}; the first step "
              "compiles the kernels (once per machine: they are cached)...", file=sys.stderr, flush=True)
        iterator = tqdm(iterator, desc=scene.name, unit="step", disable=None)
    loads = ModuleLoads(say=lambda line: tqdm.write(line, file=sys.stderr)) if progress else nullcontext()
    with stop_on_signals() as interrupted, loads:
        try:
            flush()  # the outputs exist from the start (status "running")
            for k in iterator:
                interrupted()  # a stop asked for: after a step fully recorded
                stats = sim.step()
                probes = sim.probe_positions()
                rep.record(stats, probes)
                if writer is not None:
                    writer.write_frame(stats.index, sim.state.positions(), probes)
                    writer.write_rows(stats.index, sim.constraint_geometry())
                if (k + 1) % int(flush_every) == 0:
                    flush()
            interrupted()
            rep.status = "completed"
        except (Interrupted, KeyboardInterrupt) as exc:
            rep.status, rep.error = "interrupted", f"stopped by {exc or 'SIGINT'} after {len(rep.steps)} steps"
        except WarpsoftError as exc:
            rep.status, rep.error = "failed", f"{type(exc).__name__}: {exc}"
            failure = exc
        finally:
            if rep.status == "running":  # an error of another kind: record it, then let it go on
                rep.status, rep.error = "failed", "an unexpected error stopped the run (see the traceback)"
            try:
                flush()
            except OutputError:  # (each output that can be written is; the others keep their last whole file)
                pass
    if failure is not None:
        raise failure
    return rep
