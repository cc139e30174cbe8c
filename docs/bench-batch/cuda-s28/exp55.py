"""Per-world CG iterations of 1024 Diamond designs (tools/batch_bench.py's) on the GPU."""
import sys
import time

import numpy as np

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

n, out = int(sys.argv[1]), sys.argv[2]
ds = bb.designs(n, 4)
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in ds]
sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", share_tolerance=0.01)
its, times = [], []
for k in range(int(sys.argv[3])):
    t0 = time.perf_counter()
    st = sim.step()
    times.append(time.perf_counter() - t0)
    its.append([w.cg_iterations for w in st.worlds])
    print(k, st.cg_iterations, round(1e3 * times[-1], 2), flush=True)
pre = sim.solver.precond
np.savez(out, its=np.array(its), times=np.array(times), block_of=pre.block_of, scale=pre.scale_np,
         moduli=np.array([d["young_modulus"] for d in ds]), radius=np.array([d["leg_radius"] for d in ds]))
a = np.array(its)
for k in range(a.shape[0]):
    print(k, "max", a[k].max(), "mean", a[k].mean().round(1), "argmax", a[k].argmax(), "hist",
          np.bincount(a[k]).tolist())
