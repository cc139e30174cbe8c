"""1024 Diamond designs for 40 steps: the shared blocks refreshed when the iterations grow (as
now), or never; per-step max and mean of the worlds' CG iterations, and the step times."""
import sys
import time

import numpy as np

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

n, steps = int(sys.argv[1]), int(sys.argv[2])
ds = bb.designs(n, 4)
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in ds]
for policy in sys.argv[3:]:
    sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", share_tolerance=0.01)
    if policy == "never":
        sim.solver.precond.refresh_floor = 10 ** 9
    rows = []
    for k in range(steps):
        t0 = time.perf_counter()
        st = sim.step()
        its = np.array([w.cg_iterations for w in st.worlds])
        rows.append((k, 1e3 * (time.perf_counter() - t0), its.max(), its.mean()))
    print(policy, "refreshes", sim.solver.precond.refreshes)
    for r in rows:
        print(policy, f"{r[0]} {r[1]:.1f} ms max {r[2]} mean {r[3]:.1f}")
    t = np.array([r[1] for r in rows[3:]])
    print(policy, f"steps 3..: total {t.sum():.0f} ms, median {np.median(t):.1f} ms", flush=True)
