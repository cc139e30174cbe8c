"""CUDA smoke: the panels' product against the rows' for three beams and for two Diamonds, each lane count."""
import numpy as np
import warp as wp
from warpsoft.kernels.linear.cg import NUM_SCALARS

import warpsoft as ws
from warpsoft.linear import WorldFactors


def beam(young_modulus=1e6, cells=20, across=2):
    scene = ws.Scene("beam", gravity=(0, 0, -9.81), dt=0.02, static=True)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (cells, across, across)),
                          ws.Material(young_modulus, 0.45, 1000.0))
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, -0.2))
    return scene


sim = ws.Simulator(ws.finalize([beam(), beam(3e6), beam(cells=40, across=6)]), solver="direct", device="cuda")
for _ in range(3):
    sim.step()
n = sim.model.num_nodes
r = wp.array(np.random.default_rng(1).standard_normal((2, n, 3)), dtype=wp.vec3d, device="cuda")
out = {}
for layout, spread in (("rows", None), ("panels", (4.0, 1.0)), ("panels", (1.0, 1.0)), ("panels", (64.0, 1.0)),
                       ("panels", (16.0, 1.0))):
    pre = WorldFactors(sim.operator, 2, "float32", layout=layout)
    if spread:
        pre.panel_spread = spread
    pre.watch(wp.zeros((2, 3, NUM_SCALARS), dtype=wp.float64, device="cuda"))
    pre.prepare()
    z = wp.zeros((2, n), dtype=wp.vec3d, device="cuda")
    pre.apply(r, z)
    out[layout, spread] = z.numpy().copy()
    lanes = [pre.panel_lanes(lv[2], 0) for s in pre.solves for lv in s[3]] if layout == "panels" else None
    rows = out["rows", None]
    print(layout, spread, lanes, np.abs(out[layout, spread] - rows).max() / np.abs(rows).max(), flush=True)
