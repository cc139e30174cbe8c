"""Per step of a batch of 8 quasi-static Diamond workspace designs on CUDA (one leg radius, moduli
120-260 kPa): time, CG iterations, Newton iterations, line searches, refreshes, stage times."""

import time

import numpy as np

import warpsoft as ws
from warpsoft.io.runner import build_scene

for leg in (0.011, 0.009):
    scenes = [build_scene("examples/diamond_workspace.py", {"leg_radius": leg, "young_modulus": e})
              for e in np.linspace(1.2e5, 2.6e5, 8)]
    t0 = time.perf_counter()
    sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", timing=True)
    pre = getattr(sim.solver, "precond", None)
    print(f"leg {leg} auto: setup {time.perf_counter() - t0:.1f} s, preconditioner {type(pre).__name__}", flush=True)
    for k in range(20):
        t = time.perf_counter()
        st = sim.step()
        stages = {s: round(1e3 * v, 1) for s, v in st.stages.items() if v > 0.002}
        print(f"  step {k + 1:2d} {1e3 * (time.perf_counter() - t):8.1f} ms  CG {st.cg_iterations:5d}  "
              f"newton {st.newton_iterations:2d}  ls {st.line_searches}  refreshes {getattr(pre, 'refreshes', None)}  "
              f"{stages}", flush=True)
