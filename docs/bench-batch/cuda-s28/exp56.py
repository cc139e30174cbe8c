"""Cost of a CG iteration's parts with a share of the worlds converged (1024 Diamonds, GPU)."""
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402
from warpsoft.kernels.linear.cg import DONE  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402

n = int(sys.argv[1])
ds = bb.designs(n, 4)
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in ds]
sim = ws.Simulator(ws.finalize(scenes, "cuda"), device="cuda", share_tolerance=0.01)
for _ in range(4):
    sim.step()
sol, pre, op = sim.solver, sim.solver.precond, sim.operator
dev = sim.model.device
x = wp.zeros_like(sol.r)
k = sol.r.shape[0]
def med(f, rep=20):
    ts = []
    for _ in range(rep):
        wp.synchronize_device(dev)
        t0 = time.perf_counter()
        f()
        wp.synchronize_device(dev)
        ts.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(ts))
for mode, frac in [("slot", f) for f in (0.0, 0.5, 0.75, 0.9, 1.0)] + [("spread", f) for f in (0.5, 0.75, 0.9)]:
    s = np.zeros(sol.scal.shape)
    slot = np.zeros(sim.model.num_worlds, dtype=int)
    for b in range(pre.blocks):
        ws_ = np.flatnonzero(pre.block_of == b)
        slot[ws_] = np.arange(len(ws_))
    spread = np.arange(sim.model.num_worlds) % 256
    done = (slot if mode == "slot" else spread) >= int(256 * (1 - frac))
    s[:, done, DONE] = 1.0
    sol.scal.assign(s)
    a = med(lambda: pre.apply(sol.r, sol.z))
    b = med(lambda: op.apply(sol.p, sol.ap, sol.scal))
    sd = wp.array(s, dtype=wp.float64, device=dev)
    c = med(lambda sd=sd: (wp.copy(sol.scal, sd), sol._iteration(x)))
    print(f"{mode} done {frac:.2f}: P^-1 {a:.2f} ms  A {b:.2f} ms  iteration {c:.2f} ms", flush=True)
