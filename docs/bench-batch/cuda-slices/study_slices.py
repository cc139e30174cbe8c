"""Session 29b: the factors' short-row levels with entries in slices of `width` rows (sliced
ELLPACK, coalesced thread-per-row reads) against contiguous rows (width 1), 1024 different
Diamonds: P^-1 alone at fractions of worlds running; then whole steps alternated (each round
steps on from the last, so later rounds run harder steps: compare P^-1, not the rounds). From the
repository's root, with WARPSOFT_MESH_CACHE set: python3 docs/bench-batch/cuda-slices/study_slices.py 1024 1024"""
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, "tools")
import batch_bench as bb  # noqa: E402
from warpsoft.kernels.linear.cg import DONE  # noqa: E402

import warpsoft as ws  # noqa: E402
from warpsoft.io.runner import build_scene  # noqa: E402
from warpsoft.linear import factors  # noqa: E402

meshes, n = int(sys.argv[1]), int(sys.argv[2])
DEV = "cuda"
kept = {}
orig_lay_out = factors.WorldFactors._lay_out


def lay_out(self, programs):
    kept["programs"] = programs
    orig_lay_out(self, programs)


factors.WorldFactors._lay_out = lay_out
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in bb.designs(n, meshes)]
t = time.perf_counter()
sim = ws.Simulator(ws.finalize(scenes, DEV), device=DEV, solver="pcg", preconditioner="factors",
                   share_tolerance=0.01)
for _ in range(3):
    sim.step()
pre, solver = sim.solver.precond, sim.solver
print(f"meshes {meshes} worlds {n}: setup {time.perf_counter() - t:.1f} s, levels {pre.levels}, k {solver.r.shape[0]}",
      flush=True)


def use(width):
    pre.width, pre.solves = width, None
    orig_lay_out(pre, kept["programs"])


def med(f, k=15):
    ts = []
    for _ in range(k):
        wp.synchronize_device(DEV)
        t0 = time.perf_counter()
        f()
        wp.synchronize_device(DEV)
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


scal0 = solver.scal.numpy().copy()
r = wp.array(np.random.default_rng(0).standard_normal(solver.r.shape + (3,)), dtype=wp.vec3d, device=DEV)
z = wp.zeros_like(r)
rng = np.random.default_rng(1)
fractions = (1.0, 0.4, 0.1, 0.01)
masks = {}
for f in fractions:
    s = np.zeros(scal0.shape)
    s[:, rng.random(n) >= f, DONE] = 1.0
    masks[f] = s
ref = None
VARIANTS = [1, 32, 16]
best = {}
for width in VARIANTS:
    use(width)
    line = []
    for f in fractions:
        solver.scal.assign(masks[f])
        pre.apply(r, z)  # compile
        tm = med(lambda: pre.apply(r, z))
        if f == 1.0:
            out = z.numpy()
            ref = out.copy() if ref is None else ref
            diff = np.abs(out - ref).max() / np.abs(ref).max()
            best[width] = tm
        line.append(f"{f:.2f}: {1e3 * tm:6.3f} ms")
    print(f"P^-1 width {width:3d} entries {pre.entries}: " + "  ".join(line) + f"  diff {diff:.1e}", flush=True)
solver.scal.zero_()
choice = min((tm, w) for w, tm in best.items() if w > 1)[1]
print("width chosen:", choice, flush=True)

for label, width in (("contiguous", 1), ("sliced", choice)) * 3:
    use(width)
    sim.graphs.clear()
    solver._graphs.clear()
    sim.step()
    sts = [sim.step() for _ in range(6)]
    times = [s.total for s in sts]
    graphs = [sum(v for kk, v in s.stages.items() if kk in bb.GRAPHS) for s in sts]
    print(f"steps {label} {width}: median {1e3 * np.median(times):.2f} ms graphs {1e3 * np.median(graphs):.2f} ms "
          f"CG {np.median([s.cg_iterations for s in sts]):.0f} {n / np.median(times):.1f} design-steps/s "
          f"(steps {sts[0].index}-{sts[-1].index})", flush=True)
