"""Per-sweep cost of the Grasper's Gauss-Seidel: steps run uncaptured and timed, the resolve
stage divided by that step's sweeps, median over 40 steps of the lift phase (steps 121-160).

    python tools/gs_sweep.py DEVICE device|host

``host``: the sweeps on the host between the device's stages (CUDA's default with contacts);
``device``: on the device, one thread per world."""
import sys

import numpy as np

import warpsoft as ws
from warpsoft.io.runner import build_scene

device, host_gs = sys.argv[1], sys.argv[2] == "host"
sim = ws.Simulator(build_scene("scenes/grasper.py", {}), device=device, graphs=False, timing=True)
sim.host_gauss_seidel = host_gs
per, sweeps, total = [], [], []
for k in range(160):
    st = sim.step()
    if k >= 120:
        n = st.worlds[0].resolve_iterations
        per.append(st.stages["resolve"] / max(n, 1))
        sweeps.append(n)
        total.append(st.total)
print(f"{device} gs on {'host' if sim.host_gauss_seidel else 'device'}: {1e3 * np.median(per):.4f} ms per sweep "
      f"(median of 40 steps, {np.median(sweeps):.0f} sweeps median), step {1e3 * np.median(total):.1f} ms uncaptured")
