"""The float32 blocks' accuracy (run at the trial's tree, operator32-trial.patch on b311cc3):
``python acc32.py DESIGNS STEPS`` from the repository root, on the CPU. Positions after STEPS steps
with float64 blocks at the solver's tolerance and with float32 blocks, against float64 blocks at
1e-10, over the largest displacement, world by world."""

import sys

import numpy as np
import warp as wp

import warpsoft as ws
from warpsoft.io.runner import build_scene

sys.path.insert(0, "tools")
import batch_bench  # noqa: E402

wp.config.quiet = True
n, steps = int(sys.argv[1]), int(sys.argv[2])
scenes = [build_scene(batch_bench.ROOT / "scenes/diamond.py", d) for d in batch_bench.designs(n, n)]
positions = {}
for name, precision, tolerance in (("ref", "float64", 1e-10), ("f64", "float64", 1e-6), ("f32", "float32", 1e-6)):
    sim = ws.Simulator(ws.finalize(scenes, "cpu"), device="cpu", solver="pcg", preconditioner="factors",
                       share_tolerance=0.01, operator="assembled", operator_precision=precision, tolerance=tolerance)
    its = np.array([[w.cg_iterations for w in sim.step().worlds] for _ in range(steps)])
    positions[name] = [sim.positions(w) for w in range(n)]
    print(name, "CG per step (max over worlds):", its.max(axis=1).tolist(), f"world mean {its.mean():.2f}", flush=True)
m = sim.model
for name in ("f64", "f32"):
    errors = []
    for w in range(n):
        q, ref = positions[name][w], positions["ref"][w]
        errors.append(np.abs(q - ref).max() / np.abs(ref - m.rest_np[m.world_nodes(w)]).max())
    print(name, "max |q - q_ref| / max displacement, by world:", " ".join(f"{e:.2e}" for e in errors))
