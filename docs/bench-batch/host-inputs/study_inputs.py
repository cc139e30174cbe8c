import sys, time
sys.path.insert(0, "/work/main/tools")
import numpy as np, warp as wp
wp.config.quiet = True
from batch_bench import designs
import warpsoft as ws
from warpsoft import Simulator, step as stepmod
from warpsoft.io.runner import build_scene
ds = designs(1024, 1)
for d in ds: d["mesh_size"] = 0.03
scenes = [build_scene("/work/main/scenes/diamond.py", d) for d in ds]
sim = Simulator(ws.finalize(scenes, "cpu"), solver="pcg", preconditioner="blocks", share_tolerance=0.01)
ctl = [None] * 1024
fast = getattr(stepmod, "own_inputs", None)
out = {}
for name in ["old", "new"] * 3:
    if name == "new" and fast is None: continue
    ts = []
    for k in range(20):
        t = 0.02 * (k + 1)
        t0 = time.perf_counter()
        if name == "new": v = stepmod.actuator_values(sim, t, ctl)
        else:
            # the per-actuator loop, as before this change
            rows = sim.rows; values = [0.0] * rows.num_rows
            for w, (acts, start, c) in enumerate(zip(rows.actuators, rows.world_row_start.tolist(), ctl)):
                for j, a in enumerate(acts): values[start + j] = a.input_at(t)
            v = np.array(values)
        ts.append(time.perf_counter() - t0)
    out.setdefault(name, []).append(1e3 * float(np.median(ts)))
print({k: [round(x, 2) for x in v] for k, v in out.items()})
