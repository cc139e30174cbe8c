"""Warm starts of the step's first solve, extrapolated from the last steps' solutions.

An iterative solve stops at a residual relative to its right-hand side, so the closer its start,
the fewer its iterations. The free motion of a step and the actuators' compliance columns change
smoothly from step to step: the quadratic through the last three steps' solutions, taken one step
on, starts closer than the last solution alone (8 Diamonds of different meshes on the CPU, 20
steps: the slowest world's iterations summed 318 -> 277, a world's mean 8.8 -> 7.6; the
trajectories 7e-10 m apart, of a 32 mm motion). The columns of contacts, whose rows change every
step, start from the last solution; so does every column after a state changed from outside,
every quasi-static step (its solution is a correction toward equilibrium, not a smooth motion: a
cable bar's steps took 13-16 iterations from the extrapolation against 5-6 from the last solution),
and every world with contacts or frames carried by a schedule, whose motion turns abruptly (the
Grasper on the H200: a median of 3-4 CG iterations a step extrapolated, 2 from the last solution).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.linear import guess as kernels

from ..launch import launch


class Extrapolation:
    """The history of a step's solutions and the extrapolated start of the next.

    Args:
        columns, nodes: the solve's shape ``(k, n)``.
        held: ``(worlds,)`` each world's force rows that persist from step to step (actuators,
            attachments): its columns ``1 .. held[w]`` are extrapolated, as is column 0 (the free
            motion); -1: none of the world's columns.
        node_world: ``(n,)`` each node's world.
    """

    def __init__(self, columns: int, nodes: int, held: np.ndarray, node_world: wp.array, device):
        self.device = device
        self.held = wp.array(np.asarray(held, dtype=np.int32), dtype=wp.int32, device=device)
        self.node_world = node_world
        self.last = wp.zeros((columns, nodes), dtype=wp.vec3d, device=device)  # the solution a step ago (m)
        self.before = wp.zeros((columns, nodes), dtype=wp.vec3d, device=device)  # two steps ago (m)
        self.steps = wp.zeros(1, dtype=wp.int32, device=device)  # starts made since the history began (0-3)

    def predict(self, x: wp.array, moved: wp.array) -> None:
        """``x`` ``(k, n)``, the last step's solutions, becomes the extrapolated start of this step's
        solve; ``moved`` ``(1,)`` is nonzero when the state was changed from outside since the last
        step (its solutions then say nothing of this one's)."""
        launch(kernels.extrapolate, x.shape, inputs=[self.held, self.node_world, self.steps, moved],
               outputs=[x, self.last, self.before], device=self.device)
        launch(kernels.count_steps, 1, inputs=[moved], outputs=[self.steps], device=self.device)

    def forget(self) -> None:
        """Start the history again (the solutions were discarded)."""
        self.steps.zero_()
