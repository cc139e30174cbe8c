"""CG tolerance against accuracy and iterations, 8 Diamonds batched on the CPU device (pcg + blocks).

    python cpu_tolerance_study.py N STEPS TOL1,TOL2,... BLOCK   (run from the repository root)

The first tolerance is the reference the others are measured against (probe positions).
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path.cwd() / "tools"))
from batch_bench import ROOT, designs  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

block = sys.argv[4] == "1" if len(sys.argv) > 4 else True
n = int(sys.argv[1]) if len(sys.argv) > 1 else 8
steps = int(sys.argv[2]) if len(sys.argv) > 2 else 30
tols = [float(t) for t in sys.argv[3].split(",")] if len(sys.argv) > 3 else [1e-9, 1e-6, 1e-5, 1e-4, 1e-3]
scenes = [build_scene(ROOT / "scenes/diamond.py", d) for d in designs(n, 4)]
runs = {}
for tol in tols:
    sim = ws.Simulator(ws.finalize(scenes, "cpu"), device="cpu", solver="pcg", preconditioner="blocks",
                       share_tolerance=0.01, tolerance=tol, block_cg=block)
    traj, its, newton, t = [], [], [], time.perf_counter()
    for _ in range(steps):
        st = sim.step()
        traj.append(sim.probe_array())
        its.append([w.cg_iterations for w in st.worlds])
        newton.append([w.newton_iterations for w in st.worlds])
    runs[tol] = np.array(traj)
    its, newton = np.array(its), np.array(newton)
    print(f"tol {tol:g}: world CG mean {its.mean():.2f} (steps 3+: {its[3:].mean():.2f}) max {its.max()} "
          f"newton mean {newton.mean():.3f} max {newton.max()}  wall {time.perf_counter() - t:.1f}s", flush=True)
ref = runs[tols[0]]
motion = np.abs(ref - ref[:1]).max()
print("motion (m)", motion)
for tol in tols[1:]:
    err = np.linalg.norm(runs[tol] - ref, axis=-1)
    print(f"tol {tol:g}: probe error max {err.max():.3e} m = {err.max() / motion:.2e} of motion; "
          f"final {err[-1].max():.3e}")
