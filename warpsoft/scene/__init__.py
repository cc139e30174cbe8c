"""What a user writes, host only (no Warp here): the Scene, its bodies, materials, meshes
and shapes, regions, actuators (cables, cavities), effectors and schedules.

A scene is validated as it is written, with errors that name the component and the value;
:func:`warpsoft.finalize` turns one or several scenes into a device-side Model.
"""

from . import obstacles, regions, shapes
from .actuator import Actuator, Ramp
from .cable import Cable
from .cavity import Cavity
from .effector import Effector, waypoints
from .material import Material
from .mesh import TetMesh, box_grid, load_mesh, rotation_about, save_mesh
from .regions import Box, HalfSpace, InBox, InHalfSpace, InSphere, OnPlane, Plane, Region, Sphere
from .scene import Body, Fixture, Load, Probe, Scene, load_weights
from .shapes import Ball, Cone, Cylinder, mesh_shape, mesh_surface

__all__ = [
    "Actuator", "Ball", "Body", "Box", "Cable", "Cavity", "Cone", "Cylinder", "Effector", "Fixture", "HalfSpace",
    "InBox", "InHalfSpace", "InSphere", "OnPlane",
    "Load", "Material", "Plane", "Probe", "Ramp", "Region", "Scene", "Sphere", "TetMesh", "box_grid", "load_mesh",
    "load_weights", "mesh_shape", "mesh_surface", "obstacles", "regions", "rotation_about", "save_mesh", "shapes",
    "waypoints",
]
