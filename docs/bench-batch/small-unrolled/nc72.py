"""ncu target: one P^-1 of the factors with every world running, 256 different Diamonds, between
cuProfilerStart and cuProfilerStop."""
import ctypes
import sys

import numpy as np
import warp as wp

sys.path.insert(0, "tools")
import batch_bench  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

n = int(sys.argv[1]) if len(sys.argv) > 1 else 256
ds = batch_bench.designs(1024, 1024)[:n]
scenes = [build_scene(batch_bench.ROOT / "scenes/diamond.py", d) for d in ds]
sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", solver="pcg", block_cg=True,
                   preconditioner="factors", share_tolerance=0.01)
sim.step()
pre, solver, m = sim.solver.precond, sim.solver, sim.model
k = solver.r.shape[0]
r = wp.array(np.random.default_rng(0).standard_normal((k, m.num_nodes, 3)) * m.mask_np, dtype=wp.vec3d, device="cuda")
z = wp.zeros_like(r)
pre.watch(wp.zeros(solver.scal.shape, dtype=wp.float64, device="cuda"))
pre.apply(r, z)
wp.synchronize()
cuda = ctypes.CDLL("libcuda.so.1")
with wp.ScopedDevice("cuda:0"):
    print("start", cuda.cuProfilerStart(), flush=True)
    pre.apply(r, z)
    wp.synchronize()
    print("stop", cuda.cuProfilerStop(), flush=True)
