"""Load scene files and run them: the engine behind ``warpsoft run`` (also usable from Python)."""

from __future__ import annotations

import ast
import importlib.util
import inspect
import json
import sys
from pathlib import Path
from types import ModuleType

from ..errors import SceneError, SimulationError
from ..scene import Scene
from ..simulator import Simulator
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


def load_scene_module(path: str | Path) -> ModuleType:
    """Import a scene file (it must define ``build(**params) -> Scene``)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"scene file {str(path)!r} does not exist")
    name = f"warpsoft_scene_{path.stem}_{abs(hash(str(path.resolve())))}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
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
    return scene


def run(scene: Scene, steps: int | None = None, device: str | None = None, usd: str | Path | None = None,
        report: str | Path | None = None, solver: str = "auto", tolerance: float = 1e-6, progress: bool = False,
        scene_file: str | None = None) -> RunReport:
    """Simulate ``steps`` steps (the scene's default if None), optionally writing USD and a JSON report.

    A step that fails (non-finite state) stops the run; what was recorded up to it is still
    written, and the error is raised afterwards.
    """
    steps = scene.steps if steps is None else int(steps)
    if steps < 1:
        raise SceneError(f"run: steps must be >= 1, got {steps}")
    if device is not None and device.startswith("cuda"):
        import warp as wp

        if not wp.is_cuda_available():
            raise SceneError(f"run: device {device!r} asked for, but Warp sees no CUDA device here")
    sim = Simulator(scene, device=device, solver=solver, tolerance=tolerance)
    rep = RunReport(sim, scene_file=scene_file, params=scene.params)
    writer = None
    if usd is not None:
        from .usd import UsdWriter

        writer = UsdWriter(usd, sim.model)
        writer.write_frame(0, sim.state.positions(), sim.probe_positions())
        writer.write_rows(0, sim.constraint_geometry())
    failure = None
    iterator = range(steps)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=scene.name, unit="step", disable=None)
    try:
        for _ in iterator:
            stats = sim.step()
            probes = sim.probe_positions()
            rep.record(stats, probes)
            if writer is not None:
                writer.write_frame(stats.index, sim.state.positions(), probes)
                writer.write_rows(stats.index, sim.constraint_geometry())
    except SimulationError as exc:
        failure = exc
    finally:
        if writer is not None:
            writer.save()
        if report is not None:
            rep.write(report)
    if failure is not None:
        raise failure
    return rep
