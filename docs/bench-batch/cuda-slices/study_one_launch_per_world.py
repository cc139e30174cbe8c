"""Session 29: the factors' triangular solves as one launch per direction (a block per world,
barriers between levels) against one launch per level, 1024 different Diamonds: P^-1 alone at
fractions of worlds running, per block size; then whole steps alternated. Runs on 8816de6 with
one_launch_per_world.diff applied (the variant was not kept); from the repository's root, with
WARPSOFT_MESH_CACHE set: python3 docs/bench-batch/cuda-slices/study_one_launch_per_world.py 1024 1024"""
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
factors.SCHEDULE = "levels"
scenes = [build_scene(bb.ROOT / "scenes/diamond.py", d) for d in bb.designs(n, meshes)]
t = time.perf_counter()
sim = ws.Simulator(ws.finalize(scenes, DEV), device=DEV, solver="pcg", preconditioner="factors",
                   share_tolerance=0.01)
for _ in range(3):
    sim.step()
pre, solver = sim.solver.precond, sim.solver
print(f"meshes {meshes} worlds {n}: setup {time.perf_counter() - t:.1f} s, levels {pre.levels}, k {solver.r.shape[0]}",
      flush=True)


def use(schedule, threads):
    pre.schedule, pre.threads, pre.solves = schedule, threads, None
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
VARIANTS = [("levels", 256), ("worlds", 128), ("worlds", 256), ("worlds", 512), ("worlds", 64), ("worlds", 1024)]
best = {}
for schedule, threads in VARIANTS:
    use(schedule, threads)
    line = []
    for f in fractions:
        solver.scal.assign(masks[f])
        pre.apply(r, z)  # compile
        tm = med(lambda: pre.apply(r, z))
        if f == 1.0:
            out = z.numpy()
            ref = out.copy() if ref is None else ref
            diff = np.abs(out - ref).max() / np.abs(ref).max()
            best[(schedule, threads)] = tm
        line.append(f"{f:.2f}: {1e3 * tm:6.3f} ms")
    print(f"P^-1 {schedule:6s} {threads:4d}: " + "  ".join(line) + f"  diff {diff:.1e}", flush=True)
solver.scal.zero_()
for f in fractions:
    solver.scal.assign(masks[f])
    print(f"A at {f:.2f}: {1e3 * med(lambda: sim.operator.apply(solver.p, solver.ap)):.3f} ms", flush=True)
solver.scal.zero_()
choice = min((tm, th) for (sc, th), tm in best.items() if sc == "worlds")[1]
print("worlds threads chosen:", choice, flush=True)

for label, (schedule, threads) in (("levels", ("levels", 256)), ("worlds", ("worlds", choice))) * 2:
    use(schedule, threads)
    sim.graphs.clear()
    solver._graphs.clear()
    sim.step()
    sts = [sim.step() for _ in range(8)]
    times = [s.total for s in sts]
    graphs = [sum(v for kk, v in s.stages.items() if kk in bb.GRAPHS) for s in sts]
    print(f"steps {label} {threads}: median {1e3 * np.median(times):.2f} ms graphs {1e3 * np.median(graphs):.2f} ms "
          f"CG {np.median([s.cg_iterations for s in sts]):.0f} {n / np.median(times):.1f} design-steps/s "
          f"(steps {sts[0].index}-{sts[-1].index})", flush=True)
