"""Kinematic frames: fixed regions carried by a motion (a moving base, a gripper's palm).

A region fixed with ``Scene.fix(..., motion=...)`` keeps its nodes out of the solve (as any fixed
region) but moves them: at each step's start they are put where the frame will be at the
step's end (their rest positions under the pose ``motion(t)``), along their fixed axes; the
step is then linearized there, so the elements they pull on feel the move in the same step
(one implicit step of a prescribed displacement). The schedules are called once per step on
the host and their targets uploaded in one copy; nothing of this runs in a scene without one.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels import drive as kernels

from .scene.obstacles import pose_of


class DrivenNodes:
    """The model's driven nodes (``Model.driven``).

    Device: ``ids`` ``(k,)`` global node ids, ``axes`` ``(k,)`` vec3d (1 = driven axis),
    ``target`` ``(k,)`` vec3d (m) where they go this step. Host: ``rest`` ``(k, 3)`` (m).
    """

    def __init__(self, model):
        self.model, d = model, model.device
        self.groups, start = [], 0
        for label, motion, ids, _ in model.driven:
            self.groups.append((label, motion, slice(start, start + len(ids))))
            start += len(ids)
        ids = np.concatenate([g[2] for g in model.driven])
        self.rest = model.rest_np[ids]
        self.ids = wp.array(ids.astype(np.int32), dtype=wp.int32, device=d)
        self.axes = wp.array(np.concatenate([g[3] for g in model.driven]), dtype=wp.vec3d, device=d)
        self.host = self.rest.copy()
        self.target = wp.array(self.host, dtype=wp.vec3d, device=d)

    def set_time(self, t: float) -> None:
        """Where every frame carries its nodes at time ``t`` (s), uploaded in one copy."""
        for label, motion, sl in self.groups:
            rotation, translation = pose_of(motion, t, f"{label}: motion")
            self.host[sl] = self.rest[sl] @ rotation.T + translation
        self.target.assign(self.host)

    def apply(self, q: wp.array, v: wp.array) -> None:
        """Move the driven nodes of the state ``(q, v)`` to their targets (device; capturable)."""
        m = self.model
        wp.launch(kernels.drive_nodes, len(self.rest),
                  inputs=[self.ids, self.target, self.axes, 0.0 if m.static else 1.0 / m.dt], outputs=[q, v],
                  device=m.device)
