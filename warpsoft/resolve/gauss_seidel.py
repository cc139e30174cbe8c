"""The direct model: actuator multipliers in constraint space by projected Gauss-Seidel.

Each actuator row ``i`` has ``delta_i = delta_free_i + sum_j W_ij lambda_j`` and is either
displacement-driven (``delta_i`` imposed) or force-driven (``lambda_i`` imposed), with
``lambda_i`` in ``[lo_i, hi_i]`` and ``delta_i`` in ``[dmin_i, dmax_i]`` (the displacement
bounds bind in force mode too). Projected Gauss-Seidel solves this mixed complementarity
problem; ``W`` is symmetric positive definite so the sweeps converge.

:func:`projected_gauss_seidel` is v1's NumPy reference for one world; :class:`GaussSeidel` runs
the same sweeps on the device for every world at once (``kernels/resolve/gauss_seidel.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.resolve import gauss_seidel as kernels

from ..launch import launch


@dataclass
class RowInputs:
    """Per actuator row, arrays of length ``na``: ``force_mode`` (bool), ``value`` (imposed
    delta or lambda), force bounds ``lo``/``hi``, displacement bounds ``dmin``/``dmax``."""

    force_mode: np.ndarray
    value: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    dmin: np.ndarray
    dmax: np.ndarray


@dataclass
class ResolveResult:
    lam: np.ndarray
    iterations: int
    residual: float  # largest change of a row's delta (its units) in the last sweep
    converged: bool


def projected_gauss_seidel(W: np.ndarray, delta_free: np.ndarray, rows: RowInputs, lam0: np.ndarray | None = None,
                           max_iterations: int = 1000, tolerance: float = 1e-10) -> ResolveResult:
    """Solve for ``lambda`` (``na``) given ``W`` (``na x na``) and ``delta_free`` (``na``).

    ``tolerance`` is relative to the largest ``|delta|`` scale of the problem.
    """
    na = len(delta_free)
    lam = np.zeros(na) if lam0 is None else np.clip(np.array(lam0, dtype=float), rows.lo, rows.hi)
    target = np.clip(rows.value, rows.dmin, rows.dmax)
    diag = np.diag(W).copy()
    # the scale of delta: the free deltas and the displacement-driven rows' targets (a force-driven
    # row's value is a force, N or Pa, not a delta)
    aimed = np.where(np.asarray(rows.force_mode, dtype=bool), 0.0, np.abs(target))
    scale = max(float(np.max(np.abs(delta_free), initial=0.0)), float(np.max(aimed, initial=0.0)), 1e-300)
    change = 0.0
    for it in range(1, max_iterations + 1):
        change = 0.0
        for i in range(na):
            if diag[i] <= 0.0:  # a row that moves nothing: its force is only bounded
                new = np.clip(rows.value[i] if rows.force_mode[i] else 0.0, rows.lo[i], rows.hi[i])
            else:
                d = delta_free[i] + W[i] @ lam
                if rows.force_mode[i]:
                    new = rows.value[i]
                    d_new = d + diag[i] * (new - lam[i])
                    if d_new > rows.dmax[i]:
                        new += (rows.dmax[i] - d_new) / diag[i]
                    elif d_new < rows.dmin[i]:
                        new += (rows.dmin[i] - d_new) / diag[i]
                else:
                    new = lam[i] + (target[i] - d) / diag[i]
                new = min(max(new, rows.lo[i]), rows.hi[i])
            change = max(change, abs(new - lam[i]) * max(diag[i], 0.0))
            lam[i] = new
        if change <= tolerance * scale:
            return ResolveResult(lam, it, change, True)
    return ResolveResult(lam, max_iterations, change, False)


def kinematic_jacobian(W_ea: np.ndarray, W_aa: np.ndarray) -> np.ndarray:
    """``J = W_ea W_aa^-1``: effector motion (m) per unit actuator displacement, ``(ne, na)``."""
    return np.linalg.solve(W_aa.T, W_ea.T).T


class GaussSeidel:
    """Projected Gauss-Seidel of every world on the device (one thread per world).

    Per-row inputs live on the device in ``inputs`` ``(NUM_INPUTS, rows)`` (mode, value, force
    and displacement bounds, step bound; see the kernel module): the constant ones are written
    once; :meth:`set_values` uploads the inputs of a step in one copy, only when they changed.
    ``lam`` ``(rows,)`` holds the multipliers (warm start on entry); ``result`` ``(worlds, 3)``
    the sweeps, last change and convergence of each world.
    """

    def __init__(self, rows, max_iterations: int = 1000, tolerance: float = 1e-10):
        self.rows, d = rows, rows.device
        n = max(rows.num_rows, 1)
        host = np.zeros((kernels.NUM_INPUTS, n))
        for w in range(rows.num_worlds):
            for k, a in enumerate(rows.actuators[w]):
                r = rows.world_row_start[w] + k
                host[:, r] = [a.mode == "force", 0.0, a.min_force, a.max_force, a.min_displacement,
                              a.max_displacement, a.max_step, 0.0]
            # an attachment's rows: displacement-driven at 0, the force free (bilateral)
            held = rows.bilateral_rows(w)
            host[:, held] = np.array([[0.0, 0.0, -np.inf, np.inf, -np.inf, np.inf, np.inf, 0.0]]).T
            # a contact's rows: the normal force is 0 unless the gap would close, lambda >= 0 and
            # gap >= 0 (Signorini); with friction, each tangent holds the slip at 0, its force
            # bounded by Coulomb (the kernel reads mu lambda_n)
            block = rows.contact_rows(w)
            rps = rows.rows_per_contact(w)
            for m in range(rps):
                rows_m = np.arange(block.start + m, block.stop, rps)
                host[:, rows_m] = np.array([[1.0, 0.0, 0.0, np.inf, 0.0, np.inf, np.inf, 0.0]]).T if m == 0 else \
                    np.array([[1.0, 0.0, -np.inf, np.inf, 0.0, 0.0, np.inf, float(m)]]).T
        self.host = host
        self.inputs = wp.array(host, dtype=wp.float64, device=d)
        self.lam = wp.zeros(n, dtype=wp.float64, device=d)
        self.friction = wp.zeros(n, dtype=wp.float64, device=d)  # mu of each contact tangent row (detection)
        self.result = wp.zeros((rows.num_worlds, 3), dtype=wp.float64, device=d)
        self.max_iterations, self.tolerance = int(max_iterations), float(tolerance)
        self._uploaded = None
        # the worlds it resolves: not an inverse world (its QP decides its multipliers)
        self.direct = wp.array([0 if s.inverse else 1 for s in rows.model.scenes], dtype=wp.int32, device=d)
        self._cpu = None  # the constant inputs of solve_host, on the host
        # the bilateral block's Cholesky factor and solve vector, per world (1 x 1 without one)
        nb = max(int(rows.world_bilateral.max(initial=0)), 1)
        self.factor = wp.zeros((rows.num_worlds, nb, nb), dtype=wp.float64, device=d)
        self.work = wp.zeros((rows.num_worlds, nb), dtype=wp.float64, device=d)
        self.counts = (rows.world_actuators_d, wp.array(rows.world_bilateral, dtype=wp.int32, device=d))

    def set_values(self, values: np.ndarray) -> None:
        """The imposed value of every row ``(rows,)`` this step; one copy when they changed."""
        if self._uploaded is None or not np.array_equal(values, self._uploaded):
            self.host[kernels.VALUE, : len(values)] = values
            self.inputs.assign(self.host)
            self._uploaded = values.copy()

    def host_arrays(self) -> dict:
        """The per-world arrays of a sweep on Warp's CPU device (the row starts, which worlds
        sweep, ``result``, the counts, the bilateral factor and its work vector): the device's
        own on the CPU, copies made once on CUDA (then ``result`` must be copied back)."""
        if self.rows.device.is_cpu:
            return {"row_start": self.rows.world_row_start_d, "direct": self.direct, "result": self.result,
                    "counts": self.counts, "factor": self.factor, "work": self.work}
        if self._cpu is None:  # what does not change from step to step, on the host once
            cpu, rows = "cpu", self.rows
            self._cpu = {"row_start": wp.array(rows.world_row_start, dtype=wp.int32, device=cpu),
                         "direct": wp.array(self.direct.numpy(), dtype=wp.int32, device=cpu),
                         "result": wp.zeros((rows.num_worlds, 3), dtype=wp.float64, device=cpu),
                         "counts": tuple(wp.array(c.numpy(), dtype=wp.int32, device=cpu) for c in self.counts),
                         "factor": wp.zeros(self.factor.shape, dtype=wp.float64, device=cpu),
                         "work": wp.zeros(self.work.shape, dtype=wp.float64, device=cpu)}
        return self._cpu

    def solve_host(self, host: dict[str, np.ndarray]) -> None:
        """The same sweeps on the host (Warp's CPU device), from the arrays of one read ``host``
        (``W``, ``delta_free``, ``delta`` at the step's start, ``lam``, ``force_rows``,
        ``friction``): ``host["lam"]`` is updated in place and the sweeps' ``result`` copied to the
        device. On CUDA, one thread per world sweeping many contact rows runs at its single
        thread's latency (docs/performance.md)."""
        c = self.host_arrays()
        host["lam"][:] = self._sweep_host(host, self.host, c["direct"], host["lam"], c["result"])
        self.result.assign(c["result"].numpy())

    def _sweep_host(self, host: dict[str, np.ndarray], inputs: np.ndarray, direct: wp.array, lam0: np.ndarray,
                    result: wp.array) -> np.ndarray:
        """The sweeps on Warp's CPU device from one read ``host``, with the row inputs ``inputs``,
        the worlds flagged in ``direct``, the multipliers starting at ``lam0``; the multipliers."""
        c, cpu = self.host_arrays(), "cpu"
        f64 = lambda a: wp.array(a, dtype=wp.float64, device=cpu)  # noqa: E731
        lam = f64(lam0)
        self._launch(f64(host["W"]), f64(host["delta_free"]), f64(host["delta"]), f64(inputs), c["row_start"],
                     wp.array(host["force_rows"], dtype=wp.int32, device=cpu), direct, f64(host["friction"]), lam,
                     result, c["counts"], c["factor"], c["work"])
        return lam.numpy()

    def contacts_at(self, host: dict[str, np.ndarray], world: int, actuators: slice, lam_a: np.ndarray) -> np.ndarray:
        """The direct model's multipliers of ``world``'s force rows (``(rows,)``, the others as in
        ``host["lam"]``) with its actuator rows ``actuators`` held at the forces ``lam_a``: the
        same sweeps on the host (Warp's CPU device) from one read ``host`` (as :meth:`solve_host`),
        the contacts warm-started from ``host["lam"]``."""
        cpu, k = "cpu", kernels
        inputs = self.host.copy()
        inputs[[k.FORCE_MODE, k.VALUE], actuators] = [np.ones(len(lam_a)), lam_a]
        inputs[[k.LO, k.DMIN], actuators], inputs[[k.HI, k.DMAX, k.MAX_STEP], actuators] = -np.inf, np.inf
        direct = np.zeros(self.rows.num_worlds, dtype=np.int32)
        direct[world] = 1
        lam0 = host["lam"].copy()
        lam0[actuators] = lam_a
        return self._sweep_host(host, inputs, wp.array(direct, dtype=wp.int32, device=cpu), lam0,
                                wp.zeros((self.rows.num_worlds, 3), dtype=wp.float64, device=cpu))

    def _launch(self, W, delta_free, delta_now, inputs, row_start, force_rows, direct, friction, lam, result,
                counts, factor, work) -> None:
        """The sweeps, on the device the arrays live on."""
        launch(kernels.projected_gauss_seidel, self.rows.num_worlds,
               inputs=[W, delta_free, delta_now, inputs, row_start, force_rows, direct, friction, *counts,
                       self.max_iterations, self.tolerance], outputs=[lam, result, factor, work], device=lam.device)

    def solve(self, W: wp.array, delta_free: wp.array, delta_now: wp.array) -> None:
        """``lam`` of every direct-model world's force rows in use (actuators, contacts) from ``W``
        ``(rows, columns)``, ``delta_free`` and the rows' values at the start of the step
        ``delta_now`` (``(rows,)``); on the device. Inverse-model worlds' multipliers are left alone."""
        rows = self.rows
        self._launch(W, delta_free, delta_now, self.inputs, rows.world_row_start_d, rows.world_force_rows, self.direct,
                     self.friction, self.lam, self.result, self.counts, self.factor, self.work)
