"""Linear solvers of the step's system ``A x = b``, behind one protocol:
``prepare()`` once per linearization, ``solve(b, x) -> SolveResult`` for ``(k, n)`` vec3d
columns (``x`` holds the warm start).

| name | what | where it is the fastest |
|---|---|---|
| ``pcg`` | CG preconditioned by the rest factorization warped by node rotations, loop on the device | CUDA |
| ``direct`` | assembled sparse Cholesky (CHOLMOD), pattern analysed once | CPU |
| ``jacobi`` | v1's block-Jacobi CG, kept to compare against | nowhere |
| ``auto`` | ``direct`` on the CPU device, ``pcg`` on CUDA (measured: docs/performance.md) | |
"""

from __future__ import annotations

import warp as wp

from .blocks import WorldBlocks
from .direct import SparseDirect
from .factors import WorldFactors
from .jacobi import BlockJacobi, BlockJacobiCG
from .operator import SystemOperator
from .pcg import PCG, SolveResult
from .warped import WarpedFactor

SOLVERS = ("auto", "pcg", "direct", "jacobi")
PRECONDITIONERS = ("auto", "host", "dense", "blocks", "factors")  # pcg's


def choose(name: str, device) -> str:
    """The solver ``name`` stands for on ``device``: ``auto`` is ``direct`` on the CPU device,
    ``pcg`` on CUDA."""
    if name not in SOLVERS:
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {name!r}")
    if name == "auto":
        return "pcg" if wp.get_device(device).is_cuda else "direct"
    return name


def make_solver(name: str, operator: SystemOperator, columns: int, tolerance: float = 1e-6,
                max_iterations: int = 2000, graphs: bool = True, check_every: int | None = None,
                factorization: str = "cholmod", preconditioner: str = "auto", precision: str = "float32",
                share_tolerance: float = 1e-10, block: bool = True, directions: str = "auto"):
    """A solver for ``columns`` right-hand sides: ``name`` from :data:`SOLVERS` (``auto`` resolved
    by :func:`choose`). ``check_every`` is v1's residual read-back period (``jacobi`` only);
    ``factorization`` is the direct solver's; ``preconditioner`` ("auto", "host", "dense", "blocks",
    "factors") and ``precision`` are the warped preconditioner's. "auto" takes "factors" (CHOLMOD's
    sparse factor per world, :class:`WorldFactors`) for a model of several worlds on CUDA, and
    leaves one world to :class:`WarpedFactor` (dense on CUDA up to its limit, else host); "blocks"
    keeps a dense inverse per world instead (:class:`WorldBlocks`: on one H200, 1024 Diamonds of 4
    meshes, 4 blocks either way, stepped in 87.23 ms with it against 44.12 ms with "factors"; 1024
    different meshes would need 70 GB of dense inverses). ``share_tolerance``: when worlds share a
    block. ``block``: ``pcg`` solves a world's columns as one
    block (:class:`PCG`), its directions stored as ``directions`` says."""
    name = choose(name, operator.model.device)
    if name == "direct":
        return SparseDirect(operator, factorization)
    if name == "jacobi":
        if check_every is None:
            check_every = 16 if operator.model.device.is_cuda else 1
        return BlockJacobiCG(operator, BlockJacobi(operator), columns, tolerance, max_iterations, int(check_every),
                             graphs)
    model = operator.model
    if preconditioner not in PRECONDITIONERS:
        raise ValueError(f"preconditioner must be one of {', '.join(PRECONDITIONERS)}, got {preconditioner!r}")
    if preconditioner == "factors" or (preconditioner == "auto" and model.device.is_cuda and model.num_worlds > 1):
        warp_pre = WorldFactors(operator, columns, precision, share_tolerance=share_tolerance)
    elif preconditioner == "blocks":
        warp_pre = WorldBlocks(operator, columns, precision, share_tolerance=share_tolerance)
    else:
        warp_pre = WarpedFactor(operator, columns, preconditioner, precision)
    return PCG(operator, warp_pre, columns, tolerance, max_iterations, graphs, block, directions)


__all__ = ["PCG", "SOLVERS", "BlockJacobi", "BlockJacobiCG", "SolveResult", "SparseDirect", "SystemOperator",
           "WarpedFactor", "WorldBlocks", "WorldFactors", "choose", "make_solver"]
