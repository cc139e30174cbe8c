"""Session 29c: the factors' setup (Simulator, first step: every block factorized and laid out)
of N different Diamonds on the GPU machine's host, with W worker processes. From the
repository's root, with WARPSOFT_MESH_CACHE set: python3 docs/bench-batch/cuda-setup/study_workers.py 256 16"""
import sys
import time

import warp as wp

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402
from warpsoft.linear import factors  # noqa: E402

n, workers = int(sys.argv[1]), int(sys.argv[2])
factors.WORKERS = workers
ds = bb.designs(1024, 1024)[:: 1024 // n]
t = time.perf_counter()
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in ds]
t0 = time.perf_counter()
sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", solver="pcg", preconditioner="factors",
                   share_tolerance=0.01)
t1 = time.perf_counter()
st = sim.step()
wp.synchronize_device("cuda")
t2 = time.perf_counter()
print(f"n {n} workers {workers}: scenes {t0 - t:.1f} s, simulator {t1 - t0:.1f} s, first step {t2 - t1:.1f} s, "
      f"total {t2 - t:.1f} s, CG {st.cg_iterations}", flush=True)
