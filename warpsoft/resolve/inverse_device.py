"""The inverse model's QP on the device, every world at once (``kernels/resolve/inverse_qp.py``).

The same problem as :func:`warpsoft.resolve.inverse.solve_inverse` (piqp, the reference),
solved exactly by a dual active-set method in one thread per world, for up to ``NMAX``
actuators. On CUDA it lets an inverse step run as one graph, with no host round trip around a
QP; the host reads each world's status with the step's statistics.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.resolve import inverse_qp as kernels

from ..launch import launch

NMAX = kernels.NMAX
STATUS = {int(kernels.OPTIMAL): "optimal", int(kernels.EMPTY_BOUNDS): "infeasible", int(kernels.INFEASIBLE):
          "infeasible", int(kernels.ITERATION_CAP): "failed", int(kernels.BREAKDOWN): "failed"}


class DeviceInverse:
    """Per-world data of the device QP.

    Args:
        rows: the model's :class:`~warpsoft.rows.Rows`.
        scenes: the model's scenes (which worlds use the inverse model, their ``eps``).
        effector_weights: per world, the weight of each of its effector rows, ``(ne_w,)``.
        max_iterations: active-set iterations per world and step (a cap, reported).
    """

    def __init__(self, rows, scenes, effector_weights: list[np.ndarray], max_iterations: int = 200):
        d, worlds = rows.device, rows.num_worlds
        self.rows = rows
        self.worlds = [w for w, s in enumerate(scenes) if s.inverse and rows.world_actuators[w]]
        self.usable = all(rows.world_actuators[w] <= NMAX for w in self.worlds)
        weight = np.zeros(max(rows.num_rows, 1))
        start, count = np.zeros(worlds, dtype=np.int32), np.zeros(worlds, dtype=np.int32)
        for w in range(worlds):
            e = rows.effector_rows(w)
            start[w], count[w] = e.start, e.stop - e.start
            weight[e] = effector_weights[w]
        eps = np.array([s.inverse_epsilon if w in self.worlds else -1.0 for w, s in enumerate(scenes)])
        self.effector_start = wp.array(start, dtype=wp.int32, device=d)
        self.effector_count = wp.array(count, dtype=wp.int32, device=d)
        self.row_weight = wp.array(weight, dtype=wp.float64, device=d)
        self.epsilon = wp.array(eps, dtype=wp.float64, device=d)
        self.result = wp.zeros((worlds, kernels.NUM_RESULTS), dtype=wp.float64, device=d)
        self.max_iterations = int(max_iterations)
        most = max((int(rows.world_actuators[w]) for w in self.worlds), default=1)
        self._kernel = kernels.qp_kernels(kernels.size_for(most))[0] if self.usable else None

    def solve(self, W: wp.array, delta_free: wp.array, delta_now: wp.array, inputs: wp.array, lam: wp.array) -> None:
        """``lam`` of the inverse worlds' actuator rows (device; ``lam`` holds the previous
        actuation on entry)."""
        rows = self.rows
        launch(self._kernel, rows.num_worlds,
               inputs=[W, delta_free, delta_now, inputs, rows.world_row_start_d, rows.world_actuators_d,
                       self.effector_start, self.effector_count, self.row_weight, self.epsilon,
                       self.max_iterations], outputs=[lam, self.result], device=rows.device)

    @staticmethod
    def iterations(result: np.ndarray, world: int) -> int:
        """Active-set iterations of ``world`` in a read ``result``."""
        return int(result[world, kernels.ITERATIONS])

    @staticmethod
    def outcome(result: np.ndarray, world: int) -> tuple[str, str | None]:
        """``(status, warning)`` of ``world`` from a read ``result`` ``(worlds, 3)``."""
        code = int(result[world, kernels.STATUS])
        status = STATUS.get(code, "failed")
        if code == int(kernels.OPTIMAL):
            return status, None
        if code == int(kernels.EMPTY_BOUNDS):
            return status, (f"actuator row {int(result[world, kernels.DETAIL])}: empty bounds (its displacement or "
                            "force interval is empty this step); the previous actuation is kept")
        if code == int(kernels.INFEASIBLE):
            return status, ("QP found no solution: the actuator bounds cannot all be met this step; the previous "
                            "actuation is kept")
        if code == int(kernels.BREAKDOWN):
            return status, "QP met a numerical breakdown (a non-finite solution); the previous actuation is kept"
        return status, (f"QP stopped after {int(result[world, kernels.ITERATIONS])} active-set iterations; the "
                        "previous actuation is kept")
