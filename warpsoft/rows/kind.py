"""What every kind of constraint row provides to the row table.

A kind (cable, cavity, effector, ...) is one file in ``warpsoft/rows/`` with its kernels in
``kernels/rows/`` and one line in :data:`warpsoft.rows.ROW_KINDS`. The table places the items
of every world (a scene's cables, its cavities, ...) row by row and hands each kind its
:class:`Placed` items; the kind uploads what its kernel needs and writes ``delta`` and the
sparse ``H`` entries of its rows in one launch over all worlds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Placed:
    """An item of a scene (a Cable, a Cavity, an Effector) placed in the table: its world, its
    first row and row count, its first mapped point (global point id) and point count."""

    world: int
    item: object
    first_row: int
    num_rows: int
    first_point: int = 0
    num_points: int = 0

    @property
    def rows(self) -> range:
        return range(self.first_row, self.first_row + self.num_rows)


class RowKind:
    """Base of a row kind. Class attributes: ``name``; ``columns`` (True: the rows carry a force
    solved for, so each gets a compliance column); ``actuator`` (True: the rows are the scene's
    actuators, with inputs; an actuator kind has columns); ``bilateral`` (True: rows with columns
    held at ``delta = 0`` by a free force, always in use: attachments); ``scene_attr`` (the
    Scene's list of items)."""

    name = "row"
    actuator = False
    bilateral = False
    columns = False
    scene_attr = ""

    def __init__(self, model, placed: list[Placed], entry_offset: int):
        self.model, self.placed, self.entry_offset = model, placed, entry_offset
        self.num_entries = 0

    @classmethod
    def items(cls, scene) -> list:
        return list(getattr(scene, cls.scene_attr))

    @staticmethod
    def row_count(item) -> int:
        """Rows of one item (one by default; an effector has one per controlled axis)."""
        return 1

    @staticmethod
    def points(item) -> np.ndarray:
        """Rest positions (m), ``(k, 3)``, of the item's points mapped into the mesh (none by default)."""
        return np.zeros((0, 3))

    @staticmethod
    def point_elements(model, world: int, item) -> tuple[int, int]:
        """The element range ``[start, stop)`` the item's points are located in (its body's)."""
        info = model.body_info(item.body.name, world)
        return info.elem_start, info.elem_start + info.elem_count

    def rest_delta(self) -> dict[int, float]:
        """Constant part of ``delta`` per row (row id -> value); the kernel adds the rest."""
        return {}

    def evaluate(self, table, q) -> None:
        """Write ``delta`` (added to its constant part) and the ``H`` entries of these rows at ``q``."""
        raise NotImplementedError
