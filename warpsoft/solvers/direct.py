"""Assembled sparse direct solve of ``A = mass_scale M + stiffness_scale K`` (SciPy SuperLU).

The CPU alternative to PCG and the accuracy reference for it: element blocks come from a
Warp kernel, assembly and factorization from SciPy. Fixed DOFs are removed from the system.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import warp as wp

from warpsoft.kernels import fem

from ..model import Model


class SparseDirect:
    """Factorize and solve the step's linear system on the host.

    Args:
        model: the model; its element rotations come with each :meth:`factorize` call.
    """

    def __init__(self, model: Model):
        self.model = model
        tets = model.tets_np.astype(np.int64)
        a = np.arange(4)
        # entry (e, a, b, i, j) of the (m, 16, 9) block array -> (row, col) in the global matrix
        rows = 3 * tets[:, a][:, :, None, None, None] + np.arange(3)[None, None, None, :, None]
        cols = 3 * tets[:, a][:, None, :, None, None] + np.arange(3)[None, None, None, None, :]
        rows = np.broadcast_to(rows, (len(tets), 4, 4, 3, 3)).ravel()
        cols = np.broadcast_to(cols, (len(tets), 4, 4, 3, 3)).ravel()
        free = model.mask_np.ravel() > 0
        self.free = np.flatnonzero(free)
        renum = np.full(model.num_dofs, -1, dtype=np.int64)
        renum[self.free] = np.arange(len(self.free))
        self.keep = free[rows] & free[cols]
        self.rows, self.cols = renum[rows[self.keep]], renum[cols[self.keep]]
        self.mass_free = None if model.mass is None else np.repeat(model.mass_np, 3)[self.free]
        self.blocks = wp.zeros(16 * model.num_elements, dtype=wp.mat33d, device=model.device)
        self._lu = None

    def matrix(self, rot: wp.array, mass_scale: float, stiffness_scale: float) -> sp.csc_matrix:
        """``A`` restricted to the free DOFs, shape ``(f, f)``."""
        m = self.model
        wp.launch(fem.stiffness_blocks, m.num_elements, inputs=[m.dm_inv, m.volume, m.mu, m.lam, rot],
                  outputs=[self.blocks], device=m.device)
        data = stiffness_scale * self.blocks.numpy().reshape(-1)[self.keep]
        nf = len(self.free)
        A = sp.coo_matrix((data, (self.rows, self.cols)), shape=(nf, nf)).tocsc()
        if mass_scale != 0.0:
            A = A + sp.diags(mass_scale * self.mass_free, format="csc")
        return A

    def factorize(self, rot: wp.array, mass_scale: float, stiffness_scale: float) -> None:
        self._lu = spla.splu(self.matrix(rot, mass_scale, stiffness_scale))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve for right-hand sides ``(k, n, 3)``; fixed DOFs get 0."""
        flat = b.reshape(b.shape[0], self.model.num_dofs).T
        x = np.zeros_like(flat)
        x[self.free] = self._lu.solve(np.ascontiguousarray(flat[self.free]))
        return np.ascontiguousarray(x.T).reshape(b.shape)
