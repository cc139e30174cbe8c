"""CUDA: 8 Diamonds batched, block CG against column CG: trajectories and iterations."""
import sys

import numpy as np

sys.path.insert(0, "tools")
from batch_bench import ROOT, designs

import warpsoft as ws
from warpsoft.io.runner import build_scene

scenes = [build_scene(ROOT / "scenes/diamond.py", d) for d in designs(8, 4)]
out = {}
for block in (True, False):
    sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", share_tolerance=0.01, block_cg=block)
    tr, its = [], []
    for _ in range(20):
        st = sim.step()
        tr.append(sim.probe_array())
        its.append([w.cg_iterations for w in st.worlds])
    out[block] = (np.array(tr), np.array(its))
    print("block" if block else "column", "world its mean", np.mean(its), "max", np.max(its),
          "converged", st.converged)
a, b = out[True][0], out[False][0]
print("probe gap block-column (m)", np.abs(a - b).max(), "motion", np.abs(b - b[0]).max())
