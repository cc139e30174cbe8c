"""Kinematic frames: fixed regions carried by a motion (a moving base, a gripper's palm).

A region fixed with ``Scene.fix(..., motion=...)`` keeps its nodes out of the solve (as any fixed
region) but moves them: each step prescribes their displacement, from where they are to where
the frame will be at the step's end (their rest positions under the pose ``motion(t)``, along
their fixed axes). The step's first solve takes it as a known part of ``dx``: the free nodes
solve ``A_ff e = r_f - A_fd dx_d`` (one operator product moves it to the right-hand side), so
the elements they pull on feel the move in the same step, at the linearization the last step
left (no extra one). The schedules are called once per step on the host and their targets
uploaded in one copy; nothing of this runs in a scene without one.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels import drive as kernels

from .launch import launch
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
        self.a_dx = wp.zeros((1, model.num_nodes), dtype=wp.vec3d, device=d)  # A dx of the prescribed move

    def set_time(self, t: float) -> None:
        """Where every frame carries its nodes at time ``t`` (s), uploaded in one copy when it
        changed."""
        target = self.host.copy()
        for label, motion, sl in self.groups:
            rotation, translation = pose_of(motion, t, f"{label}: motion")
            target[sl] = self.rest[sl] @ rotation.T + translation
        if not np.array_equal(target, self.host):  # a frame at rest uploads nothing
            self.host = target
            self.target.assign(self.host)

    def prescribe(self, q: wp.array, dx: wp.array, rhs: wp.array, operator, mask: wp.array) -> None:
        """The step starts with the driven nodes' move in ``dx`` (``(1, n)``, from ``q``) and its
        pull on the free nodes taken off ``rhs[0]`` (device; capturable)."""
        m = self.model
        launch(kernels.prescribe, len(self.rest), inputs=[self.ids, self.target, self.axes, q], outputs=[dx],
               device=m.device)
        operator.apply(dx, self.a_dx)
        launch(kernels.lift_rhs, m.num_nodes, inputs=[mask, self.a_dx], outputs=[rhs], device=m.device)
