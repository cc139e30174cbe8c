"""Step wall time against the step graph's time for N Diamond designs (the host's share)."""
import sys
import time

import numpy as np

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

n = int(sys.argv[1])
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in bb.designs(n, 4)]
sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", share_tolerance=0.01)
rows = []
for _ in range(12):
    t0 = time.perf_counter()
    st = sim.step()
    rows.append((1e3 * (time.perf_counter() - t0), 1e3 * st.stages.get("device_step", np.nan), st.cg_iterations))
rows = np.array(rows[3:])
host = rows[:, 0] - rows[:, 1]
print(f"{n} designs: step {np.median(rows[:, 0]):.1f} ms, graph {np.median(rows[:, 1]):.1f} ms, "
      f"the rest (host) {np.median(host):.1f} ms (min {host.min():.1f}, max {host.max():.1f}), "
      f"CG {rows[:, 2].tolist()}")
