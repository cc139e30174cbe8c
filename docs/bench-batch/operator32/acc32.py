import sys, numpy as np, warp as wp
sys.path.insert(0, "tools")
import batch_bench
import warpsoft as ws
from warpsoft.io.runner import build_scene
wp.config.quiet = True
n = int(sys.argv[1]); steps = int(sys.argv[2])
designs = batch_bench.designs(n, n)
scenes = [build_scene(batch_bench.ROOT / "scenes/diamond.py", d) for d in designs]
res = {}
for name, prec, tol in (("ref", "float64", 1e-10), ("f64", "float64", 1e-6), ("f32", "float32", 1e-6)):
    sim = ws.Simulator(ws.finalize(scenes, "cpu"), device="cpu", solver="pcg", preconditioner="factors",
                       share_tolerance=0.01, operator="assembled", operator_precision=prec, tolerance=tol)
    its = []
    for s in range(steps):
        st = sim.step(); its.append([w.cg_iterations for w in st.worlds])
    res[name] = (np.array([sim.positions(w) for w in range(n)], dtype=object), np.array(its))
    print(name, "CG per step (max over worlds):", np.array(its).max(axis=1).tolist(), "world mean %.2f" % np.mean(its), flush=True)
m = sim.model
for name in ("f64", "f32"):
    errs = []
    for w in range(n):
        q, r = res[name][0][w], res["ref"][0][w]
        moved = np.abs(r - m.rest_np[m.world_nodes(w)]).max()
        errs.append(np.abs(q - r).max() / moved)
    print(name, "max |q - q_ref| / max displacement, by world:", " ".join(f"{e:.2e}" for e in errs))
