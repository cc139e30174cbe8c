"""warpsoft: model, simulate and control soft robots with NVIDIA Warp.

A scene is written in Python (``import warpsoft as ws``), built into a device-side
:class:`Model` of one or more worlds (:func:`finalize`) and stepped by a :class:`Simulator`
on Warp's CPU or CUDA device.
"""

import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no banner or per-module load lines


def _init_warp_without_driver_warning() -> None:
    """On a machine with no NVIDIA driver, Warp's C runtime prints a warning on stderr at every
    start (and runs on the CPU device, as it should): initialize it now with that stream muted.
    With a driver, nothing happens here and Warp starts when first used, as usual."""
    import ctypes.util
    import os

    if ctypes.util.find_library("cuda") is not None:
        return
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        _wp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


_init_warp_without_driver_warning()

from .errors import (  # noqa: E402
    MeshError,
    OutputError,
    SceneError,
    SimulationError,
    UserCodeError,
    WarpsoftError,
)
from .model import Model, finalize  # noqa: E402
from .scene import (  # noqa: E402
    Ball,
    Box,
    Cone,
    Cylinder,
    HalfSpace,
    InBox,
    InHalfSpace,
    InSphere,
    Material,
    OnPlane,
    Plane,
    Ramp,
    Region,
    Scene,
    Sphere,
    TetMesh,
    box_grid,
    load_mesh,
    mesh_shape,
    mesh_surface,
    obstacles,
    regions,
    rotation_about,
    save_mesh,
    shapes,
    waypoints,
)
from .simulator import ConvergenceWarning, Simulator, StepStats, WorldStats  # noqa: E402
from .state import Control, State  # noqa: E402

__version__ = "0.1.0"

__all__ = [
    "Ball", "Box", "Cone", "Control", "ConvergenceWarning", "Cylinder", "HalfSpace", "InBox", "InHalfSpace", "InSphere",
    "Material", "MeshError", "Model", "OnPlane", "OutputError",
    "Plane", "Ramp", "Region", "Scene", "SceneError", "SimulationError", "Simulator", "Sphere", "State", "StepStats",
    "TetMesh", "UserCodeError", "WarpsoftError", "WorldStats", "box_grid", "finalize", "load_mesh", "mesh_shape",
    "mesh_surface", "obstacles", "regions", "rotation_about", "save_mesh", "shapes", "waypoints",
]
