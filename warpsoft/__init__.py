"""warpsoft: model, simulate and control soft robots with NVIDIA Warp.

A scene is written in Python (``import warpsoft as ws``), built into a device-side
:class:`Model` and stepped by a :class:`Simulator` on Warp's CPU or CUDA device.
"""

import warp as _wp

_wp.config.log_level = _wp.LOG_WARNING  # no banner or per-module load lines

from . import regions, shapes  # noqa: E402
from .constraints.effector import waypoints  # noqa: E402
from .control import Control  # noqa: E402
from .errors import MeshError, SceneError, SimulationError, WarpsoftError  # noqa: E402
from .material import Material  # noqa: E402
from .mesh import TetMesh, box_grid, load_mesh, rotation_about, save_mesh  # noqa: E402
from .model import Model, State  # noqa: E402
from .regions import Box, HalfSpace, Plane, Region, Sphere  # noqa: E402
from .scene import Scene  # noqa: E402
from .shapes import Ball, Cone, Cylinder, mesh_shape  # noqa: E402
from .simulator import ConvergenceWarning, Simulator, StepStats  # noqa: E402

__version__ = "0.1.0"

__all__ = [
    "Ball", "Box", "Cone", "Control", "ConvergenceWarning", "Cylinder", "HalfSpace", "Material", "MeshError", "Model",
    "Plane", "Region", "Scene", "SceneError", "SimulationError", "Simulator", "Sphere", "State", "StepStats",
    "TetMesh", "WarpsoftError", "box_grid", "load_mesh", "mesh_shape", "regions", "rotation_about", "save_mesh",
    "shapes", "waypoints",
]
