"""Where a step of 1024 Diamond designs goes: its stages, and the host's profile of one step."""
import cProfile
import pstats
import sys
import time

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

n = int(sys.argv[1])
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in bb.designs(n, 4)]
sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", share_tolerance=0.01)
for k in range(8):
    t0 = time.perf_counter()
    st = sim.step()
    print(k, f"{1e3 * (time.perf_counter() - t0):.1f} ms", st.cg_iterations, st.newton_iterations,
          {a: round(1e3 * b, 2) for a, b in st.stages.items()}, flush=True)
prof = cProfile.Profile()
prof.enable()
sim.step()
prof.disable()
pstats.Stats(prof).sort_stats("cumulative").print_stats(30)
