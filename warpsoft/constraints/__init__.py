"""Constraint rows: actuators (cables, pneumatic cavities) and effectors, each row a
measure ``delta(q)``, a direction ``H = d delta / dq`` and a multiplier ``lambda``."""

from .actuator import Actuator
from .cable import Cable
from .cavity import Cavity
from .effector import Effector
from .rows import ConstraintSet

__all__ = ["Actuator", "Cable", "Cavity", "ConstraintSet", "Effector"]
