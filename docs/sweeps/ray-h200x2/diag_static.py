import sys, time
import numpy as np
import warpsoft as ws
from warpsoft.io.runner import build_scene
for leg in (0.011, 0.009):
    for pre in ("auto",):
        scenes = [build_scene("examples/diamond_workspace.py", {"leg_radius": leg, "young_modulus": e}) for e in np.linspace(1.2e5, 2.6e5, 8)]
        t0 = time.perf_counter()
        sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", timing=True)
        print(f"leg {leg} {pre}: setup {time.perf_counter() - t0:.1f} s, preconditioner {type(getattr(sim.solver, 'precond', None)).__name__}", flush=True)
        for k in range(20):
            t = time.perf_counter()
            st = sim.step()
            pc = getattr(sim.solver, "precond", None)
            stages = {s: round(1e3 * v, 1) for s, v in st.stages.items() if v > 0.002}
            print(f"  step {k+1:2d} {1e3 * (time.perf_counter() - t):8.1f} ms  CG {st.cg_iterations:5d}  newton {st.newton_iterations:2d}  ls {st.line_searches}  refreshes {getattr(pc, 'refreshes', None)}  {stages}", flush=True)
